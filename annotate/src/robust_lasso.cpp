// Strokes on the screen without GL: projection, a CPU depth buffer for visibility, picking
// under a stroke, and the robust lasso's seeds (thesis 4.3.1).
#include <tessera/annotate/lazy_snapping.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace tessera::annotate {

namespace {

constexpr uint64_t kMaxViewportPixels = uint64_t(1) << 26;

void checkView(const ScreenView& view, const char* who) {
  if (view.viewport.x == 0 || view.viewport.y == 0 ||
      uint64_t(view.viewport.x) * view.viewport.y > kMaxViewportPixels)
    throw SnappingError(std::string(who) + ": viewport " + std::to_string(view.viewport.x) + "x" +
                        std::to_string(view.viewport.y) + " is empty or larger than 2^26 pixels");
}

double segmentDistance(const glm::dvec2& p, const glm::dvec2& a, const glm::dvec2& b) {
  const glm::dvec2 ab = b - a;
  const double len2 = glm::dot(ab, ab);
  const double t = len2 > 0 ? std::clamp(glm::dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
  return glm::length(p - (a + t * ab));
}

double polylineDistance(const glm::dvec2& p, std::span<const glm::dvec2> line, bool closed) {
  if (line.size() == 1) return glm::length(p - line[0]);
  double d = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k + 1 < line.size(); ++k)
    d = std::min(d, segmentDistance(p, line[k], line[k + 1]));
  if (closed) d = std::min(d, segmentDistance(p, line.back(), line.front()));
  return d;
}

/// Even-odd point in polygon (the polygon closes from the last point to the first).
bool inside(const glm::dvec2& p, std::span<const glm::dvec2> poly) {
  bool in = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const glm::dvec2 &a = poly[i], &b = poly[j];
    if ((a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x) in = !in;
  }
  return in;
}

bool finite2(const glm::dvec2& p) {
  return std::isfinite(p.x) && std::isfinite(p.y);
}

}  // namespace

ScreenPoint project(const ScreenView& view, const glm::dvec3& position) {
  const glm::dvec4 eye = view.view * glm::dvec4(position, 1.0);
  const glm::dvec4 clip = view.projection * eye;
  ScreenPoint sp{{0.0, 0.0}, -eye.z, false};
  if (!(clip.w > 0)) return sp;
  const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
  sp.pixel = {(ndc.x + 1.0) * 0.5 * view.viewport.x, (ndc.y + 1.0) * 0.5 * view.viewport.y};
  sp.in_front = ndc.z >= -1.0 && ndc.z <= 1.0;
  return sp;
}

std::vector<uint8_t> visibleSamples(const SurfaceSamples& samples, const ScreenView& view,
                                    double splat_px, double depth_tolerance) {
  checkView(view, "visibleSamples()");
  if (!(splat_px >= 0 && splat_px <= 64) || !(depth_tolerance >= 0))
    throw SnappingError("visibleSamples(): splat_px must be in [0, 64], depth_tolerance >= 0");
  const int w = int(view.viewport.x), h = int(view.viewport.y);
  std::vector<float> zbuf(size_t(w) * size_t(h), std::numeric_limits<float>::infinity());
  std::vector<ScreenPoint> sp(samples.size());
  const int r = int(std::ceil(splat_px));
  for (size_t i = 0; i < samples.size(); ++i) {
    sp[i] = project(view, samples.positions[i]);
    if (!sp[i].in_front) continue;
    const int cx = int(std::floor(sp[i].pixel.x)), cy = int(std::floor(sp[i].pixel.y));
    for (int y = std::max(0, cy - r); y <= std::min(h - 1, cy + r); ++y)
      for (int x = std::max(0, cx - r); x <= std::min(w - 1, cx + r); ++x) {
        if (double((x - cx) * (x - cx) + (y - cy) * (y - cy)) > splat_px * splat_px) continue;
        float& z = zbuf[size_t(y) * size_t(w) + size_t(x)];
        z = std::min(z, float(sp[i].depth));
      }
  }
  std::vector<uint8_t> visible(samples.size(), 0);
  for (size_t i = 0; i < samples.size(); ++i) {
    if (!sp[i].in_front) continue;
    const int x = int(std::floor(sp[i].pixel.x)), y = int(std::floor(sp[i].pixel.y));
    if (x < 0 || y < 0 || x >= w || y >= h) continue;
    visible[i] = sp[i].depth <= double(zbuf[size_t(y) * size_t(w) + size_t(x)]) + depth_tolerance;
  }
  return visible;
}

std::vector<uint32_t> pickStroke(const SurfaceSamples& samples, const ScreenView& view,
                                 std::span<const glm::dvec2> stroke, double radius_px,
                                 std::span<const uint8_t> visible) {
  checkView(view, "pickStroke()");
  if (stroke.empty() || !std::all_of(stroke.begin(), stroke.end(), finite2))
    throw SnappingError("pickStroke(): the stroke is empty or has non-finite points");
  if (!visible.empty() && visible.size() != samples.size())
    throw SnappingError("pickStroke(): visibility mask of the wrong size");
  std::vector<uint32_t> picked;
  for (uint32_t i = 0; i < samples.size(); ++i) {
    if (!visible.empty() && !visible[i]) continue;
    const ScreenPoint sp = project(view, samples.positions[i]);
    if (sp.in_front && polylineDistance(sp.pixel, stroke, false) <= radius_px) picked.push_back(i);
  }
  return picked;
}

Strokes robustLassoSeeds(const SurfaceSamples& samples, const ScreenView& view,
                         const HeavyStroke& stroke, std::span<const uint8_t> visible) {
  checkView(view, "robustLassoSeeds()");
  if (stroke.polyline.size() < 3 ||
      !std::all_of(stroke.polyline.begin(), stroke.polyline.end(), finite2))
    throw SnappingError(
        "robustLassoSeeds(): the heavy stroke needs at least 3 finite points (got " +
        std::to_string(stroke.polyline.size()) + ")");
  if (!(stroke.width_px >= 0) || !(stroke.seed_band_px >= 0))
    throw SnappingError("robustLassoSeeds(): width_px and seed_band_px must be >= 0");
  if (!visible.empty() && visible.size() != samples.size())
    throw SnappingError("robustLassoSeeds(): visibility mask of the wrong size");
  // Samples under the heavy stroke are unknown; the thesis' automatic yellow (inside) and blue
  // (outside) markers run along the stroke's two sides: bands seed_band_px wide next to it.
  const double half = 0.5 * stroke.width_px;
  const double reach = stroke.seed_band_px > 0 ? half + stroke.seed_band_px
                                               : std::numeric_limits<double>::infinity();
  Strokes seeds;
  for (uint32_t i = 0; i < samples.size(); ++i) {
    if (!visible.empty() && !visible[i]) continue;
    const ScreenPoint sp = project(view, samples.positions[i]);
    if (!sp.in_front) continue;
    const double d = polylineDistance(sp.pixel, stroke.polyline, true);
    if (d <= half || d > reach) continue;
    (inside(sp.pixel, stroke.polyline) ? seeds.foreground : seeds.background).push_back(i);
  }
  return seeds;
}

}  // namespace tessera::annotate
