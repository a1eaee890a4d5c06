#include "node_sampler.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace tessera::lod {

size_t gridSelect(std::span<const BuildPoint> pts, const glm::dvec3& box_min, double size, int grid,
                  std::vector<uint8_t>& chosen) {
  const size_t cells = size_t(grid) * grid * grid;
  // Cell -> point index + 1 (0: empty) and its squared distance to the centre, side by side:
  // one cache line a point.
  struct Best {
    uint32_t index;
    float d;
  };
  thread_local std::vector<Best> best;
  thread_local std::vector<uint32_t> touched;
  if (best.size() != cells) best.assign(cells, Best{0, 0.f});
  touched.clear();
  const double inv_cell = grid / size;
  const glm::dvec3 lo = box_min;  // a copy: no store below can change it
  Best* const cell_best = best.data();
  for (size_t i = 0; i < pts.size(); ++i) {
    const glm::dvec3 f = (pts[i].position - lo) * inv_cell;
    auto axis = [&](double v) { return v <= 0.0 ? 0 : v >= grid ? grid - 1 : int(v); };
    const glm::ivec3 c(axis(f.x), axis(f.y), axis(f.z));
    const size_t idx = (size_t(c.z) * size_t(grid) + size_t(c.y)) * size_t(grid) + size_t(c.x);
    const glm::dvec3 e = f - (glm::dvec3(c) + 0.5);
    const float d = float(glm::dot(e, e));
    Best& b = cell_best[idx];
    if (b.index == 0) {
      touched.push_back(uint32_t(idx));
      b = {uint32_t(i + 1), d};
    } else if (d < b.d) {
      b = {uint32_t(i + 1), d};
    }
  }
  chosen.assign(pts.size(), 0);
  for (uint32_t idx : touched) {
    chosen[best[idx].index - 1] = 1;
    best[idx].index = 0;
  }
  return touched.size();
}

size_t gridSample(std::span<BuildPoint> pts, const glm::dvec3& box_min, double size, int grid) {
  thread_local std::vector<uint8_t> chosen;
  const size_t n = gridSelect(pts, box_min, size, grid, chosen);
  // Stable partition: chosen first, both groups in their original order.
  std::vector<BuildPoint> tmp(pts.begin(), pts.end());
  size_t front = 0, back = n;
  for (size_t i = 0; i < tmp.size(); ++i) pts[chosen[i] ? front++ : back++] = tmp[i];
  return n;
}

void partitionCells(std::span<const BuildPoint> pts, std::span<BuildPoint> out,
                    const CubeFrame& frame, const CellKey& key, int levels,
                    std::array<size_t, 65>& bounds) {
  assert(out.size() == pts.size() && (levels == 1 || levels == 2));
  // The cell `levels` below the key; its ancestors are its integer halves (CubeFrame::cellOf).
  const CubeFrame::LevelGrid grid = frame.levelGrid(key.level + levels);
  const int buckets = 1 << (3 * levels);
  thread_local std::vector<uint8_t> cells;
  cells.resize(pts.size());
  uint8_t* cell = cells.data();
  bounds.fill(0);
  for (size_t i = 0; i < pts.size(); ++i) {
    const CellKey c = grid.cellOf(pts[i].position);
    const int fine = c.childIndex();
    const uint8_t b = uint8_t(levels == 1 ? fine : c.parent().childIndex() * 8 + fine);
    cell[i] = b;
    ++bounds[b + 1u];
  }
  for (int i = 0; i < buckets; ++i) bounds[size_t(i) + 1] += bounds[size_t(i)];
  std::array<size_t, 64> fill{};
  for (int i = 0; i < buckets; ++i) fill[size_t(i)] = bounds[size_t(i)];
  for (size_t i = 0; i < pts.size(); ++i) out[fill[cell[i]]++] = pts[i];
}

std::array<size_t, 9> partitionOctants(std::span<const BuildPoint> pts, std::span<BuildPoint> out,
                                       const CubeFrame& frame, const CellKey& key) {
  std::array<size_t, 65> all;
  partitionCells(pts, out, frame, key, 1, all);
  std::array<size_t, 9> bounds;
  std::copy(all.begin(), all.begin() + 9, bounds.begin());
  return bounds;
}

double meanSpacing(std::span<const BuildPoint> pts, double extent, double fallback,
                   size_t samples) {
  const size_t n = pts.size();
  if (n < 2 || !(extent > 0)) return fallback;
  // Hash grid with about one point per cell for a surface sampling (n ~ (extent / s)^2), built
  // by a counting sort over hash buckets: O(n), no comparison sort.
  const double cell = std::max(extent / std::sqrt(double(n)), extent * 1e-7);
  glm::dvec3 lo(std::numeric_limits<double>::max());
  for (const auto& p : pts) lo = glm::min(lo, p.position);
  const double inv_cell = 1.0 / cell;
  // p - lo is never negative: truncation is floor.
  auto cellOf = [&](const glm::dvec3& p) { return glm::ivec3((p - lo) * inv_cell); };
  const size_t buckets = size_t(1) << std::max(4, int(std::ceil(std::log2(double(n)))) + 1);
  auto bucketOf = [&](const glm::ivec3& c) {
    uint64_t h = uint64_t(uint32_t(c.x)) * 0x9E3779B97F4A7C15ull ^
                 uint64_t(uint32_t(c.y)) * 0xC2B2AE3D27D4EB4Full ^
                 uint64_t(uint32_t(c.z)) * 0x165667B19E3779F9ull;
    return size_t(h >> 20) & (buckets - 1);
  };
  thread_local std::vector<uint32_t> start, order, bucket;
  thread_local std::vector<glm::ivec3> cells;
  start.assign(buckets + 1, 0);
  order.resize(n);
  cells.resize(n);
  bucket.resize(n);
  for (size_t i = 0; i < n; ++i) {
    cells[i] = cellOf(pts[i].position);
    bucket[i] = uint32_t(bucketOf(cells[i]));
    ++start[bucket[i] + 1];
  }
  for (size_t b = 0; b < buckets; ++b) start[b + 1] += start[b];
  {
    thread_local std::vector<uint32_t> fill;
    fill.assign(start.begin(), start.end() - 1);
    for (size_t i = 0; i < n; ++i) order[fill[bucket[i]]++] = uint32_t(i);
  }
  const size_t stride = std::max<size_t>(1, n / samples);
  double sum = 0.0;
  size_t measured = 0;
  for (size_t s = 0; s < n; s += stride) {
    const glm::dvec3 p = pts[s].position;
    const glm::ivec3 c = cells[s];
    double best = std::numeric_limits<double>::infinity();
    for (int r = 1; r <= 3 && !std::isfinite(best); ++r) {
      for (int dz = -r; dz <= r; ++dz)
        for (int dy = -r; dy <= r; ++dy)
          for (int dx = -r; dx <= r; ++dx) {
            if (r > 1 && std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) < r) continue;
            const glm::ivec3 q = c + glm::ivec3(dx, dy, dz);
            const size_t b = bucketOf(q);
            for (uint32_t k = start[b]; k < start[b + 1]; ++k) {
              const uint32_t j = order[k];
              if (j == s || cells[j] != q) continue;
              double d = glm::length(pts[j].position - p);
              if (d > 0.0) best = std::min(best, d);
            }
          }
      // A neighbour found in ring r may be beaten by one just outside it; the bias is small and
      // spacing is a statistic, not a bound.
    }
    if (std::isfinite(best)) {
      sum += best;
      ++measured;
    }
  }
  return measured > 0 ? sum / double(measured) : fallback;
}

}  // namespace tessera::lod
