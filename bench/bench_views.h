// Views the renderer benchmarks share (bench/render_lod, bench/loader_pool, bench/edl,
// bench/paraview_peer, bench/fill).
#pragma once

#include <cmath>
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

/// ParaView's reset camera for the unit cube of random points (bench/paraview_peer, bench/fill):
/// the bounding sphere fits the 30 degree view, looking along (1, -0.8, 0.6) at the centre, z up.
struct CubeCamera {
  glm::dvec3 eye, target{0.5}, up{0, 0, 1};
  double fovy = 30.0;
};

/// ParaView's reset camera for the box [lo, hi] (bench/paraview_peer's second input, tiled
/// LiDAR): the same direction, the box's bounding sphere filling the view.
inline CubeCamera boxCamera(const glm::dvec3& lo, const glm::dvec3& hi) {
  CubeCamera c;
  c.target = 0.5 * (lo + hi);
  const double radius = 0.5 * glm::length(hi - lo);
  const double distance = radius / std::sin(glm::radians(c.fovy) / 2.0);
  c.eye = c.target + glm::normalize(glm::dvec3(1.0, -0.8, 0.6)) * distance;
  return c;
}

inline CubeCamera cubeCamera() { return boxCamera(glm::dvec3(0.0), glm::dvec3(1.0)); }

inline render::ViewSetup cubeView(const CubeCamera& c, uint32_t w = 1920, uint32_t h = 1080) {
  render::ViewSetup v;
  v.view = glm::lookAt(c.eye, c.target, c.up);
  const double d = glm::length(c.eye - c.target);
  v.projection = glm::perspective(glm::radians(c.fovy), double(w) / h, 0.05 * d, 4.0 * d);
  v.width = w;
  v.height = h;
  v.eye_world = c.eye;
  return v;
}

}  // namespace tessera::bench
