// Neighbourhoods of a chunk's points, for what the loader measures on decoding (see-through
// densities and surface cells, spbr.h; splat sizes, splat_sizes.h): a hashed cell grid for
// fixed-radius queries, local tangent planes by PCA, and a point's Voronoi cell in its tangent
// plane. Internal to the render library.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <tuple>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

namespace tessera::render::detail {

/// Points bucketed by a hash of their cell of side `cell` (a counting sort into a flat table: no
/// allocation per cell, as this runs on every chunk the loader decodes): a sphere of radius
/// `cell` around any point meets the 27 cells around its own.
class CellGrid {
 public:
  CellGrid(std::span<const glm::vec3> points, double cell) : mPoints(points), mCell(float(cell)) {
    mLo = glm::vec3(std::numeric_limits<float>::max());
    for (const glm::vec3& p : points) mLo = glm::min(mLo, p);
    size_t buckets = 16;
    while (buckets < 2 * points.size()) buckets *= 2;
    mMask = buckets - 1;
    mStart.assign(buckets + 1, 0);
    for (const glm::vec3& p : points) ++mStart[bucket(cellOf(p)) + 1];
    for (size_t b = 0; b < buckets; ++b) mStart[b + 1] += mStart[b];
    mOrder.resize(points.size());
    std::vector<uint32_t> fill(mStart.begin(), mStart.end() - 1);
    for (size_t i = 0; i < points.size(); ++i)
      mOrder[fill[bucket(cellOf(points[i]))]++] = uint32_t(i);
  }
  /// Calls f(j) for every point j within `radius` (<= cell) of `p`.
  template <typename F>
  void near(const glm::vec3& p, float radius, F&& f) const {
    const glm::ivec3 c = cellOf(p);
    // Neighbouring cells may share a bucket: visit each bucket once.
    std::array<size_t, 27> visit;
    size_t n = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) visit[n++] = bucket(c + glm::ivec3(dx, dy, dz));
    std::sort(visit.begin(), visit.end());
    const float r2 = radius * radius;
    for (size_t k = 0; k < visit.size(); ++k) {
      if (k && visit[k] == visit[k - 1]) continue;
      for (uint32_t o = mStart[visit[k]]; o < mStart[visit[k] + 1]; ++o) {
        const uint32_t j = mOrder[o];
        const glm::vec3 d = mPoints[j] - p;
        if (glm::dot(d, d) <= r2) f(j);
      }
    }
  }

 private:
  glm::ivec3 cellOf(const glm::vec3& p) const { return glm::ivec3(glm::floor((p - mLo) / mCell)); }
  size_t bucket(const glm::ivec3& c) const {
    const uint64_t h = (uint64_t(uint32_t(c.x)) * 0x9E3779B97F4A7C15ull) ^
                       (uint64_t(uint32_t(c.y)) * 0xC2B2AE3D27D4EB4Full) ^
                       (uint64_t(uint32_t(c.z)) * 0x165667B19E3779F9ull);
    return size_t(h >> 24) & mMask;
  }
  std::span<const glm::vec3> mPoints;
  float mCell;
  glm::vec3 mLo;
  size_t mMask = 0;
  std::vector<uint32_t> mStart, mOrder;
};

/// The two leading eigenvectors of a 3x3 covariance (power iteration and deflation): they span
/// the local tangent plane; their cross product is the normal.
inline std::pair<glm::dvec3, glm::dvec3> tangentPlane(const glm::dmat3& cov) {
  auto leading = [](const glm::dmat3& m, glm::dvec3 v) {
    for (int it = 0; it < 24; ++it) {
      const glm::dvec3 w = m * v;
      const double len = glm::length(w);
      if (!(len > 1e-300)) break;
      v = w / len;
    }
    return v;
  };
  const glm::dvec3 e1 = leading(cov, glm::dvec3(0.57, 0.61, 0.55));
  const double l1 = glm::dot(e1, cov * e1);
  const glm::dmat3 deflated = cov - l1 * glm::outerProduct(e1, e1);
  glm::dvec3 seed2 = glm::cross(e1, glm::dvec3(0.31, 0.47, 0.83));
  if (glm::length(seed2) < 1e-6) seed2 = glm::cross(e1, glm::dvec3(1, 0, 0));
  return {e1, leading(deflated, glm::normalize(seed2))};
}

/// Covariance of the offsets `q` (relative to a point), about their mean.
struct Moments {
  glm::dvec3 mean{0.0};
  glm::dmat3 outer{0.0};
  size_t count = 0;
  void add(const glm::dvec3& q) {
    mean += q;
    outer += glm::outerProduct(q, q);
    ++count;
  }
  glm::dmat3 covariance() const {
    const glm::dvec3 m = mean / double(count);
    return outer / double(count) - glm::outerProduct(m, m);
  }
};

