// Closest points on a triangle soup through a uniform grid: the mesh builder's and verifier's
// distance between two versions of a surface (mesh_builder.cpp). Header-only, not thread-safe
// to build, thread-safe to query.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/lod/triangle_geometry.h>

namespace tessera::lod {


class TriangleGrid {
 public:
  /// `positions` and `indices` (3 a triangle) must outlive the grid. About 2 triangles a cell.
  TriangleGrid(std::span<const glm::dvec3> positions, std::span<const uint32_t> indices)
      : mPos(positions), mIdx(indices) {
    const size_t n = indices.size() / 3;
    mLo = glm::dvec3(std::numeric_limits<double>::max());
    glm::dvec3 hi(-std::numeric_limits<double>::max());
    for (uint32_t i : indices) {
      mLo = glm::min(mLo, positions[i]);
      hi = glm::max(hi, positions[i]);
    }
    if (n == 0) {
      mLo = hi = glm::dvec3(0.0);
    }
    const glm::dvec3 ext = glm::max(hi - mLo, glm::dvec3(1e-12));
    const double volume_cell = ext.x * ext.y * ext.z / std::max<double>(1.0, double(n) / 2.0);
    // Surfaces fill few cells of a volume: size cells by area instead when the box is flat.
    const double area_cell = (ext.x * ext.y + ext.y * ext.z + ext.x * ext.z) / std::max(1.0, n / 2.0);
    mCell = std::max({std::cbrt(volume_cell), std::sqrt(area_cell), 1e-12});
    for (int a = 0; a < 3; ++a)
      mDims[a] = int(std::clamp(std::ceil(ext[a] / mCell), 1.0, 1024.0));
    mStart.assign(size_t(mDims.x) * mDims.y * mDims.z + 1, 0);
    auto range = [&](size_t t, glm::ivec3& a, glm::ivec3& b) {
      glm::dvec3 lo = positions[indices[3 * t]], hi2 = lo;
      for (int k = 1; k < 3; ++k) {
        lo = glm::min(lo, positions[indices[3 * t + k]]);
        hi2 = glm::max(hi2, positions[indices[3 * t + k]]);
      }
      a = cellOf(lo);
      b = cellOf(hi2);
    };
    // Each triangle's bounding sphere (centroid, farthest corner): a query skips a triangle
    // whose sphere lies farther than the nearest point found so far.
    mSpheres.resize(n);
    for (size_t t = 0; t < n; ++t) {
      const glm::dvec3 a = positions[indices[3 * t]], b = positions[indices[3 * t + 1]],
                       c = positions[indices[3 * t + 2]];
      const glm::dvec3 m = (a + b + c) / 3.0;
      const double r2 = std::max({glm::dot(a - m, a - m), glm::dot(b - m, b - m),
                                  glm::dot(c - m, c - m)});
      mSpheres[t] = glm::dvec4(m, std::sqrt(r2));
    }
    for (int pass = 0; pass < 2; ++pass) {
      for (size_t t = 0; t < n; ++t) {
        glm::ivec3 a, b;
        range(t, a, b);
        for (int z = a.z; z <= b.z; ++z)
          for (int y = a.y; y <= b.y; ++y)
            for (int x = a.x; x <= b.x; ++x) {
              const size_t c = index({x, y, z});
              if (pass == 0) {
                ++mStart[c + 1];
              } else {
                mItems[mFill[c]++] = uint32_t(t);
              }
            }
      }
      if (pass == 0) {
        for (size_t c = 1; c < mStart.size(); ++c) mStart[c] += mStart[c - 1];
        mItems.resize(mStart.back());
        mFill.assign(mStart.begin(), mStart.end() - 1);
      }
    }
  }

  /// Distance from p to the nearest triangle (infinity when there is none).
  double distance(const glm::dvec3& p) const {
    if (mIdx.empty()) return std::numeric_limits<double>::infinity();
    return glm::length(closest(p) - p);
  }

  /// The nearest point of the triangles to p (p itself when there are none). Searches shells
  /// of cells outwards until the nearest found is closer than the next shell.
  /// `triangle`, when given, receives the nearest triangle's index (unchanged when none).
  glm::dvec3 closest(const glm::dvec3& p, uint32_t* triangle = nullptr) const {
    if (mIdx.empty()) return p;
    const glm::ivec3 c = cellOf(p);
    double best = std::numeric_limits<double>::infinity();
    glm::dvec3 best_q = p;
    const int max_r = std::max({mDims.x, mDims.y, mDims.z});
    for (int r = 0; r <= max_r; ++r) {
      // Every triangle not yet seen lies outside the block of cells within r - 1 of c: at least
      // as far as p is from that block's faces (p inside the grid), or (r - 1) cells (outside).
      if (r > 0 && best <= shellBound(p, c, r)) break;
      for (int z = c.z - r; z <= c.z + r; ++z)
        for (int y = c.y - r; y <= c.y + r; ++y)
          for (int x = c.x - r; x <= c.x + r; ++x) {
            if (std::max({std::abs(x - c.x), std::abs(y - c.y), std::abs(z - c.z)}) != r) continue;
            if (x < 0 || y < 0 || z < 0 || x >= mDims.x || y >= mDims.y || z >= mDims.z) continue;
            const size_t cell = index({x, y, z});
            for (uint32_t k = mStart[cell]; k < mStart[cell + 1]; ++k) {
              const uint32_t t = mItems[k];
              // No point of the triangle is nearer than its sphere: |p - m| - radius >= best
              // means it cannot be strictly nearer (the same result, fewer tests).
              const glm::dvec4& s = mSpheres[t];
              const glm::dvec3 pm = p - glm::dvec3(s);
              const double reach = best + s.w;
              if (glm::dot(pm, pm) >= reach * reach) continue;
              const glm::dvec3 q = closestOnTriangle(p, mPos[mIdx[3 * t]], mPos[mIdx[3 * t + 1]],
                                                     mPos[mIdx[3 * t + 2]]);
              const double d = glm::length(q - p);
              if (d < best) {
                best = d;
                best_q = q;
                if (triangle) *triangle = t;
              }
            }
          }
    }
    return best_q;
  }

 private:
  /// A lower bound on the distance from p (in cell c) to any cell outside the block of cells
  /// within Chebyshev distance r - 1 of c.
  double shellBound(const glm::dvec3& p, const glm::ivec3& c, int r) const {
    double bound = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
      const double lo = mLo[a] + double(c[a] - (r - 1)) * mCell;
      const double hi = mLo[a] + double(c[a] + r) * mCell;
      if (p[a] < lo || p[a] > hi) return double(r - 1) * mCell;  // p outside the grid
      bound = std::min({bound, p[a] - lo, hi - p[a]});
    }
    return bound;
  }
  glm::ivec3 cellOf(const glm::dvec3& p) const {
    glm::ivec3 c;
    for (int a = 0; a < 3; ++a)
      c[a] = int(std::clamp(std::floor((p[a] - mLo[a]) / mCell), 0.0, double(mDims[a] - 1)));
    return c;
  }
  size_t index(const glm::ivec3& c) const {
    return (size_t(c.z) * mDims.y + c.y) * mDims.x + c.x;
  }
  std::span<const glm::dvec3> mPos;
  std::span<const uint32_t> mIdx;
  glm::dvec3 mLo{0.0};
  double mCell = 1.0;
  glm::ivec3 mDims{1};
  std::vector<uint32_t> mStart, mFill, mItems;
  std::vector<glm::dvec4> mSpheres;  ///< per triangle: centroid, radius
};

}  // namespace tessera::lod
