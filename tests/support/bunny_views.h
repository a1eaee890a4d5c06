// Views of a store for the renderer's tests: a camera on the store's box centre from the front,
// and a plain perspective view through it.
#pragma once

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/point_store.h>
#include <tessera/render/tile_frustum.h>

namespace tessera::test {

/// Looking down -z at the centre of `s`'s box from `distance` in front (a little off axis, so
/// no point column lines up with the view), y up.
inline config::Camera frontCamera(const lod::PointStore& s, double distance) {
  const auto& sum = s.summary();
  const glm::dvec3 c = sum.origin + 0.5 * (sum.bbox_min + sum.bbox_max);
  config::Camera cam;
  cam.mutable_eye()->set_x(c.x + 0.05);
  cam.mutable_eye()->set_y(c.y + 0.02);
  cam.mutable_eye()->set_z(c.z + distance);
  cam.mutable_target()->set_x(c.x);
  cam.mutable_target()->set_y(c.y);
  cam.mutable_target()->set_z(c.z);
  cam.mutable_up()->set_y(1);
  return cam;
}

/// A `w` x `h` perspective view through `cam`, `fovy_degrees` vertically, near 0.01, far 10.
inline render::ViewSetup perspectiveView(const config::Camera& cam, uint32_t w, uint32_t h,
                                         double fovy_degrees = 40.0) {
  render::ViewSetup v;
  v.view = render::cameraView(cam);
  v.projection = glm::perspective(glm::radians(fovy_degrees), double(w) / h, 0.01, 10.0);
  v.width = w;
  v.height = h;
  v.eye_world = glm::dvec3(cam.eye().x(), cam.eye().y(), cam.eye().z());
  return v;
}

}  // namespace tessera::test
