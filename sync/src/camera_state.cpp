#include <tessera/sync/camera_state.h>

#include <cmath>

#include <glm/glm.hpp>

#include <tessera/core/check.h>

#include <tessera/sync/vec3.h>
#include <tessera/sync/view.h>

namespace tessera::sync {
namespace {


// The frame roll is measured in: r is the world axis z (or y when the view is within 26 degrees
// of z, where z's projection gets short) projected onto the plane orthogonal to the unit view d,
// and s = d x r. Both depend on the view alone, so encoder and decoder agree.
void rollFrame(const glm::dvec3& d, glm::dvec3& r, glm::dvec3& s) {
  const glm::dvec3 axis = std::abs(d.z) > 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(0, 0, 1);
  r = glm::normalize(axis - d * glm::dot(d, axis));
  s = glm::cross(d, r);
}

}  // namespace

scene::CameraState encodeCamera(const config::Camera& camera) {
  const auto problem = viewProblem(camera);
  TESSERA_CHECK(!problem, "sync::encodeCamera(): " + describe(*problem, "camera"));
  const glm::dvec3 eye = vec(camera.eye()), up = vec(camera.up());
  const glm::vec3 view_f(vec(camera.target()) - eye);
  // Roll is taken around the view direction the decoder will see (the float one); the view rule
  // keeps up at more than 1e-6 radians from it, so up_ortho is never zero.
  const glm::dvec3 d = glm::normalize(glm::dvec3(view_f));
  const glm::dvec3 up_ortho = up - d * glm::dot(d, up);
  glm::dvec3 r, s;
  rollFrame(d, r, s);
  scene::CameraState state;
  for (int i = 0; i < 3; ++i) {
    state.add_eye(eye[i]);
    state.add_view(view_f[i]);
  }
  state.set_roll(float(std::atan2(glm::dot(up_ortho, s), glm::dot(up_ortho, r))));
  return state;
}

bool isCompleteCamera(const scene::CameraState& state) {
  if (state.eye_size() != 3 || state.view_size() != 3 || !state.has_roll()) return false;
  const glm::dvec3 eye(state.eye(0), state.eye(1), state.eye(2));
  const glm::dvec3 view(state.view(0), state.view(1), state.view(2));
  return finite(eye) && finite(view) && glm::length(view) > 0.0 && std::isfinite(state.roll());
}

config::Camera decodeCamera(const scene::CameraState& state) {
  TESSERA_CHECK(isCompleteCamera(state), "sync::decodeCamera(): incomplete or invalid camera");
  const glm::dvec3 eye(state.eye(0), state.eye(1), state.eye(2));
  const glm::dvec3 view(state.view(0), state.view(1), state.view(2));
  glm::dvec3 r, s;
  rollFrame(glm::normalize(view), r, s);
  const double roll = state.roll();
  config::Camera camera;
  *camera.mutable_eye() = toVec3(eye);
  *camera.mutable_target() = toVec3(eye + view);
  *camera.mutable_up() = toVec3(std::cos(roll) * r + std::sin(roll) * s);
  return camera;
}

}  // namespace tessera::sync