/// A neighbour of a point, relative to it.
struct Neighbour {
  float d2;     ///< squared distance
  glm::vec3 q;  ///< offset from the point
};

/// Point i's neighbours within `radius` (<= the grid's cell) into `near`, nearest first, and
/// their tangent plane (t1, t2) by PCA of the neighbourhood with the point. False (and no plane)
/// with fewer than 3 neighbours.
inline bool tangentNeighbours(const CellGrid& grid, std::span<const glm::vec3> points, size_t i,
                              float radius, std::vector<Neighbour>& near, glm::dvec3& t1,
                              glm::dvec3& t2) {
  const glm::vec3 p = points[i];
  near.clear();
  Moments m;
  grid.near(p, radius, [&](uint32_t j) {
    const glm::vec3 q = points[j] - p;
    m.add(glm::dvec3(q));
    if (j != i) near.push_back({glm::dot(q, q), q});
  });
  if (near.size() < 3) return false;
  std::tie(t1, t2) = tangentPlane(m.covariance());
  std::sort(near.begin(), near.end(),
            [](const Neighbour& a, const Neighbour& b) { return a.d2 < b.d2; });
  return true;
}

/// Keeps the part of the convex polygon `poly` where x . u <= h (`scratch` is reused).
inline void clipPolygon(std::vector<glm::dvec2>& poly, const glm::dvec2& u, double h,
                        std::vector<glm::dvec2>& scratch) {
  scratch.clear();
  for (size_t v = 0; v < poly.size(); ++v) {
    const glm::dvec2 a = poly[v], b = poly[(v + 1) % poly.size()];
    const double fa = glm::dot(a, u) - h, fb = glm::dot(b, u) - h;
    if (fa <= 0) scratch.push_back(a);
    if ((fa < 0) != (fb < 0)) scratch.push_back(a + (b - a) * (fa / (fa - fb)));
  }
  poly.swap(scratch);
}

/// The square of half-width `radius` around a point, in its tangent plane: where a Voronoi cell
/// starts before any neighbour cuts it (counter-clockwise).
inline void cellSquare(double radius, std::vector<glm::dvec2>& poly) {
  poly = {{-radius, -radius}, {radius, -radius}, {radius, radius}, {-radius, radius}};
}

/// Cuts `poly` (a point's cell so far, tangent-plane coordinates) by the bisector of each of
/// `near` (its neighbours within `radius`, sorted nearest first) in the tangent plane (t1, t2):
/// neighbours beyond twice the cell's farthest corner cannot cut it. Fewer than 3 vertices left:
/// no cell (degenerate neighbours).
inline void cutByNeighbours(std::span<const Neighbour> near, const glm::dvec3& t1,
                            const glm::dvec3& t2, double radius, std::vector<glm::dvec2>& poly,
                            std::vector<glm::dvec2>& scratch) {
  double reach2 = 2.0 * radius * radius;
  for (const Neighbour& q : near) {
    if (double(q.d2) > 4.0 * reach2 || poly.size() < 3) break;
    const glm::dvec2 u(glm::dot(glm::dvec3(q.q), t1), glm::dot(glm::dvec3(q.q), t2));
    const double h = 0.5 * glm::dot(u, u);  // keep points x with x . u <= |u|^2 / 2
    if (!(h > 0)) continue;                 // a duplicate point: no bisector
    clipPolygon(poly, u, h, scratch);
    if (poly.size() < 3) return;
    reach2 = 0;
    for (const glm::dvec2& v : poly) reach2 = std::max(reach2, glm::dot(v, v));
  }
}

/// The Voronoi cell of a point among `near` (its neighbours within `radius`, sorted nearest
/// first) in the tangent plane (t1, t2): cellSquare() cut by cutByNeighbours(). Into `poly`.
inline void tangentCell(std::span<const Neighbour> near, const glm::dvec3& t1, const glm::dvec3& t2,
                        double radius, std::vector<glm::dvec2>& poly,
                        std::vector<glm::dvec2>& scratch) {
  cellSquare(radius, poly);
  cutByNeighbours(near, t1, t2, radius, poly, scratch);
}

/// Whether a cell vertex lies on the square tangentCell() started from (the cell is open there:
/// the edge of the data, or of the node, whose neighbours beyond its faces are elsewhere).
inline bool onSquare(const glm::dvec2& v, double radius) {
  return std::max(std::abs(v.x), std::abs(v.y)) > 0.999 * radius;
}

}  // namespace tessera::render::detail
