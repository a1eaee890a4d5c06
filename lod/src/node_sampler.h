// Per-node work of the LOD builder: even grid sampling, octant partition, spacing measurement.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "build_point.h"
#include "point_distributor.h"

namespace tessera::lod {

/// Moves to the front of `pts` one point per occupied cell of a `grid`^3 grid over the cube
/// [box_min, box_min + size]: the point nearest the cell centre, so the subset is spatially
/// even (no clumps), as the grid/Poisson-disk subsampling of Layered Point Clouds and Potree.
/// Returns how many were selected. Stable: equal inputs give equal outputs.
size_t gridSample(std::span<BuildPoint> pts, const glm::dvec3& box_min, double size, int grid);

/// Reorders the points of cell `key` by child cell (index x | y << 1 | z << 2) and returns the 9
/// boundaries: child i spans [bounds[i], bounds[i + 1]). Uses CubeFrame::cellOf, the same
/// arithmetic as distribution and verification, so a point on a boundary lands in one place.
std::array<size_t, 9> partitionOctants(std::span<BuildPoint> pts, const CubeFrame& frame,
                                       const CellKey& key);

/// Mean distance from a point to its nearest other sample (exact duplicates excluded), over up
/// to `samples` points spread through `pts`. Returns `fallback` when nothing can be measured.
double meanSpacing(std::span<const BuildPoint> pts, double extent, double fallback,
                   size_t samples = 256);

}  // namespace tessera::lod
