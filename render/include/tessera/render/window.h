// A desktop window (GLFW) with an OpenGL 4.5 core context: the windowed twin of
// GlContext::createHeadless(). The renderer draws into its own buffers either way; a window only
// shows the result (present()), so windowed and headless pixels are the same.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace tessera::render {

/// Input gathered since the previous poll().
struct WindowInput {
  glm::dvec2 cursor{0.0};        ///< pixels from the top-left corner of the window
  glm::dvec2 cursor_delta{0.0};  ///< movement since the previous poll
  bool left = false, right = false, middle = false;  ///< buttons held now
  /// Transitions since the previous poll; a click within one poll sets both (left then false).
  bool left_pressed = false, left_released = false;
  bool right_pressed = false, right_released = false;
  /// Every cursor position reported since the previous poll, oldest first (at most 4096): a
  /// drag keeps its shape however slow the frames are.
  std::vector<glm::dvec2> path;
  /// Per path point, the buttons held there (kLeftHeld | kRightHeld); a button's press adds the
  /// point where it went down. So one poll's left drag and right drag stay apart.
  std::vector<uint8_t> path_buttons;
  static constexpr uint8_t kLeftHeld = 1, kRightHeld = 2;
  /// The path's points where `button` (kLeftHeld or kRightHeld) was held, in order.
  std::vector<glm::dvec2> dragOf(uint8_t button) const {
    std::vector<glm::dvec2> out;
    for (size_t i = 0; i < path.size() && i < path_buttons.size(); ++i)
      if (path_buttons[i] & button) out.push_back(path[i]);
    return out;
  }
  double scroll = 0.0;    ///< wheel steps, up positive
  std::vector<int> keys;  ///< GLFW key codes pressed (not repeats)
  glm::uvec2 size{0};     ///< window size in screen coordinates
};

class Window {
 public:
  /// Opens a window and makes its GL 4.5 core context current on this thread. Throws
  /// RenderError saying why not (no display: DISPLAY unset or unreachable; no GL 4.5 core).
  static std::unique_ptr<Window> open(uint32_t width, uint32_t height, const std::string& title);
  ~Window();
  Window(const Window&) = delete;
  Window& operator=(const Window&) = delete;

  /// The user asked to close (window button or Escape).
  bool closing() const;
  /// Shows `image_buffer` (a GL buffer of width x height RGBA8 pixels, top row first, as
  /// PointRasterizer writes it) scaled to the window, and swaps.
  void present(uint32_t image_buffer, uint32_t width, uint32_t height);
  /// What the window shows now (its back buffer after present(), before the next swap is
  /// drawn), RGBA top row first: for checking that the window shows the renderer's pixels.
  std::vector<uint8_t> readFramebuffer(uint32_t& width, uint32_t& height) const;
  /// Processes pending events.
  WindowInput poll();

  /// Dear ImGui in this window (the master console's panels): a context with the GLFW and
  /// OpenGL 3 backends (GLSL 450), whose GLFW callbacks are installed after the window's own and
  /// call them first, so poll() reports the same input as without. No imgui.ini is written.
  /// Once; a window without it never touches ImGui.
  void enableUi();
  /// Starts an ImGui frame (after poll()): ImGui:: calls until endUi() build it. Needs enableUi().
  void beginUi();
  /// Ends the frame begun: present() draws it over the picture, so readFramebuffer() sees it.
  void endUi();
  /// Whether the panels take the mouse / the keyboard now (io.WantCaptureMouse,
  /// WantCaptureKeyboard of the last frame begun); false without enableUi(). While the keyboard
  /// is taken (a text field is active) Escape does not close the window.
  bool uiWantsMouse() const;
  bool uiWantsKeyboard() const;
  /// Takes from `in` what the panels took (after endUi()): the mouse while it is over them, the
  /// keys while a text field is active, so the view does not also get them. A right-button drag
  /// begun on the view (`right_held`) goes on under a panel.
  void withoutWhatUiTook(WindowInput& in, bool right_held) const;
  void setTitle(const std::string& title);

  struct Impl;  ///< GLFW state (window.cpp); public so GLFW callbacks can reach it

 private:
  Window();
  std::unique_ptr<Impl> mImpl;
};

}  // namespace tessera::render
