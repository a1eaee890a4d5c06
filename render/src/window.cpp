#include <tessera/render/window.h>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>

#include <tessera/render/gl_context.h>

namespace tessera::render {

struct Window::Impl {
  GLFWwindow* window = nullptr;
  GLuint texture = 0, framebuffer = 0;
  uint32_t tex_w = 0, tex_h = 0;
  WindowInput pending;
  glm::dvec2 last_cursor{0.0};
  bool was_left = false;
  bool ui = false;        // enableUi() made an ImGui context
  bool ui_frame = false;  // beginUi() called, endUi() not yet
};

namespace {

std::string glfwFailure() {
  const char* text = nullptr;
  glfwGetError(&text);
  return text ? text : "unknown GLFW error";
}

Window::Impl* implOf(GLFWwindow* w) {
  return static_cast<Window::Impl*>(glfwGetWindowUserPointer(w));
}

/// A cursor position into the poll's path, with the buttons held there (GLFW's state is that
/// of the events handled so far, so a drag's points are told from those before and after it).
void pushPath(GLFWwindow* gw, double x, double y) {
  WindowInput& in = implOf(gw)->pending;
  if (in.path.size() >= 4096) return;
  in.path.push_back({x, y});
  in.path_buttons.push_back(uint8_t(
      (glfwGetMouseButton(gw, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS ? WindowInput::kLeftHeld : 0) |
      (glfwGetMouseButton(gw, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS ? WindowInput::kRightHeld
                                                                     : 0)));
}

}  // namespace

Window::Window() : mImpl(std::make_unique<Impl>()) {}

std::unique_ptr<Window> Window::open(uint32_t width, uint32_t height, const std::string& title) {
  const char* display = std::getenv("DISPLAY");
  const char* wayland = std::getenv("WAYLAND_DISPLAY");
  if ((!display || !*display) && (!wayland || !*wayland))
    throw RenderError("render::Window: no display (DISPLAY is not set); run headless instead");
  if (!glfwInit()) throw RenderError("render::Window: GLFW cannot start: " + glfwFailure());
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  GLFWwindow* w = glfwCreateWindow(int(width), int(height), title.c_str(), nullptr, nullptr);
  if (!w) {
    std::string why = glfwFailure();
    glfwTerminate();
    throw RenderError("render::Window: no OpenGL 4.5 core window: " + why);
  }
  std::unique_ptr<Window> win(new Window());
  win->mImpl->window = w;
  glfwSetWindowUserPointer(w, win->mImpl.get());
  glfwMakeContextCurrent(w);
  glfwSwapInterval(0);
  glfwSetScrollCallback(
      w, [](GLFWwindow* gw, double, double dy) { implOf(gw)->pending.scroll += dy; });
  // Button transitions are latched as they happen: a click shorter than a frame (a slow frame
  // on llvmpipe lasts a second) is a press and a release, not nothing.
  glfwSetMouseButtonCallback(w, [](GLFWwindow* gw, int button, int action, int) {
    WindowInput& in = implOf(gw)->pending;
    if (button == GLFW_MOUSE_BUTTON_LEFT) {
      if (action == GLFW_PRESS) in.left_pressed = true;
      if (action == GLFW_RELEASE) in.left_released = true;
    } else if (button == GLFW_MOUSE_BUTTON_RIGHT) {
      if (action == GLFW_PRESS) in.right_pressed = true;
      if (action == GLFW_RELEASE) in.right_released = true;
    } else {
      return;
    }
    // Where a drag begins, with the buttons held from now on.
    double x = 0.0, y = 0.0;
    glfwGetCursorPos(gw, &x, &y);
    pushPath(gw, x, y);
  });
  glfwSetCursorPosCallback(w, [](GLFWwindow* gw, double x, double y) { pushPath(gw, x, y); });
  glfwSetKeyCallback(w, [](GLFWwindow* gw, int key, int, int action, int) {
    if (action == GLFW_PRESS) implOf(gw)->pending.keys.push_back(key);
    // Escape in a text field of the panels leaves the field, not the session.
    if (key == GLFW_KEY_ESCAPE && action == GLFW_PRESS &&
        !(implOf(gw)->ui && ImGui::GetIO().WantCaptureKeyboard))
      glfwSetWindowShouldClose(gw, GLFW_TRUE);
  });
  glfwGetCursorPos(w, &win->mImpl->last_cursor.x, &win->mImpl->last_cursor.y);
  return win;
}

Window::~Window() {
  if (mImpl->ui) {  // with the context still current
    if (mImpl->ui_frame) ImGui::EndFrame();
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
  }
  if (mImpl->framebuffer) glDeleteFramebuffers(1, &mImpl->framebuffer);
  if (mImpl->texture) glDeleteTextures(1, &mImpl->texture);
  glfwDestroyWindow(mImpl->window);
  glfwTerminate();
}

bool Window::closing() const {
  return glfwWindowShouldClose(mImpl->window);
}

void Window::setTitle(const std::string& title) {
  glfwSetWindowTitle(mImpl->window, title.c_str());
}

void Window::present(uint32_t image_buffer, uint32_t width, uint32_t height) {
  Impl& s = *mImpl;
  if (s.tex_w != width || s.tex_h != height) {
    if (s.framebuffer) glDeleteFramebuffers(1, &s.framebuffer);
    if (s.texture) glDeleteTextures(1, &s.texture);
    glCreateTextures(GL_TEXTURE_2D, 1, &s.texture);
    glTextureStorage2D(s.texture, 1, GL_RGBA8, GLsizei(width), GLsizei(height));
    glCreateFramebuffers(1, &s.framebuffer);
    glNamedFramebufferTexture(s.framebuffer, GL_COLOR_ATTACHMENT0, s.texture, 0);
    s.tex_w = width;
    s.tex_h = height;
  }
  glMemoryBarrier(GL_PIXEL_BUFFER_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT);
  glBindBuffer(GL_PIXEL_UNPACK_BUFFER, image_buffer);
  glTextureSubImage2D(s.texture, 0, 0, 0, GLsizei(width), GLsizei(height), GL_RGBA,
                      GL_UNSIGNED_BYTE, nullptr);
  glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
  int fw = 0, fh = 0;
  glfwGetFramebufferSize(s.window, &fw, &fh);
  // The image's first row is the top: flip while blitting into GL's bottom-up framebuffer.
  glBlitNamedFramebuffer(s.framebuffer, 0, 0, 0, GLint(width), GLint(height), 0, fh, fw, 0,
                         GL_COLOR_BUFFER_BIT, GL_LINEAR);
  // The panels over the picture, from the last frame ended (ImGui keeps its draw data).
  ImDrawData* ui = s.ui ? ImGui::GetDrawData() : nullptr;
  if (ui && ui->Valid) {
    glBindFramebuffer(GL_FRAMEBUFFER, 0);  // the backend draws into the bound framebuffer
    ImGui_ImplOpenGL3_RenderDrawData(ui);
  }
  glfwSwapBuffers(s.window);
  // The back buffer is undefined after a swap: draw the frame into it again so that
  // readFramebuffer() and the next partial update see what is on screen.
  glBlitNamedFramebuffer(s.framebuffer, 0, 0, 0, GLint(width), GLint(height), 0, fh, fw, 0,
                         GL_COLOR_BUFFER_BIT, GL_LINEAR);
  if (ui && ui->Valid) ImGui_ImplOpenGL3_RenderDrawData(ui);
}

void Window::enableUi() {
  Impl& s = *mImpl;
  if (s.ui) return;
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // the panels start where the console puts them, every session
  // A hinted sans-serif reads better than the built-in bitmap font in a screenshot; the
  // built-in one where it is not installed. DejaVu Sans gives Latin, Greek and Cyrillic; Noto
  // Sans CJK (merged) the kana and the ideographs of Japanese and Chinese titles in the panels.
  // Dear ImGui neither shapes nor orders right to left, nor draws beyond the 16-bit range: the
  // wall's labels do (text_shaper.h).
  static const ImWchar kPanelRanges[] = {0x0020, 0x024F, 0x0370, 0x03FF, 0x0400, 0x04FF,
                                         0x1F00, 0x1FFF, 0x2000, 0x206F, 0x20A0, 0x20CF,
                                         0x2100, 0x214F, 0x2190, 0x21FF, 0};
  const char* font = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
  const char* cjk = "/usr/share/fonts/opentype/noto/NotoSansCJK-Regular.ttc";
  if (std::error_code ec; std::filesystem::exists(font, ec)) {
    io.Fonts->AddFontFromFileTTF(font, 14.0f, nullptr, kPanelRanges);
    if (std::filesystem::exists(cjk, ec)) {
      ImFontConfig merge;
      merge.MergeMode = true;
      io.Fonts->AddFontFromFileTTF(cjk, 14.0f, &merge,
                                   io.Fonts->GetGlyphRangesChineseSimplifiedCommon());
      io.Fonts->AddFontFromFileTTF(cjk, 14.0f, &merge, io.Fonts->GetGlyphRangesJapanese());
    }
  }
  ImGui::StyleColorsDark();
  ImGui::GetStyle().WindowRounding = 3.0f;
  ImGui::GetStyle().Alpha = 0.92f;
  // Installed after the window's callbacks: the backend keeps them and calls them first.
  ImGui_ImplGlfw_InitForOpenGL(s.window, true);
  ImGui_ImplOpenGL3_Init("#version 450");
  s.ui = true;
}

void Window::beginUi() {
  Impl& s = *mImpl;
  if (!s.ui) return;
  if (s.ui_frame) ImGui::EndFrame();  // a frame begun and never ended: dropped
  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
  s.ui_frame = true;
}

void Window::endUi() {
  Impl& s = *mImpl;
  if (!s.ui_frame) return;
  ImGui::Render();
  s.ui_frame = false;
}

bool Window::uiWantsMouse() const {
  return mImpl->ui && ImGui::GetIO().WantCaptureMouse;
}

bool Window::uiWantsKeyboard() const {
  return mImpl->ui && ImGui::GetIO().WantCaptureKeyboard;
}

void Window::withoutWhatUiTook(WindowInput& in, bool right_held) const {
  if (uiWantsMouse()) {
    in.left = in.left_pressed = in.left_released = false;
    in.scroll = 0.0;
    in.path.clear();
    in.path_buttons.clear();
    if (!right_held) in.right = false;
  }
  if (uiWantsKeyboard()) in.keys.clear();
}

std::vector<uint8_t> Window::readFramebuffer(uint32_t& width, uint32_t& height) const {
  int fw = 0, fh = 0;
  glfwGetFramebufferSize(mImpl->window, &fw, &fh);
  width = uint32_t(fw);
  height = uint32_t(fh);
  std::vector<uint8_t> rows(size_t(fw) * size_t(fh) * 4), out(rows.size());
  glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  glReadBuffer(GL_BACK);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, fw, fh, GL_RGBA, GL_UNSIGNED_BYTE, rows.data());
  const size_t stride = size_t(fw) * 4;
  for (int y = 0; y < fh; ++y)  // GL's rows run bottom-up
    std::copy_n(&rows[size_t(fh - 1 - y) * stride], stride, &out[size_t(y) * stride]);
  return out;
}

WindowInput Window::poll() {
  Impl& s = *mImpl;
  glfwPollEvents();
  WindowInput in = std::move(s.pending);
  s.pending = WindowInput{};
  glfwGetCursorPos(s.window, &in.cursor.x, &in.cursor.y);
  in.cursor_delta = in.cursor - s.last_cursor;
  s.last_cursor = in.cursor;
  in.left = glfwGetMouseButton(s.window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
  in.right = glfwGetMouseButton(s.window, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
  in.middle = glfwGetMouseButton(s.window, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
  in.left_pressed = in.left_pressed || (in.left && !s.was_left);
  in.left_released = in.left_released || (!in.left && s.was_left);
  s.was_left = in.left;
  int w = 0, h = 0;
  glfwGetWindowSize(s.window, &w, &h);
  in.size = glm::uvec2(uint32_t(w), uint32_t(h));
  return in;
}

}  // namespace tessera::render
