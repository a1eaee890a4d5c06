// Views the renderer benchmarks share (bench/render_lod, bench/loader_pool).
#pragma once

#include <cstdint>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/render/tile_frustum.h>
#include <tessera/sync/config.h>

namespace tessera::bench {

/// The camera on the virtual bunny scan (bench_inputs.h bigBunnyStore()): the whole bunny from
/// the front, 0.16 m away, metres in the scan's frame.
inline config::Camera bigBunnyCamera() {
  config::Camera c;
  c.mutable_eye()->set_x(-0.02);
  c.mutable_eye()->set_y(0.13);
  c.mutable_eye()->set_z(0.26);
  c.mutable_target()->set_x(-0.02);
  c.mutable_target()->set_y(0.1);
  c.mutable_up()->set_y(1);
  return c;
}

/// bigBunnyCamera() at `width` x `height` pixels, 45 degrees vertical field of view.
inline render::ViewSetup bigBunnyView(uint32_t width = 1920, uint32_t height = 1080) {
  const config::Camera cam = bigBunnyCamera();
  render::ViewSetup view;
  view.view = render::cameraView(cam);
  view.projection = glm::perspective(glm::radians(45.0), double(width) / height, 0.01, 2.0);
  view.width = width;
  view.height = height;
  view.eye_world = glm::dvec3(cam.eye().x(), cam.eye().y(), cam.eye().z());
  return view;
}

}  // namespace tessera::bench
