#include <tessera/render/spbr.h>

#include "point_neighbourhood.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

namespace tessera::render {

using detail::CellGrid;
using detail::Moments;
using detail::tangentPlane;

double spbrOpacity(double n, double s, double S) {
  return 1.0 - std::pow(1.0 - s / S, n);
}

double spbrPointsFor(double alpha, double s, double S) {
  return std::log1p(-alpha) / std::log1p(-s / S);
}

double spbrCellSpread(double density, double spacing) {
  const double per_disc = density * std::numbers::pi * spacing * spacing;
  return per_disc < kSpreadBelowPerDisc ? 1.0 : 0.0;
}

double spbrShiftScale(uint32_t total_ensembles) {
  return std::max(1.0, std::pow(double(total_ensembles) / 64.0, 0.3));
}

double spbrCoverAlpha(double alpha, SpbrCopies copies, double spread) {
  if (!(alpha > 0.0) || alpha >= 1.0 || copies == SpbrCopies::kAtPoint) return alpha;
  if (copies == SpbrCopies::kInCell && !(spread > 0.0)) return alpha;
  const double target = -std::log1p(-alpha);  // the lambda that should show
  double lambda = target;
  if (copies == SpbrCopies::kGaussian) {
    // Measured -ln(1 - shown) = lambda (1.015 + 0.06 lambda) (max_share 0.5; re-measured with
    // cells cut by the node's box: 1.018 + 0.061 lambda): the quadratic.
    lambda = (-1.015 + std::sqrt(1.015 * 1.015 + 0.24 * target)) / 0.12;
  } else {
    // Copies in cells, measured on the Figure 5 plane at 10^6 points (rho s 0.66 - 0.87,
    // spread 1, max_share 1, L = 64; the same at L = 16 and 256): (lambda asked of eq. 1,
    // -ln(1 - shown)), at the opacities asked without a correction and at those this table
    // asked for alpha 0.05 to 0.95. Each ensemble holds at most one copy of a point, stratified
    // over its cell, so discs overlap far less than eq. 1's Poisson placement, the more so as
    // points fill more of the ensembles. Piecewise linear, inverted; beyond the table its last
    // ratio.
    static constexpr std::array<std::pair<double, double>, 21> kShown{
        {{0.0, 0.0},       {0.0513, 0.0525}, {0.1016, 0.1054}, {0.1054, 0.1093}, {0.2086, 0.2225},
         {0.2231, 0.2392}, {0.3222, 0.3553}, {0.3567, 0.3976}, {0.4308, 0.4912}, {0.4452, 0.5098},
         {0.5789, 0.6881}, {0.6931, 0.8489}, {0.7369, 0.9138}, {0.9241, 1.1993}, {1.0498, 1.3972},
         {1.1763, 1.609},  {1.204, 1.6559},  {1.5688, 2.3045}, {1.6094, 2.3745}, {2.3026, 3.7646},
         {2.9957, 5.2412}}};
    double fitted = target * kShown.back().first / kShown.back().second;
    for (size_t i = 1; i < kShown.size(); ++i) {
      if (target <= kShown[i].second) {
        const auto [a0, s0] = kShown[i - 1];
        const auto [a1, s1] = kShown[i];
        fitted = a0 + (a1 - a0) * (target - s0) / (s1 - s0);
        break;
      }
    }
    lambda = target + (fitted - target) * std::min(spread, 1.0);
  }
  return -std::expm1(-lambda);
}

SpbrNodeParams spbrNodeParams(double alpha, double density, double spacing,
                              uint32_t total_ensembles, double max_k) {
  SpbrNodeParams p;
  const double L = double(total_ensembles);
  p.cross_section = std::numbers::pi * spacing * spacing;
  if (alpha >= 1.0 || !(density > 0)) {
    p.k = L;  // opaque: every point in every ensemble
    return p;
  }
  // Eq. 1 on a segment much larger than a point (S = 100 s: the binomial is then within 1% of
  // its Poisson limit, so the choice of S does not matter), n_raw = density * S, eq. 4.
  auto kFor = [&](double s) {
    const double S = 100.0 * s;
    return spbrPointsFor(alpha, s, S) * L / (density * S);
  };
  p.k = kFor(p.cross_section);
  // Never more copies than ensembles (two copies of a point in one ensemble coincide).
  const double cap = std::min(std::max(max_k, 1e-3), L);
  if (p.k > cap) {
    // k scales as 1/s: the smallest cross-section with k = cap.
    p.cross_section *= p.k / cap;
    p.k = kFor(p.cross_section);
  }
  return p;
}

double sphereDensity(std::span<const glm::vec3> all, double radius, uint32_t centres, uint32_t seed,
                     size_t max_points) {
  if (all.size() < 8 || !(radius > 0)) return 0.0;
  uint64_t state = seed * 0x9E3779B97F4A7C15ull + 1;
  auto next = [&] {  // splitmix64
    uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  };
  // Large inputs: a random subset, each point kept with probability q, and spheres 1/sqrt(q)
  // wider so they still hold as many points; the density is the subset's divided by q.
  std::vector<glm::vec3> subset;
  std::span<const glm::vec3> points = all;
  double q = 1.0;
  if (all.size() > max_points) {
    q = double(max_points) / double(all.size());
    const uint64_t threshold = uint64_t(q * 18446744073709551615.0);
    subset.reserve(max_points + max_points / 8);
    for (const glm::vec3& p : all)
      if (next() <= threshold) subset.push_back(p);
    points = subset;
    radius /= std::sqrt(q);
  }
  const size_t n = points.size();
  if (n < 8) return 0.0;
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (const glm::vec3& p : points) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const CellGrid grid(points, radius);
  // Centres at least `radius` inside the box on the axes where the box is wide enough.
  const float margin = float(radius);
  const glm::vec3 ext = hi - lo;
  auto interior = [&](const glm::vec3& p) {
    for (int a = 0; a < 3; ++a) {
      if (ext[a] > 4.0f * margin && (p[a] < lo[a] + margin || p[a] > hi[a] - margin)) return false;
    }
    return true;
  };
  double sum = 0.0;
  uint32_t used = 0;
  for (uint32_t tries = 0; used < centres && tries < centres * 8; ++tries) {
    const size_t ci = next() % n;
    const glm::vec3 c = points[ci];
    if (!interior(c) && tries < centres * 4) continue;
    size_t count = 0;
    grid.near(c, float(radius), [&](uint32_t j) { count += j != ci; });
    // The centre is not counted: a sphere around a data point otherwise holds one point more
    // than the density predicts (Palm's bias, 2% at 50 points).
    sum += double(count);
    ++used;
  }
  return used ? sum / used / (std::numbers::pi * radius * radius) / q : 0.0;
}

std::vector<uint32_t> estimateNormals(std::span<const glm::vec3> points, double radius) {
  const size_t n = points.size();
  std::vector<uint32_t> out(n, 0);
  if (n == 0 || !(radius > 0)) return out;
  const CellGrid grid(points, radius);
  auto pack = [](glm::vec3 v) {
    const glm::ivec3 q = glm::ivec3(glm::round(glm::clamp(v, -1.0f, 1.0f) * 511.0f));
    return uint32_t(q.x & 1023) | uint32_t(q.y & 1023) << 10 | uint32_t(q.z & 1023) << 20;
  };
  for (size_t i = 0; i < n; ++i) {
    const glm::vec3 p = points[i];
    Moments m;
    grid.near(p, float(radius), [&](uint32_t j) { m.add(glm::dvec3(points[j] - p)); });
    if (m.count < 3) continue;  // no normal: 0, which the shader treats as facing the viewer
    // The normal is the eigenvector of the smallest eigenvalue: the cross product of the two
    // leading ones.
    const auto [e1, e2] = tangentPlane(m.covariance());
    const glm::dvec3 normal = glm::cross(e1, e2);
    const double len = glm::length(normal);
    if (len > 1e-9) out[i] = pack(glm::vec3(normal / len));
  }
  return out;
}

std::vector<SurfaceCell> surfaceCells(std::span<const glm::vec3> points, double radius,
                                      double node_density, const glm::vec3& box_min,
                                      const glm::vec3& box_max) {
  const size_t n = points.size();
  std::vector<SurfaceCell> cells(n);
  if (n < 8 || !(radius > 0) || !(node_density > 0)) return cells;
  const CellGrid grid(points, radius);
  const float r = float(radius);
  std::vector<detail::Neighbour> near;
  std::vector<glm::dvec2> poly, scratch;
  glm::dvec3 t1, t2;
  for (size_t i = 0; i < n; ++i) {
    if (!detail::tangentNeighbours(grid, points, i, r, near, t1, t2)) continue;
    const glm::vec3 p = points[i];
    // Open cells (below) spread their copies over the node's mean cell, a square of area
    // 1 / density around the point: decorrelated like the rest, and no farther out than half a
    // spacing (an edge of the data stays where it is).
    const double half_side = 0.5 / std::sqrt(node_density);
    cells[i].axis_u = glm::vec3(half_side * t1);
    cells[i].axis_v = glm::vec3(half_side * t2);
    detail::cellSquare(radius, poly);
    // The node's box first: the neighbours beyond its faces belong to other nodes, whose cells
    // stop at the same faces, so the cells of all nodes tile the surface between them.
    for (int a = 0; a < 3 && poly.size() >= 3; ++a) {
      const glm::dvec2 g(t1[a], t2[a]);     // the axis in the tangent plane
      if (glm::length(g) < 1e-3) continue;  // the plane is parallel to these faces
      if (std::isfinite(box_max[a]))
        detail::clipPolygon(poly, g, double(box_max[a]) - double(p[a]), scratch);
      if (std::isfinite(box_min[a]) && poly.size() >= 3)
        detail::clipPolygon(poly, -g, double(p[a]) - double(box_min[a]), scratch);
    }
    detail::cutByNeighbours(near, t1, t2, radius, poly, scratch);
    // A cell still touching the square is open: the point is on the edge of the data (of the
    // scan, or of the node, whose neighbours beyond its faces are not here). It keeps weight 1
    // and no offset. (Large closed cells are the gaps of a random sample: they keep their area.)
    bool open = poly.size() < 3;
    for (const glm::dvec2& v : poly) open |= detail::onSquare(v, radius);
    if (open) continue;
    // Area, centroid and second moments of the polygon (Green's theorem over its edges).
    double area = 0, ixx = 0, iyy = 0, ixy = 0;
    glm::dvec2 centroid(0.0);
    for (size_t v = 0; v < poly.size(); ++v) {
      const glm::dvec2 a = poly[v], b = poly[(v + 1) % poly.size()];
      const double cross = a.x * b.y - b.x * a.y;
      area += cross;
      centroid += (a + b) * cross;
      ixx += cross * (a.x * a.x + a.x * b.x + b.x * b.x);
      iyy += cross * (a.y * a.y + a.y * b.y + b.y * b.y);
      ixy += cross * (a.x * b.y + 2.0 * a.x * a.y + 2.0 * b.x * b.y + b.x * a.y);
    }
    area *= 0.5;
    if (!(area > 0)) continue;
    centroid /= 6.0 * area;
    // Covariance of a uniform point of the cell, about its centroid.
    const double cxx = ixx / (12.0 * area) - centroid.x * centroid.x;
    const double cyy = iyy / (12.0 * area) - centroid.y * centroid.y;
    const double cxy = ixy / (24.0 * area) - centroid.x * centroid.y;
    // Its principal axes; a uniform [-h, h] has variance h^2 / 3, so the rectangle's half-sides
    // are sqrt(3 lambda).
    const double mid = 0.5 * (cxx + cyy), dev = std::hypot(0.5 * (cxx - cyy), cxy);
    const double angle = 0.5 * std::atan2(2.0 * cxy, cxx - cyy);
    const glm::dvec3 e1 = std::cos(angle) * t1 + std::sin(angle) * t2;
    const glm::dvec3 e2 = -std::sin(angle) * t1 + std::cos(angle) * t2;
    cells[i].axis_u = glm::vec3(std::sqrt(3.0 * std::max(mid + dev, 0.0)) * e1);
    cells[i].axis_v = glm::vec3(std::sqrt(3.0 * std::max(mid - dev, 0.0)) * e2);
    cells[i].offset = glm::vec3(centroid.x * t1 + centroid.y * t2);
    cells[i].weight = float(std::clamp(area * node_density, 0.125, 8.0));
  }
  return cells;
}

std::vector<float> densityRatios(std::span<const glm::vec3> points, double radius,
                                 const glm::vec3& box_min, const glm::vec3& box_max,
                                 double node_density, size_t max_points) {
  std::vector<float> ratios(points.size(), 1.0f);
  if (points.size() < 8 || !(radius > 0) || !(node_density > 0)) return ratios;
  // Neighbours are counted in a random subset for large inputs (as sphereDensity()).
  std::vector<glm::vec3> subset;
  std::span<const glm::vec3> counted = points;
  double q = 1.0, r = radius;
  if (points.size() > max_points) {
    q = double(max_points) / double(points.size());
    uint64_t state = 0x9E3779B97F4A7C15ull;
    const uint64_t threshold = uint64_t(q * 18446744073709551615.0);
    for (const glm::vec3& p : points) {
      uint64_t z = (state += 0x9E3779B97F4A7C15ull);
      z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
      z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
      if ((z ^ (z >> 31)) <= threshold) subset.push_back(p);
    }
    counted = subset;
    r /= std::sqrt(q);
  }
  const CellGrid grid(counted, r);
  const glm::vec3 margin = glm::vec3(float(r));
  const double area = std::numbers::pi * r * r * q;
  for (size_t i = 0; i < points.size(); ++i) {
    const glm::vec3 p = points[i];
    // Near a face of the box (on axes where the box is wider than two spheres): spheres there
    // lose the neighbours beyond the face.
    bool inside = true;
    for (int a = 0; a < 3; ++a) {
      if (box_max[a] - box_min[a] > 4.0f * margin[a] &&
          (p[a] < box_min[a] + margin[a] || p[a] > box_max[a] - margin[a]))
        inside = false;
    }
    if (!inside) continue;
    size_t count = 0;
    grid.near(p, float(r), [&](uint32_t) { ++count; });
    // The point itself is among those counted when it is in the subset: do not count it.
    const double local = (double(count) - (q >= 1.0 ? 1.0 : 0.0)) / area;
    if (local > 0) ratios[i] = float(std::clamp(node_density / local, 0.125, 8.0));
  }
  return ratios;
}

}  // namespace tessera::render
