#include <tessera/interact/one_button_navigation.h>

#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/sync/vec3.h>

namespace tessera::interact {

PointerInput pointerInView(const render::WindowInput& in, glm::dvec2 size, glm::dvec2& scale) {
  scale = size / glm::max(glm::dvec2(in.size), glm::dvec2(1.0));
  PointerInput p;
  p.cursor = in.cursor * scale;
  p.down = in.left;
  p.pressed = in.left_pressed;
  p.released = in.left_released;
  p.scroll = in.scroll;
  p.size = size;
  return p;
}

namespace {

using sync::set;
using sync::vec;

glm::dvec3 rotate(const glm::dvec3& v, double angle, const glm::dvec3& axis) {
  return glm::dvec3(glm::rotate(glm::dmat4(1.0), angle, axis) * glm::dvec4(v, 0.0));
}

}  // namespace

config::Camera OneButtonNavigation::update(const config::Camera& camera, const PointerInput& in,
                                           double dt, double fovy, const Picker& pick,
                                           const Projector& project) {
  glm::dvec3 eye = vec(camera.eye()), look = vec(camera.target()), up = vec(camera.up());
  const glm::dvec3 forward = glm::normalize(look - eye);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, up));
  const glm::dvec3 cam_up = glm::cross(right, forward);
  const double dist = glm::length(look - eye);
  // Radians per pixel: the drag speed of turning and orbiting follows the view's own scale.
  const double rad_per_px = fovy / std::max(1.0, in.size.y);

  if (in.pressed) {
    mFlight.reset();  // any touch stops a flight
    mPressAt = mLastCursor = in.cursor;
    mDrag = in.cursor.x >= in.size.x * (1.0 - kBarFraction) ? Drag::kBar : Drag::kPending;
  }
  const glm::dvec2 delta = in.cursor - mLastCursor;
  mLastCursor = in.cursor;

  if (in.down && mDrag == Drag::kPending && glm::length(in.cursor - mPressAt) > kClickSlopPx) {
    const glm::dvec2 moved = in.cursor - mPressAt;
    mDrag = mTarget ? Drag::kOrbit
                    : (std::abs(moved.x) >= std::abs(moved.y) ? Drag::kTurn : Drag::kPan);
  }
  if (in.down || in.released) {
    switch (mDrag) {
      case Drag::kBar: {  // (E) up moves forward
        const glm::dvec3 step = forward * (-delta.y * 0.005 * std::max(dist, 1e-6));
        eye += step;
        look += step;
        break;
      }
      case Drag::kOrbit: {  // (A) both eye and look-at point turn about the target
        const glm::dvec3 pivot = *mTarget;
        const double yaw = -delta.x * rad_per_px, pitch = -delta.y * rad_per_px;
        glm::dvec3 e = rotate(rotate(eye - pivot, pitch, right), yaw, up);
        glm::dvec3 l = rotate(rotate(look - pivot, pitch, right), yaw, up);
        // Keep clear of the poles, where the up vector would lie along the view.
        const glm::dvec3 f = glm::normalize(l - e);
        if (std::abs(glm::dot(f, glm::normalize(up))) < 0.98) {
          eye = pivot + e;
          look = pivot + l;
        }
        break;
      }
      case Drag::kTurn: {  // (C) the view turns about the eye
        const double yaw = -delta.x * rad_per_px, pitch = -delta.y * rad_per_px;
        const glm::dvec3 v = rotate(rotate(look - eye, pitch, right), yaw, up);
        if (std::abs(glm::dot(glm::normalize(v), glm::normalize(up))) < 0.98) look = eye + v;
        break;
      }
      case Drag::kPan: {  // (D) film-plane translation, the scene follows the cursor
        const double world_per_px = 2.0 * dist * std::tan(0.5 * fovy) / std::max(1.0, in.size.y);
        const glm::dvec3 step = (-delta.x * right + delta.y * cam_up) * world_per_px;
        eye += step;
        look += step;
        break;
      }
      default:
        break;
    }
  }
  if (in.released) {
    if (mDrag == Drag::kPending) {  // a click
      const auto on_screen = mTarget ? project(*mTarget) : std::nullopt;
      if (on_screen && glm::length(*on_screen - in.cursor) <= kTargetRadiusPx) {
        // (B) fly towards the target: look at it from half the distance, same direction.
        const glm::dvec3 t = *mTarget;
        mFlight = Flight{eye, look, t + 0.5 * (eye - t), t, 0.0};
      } else {
        mTarget = pick(in.cursor);  // a miss clears the target
      }
    }
    mDrag = Drag::kNone;
  }
  if (in.scroll != 0.0) {  // towards the target, or the look-at point, keeping the direction
    const glm::dvec3 pivot = mTarget ? *mTarget : look;
    const double f = std::pow(0.85, in.scroll);
    const glm::dvec3 dir = glm::normalize(look - eye);
    const double d = glm::length(look - eye);
    eye = pivot + (eye - pivot) * f;
    look = eye + dir * std::max(d * f, 1e-6);
  }
  if (mFlight) {
    mFlight->t = std::min(1.0, mFlight->t + dt / kFlightSeconds);
    const double s = mFlight->t * mFlight->t * (3.0 - 2.0 * mFlight->t);  // smoothstep
    eye = glm::mix(mFlight->eye0, mFlight->eye1, s);
    look = glm::mix(mFlight->target0, mFlight->target1, s);
    if (mFlight->t >= 1.0) mFlight.reset();
  }
  config::Camera out = camera;
  set(out.mutable_eye(), eye);
  set(out.mutable_target(), look);
  set(out.mutable_up(), up);
  return out;
}

}  // namespace tessera::interact
