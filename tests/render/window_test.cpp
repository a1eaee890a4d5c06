// The windowed context shows exactly the pixels the headless renderer makes (same renderer code
// on both). Needs a display: ctest runs it under xvfb-run (Mesa llvmpipe through GLX); without
// one it is skipped, and the refusal is tested instead.
#include <gtest/gtest.h>

#include <cstdlib>

#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/view_renderer.h>
#include <tessera/render/window.h>

#include <glm/gtc/matrix_transform.hpp>

#include <imgui.h>

#include "../support/temp_dir.h"

namespace tessera::render {
namespace {

TEST(Window, ShowsTheRenderersPixelsAndMatchesHeadless) {
  const char* display = std::getenv("DISPLAY");
  if (!display || !*display) GTEST_SKIP() << "no display (ctest runs this under xvfb-run)";
  test::TempDir dir;
  lod::BuildOptions o;
  o.quiet = true;
  lod::buildStore({std::string(TESSERA_DATA_DIR) + "/stanford-bunny/scans/bun.conf"},
                  dir / "b.tlod", o);
  auto store = lod::PointStore::open(dir / "b.tlod");
  ModelInstance inst{store.get(), storeModel(*store)};
  config::Camera cam;
  cam.mutable_eye()->set_x(-0.02);
  cam.mutable_eye()->set_y(0.11);
  cam.mutable_eye()->set_z(0.35);
  cam.mutable_target()->set_x(-0.02);
  cam.mutable_target()->set_y(0.1);
  cam.mutable_up()->set_y(1);
  ViewSetup v;
  v.view = cameraView(cam);
  v.projection = glm::perspective(glm::radians(40.0), 320.0 / 240.0, 0.01, 10.0);
  v.width = 320;
  v.height = 240;
  v.eye_world = {-0.02, 0.11, 0.35};
  RenderOptions opt;
  opt.edl.strength = 1.0f;

  Image windowed;
  {
    auto win = Window::open(320, 240, "tessera window test");
    ViewRenderer r(320, 240);
    windowed = r.renderSettled({&inst, 1}, v, opt);
    win->present(r.imageBuffer(), 320, 240);
    uint32_t w = 0, h = 0;
    std::vector<uint8_t> shown = win->readFramebuffer(w, h);
    ASSERT_EQ(w, 320u);
    ASSERT_EQ(h, 240u);
    size_t differ = 0;
    for (size_t i = 0; i < shown.size(); i += 4)
      differ += std::memcmp(&shown[i], &windowed.rgba[i], 3) != 0;
    EXPECT_EQ(differ, 0u) << "the window shows other pixels than the renderer made";
  }
  auto ctx = GlContext::createHeadless();
  ViewRenderer r(320, 240);
  EXPECT_EQ(r.renderSettled({&inst, 1}, v, opt).rgba, windowed.rgba);
}

// The console's panels: Dear ImGui drawn over the picture, in what readFramebuffer() (so
// --console-screenshot) reads, and nowhere else.
TEST(Window, ThePanelsAreDrawnOverThePicture) {
  const char* display = std::getenv("DISPLAY");
  if (!display || !*display) GTEST_SKIP() << "no display (ctest runs this under xvfb-run)";
  auto win = Window::open(320, 240, "tessera panels test");
  win->enableUi();
  ViewRenderer r(320, 240);
  ViewSetup v;
  v.view = glm::lookAt(glm::dvec3(0, 0, 1), glm::dvec3(0), glm::dvec3(0, 1, 0));
  v.projection = glm::perspective(glm::radians(40.0), 320.0 / 240.0, 0.01, 10.0);
  v.width = 320;
  v.height = 240;
  const Image picture = r.renderSettled({}, v, RenderOptions{});
  (void)win->poll();
  win->beginUi();
  ImGui::SetNextWindowPos(ImVec2(10, 10));
  ImGui::SetNextWindowSize(ImVec2(100, 60));
  ImGui::Begin("panel");
  ImGui::TextUnformatted("text");
  ImGui::End();
  win->endUi();
  win->present(r.imageBuffer(), 320, 240);
  EXPECT_FALSE(win->uiWantsKeyboard()) << "no text field is active";
  uint32_t w = 0, h = 0;
  const std::vector<uint8_t> shown = win->readFramebuffer(w, h);
  ASSERT_EQ(w, 320u);
  size_t inside = 0, outside = 0;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t i = (size_t(y) * w + x) * 4;
      const bool differs = std::memcmp(&shown[i], &picture.rgba[i], 3) != 0;
      const bool in_panel = x >= 12 && x < 108 && y >= 12 && y < 68;
      const bool near_panel = x >= 6 && x < 114 && y >= 6 && y < 74;
      if (in_panel) inside += differs;
      if (!near_panel) outside += differs;
    }
  EXPECT_GT(inside, 96u * 56u * 9 / 10) << "the panel over the picture";
  EXPECT_EQ(outside, 0u) << "the picture untouched beside it";
}

TEST(Window, WithoutADisplaySaysSo) {
  const char* saved = std::getenv("DISPLAY");
  const std::string keep = saved ? saved : "";
  unsetenv("DISPLAY");
  const char* wayland = std::getenv("WAYLAND_DISPLAY");
  if (wayland && *wayland) GTEST_SKIP() << "a Wayland display is set";
  try {
    Window::open(64, 64, "none");
    ADD_FAILURE() << "opened a window without a display";
  } catch (const RenderError& e) {
    EXPECT_NE(std::string(e.what()).find("no display"), std::string::npos) << e.what();
  }
  if (saved) setenv("DISPLAY", keep.c_str(), 1);
}

}  // namespace
}  // namespace tessera::render
