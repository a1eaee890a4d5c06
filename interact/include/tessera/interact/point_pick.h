// The point of a model under a console pixel, found on the CPU from the stores (no GL): the
// nearest stored sample within a pixel's cone around the ray, searched down the LOD hierarchy to
// the level the view would draw. For setting the navigation target (one_button_navigation.h).
#pragma once

#include <optional>
#include <span>

#include <glm/glm.hpp>

#include <tessera/render/view_renderer.h>

namespace tessera::interact {

struct PickOptions {
  /// The angle one pixel covers, radians (vertical field of view / view height).
  double pixel_angle = 1e-3;
  /// A sample is hit when its distance to the ray is at most this many pixels' width at its
  /// depth (the renderer's splats are about 2 spacings wide).
  double radius_px = 3.0;
  /// At most this many chunks are read per model (a click stays a few milliseconds).
  size_t max_chunks = 256;
};

/// The nearest hit point (world, metres) along the ray from `origin` in direction `dir`, over
/// every model, or nullopt; samples a model's clip planes cut away are skipped. Reads hierarchy
/// pages and chunks through the stores' caches (thread-safe; may touch the disk). Corrupt chunks
/// and pages are skipped.
std::optional<glm::dvec3> pickPoint(std::span<const render::ModelInstance> models,
                                    const glm::dvec3& origin, const glm::dvec3& dir,
                                    const PickOptions& options = {});

}  // namespace tessera::interact
