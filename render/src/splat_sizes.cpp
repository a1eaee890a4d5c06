#include <tessera/render/splat_sizes.h>

#include <algorithm>
#include <cmath>

#include "point_neighbourhood.h"

namespace tessera::render {

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
