// A photograph as a point cloud on a rectangle in 3D, for fused see-through views of photos
// and scans (Tanaka et al. 2016, section 4.5): one coloured point per pixel, moved along the
// rectangle's normal by a height map, and copied 1/cos(phi) times (phi: the angle between the
// rectangle's normal and the height map's), the fractional part drawn at random, so the
// displaced surface keeps the point density per area that see-through opacity relies on.
#pragma once

#include <cstdint>
#include <filesystem>

#include <glm/glm.hpp>

#include <tessera/lod/point_batch.h>

namespace tessera::lod {

struct PhotoOptions {
  std::filesystem::path image;        ///< PNG (8 or 16 bit, any channels): the points' colours
  std::filesystem::path height;       ///< optional PNG height map (grey levels; resampled to image)
  double height_scale = 0.0;          ///< metres at full grey level (white)
  glm::dvec3 corner{0.0};             ///< the picture's lower-left corner
  glm::dvec3 u{1.0, 0.0, 0.0};        ///< its width: lower-left to lower-right
  glm::dvec3 v{0.0, 1.0, 0.0};        ///< its height: lower-left to upper-left
  uint64_t seed = 1;                  ///< for the fractional copies
  uint64_t max_pixels = 200'000'000;  ///< refuse larger pictures (memory: ~40 bytes a pixel)
};

struct PhotoReport {
  uint32_t width = 0, height = 0;
  uint64_t points = 0;      ///< after proliferation
  double max_copies = 1.0;  ///< the largest 1 / cos(phi)
};

/// The photo's points (positions relative to `origin`, returned through it: the corner).
/// Throws ReadError naming the file and what is wrong (unreadable, not PNG, too large), and
/// PreconditionError for a degenerate rectangle (u and v parallel or zero).
PointBatch photoPoints(const PhotoOptions& options, glm::dvec3& origin,
                       PhotoReport* report = nullptr);

}  // namespace tessera::lod
