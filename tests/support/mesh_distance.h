// Exact point-to-mesh distance for tests: a uniform grid of triangles, searched in growing
// shells of cells until no closer triangle can exist. Independent of the code under test.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <vector>

#include <glm/glm.hpp>

namespace tessera::test {

/// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
inline glm::dvec3 closestOnTriangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                    const glm::dvec3& c) {
  glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
  double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  glm::dvec3 bp = p - b;
  double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  glm::dvec3 cp = p - c;
  double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

class MeshDistance {
 public:
  MeshDistance(std::vector<glm::dvec3> vertices, std::vector<glm::u32vec3> triangles, double cell)
      : mV(std::move(vertices)), mT(std::move(triangles)), mCell(cell) {
    for (uint32_t t = 0; t < mT.size(); ++t) {
      glm::dvec3 lo = glm::min(mV[mT[t].x], glm::min(mV[mT[t].y], mV[mT[t].z]));
      glm::dvec3 hi = glm::max(mV[mT[t].x], glm::max(mV[mT[t].y], mV[mT[t].z]));
      glm::ivec3 a = cellOf(lo), b = cellOf(hi);
      for (int x = a.x; x <= b.x; ++x)
        for (int y = a.y; y <= b.y; ++y)
          for (int z = a.z; z <= b.z; ++z) mGrid[key({x, y, z})].push_back(t);
    }
  }

  /// Distance from p to the nearest triangle (searches at most `max_shells` shells of cells;
  /// returns infinity if nothing is that close).
  double distance(const glm::dvec3& p, int max_shells = 8) const {
    glm::ivec3 c = cellOf(p);
    double best = std::numeric_limits<double>::infinity();
    for (int r = 0; r <= max_shells; ++r) {
      for (int x = -r; x <= r; ++x)
        for (int y = -r; y <= r; ++y)
          for (int z = -r; z <= r; ++z) {
            if (std::max({std::abs(x), std::abs(y), std::abs(z)}) != r) continue;
            auto it = mGrid.find(key(c + glm::ivec3(x, y, z)));
            if (it == mGrid.end()) continue;
            for (uint32_t t : it->second) {
              glm::dvec3 q = closestOnTriangle(p, mV[mT[t].x], mV[mT[t].y], mV[mT[t].z]);
              best = std::min(best, glm::length(p - q));
            }
          }
      // Everything outside shell r is at least r cells away.
      if (best <= r * mCell) break;
    }
    return best;
  }

 private:
  glm::ivec3 cellOf(const glm::dvec3& p) const { return glm::ivec3(glm::floor(p / mCell)); }
  static int64_t key(const glm::ivec3& c) {
    return (int64_t(c.x & 0x1FFFFF) << 42) | (int64_t(c.y & 0x1FFFFF) << 21) |
           int64_t(c.z & 0x1FFFFF);
  }
  std::vector<glm::dvec3> mV;
  std::vector<glm::u32vec3> mT;
  double mCell;
  std::unordered_map<int64_t, std::vector<uint32_t>> mGrid;
};

inline double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace tessera::test
