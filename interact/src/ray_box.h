// The ray-box slab test the CPU picks share (point_pick.cpp, surface_pick.cpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include <glm/glm.hpp>

namespace tessera::interact {

/// Where the ray o + t d (t >= 0) enters the box [lo, hi]: 0 when o is inside, nullopt when the
/// ray misses it or the box lies behind.
inline std::optional<double> enter(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& lo,
                                   const glm::dvec3& hi) {
  double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-300) {
      if (o[a] < lo[a] || o[a] > hi[a]) return std::nullopt;
      continue;
    }
    double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return std::nullopt;
  }
  return t0;
}

}  // namespace tessera::interact
