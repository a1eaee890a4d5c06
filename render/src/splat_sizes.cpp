#include <tessera/render/splat_sizes.h>

#include <algorithm>
#include <cmath>

#include "point_neighbourhood.h"

namespace tessera::render {

namespace {

/// Whether a neighbourhood is a surface (its spread along the normal at most
/// kMaxNormalVarianceShare of its spread): a volume of points (foliage, the random cube) has no
/// surface whose gaps a wider disc would close, only an outline it would fatten.
bool surfaceLike(std::span<const detail::Neighbour> near, const glm::dvec3& normal) {
  glm::dvec3 mean(0.0);
  for (const detail::Neighbour& q : near) mean += glm::dvec3(q.q);
  mean /= double(near.size());
  double along = 0.0, all = 0.0;
  for (const detail::Neighbour& q : near) {
    const glm::dvec3 d = glm::dvec3(q.q) - mean;
    along += glm::dot(d, normal) * glm::dot(d, normal);
    all += glm::dot(d, d);
  }
  return along <= kMaxNormalVarianceShare * all;
}

}  // namespace

std::vector<uint8_t> splatScales(std::span<const glm::vec3> points, double spacing) {
  const size_t n = points.size();
  std::vector<uint8_t> codes(n, 0);
  if (n < 8 || !(spacing > 0) || !std::isfinite(spacing)) return codes;
  const double radius = 4.0 * spacing;
  const detail::CellGrid grid(points, radius);
  std::vector<detail::Neighbour> near;
  std::vector<glm::dvec2> poly, scratch;
  glm::dvec3 t1, t2;
  for (size_t i = 0; i < n; ++i) {
    if (!detail::tangentNeighbours(grid, points, i, float(radius), near, t1, t2)) continue;
    if (!surfaceLike(near, glm::cross(t1, t2))) continue;
    detail::tangentCell(near, t1, t2, radius, poly, scratch);
    if (poly.size() < 3) continue;
    double reach2 = 0;
    for (const glm::dvec2& v : poly)
      if (!detail::onSquare(v, radius)) reach2 = std::max(reach2, glm::dot(v, v));
    const double scale =
        std::clamp(kCellMargin * std::sqrt(reach2) / spacing, 1.0, double(kMaxPointSplatScale));
    codes[i] = uint8_t(std::lround((scale - 1.0) * 64.0));
  }
  return codes;
}

}  // namespace tessera::render
