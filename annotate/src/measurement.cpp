#include <tessera/annotate/measurement.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <unordered_map>

namespace tessera::annotate {

namespace {

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

void check(const SurfacePoint& p, const char* what) {
  if (!finite(p.world) || !std::isfinite(p.uncertainty) || p.uncertainty < 0.0)
    throw MeasureError(std::string("interact::measure: ") + what +
                       ": coordinates and uncertainty must be finite (uncertainty >= 0)");
}

double triangleArea(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  return 0.5 * glm::length(glm::cross(b - a, c - a));
}

}  // namespace

Measurement distance(const SurfacePoint& a, const SurfacePoint& b) {
  check(a, "distance: first point");
  check(b, "distance: second point");
  // d|a-b|/da is a unit vector: each point moves the distance by at most its own uncertainty.
  return {glm::length(a.world - b.world), a.uncertainty + b.uncertainty};
}

Measurement polylineLength(std::span<const SurfacePoint> points) {
  if (points.size() < 2) throw MeasureError("annotate::polylineLength(): needs at least 2 points");
  for (const SurfacePoint& p : points) check(p, "polyline length: a point");
  Measurement m;
  for (size_t i = 0; i + 1 < points.size(); ++i)
    m.value += glm::length(points[i + 1].world - points[i].world);
  // The length's gradient at point i is the difference of the unit directions of its two
  // segments (one at the ends): a straight run's inner points barely count, a zigzag's twice.
  for (size_t i = 0; i < points.size(); ++i) {
    glm::dvec3 g(0.0);
    if (i > 0) {
      const glm::dvec3 d = points[i].world - points[i - 1].world;
      if (glm::length(d) > 0) g += glm::normalize(d);
    }
    if (i + 1 < points.size()) {
      const glm::dvec3 d = points[i + 1].world - points[i].world;
      if (glm::length(d) > 0) g -= glm::normalize(d);
    }
    m.uncertainty += points[i].uncertainty * glm::length(g);
  }
  return m;
}

Measurement angle(const SurfacePoint& a, const SurfacePoint& vertex, const SurfacePoint& b) {
  check(a, "angle: first point");
  check(vertex, "angle: vertex");
  check(b, "angle: second point");
  const glm::dvec3 u = a.world - vertex.world, v = b.world - vertex.world;
  const double lu = glm::length(u), lv = glm::length(v);
  if (!(lu > 0.0) || !(lv > 0.0))
    throw MeasureError("annotate::angle(): an end point coincides with the vertex");
  // atan2 of |u x v| and u.v keeps precision near 0 and pi, where acos does not.
  const double value = std::atan2(glm::length(glm::cross(u, v)), glm::dot(u, v));
  // Moving an end point sideways by e turns its ray by e / length; the vertex turns both.
  const double unc = a.uncertainty / lu + b.uncertainty / lv +
                     vertex.uncertainty * (1.0 / lu + 1.0 / lv);
  return {value, std::min(unc, M_PI)};
}

std::vector<glm::u32vec3> minimumAreaTriangulation(std::span<const glm::dvec3> loop) {
  const size_t n = loop.size();
  if (n < 3) throw MeasureError("annotate::minimumAreaTriangulation(): needs at least 3 points");
  if (n > kMaxAreaLoop)
    throw MeasureError("annotate::minimumAreaTriangulation(): " + std::to_string(n) +
                       " points; at most " + std::to_string(kMaxAreaLoop) +
                       " (resample the loop)");
  for (const glm::dvec3& p : loop)
    if (!finite(p)) throw MeasureError("annotate::minimumAreaTriangulation(): a point is not finite");
  // W(i, j): the least area spanning the sub-polygon i, i+1, ..., j closed by the chord (i, j);
  // W(i, i+1) = 0 and W(i, j) = min over i < k < j of W(i, k) + W(k, j) + area(i, k, j)
  // (Barequet and Sharir 1995; Liepa 2003 uses the same recurrence to fill holes).
  std::vector<double> w(n * n, 0.0);
  std::vector<uint32_t> best(n * n, 0);
  for (size_t len = 2; len < n; ++len) {
    for (size_t i = 0; i + len < n; ++i) {
      const size_t j = i + len;
      double m = std::numeric_limits<double>::infinity();
      uint32_t arg = uint32_t(i + 1);
      for (size_t k = i + 1; k < j; ++k) {
        const double c = w[i * n + k] + w[k * n + j] + triangleArea(loop[i], loop[k], loop[j]);
        if (c < m) {
          m = c;
          arg = uint32_t(k);
        }
      }
      w[i * n + j] = m;
      best[i * n + j] = arg;
    }
  }
  std::vector<glm::u32vec3> out;
  out.reserve(n - 2);
  std::vector<std::pair<uint32_t, uint32_t>> stack = {{0u, uint32_t(n - 1)}};
  while (!stack.empty()) {
    const auto [i, j] = stack.back();
    stack.pop_back();
    if (j - i < 2) continue;
    const uint32_t k = best[size_t(i) * n + j];
    out.push_back({i, k, j});
    stack.emplace_back(i, k);
    stack.emplace_back(k, j);
  }
  return out;
}

AreaMeasurement surfaceArea(std::span<const SurfacePoint> loop, const SurfaceProjector& project,
                            const AreaOptions& options) {
  if (loop.size() < 3) throw MeasureError("annotate::surfaceArea(): needs at least 3 points");
  if (!project) throw MeasureError("annotate::surfaceArea(): no surface to measure on");
  for (const SurfacePoint& p : loop) check(p, "area: a point of the loop");
  AreaMeasurement m;
  m.vertices.reserve(loop.size());
  double perimeter = 0.0, mean_unc = 0.0;
  for (size_t i = 0; i < loop.size(); ++i) {
    m.vertices.push_back(loop[i].world);
    perimeter += glm::length(loop[(i + 1) % loop.size()].world - loop[i].world);
    mean_unc += loop[i].uncertainty / double(loop.size());
  }
  m.triangles = minimumAreaTriangulation(m.vertices);
  auto area = [&] {
    double a = 0.0;
    for (const glm::u32vec3& t : m.triangles)
      a += triangleArea(m.vertices[t.x], m.vertices[t.y], m.vertices[t.z]);
    return a;
  };
  double previous = area();
  // Until a refinement says otherwise the whole area is uncertain (max_levels 0).
  double discretisation = previous;
  const double min_edge2 = options.min_edge * options.min_edge;
  for (int level = 0; level < options.max_levels; ++level) {
    if (m.triangles.size() * 4 > options.max_triangles) break;
    // Split every edge longer than min_edge at its midpoint brought onto the surface; a
    // triangle with some edges kept is split into 2 or 3 (the usual red-green pattern), so no
    // T-junction opens.
    std::unordered_map<uint64_t, uint32_t> mid;
    auto midpoint = [&](uint32_t a, uint32_t b) -> uint32_t {
      const uint64_t key = (uint64_t(std::min(a, b)) << 32) | std::max(a, b);
      if (auto it = mid.find(key); it != mid.end()) return it->second;
      const glm::dvec3 pa = m.vertices[a], pb = m.vertices[b];
      uint32_t id = UINT32_MAX;
      const glm::dvec3 d = pb - pa;
      if (glm::dot(d, d) > min_edge2) {
        const glm::dvec3 c = 0.5 * (pa + pb);
        std::optional<glm::dvec3> s = project(c);
        if (s && !finite(*s)) s.reset();
        if (!s) ++m.unprojected;
        id = uint32_t(m.vertices.size());
        m.vertices.push_back(s ? *s : c);
      }
      mid.emplace(key, id);
      return id;
    };
    std::vector<glm::u32vec3> next;
    next.reserve(m.triangles.size() * 4);
    size_t split = 0;
    for (const glm::u32vec3& t : m.triangles) {
      const uint32_t v[3] = {t.x, t.y, t.z};
      const uint32_t e[3] = {midpoint(v[0], v[1]), midpoint(v[1], v[2]), midpoint(v[2], v[0])};
      const int cut = (e[0] != UINT32_MAX) + (e[1] != UINT32_MAX) + (e[2] != UINT32_MAX);
      split += cut > 0;
      if (cut == 0) {
        next.push_back(t);
      } else if (cut == 3) {
        next.push_back({v[0], e[0], e[2]});
        next.push_back({v[1], e[1], e[0]});
        next.push_back({v[2], e[2], e[1]});
        next.push_back({e[0], e[1], e[2]});
      } else {
        // Rotate so that edge 0 (v0-v1) is cut; fan from its midpoint.
        int r = 0;
        while (e[r] == UINT32_MAX) ++r;
        const uint32_t a = v[r], b = v[(r + 1) % 3], c = v[(r + 2) % 3];
        const uint32_t eab = e[r], ebc = e[(r + 1) % 3], eca = e[(r + 2) % 3];
        if (cut == 1) {
          next.push_back({a, eab, c});
          next.push_back({eab, b, c});
        } else if (ebc != UINT32_MAX) {  // ab and bc cut
          next.push_back({a, eab, c});
          next.push_back({eab, b, ebc});
          next.push_back({eab, ebc, c});
        } else {  // ab and ca cut
          next.push_back({a, eab, eca});
          next.push_back({eab, b, c});
          next.push_back({eab, c, eca});
        }
      }
    }
    if (split == 0) {  // every edge at the data's resolution: nothing finer to measure
      if (level == 0) discretisation = 0.0;
      break;
    }
    m.triangles = std::move(next);
    ++m.levels;
    const double now = area();
    discretisation = std::abs(now - previous) / 3.0;
    previous = now;
    if (discretisation <= options.relative_tolerance * now) break;
  }
  m.value = previous;
  m.discretisation = 2.0 * discretisation;
  m.uncertainty = m.discretisation + perimeter * mean_unc;
  return m;
}

}  // namespace tessera::annotate
