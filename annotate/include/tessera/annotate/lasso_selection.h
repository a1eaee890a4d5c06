// Lasso selection on huge models: every element of a store whose projection falls
// inside a closed screen polygon, through the whole depth or only where it is visible, exact at
// the leaves and out of core. The thesis' base selection method back-projects the lasso's 2D
// region onto the model and keeps the vertices rendered inside it
// (../shared/papers/patch-lod-annotation-thesis.txt, sections 4.1.1 and 4.1.2); here the
// hierarchy does the work instead of an index image: a node whose projected bounds lie wholly
// inside the lasso is taken without reading its payload, one wholly outside is pruned, and only
// the leaves the lasso's border crosses are read and tested element by element.
//
// What is selected: input elements, at the leaves. Points: the points of the PointStore's leaf
// chunks (every input point is stored once, in the leaf holding it; inner nodes' LOD copies are
// never selected), at their stored (decoded) positions. Triangles: the triangles of the
// MeshStore's leaf patches (the input mesh at full resolution); a triangle is inside when its
// centroid (the mean of its three decoded vertices) is. The result is a Selection (selection.h)
// over leaf node ids and payload indices.
//
// The test applied to one element at store-local position p (LassoProjector does it, so callers
// and tests apply the very same arithmetic, in doubles):
//   clip = projection * view * model * (p, 1); the element is in front when clip.w > 0 (elements
//   behind the eye, or on the eye plane, are never inside; there is no near or far clipping);
//   pixel = ((clip.x / clip.w + 1) / 2 * width, (1 - clip.y / clip.w) / 2 * height): pixel
//   coordinates with the origin at the viewport's top-left corner, x right, y down (GLFW cursor
//   coordinates; pixel (i, j) covers [i, i + 1) x [j, j + 1), its centre at (i + 0.5, j + 0.5));
//   inside the lasso by the even-odd rule (a self-intersecting lasso's doubly wound parts are
//   outside), with the half-open crossing rule, so a point exactly on an edge is decided the same
//   way every time.
//   on screen: 0 <= pixel.x < width and 0 <= pixel.y < height (a lasso reaching past the
//   viewport's edge selects nothing off screen).
//   THROUGH: selected when in front, on screen and inside. VISIBLE: also not hidden in the
//   depth image (DepthImage, VisibilityOptions).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_store.h>
#include <tessera/annotate/selection.h>

namespace tessera::annotate {

enum class LassoMode {
  kThrough,  ///< everything whose projection falls inside, through the whole depth
  kVisible,  ///< only what the depth image shows (nothing hidden behind a nearer surface)
};

/// The view the lasso was drawn in. Matrices are GL's: right-handed eye space looking down -z,
/// clip z in [-w, w]; perspective, off-axis (tiles) and orthographic projections all work. Keep
/// them in doubles: with georeferenced data the world frame sits far from the origin.
struct LassoView {
  glm::dmat4 view{1.0};        ///< world -> eye
  glm::dmat4 projection{1.0};  ///< eye -> clip
  glm::uvec2 viewport{0};      ///< width, height in pixels (> 0)
};

/// A closed lasso in pixels (coordinates as in the header comment; the last vertex joins the
/// first). Any polygon: concave, self-intersecting, reaching past the viewport's edges. Inside is
/// the even-odd rule. Preprocessed into horizontal bands of edges, so a point test costs about
/// the number of edges crossing its band, not the whole polygon.
class LassoPolygon {
 public:
  /// At least three finite vertices (PreconditionError otherwise). Cost: O(edges + bands).
  explicit LassoPolygon(std::vector<glm::dvec2> vertices);

  const std::vector<glm::dvec2>& vertices() const { return mVertices; }
  /// Even-odd with the half-open crossing rule: an edge (a, b) counts when (a.y > p.y) !=
  /// (b.y > p.y) and p.x < a.x + (p.y - a.y) * s, with s = (b.x - a.x) / (b.y - a.y) computed
  /// once per edge (the doubles of that expression decide points on an edge).
  bool contains(const glm::dvec2& p) const;

  enum class Overlap { kOutside, kInside, kStraddles };
  /// Where the closed rectangle [lo, hi] lies: kInside or kOutside only when no edge comes
  /// within `margin` pixels of it (then every point of it tests as contains() says for its
  /// centre); kStraddles otherwise.
  Overlap classify(const glm::dvec2& lo, const glm::dvec2& hi, double margin) const;

