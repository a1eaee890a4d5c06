// Per-node work of the LOD builder: even grid sampling, octant partition, spacing measurement.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "build_point.h"
#include "point_distributor.h"

namespace tessera::lod {

/// Chooses one point per occupied cell of a `grid`^3 grid over the cube [box_min, box_min +
/// size]: the point nearest the cell centre (the first of equals), so the subset is spatially
/// even (no clumps), as the grid/Poisson-disk subsampling of Layered Point Clouds and Potree.
/// Sets `chosen[i]` to 1 for a chosen point i, else 0 (pts.size() bytes); returns how many.
/// Moves no point: O(n) reads and one byte written a point.
size_t gridSelect(std::span<const BuildPoint> pts, const glm::dvec3& box_min, double size, int grid,
                  std::vector<uint8_t>& chosen);

/// gridSelect(), then moves the chosen points to the front of `pts`, both groups in their
/// order. Returns how many were chosen. Stable: equal inputs give equal outputs.
size_t gridSample(std::span<BuildPoint> pts, const glm::dvec3& box_min, double size, int grid);

/// Copies the points of cell `key` into `out` (as many) by child cell (index x | y << 1 | z << 2),
/// each child's points in their order, and returns the 9 boundaries: child i spans [bounds[i],
/// bounds[i + 1]). Uses CubeFrame::cellOf, the same arithmetic as distribution and verification,
/// so a point on a boundary lands in one place. Each point's cell is computed once.
std::array<size_t, 9> partitionOctants(std::span<const BuildPoint> pts, std::span<BuildPoint> out,
                                       const CubeFrame& frame, const CellKey& key);

/// partitionOctants() for the cells `levels` (1 or 2) below `key` at once: 8^levels cells in
/// Morton order, child-major (cell = child * 8 + grandchild for two levels), so each child's
/// points come out already grouped by its own children. `bounds[0 .. 8^levels]` are the
/// boundaries. Two levels move each point once where two partitions move it twice.
/// Precondition: key.level + levels <= store::kMaxLevel (a cell's coordinates fit 32 bits).
void partitionCells(std::span<const BuildPoint> pts, std::span<BuildPoint> out,
                    const CubeFrame& frame, const CellKey& key, int levels,
                    std::array<size_t, 65>& bounds);

/// Mean distance from a point to its nearest other sample (exact duplicates excluded), over up
/// to `samples` points spread through `pts`. Returns `fallback` when nothing can be measured.
double meanSpacing(std::span<const BuildPoint> pts, double extent, double fallback,
                   size_t samples = 256);

}  // namespace tessera::lod
