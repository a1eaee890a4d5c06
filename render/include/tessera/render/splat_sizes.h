// Per-point splat sizes from each point's own neighbours. A node's spacing is a mean: on
// airborne LiDAR the samples lie on scan lines whose gaps are several times the spacing along
// them, so discs sized from the node's spacing leave stripes on close views. The
// loader measures, for each point of a leaf, the disc that closes the surface around it, and
// the point pass draws that disc (shaders/point_raster.comp): the radius of the point's Voronoi
// cell in its tangent plane, i.e. the distance to the cell's farthest vertex. Discs of those
// radii cover the plane exactly (every location lies in some point's cell, within the cell's
// radius of it), whatever the sampling pattern; an even sample gets about the disc it has today.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

namespace tessera::render {

/// The largest splat scale a point may get (relative to its node's disc): a point whose cell is
/// wider (a stray point in a tree, an outlier) is capped at it.
constexpr float kMaxPointSplatScale = 4.0f;

/// How much wider than its cell's radius a point's disc is drawn: the disc is a circle on the
/// screen sized at the point's own depth, while the cell's far vertices lie nearer or farther on
/// a slanted surface, so exact discs leave slivers where three cells meet.
constexpr double kCellMargin = 1.1;

/// A neighbourhood whose spread along its normal is more than this share of its whole spread
/// is a volume, not a surface (uniform random points in a ball: a third), and its points keep
/// the node's disc. A scanned surface with noise and curvature within 4 spacings: a few hundredths.
constexpr double kMaxNormalVarianceShare = 0.05;

/// The splat scale in a GPU point's top byte (GpuPoint::rgba >> 24): 1 + byte / 64, so 0 is the
/// node's own disc and points without a measured scale draw as before.
constexpr float pointSplatScale(uint32_t rgba) {
  return 1.0f + float(rgba >> 24) / 64.0f;
}

/// Per point of a chunk, the byte of pointSplatScale(): the radius that closes the surface
/// around it (times kCellMargin), as a multiple of `spacing` (the node's mean spacing, which the
/// disc is at the default splat scale 2), at least 1 and at most kMaxPointSplatScale. The Voronoi cell is
/// taken among the neighbours within 4 spacings (a gap wider than about 4 spacings is not the
/// sampling's but the data's, and stays); its vertices on that search square (the cell is open:
/// the edge of the data or of the node) do not count. Points whose neighbourhood is a volume
/// (kMaxNormalVarianceShare) keep 0. Empty `points`, a non-finite or
/// non-positive spacing, or fewer than 8 points: all 0. O(n), ~12 neighbours a point.
std::vector<uint8_t> splatScales(std::span<const glm::vec3> points, double spacing);

}  // namespace tessera::render
