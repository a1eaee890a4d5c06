// One-button navigation for the master's console, after Bettio et al. 2009, section 4.2 and
// Figure 5 (../shared/papers/point-based-local-remote-exploration.txt): one mouse button (or one
// finger), no modifiers, the gesture and its context choose the action.
//
//  - The view has a main area and a bar on its right edge (kBarFraction of the width). In the
//    bar a vertical drag moves the camera forward (up) or backward (down) along its view (E).
//  - A click (press and release without moving) on the model sets a target, the point under
//    the cursor; a click where there is no model clears it. A click on the target itself
//    (within kTargetRadiusPx of its projection) flies the camera towards it, looking at it (B).
//  - With a target, a drag in the main area orbits the camera around it (A).
//  - Without a target the drag's first movement decides: horizontal turns the view about the
//    eye (C), vertical pans in the film plane (D).
//  - The mouse wheel moves towards the target (or the camera's look-at point); the paper's
//    precomputed views (F) are the camera path scripts here.
//
// Pure logic on the camera, no GL: the console supplies the picking and the projection.
#pragma once

#include <functional>
#include <optional>

#include <glm/glm.hpp>

#include <tessera/config.pb.h>
#include <tessera/render/window.h>

namespace tessera::interact {

/// The pointer as the navigation sees it, in view pixels (top-left origin).
struct PointerInput {
  glm::dvec2 cursor{0.0};
  bool down = false;          ///< the button is held
  bool pressed = false;       ///< went down since the previous update
  bool released = false;      ///< went up since the previous update
  double scroll = 0.0;        ///< wheel steps, up positive
  glm::dvec2 size{1.0, 1.0};  ///< the view's size in the same pixels
};

/// A window's input as the pointer of a view of `size` pixels: window coordinates to view pixels
/// (Window::present() scales the picture to the window). `scale` receives the factor, view
/// pixels per window pixel, for the input's drags.
PointerInput pointerInView(const render::WindowInput& in, glm::dvec2 size, glm::dvec2& scale);

class OneButtonNavigation {
 public:
  static constexpr double kBarFraction = 0.08;
  static constexpr double kTargetRadiusPx = 12.0;
  static constexpr double kClickSlopPx = 4.0;
  static constexpr double kFlightSeconds = 0.6;

  /// The world point under a view pixel, if any model is there.
  using Picker = std::function<std::optional<glm::dvec3>(glm::dvec2 pixel)>;
  /// World point -> view pixel (top-left origin); nullopt behind the eye.
  using Projector = std::function<std::optional<glm::dvec2>(const glm::dvec3& world)>;

  /// One step: returns the camera after `input`, `dt` seconds after the previous step (for
  /// the flight). `fovy` is the view's vertical field of view in radians (pan and turn speeds).
  config::Camera update(const config::Camera& camera, const PointerInput& input, double dt,
                        double fovy, const Picker& pick, const Projector& project);

  const std::optional<glm::dvec3>& target() const { return mTarget; }
  bool flying() const { return mFlight.has_value(); }

 private:
  enum class Drag { kNone, kPending, kBar, kOrbit, kTurn, kPan };
  struct Flight {
    glm::dvec3 eye0, target0, eye1, target1;
    double t = 0.0;
  };
  std::optional<glm::dvec3> mTarget;
  std::optional<Flight> mFlight;
  Drag mDrag = Drag::kNone;
  glm::dvec2 mPressAt{0.0}, mLastCursor{0.0};
};

}  // namespace tessera::interact
