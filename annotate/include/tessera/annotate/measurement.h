// Measuring on the model (Atelier3D section 4.1): distance, polyline
// length, angle, and the area of a surface region bounded by a closed polyline, in metres, each
// with the bound of its error that the data allows. Pure geometry on doubles (georeferenced
// LiDAR keeps millimetres hundreds of kilometres from its origin); the surface enters only
// through a projector (surface_pick.h makes them for point and mesh stores), so every method is
// tested against analytic shapes.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <stdexcept>
#include <vector>

#include <glm/glm.hpp>

namespace tessera::annotate {

/// A measurement that cannot be made: too few points, non-finite coordinates, a loop too long
/// for the triangulation. The message says which and why.
class MeasureError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A point on a model's surface: world frame, metres, and the radius within which the data
/// places it (quantisation, sampling), metres, >= 0.
struct SurfacePoint {
  glm::dvec3 world{0.0};
  double uncertainty = 0.0;
};

/// A value and the worst-case bound of its error, to first order in the points' uncertainties
/// (and, for areas, the discretisation of the surface).
struct Measurement {
  double value = 0.0;
  double uncertainty = 0.0;
};

/// |a - b|, metres.
Measurement distance(const SurfacePoint& a, const SurfacePoint& b);
/// The length of the open polyline through `points` (at least 2), metres.
Measurement polylineLength(std::span<const SurfacePoint> points);
/// The angle at `vertex` between the directions to `a` and to `b`, radians in [0, pi]. Throws
/// MeasureError when a or b coincides with the vertex.
Measurement angle(const SurfacePoint& a, const SurfacePoint& vertex, const SurfacePoint& b);

/// The triangulation of a closed polygon in space (vertex indices into `loop`, n - 2 triangles)
/// whose total area is least (Barequet and Sharir 1995, dynamic programming over the polygon's
/// chords). For a planar simple polygon it is a proper triangulation and its area the polygon's;
/// for a loop drawn on a curved surface it is the flattest spanning surface, which surfaceArea()
/// then brings onto the surface. Cost: O(n^3) time, O(n^2) memory; n <= kMaxAreaLoop.
std::vector<glm::u32vec3> minimumAreaTriangulation(std::span<const glm::dvec3> loop);
constexpr size_t kMaxAreaLoop = 1024;

/// The point of the surface nearest to `p` (world, metres), or nullopt where there is no
/// surface within the projector's reach. Called from one thread at a time.
using SurfaceProjector = std::function<std::optional<glm::dvec3>(const glm::dvec3& p)>;

struct AreaOptions {
  /// Stop refining when the estimated discretisation error is below this share of the area.
  double relative_tolerance = 1e-3;
  /// Do not split edges shorter than this (metres): below the data's resolution refinement
  /// measures noise, not shape. 0: no limit.
  double min_edge = 0.0;
  int max_levels = 8;
  size_t max_triangles = size_t(1) << 17;
};

struct AreaMeasurement : Measurement {
  int levels = 0;              ///< refinements made
  size_t unprojected = 0;      ///< midpoints the projector found no surface for (kept flat)
  double discretisation = 0.0; ///< the part of `uncertainty` from the triangulation
  /// The region's surface as measured (world, metres): for drawing it.
  std::vector<glm::dvec3> vertices;
  std::vector<glm::u32vec3> triangles;
};

/// The area of the surface region bounded by the closed polyline `loop` (at least 3 points; the
/// last joins the first), metres^2: the minimum-area triangulation of the loop, refined by
/// splitting every edge at its midpoint brought onto the surface by `project` (boundary edges
/// too, so the boundary follows the surface between the picked points) until the area settles.
/// The discretisation error after level k is estimated as (A_k - A_{k-1}) / 3 (a smooth surface's
/// inscribed triangulation converges with the square of the edge length) and counted twice;
/// the data's part is the perimeter times the mean uncertainty of the loop's points.
AreaMeasurement surfaceArea(std::span<const SurfacePoint> loop, const SurfaceProjector& project,
                            const AreaOptions& options = {});

}  // namespace tessera::annotate