 private:
  struct Edge {
    glm::dvec2 a, b;
    double slope;  ///< dx / dy
  };
  std::vector<glm::dvec2> mVertices;
  std::vector<Edge> mEdges;
  double mY0 = 0.0, mBandScale = 1.0;  ///< band of y: floor((y - mY0) * mBandScale)
  glm::dvec2 mLo{0.0}, mHi{0.0};       ///< the polygon's bounds
  std::vector<uint32_t> mBandStart;    ///< per band, its first entry in mBandEdges (+1 at end)
  std::vector<uint32_t> mBandEdges;    ///< edge indices per band
  size_t mLastBand = 0;
  /// The band of a row. Monotone in y (IEEE subtraction and multiplication by a positive
  /// constant are), so an edge whose y range holds a row is listed in that row's band.
  size_t band(double y) const {
    const double f = (y - mY0) * mBandScale;
    if (!(f > 0.0)) return 0;
    return f >= double(mLastBand) ? mLastBand : size_t(f);  // truncation: floor for f > 0
  }
};

/// A depth image of the view, as the renderer's frame target gives it
/// (render/frame_target.h, FrameTarget::readDepth() with each word's bits taken as a float):
/// window depth in [0, 1] (GL's default depth range: (clip.z / clip.w + 1) / 2), raster order
/// (row 0 at the BOTTOM of the view, so the pixel at lasso coordinates (x, y) is row
/// height - 1 - floor(y)), width * height floats. A pixel where nothing was drawn holds NaN (the
/// frame target's empty word 0xFFFFFFFF is a NaN) or any value outside [0, 1].
struct DepthImage {
  uint32_t width = 0, height = 0;  ///< must equal the view's viewport
  std::span<const float> depth;
};

/// When an element counts as visible. Depths are compared as eye depth (distance along the view
/// axis, -z in eye space, world units), recovered from window depth through the projection.
struct VisibilityOptions {
  /// Visible when the element's eye depth <= surface * (1 + relative) + absolute, where surface
  /// is the eye depth drawn at its pixel: splats and coarse LOD samples lie a little off the
  /// leaf positions.
  double relative_tolerance = 0.01;
  double absolute_tolerance = 0.0;
  /// A pixel where nothing was drawn (a gap between splats) takes the nearest depth drawn within
  /// this many pixels (Chebyshev distance, at most 64); with none there, the element is visible.
  uint32_t gap_radius_px = 1;
};

struct LassoOptions {
  LassoMode mode = LassoMode::kThrough;
  /// Store-local -> world. Default: a translation by the store's origin (world = origin + local).
  std::optional<glm::dmat4> model;
  /// kVisible only (required there, PreconditionError otherwise).
  std::optional<DepthImage> depth;
  VisibilityOptions visibility;
  /// Threads reading and testing the leaves (0: one per core). The traversal itself is one
  /// thread: it reads only hierarchy pages.
  unsigned threads = 0;
};

/// The element test of the header comment for one view and model, in doubles.
class LassoProjector {
 public:
  LassoProjector(const LassoView& view, const glm::dmat4& model);
  struct Projected {
    bool in_front = false;  ///< clip.w > 0
    glm::dvec2 pixel{0.0};  ///< valid when in_front
  };
  /// About 12 multiply-adds and 2 divisions.
  Projected project(const glm::dvec3& local) const;
  /// -z in eye space (world units): what the visibility test compares.
  double eyeDepth(const glm::dvec3& local) const;
  const glm::dmat4& localToClip() const { return mLocalToClip; }
  const glm::dmat4& localToEye() const { return mLocalToEye; }
  const LassoView& view() const { return mView; }

 private:
  LassoView mView;
  glm::dmat4 mLocalToClip, mLocalToEye;
};

/// The depth image turned into what the visibility test compares against: per pixel the largest
/// eye depth a visible element may have (VisibilityOptions), +infinity where nothing hides.
class VisibilityMap {
 public:
  /// PreconditionError when the image's size is not the view's viewport, its span is short or
  /// the gap radius is above 64. Cost: one pass over the image, (2r + 1)^2 reads per empty pixel.
  VisibilityMap(const DepthImage& depth, const LassoView& view, const VisibilityOptions& options);
  /// Whether an element at lasso pixel coordinates with this eye depth is visible (false outside
  /// the viewport).
  bool visible(const glm::dvec2& pixel, double eye_depth) const;
  /// Smallest and largest limit over the pixels [x0, x1] x [y0, y1] (lasso rows, inclusive,
  /// clamped to the viewport). Cost: the rectangle's area.
  std::pair<double, double> limits(int x0, int y0, int x1, int y1) const;
  uint32_t width() const { return mWidth; }
  uint32_t height() const { return mHeight; }

 private:
  uint32_t mWidth, mHeight;
  std::vector<double> mLimit;  ///< lasso row order (row 0 at the top)
};

struct LassoStats {
  uint64_t nodes_visited = 0;
  uint64_t nodes_whole = 0;   ///< taken whole without reading their payload
  uint64_t nodes_pruned = 0;  ///< wholly outside (or hidden)
  uint64_t leaves_read = 0;   ///< leaf payloads read and tested element by element
  uint64_t elements_tested = 0;
  /// Leaves whose payload failed its checksum or decoding: their elements are not selected.
  uint64_t corrupt_chunks = 0;
  /// Hierarchy pages the store has refused, in this call or an earlier one (a point store reads a
  /// bad page once: PointStore::cacheStats().corrupt_pages): the subtrees below them are missing
  /// from the selection. Mesh stores check their whole table on open: always 0.
  uint64_t corrupt_pages = 0;
  std::vector<lod::NodeId> corrupt_nodes;  ///< the leaves counted in corrupt_chunks
};

struct LassoResult {
  Selection selection;
  LassoStats stats;
};

/// Selects the store's points inside the lasso. Reads hierarchy pages and the leaf chunks the
/// lasso's border (or, kVisible, the depth image's edges) crosses, through the store's cache
/// (thread-safe, touches the disk); corrupt chunks and pages are counted in the stats and
/// skipped, never thrown. PreconditionError for an empty viewport or a missing depth image.
/// Cost (bench/lasso.cpp): about 70 ns per point of the leaves read, one thread; the rest of
/// the store costs its hierarchy's metadata only.
LassoResult lassoPoints(lod::PointStore& store, const LassoView& view, const LassoPolygon& lasso,
                        const LassoOptions& options = {});

/// Selects the store's leaf triangles whose centroid is inside the lasso (the same test and
/// pruning by patch bounds). Reads the leaf patches the border crosses.
LassoResult lassoTriangles(lod::MeshStore& store, const LassoView& view, const LassoPolygon& lasso,
                           const LassoOptions& options = {});

}  // namespace tessera::annotate
