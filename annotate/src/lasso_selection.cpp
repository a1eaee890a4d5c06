#include <tessera/annotate/lasso_selection.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <mutex>
#include <thread>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/parallel.h>
#include <tessera/core/check.h>

namespace tessera::annotate {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// Pixels of slack between a node's projected bounds and the lasso's edges before the node is
/// decided without testing its elements: far above the rounding of the projection in doubles
/// (about 1e-12 pixels for views of a few thousand pixels), so a whole node never holds an element
/// the element test would decide otherwise.
constexpr double kMarginPx = 1e-4;

}  // namespace

// --- LassoPolygon ----------------------------------------------------------------------------

LassoPolygon::LassoPolygon(std::vector<glm::dvec2> vertices) : mVertices(std::move(vertices)) {
  TESSERA_CHECK(mVertices.size() >= 3, "LassoPolygon: a lasso needs at least three vertices");
  for (const glm::dvec2& v : mVertices)
    TESSERA_CHECK(std::isfinite(v.x) && std::isfinite(v.y), "LassoPolygon: a vertex is not finite");
  mLo = mHi = mVertices[0];
  for (size_t i = 0; i < mVertices.size(); ++i) {
    const glm::dvec2 a = mVertices[i], b = mVertices[(i + 1) % mVertices.size()];
    mLo = glm::min(mLo, a);
    mHi = glm::max(mHi, a);
    // Horizontal ones too: contains() never counts them (nor reads their infinite slope).
    mEdges.push_back({a, b, (b.x - a.x) / (b.y - a.y)});
  }
  // Bands of about one edge each (at most 4096): a freehand lasso crosses a row a few times,
  // so a point meets a handful of edges.
  const size_t bands = std::clamp<size_t>(mEdges.size(), 1, 4096);
  mY0 = mLo.y;
  mBandScale = double(bands) / std::max(mHi.y - mLo.y, 1e-9);
  mBandStart.assign(bands + 1, 0);
  mLastBand = bands - 1;
  std::vector<uint32_t> counts(bands + 1, 0);
  auto span = [&](const Edge& e) {
    return std::pair(band(std::min(e.a.y, e.b.y)), band(std::max(e.a.y, e.b.y)));
  };
  for (const Edge& e : mEdges) {
    const auto [b0, b1] = span(e);
    for (size_t b = b0; b <= b1; ++b) ++counts[b + 1];
  }
  for (size_t b = 0; b < bands; ++b) counts[b + 1] += counts[b];
  mBandStart = counts;
  mBandEdges.resize(counts.back());
  for (uint32_t i = 0; i < mEdges.size(); ++i) {
    const auto [b0, b1] = span(mEdges[i]);
    for (size_t b = b0; b <= b1; ++b) mBandEdges[counts[b]++] = i;
  }
}

bool LassoPolygon::contains(const glm::dvec2& p) const {
  // Edges not listed in p's band have no crossing with p's row, so skipping them changes
  // nothing: the same answer as the test over every edge.
  if (!(p.y >= mLo.y && p.y < mHi.y)) return false;
  const size_t b = band(p.y);
  bool inside = false;
  for (uint32_t k = mBandStart[b]; k < mBandStart[b + 1]; ++k) {
    const Edge& e = mEdges[mBandEdges[k]];
    if ((e.a.y > p.y) != (e.b.y > p.y) && p.x < e.a.x + (p.y - e.a.y) * e.slope) inside = !inside;
  }
  return inside;
}

LassoPolygon::Overlap LassoPolygon::classify(const glm::dvec2& lo_in, const glm::dvec2& hi_in,
                                             double margin) const {
  const glm::dvec2 lo = lo_in - margin, hi = hi_in + margin;
  if (hi.x < mLo.x || lo.x > mHi.x || hi.y < mLo.y || lo.y > mHi.y) return Overlap::kOutside;
  // Any edge (horizontal ones included) meeting the rectangle makes it straddle: separating
  // axes x, y and the edge's normal.
  const size_t b0 = band(lo.y), b1 = band(hi.y);
  auto meets = [&](const glm::dvec2& a, const glm::dvec2& b) {
    if (std::max(a.x, b.x) < lo.x || std::min(a.x, b.x) > hi.x || std::max(a.y, b.y) < lo.y ||
        std::min(a.y, b.y) > hi.y)
      return false;
    const glm::dvec2 d = b - a;
    int neg = 0, pos = 0;
    for (const glm::dvec2& c : {lo, hi, glm::dvec2(lo.x, hi.y), glm::dvec2(hi.x, lo.y)}) {
      const double s = d.x * (c.y - a.y) - d.y * (c.x - a.x);
      neg += s <= 0.0;
      pos += s >= 0.0;
    }
    return neg > 0 && pos > 0;
  };
  // An edge meeting the rectangle has a point in its rows, so it is listed in one of their
  // bands (band() is monotone).
  for (size_t b = b0; b <= b1; ++b)
    for (uint32_t k = mBandStart[b]; k < mBandStart[b + 1]; ++k)
      if (meets(mEdges[mBandEdges[k]].a, mEdges[mBandEdges[k]].b)) return Overlap::kStraddles;
  return contains((lo_in + hi_in) * 0.5) ? Overlap::kInside : Overlap::kOutside;
}

// --- LassoProjector ---------------------------------------------------------------------------

LassoProjector::LassoProjector(const LassoView& view, const glm::dmat4& model)
    : mView(view),
      mLocalToClip(view.projection * view.view * model),
      mLocalToEye(view.view * model) {
  TESSERA_CHECK(view.viewport.x > 0 && view.viewport.y > 0,
                "LassoProjector: the viewport is empty");
}

LassoProjector::Projected LassoProjector::project(const glm::dvec3& local) const {
  // Rows x, y and w of the local -> clip matrix only (z is not needed), in doubles.
  const glm::dmat4& m = mLocalToClip;
  const double x = m[0][0] * local.x + m[1][0] * local.y + m[2][0] * local.z + m[3][0];
  const double y = m[0][1] * local.x + m[1][1] * local.y + m[2][1] * local.z + m[3][1];
  const double w = m[0][3] * local.x + m[1][3] * local.y + m[2][3] * local.z + m[3][3];
  Projected p;
  p.in_front = w > 0.0;
  if (p.in_front)
    p.pixel =
        glm::dvec2((x / w + 1.0) * 0.5 * mView.viewport.x, (1.0 - y / w) * 0.5 * mView.viewport.y);
  return p;
}

double LassoProjector::eyeDepth(const glm::dvec3& local) const {
  const glm::dmat4& m = mLocalToEye;
  return -(m[0][2] * local.x + m[1][2] * local.y + m[2][2] * local.z + m[3][2]);
}

// --- VisibilityMap ----------------------------------------------------------------------------

VisibilityMap::VisibilityMap(const DepthImage& depth, const LassoView& view,
                             const VisibilityOptions& options)
    : mWidth(depth.width), mHeight(depth.height) {
  TESSERA_CHECK(depth.width == view.viewport.x && depth.height == view.viewport.y,
                "VisibilityMap: the depth image's size is not the view's viewport");
  TESSERA_CHECK(depth.depth.size() >= size_t(depth.width) * depth.height,
                "VisibilityMap: the depth image holds fewer than width * height floats");
  TESSERA_CHECK(options.gap_radius_px <= 64, "VisibilityMap: gap_radius_px is at most 64");
  const glm::dmat4 inv = glm::inverse(view.projection);
  const size_t n = size_t(mWidth) * mHeight;
  // Eye depth of what was drawn, lasso row order; NaN where nothing was.
  std::vector<double> eye(n, std::numeric_limits<double>::quiet_NaN());
  for (uint32_t y = 0; y < mHeight; ++y) {
    const float* row = depth.depth.data() + size_t(mHeight - 1 - y) * mWidth;
    const double ndc_y = 1.0 - 2.0 * (y + 0.5) / mHeight;
    for (uint32_t x = 0; x < mWidth; ++x) {
      const float d = row[x];
      if (!(d >= 0.0f && d <= 1.0f)) continue;
      // Unproject the pixel centre at its window depth (works for any projection matrix).
      const glm::dvec4 e =
          inv * glm::dvec4(2.0 * (x + 0.5) / mWidth - 1.0, ndc_y, 2.0 * double(d) - 1.0, 1.0);
      const double z = -e.z / e.w;
      if (std::isfinite(z)) eye[size_t(y) * mWidth + x] = z;
    }
  }
  const int r = int(options.gap_radius_px);
  mLimit.assign(n, kInf);
  for (int y = 0; y < int(mHeight); ++y) {
    for (int x = 0; x < int(mWidth); ++x) {
      double s = eye[size_t(y) * mWidth + x];
      if (std::isnan(s)) {  // a gap: the nearest surface drawn around it
        s = kInf;
        for (int v = std::max(0, y - r); v <= std::min(int(mHeight) - 1, y + r); ++v)
          for (int u = std::max(0, x - r); u <= std::min(int(mWidth) - 1, x + r); ++u) {
            const double t = eye[size_t(v) * mWidth + u];
            if (!std::isnan(t)) s = std::min(s, t);
          }
      }
      if (s < kInf)
        mLimit[size_t(y) * mWidth + x] =
            s * (1.0 + options.relative_tolerance) + options.absolute_tolerance;
    }
  }
}

bool VisibilityMap::visible(const glm::dvec2& pixel, double eye_depth) const {
  if (!(pixel.x >= 0.0 && pixel.y >= 0.0 && pixel.x < mWidth && pixel.y < mHeight)) return false;
  const size_t x = std::min(size_t(pixel.x), size_t(mWidth - 1));
  const size_t y = std::min(size_t(pixel.y), size_t(mHeight - 1));
  return eye_depth <= mLimit[y * mWidth + x];
}

std::pair<double, double> VisibilityMap::limits(int x0, int y0, int x1, int y1) const {
  x0 = std::max(x0, 0);
  y0 = std::max(y0, 0);
  x1 = std::min(x1, int(mWidth) - 1);
  y1 = std::min(y1, int(mHeight) - 1);
  double lo = kInf, hi = -kInf;
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      const double l = mLimit[size_t(y) * mWidth + x];
      lo = std::min(lo, l);
      hi = std::max(hi, l);
    }
  return {lo, hi};
}

// --- The traversal ---------------------------------------------------------------------------

namespace {

enum class Verdict { kOutside, kWhole, kStraddles };

/// What the traversal needs of a store: its nodes' bounds and its leaves' elements.
struct PointSource {
  lod::PointStore& store;
  /// Bounds of every element below a node: a stored position lies within the node's error
  /// bound of its input point, which lies in the node's octree cell (children's cells nest);
  /// positions are floats relative to the box minimum.
  std::pair<glm::dvec3, glm::dvec3> bounds(lod::NodeId, const lod::NodeInfo& n) const {
    const double pad = double(n.error_bound) + 1e-6 * glm::length(n.box_max - n.box_min);
    return {n.box_min - pad, n.box_max + pad};
  }
  /// Pages the store has refused, in this call or before (a refused page is not read again, so
  /// children() throws only once for it).
  uint64_t corruptPages() const { return store.cacheStats().corrupt_pages; }
  /// Calls f(index, local position) for every element of a leaf; returns their number. Throws
  /// StoreError.
  template <class F>
  uint32_t forEach(lod::NodeId id, F&& f) const {
    const std::shared_ptr<const lod::ChunkPoints> c = store.loadChunk(id);
    for (size_t i = 0; i < c->positions.size(); ++i)
      f(uint32_t(i), c->offset + glm::dvec3(c->positions[i]));
    return uint32_t(c->positions.size());
  }
};

struct MeshSource {
  explicit MeshSource(lod::MeshStore& s) : store(s), lo(s.nodeCount()), hi(s.nodeCount()) {
    // An inner patch is its children simplified: its own box need not hold theirs (collapses
    // keep a subset of the vertices), so prune by the union of the subtree's boxes. Post-order
    // with an explicit stack (the table is a tree: MeshStore::open() checked it).
    std::vector<std::pair<lod::NodeId, bool>> stack = {{s.root(), false}};
    while (!stack.empty()) {
      const auto [id, done] = stack.back();
      stack.pop_back();
      const lod::MeshNodeRecord& r = s.record(id);
      if (!done) {
        stack.push_back({id, true});
        for (uint32_t c = 0; c < r.child_count; ++c) stack.push_back({r.first_child + c, false});
        continue;
      }
      lo[id] = glm::dvec3(r.box_min);
      hi[id] = glm::dvec3(r.box_max);
      for (uint32_t c = 0; c < r.child_count; ++c) {
        lo[id] = glm::min(lo[id], lo[r.first_child + c]);
        hi[id] = glm::max(hi[id], hi[r.first_child + c]);
      }
    }
  }
  lod::MeshStore& store;
  std::vector<glm::dvec3> lo, hi;

  uint64_t corruptPages() const { return 0; }  // the node table is checked on open
  std::pair<glm::dvec3, glm::dvec3> bounds(lod::NodeId id, const lod::NodeInfo&) const {
    // The table's boxes are floats; vertices sit on the store's grid.
    const double far = glm::length(glm::max(glm::abs(lo[id]), glm::abs(hi[id])));
    const double pad = store.summary().step + 1e-6 * (glm::length(hi[id] - lo[id]) + far);
    return {lo[id] - pad, hi[id] + pad};
  }
  template <class F>
  uint32_t forEach(lod::NodeId id, F&& f) const {
    const lod::MeshPatch p = store.readPatch(id);
    for (size_t t = 0; t < p.triangles(); ++t) {
      glm::dvec3 sum(0.0);
      for (int k = 0; k < 3; ++k) sum += p.offset + glm::dvec3(p.positions[p.indices[3 * t + k]]);
      f(uint32_t(t), sum / 3.0);
    }
    return uint32_t(p.triangles());
  }
};

template <class Source>
class Lasso {
 public:
  Lasso(lod::LodHierarchy& tree, const Source& source, const LassoView& view,
        const LassoPolygon& polygon, const LassoOptions& options, const glm::dmat4& model,
        SelectionElements elements)
      : mTree(tree),
        mSource(source),
        mPolygon(polygon),
        mMode(options.mode),
        mProjector(view, model),
        mViewport(view.viewport) {
    mResult.selection = Selection(elements);
    if (mMode == LassoMode::kVisible) {
      TESSERA_CHECK(options.depth.has_value(), "lasso: kVisible needs a depth image");
      mVisibility.emplace(*options.depth, view, options.visibility);
    }
    // The polygon's bounds within the viewport as NDC half-spaces, for the
    // outside test in homogeneous coordinates.
    glm::dvec2 lo(kInf), hi(-kInf);
    for (const glm::dvec2& v : polygon.vertices()) {
      lo = glm::min(lo, v);
      hi = glm::max(hi, v);
    }
    // Clipped to the viewport, with a pixel of slack: the test only prunes.
    lo = glm::max(lo, glm::dvec2(0.0)) - 1.0;
    hi = glm::min(hi, glm::dvec2(mViewport)) + 1.0;
    mNdcLo = glm::dvec2(2.0 * lo.x / mViewport.x - 1.0, 1.0 - 2.0 * hi.y / mViewport.y);
    mNdcHi = glm::dvec2(2.0 * hi.x / mViewport.x - 1.0, 1.0 - 2.0 * lo.y / mViewport.y);
  }

  LassoResult run(unsigned threads) {
    visit(mTree.root());  // metadata only: the hierarchy's pages
    testLeaves(threads);
    mResult.stats.corrupt_pages = std::max(mResult.stats.corrupt_pages, mSource.corruptPages());
    return std::move(mResult);
  }

 private:
  Verdict classify(lod::NodeId id, const lod::NodeInfo& n) {
    const auto [lo, hi] = mSource.bounds(id, n);
    std::array<glm::dvec4, 8> clip;
    double e_lo = kInf, e_hi = -kInf;
    for (int i = 0; i < 8; ++i) {
      const glm::dvec3 c(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
      clip[i] = mProjector.localToClip() * glm::dvec4(c, 1.0);
      const double e = mProjector.eyeDepth(c);
      e_lo = std::min(e_lo, e);
      e_hi = std::max(e_hi, e);
    }
    // Outside: all eight corners (so every point of the box, clip coordinates being affine in
    // position) behind the eye or beyond one side of the lasso's bounds. Exact across the eye
    // plane, where projecting corners would not be.
    auto allFail = [&](auto&& f) {
      return std::all_of(clip.begin(), clip.end(), [&](const glm::dvec4& c) { return f(c); });
    };
    if (allFail([](const glm::dvec4& c) { return c.w <= 0.0; }) ||
        allFail([&](const glm::dvec4& c) { return c.x < mNdcLo.x * c.w; }) ||
        allFail([&](const glm::dvec4& c) { return c.x > mNdcHi.x * c.w; }) ||
        allFail([&](const glm::dvec4& c) { return c.y < mNdcLo.y * c.w; }) ||
        allFail([&](const glm::dvec4& c) { return c.y > mNdcHi.y * c.w; }))
      return Verdict::kOutside;
    // A box reaching behind the eye projects to no bounded region: open it.
    if (!allFail([](const glm::dvec4& c) { return c.w > 0.0; })) return Verdict::kStraddles;
    // In front: the box projects into the convex hull of its projected corners.
    glm::dvec2 plo(kInf), phi(-kInf);
    for (const glm::dvec4& c : clip) {
      const glm::dvec2 p((c.x / c.w + 1.0) * 0.5 * mViewport.x,
                         (1.0 - c.y / c.w) * 0.5 * mViewport.y);
      plo = glm::min(plo, p);
      phi = glm::max(phi, p);
    }
    const double margin = kMarginPx + 1e-9 * std::max({std::abs(plo.x), std::abs(plo.y),
                                                       std::abs(phi.x), std::abs(phi.y)});
    // Only the viewport's pixels count: off screen is never inside.
    const glm::dvec2 vlo = plo - margin, vhi = phi + margin;
    if (vhi.x < 0.0 || vhi.y < 0.0 || vlo.x >= mViewport.x || vlo.y >= mViewport.y)
      return Verdict::kOutside;
    const bool on_screen =
        vlo.x >= 0.0 && vlo.y >= 0.0 && vhi.x < mViewport.x && vhi.y < mViewport.y;
    Verdict v = Verdict::kStraddles;
    switch (mPolygon.classify(plo, phi, margin)) {
      case LassoPolygon::Overlap::kOutside:
        return Verdict::kOutside;
      case LassoPolygon::Overlap::kInside:
        v = on_screen ? Verdict::kWhole : Verdict::kStraddles;
        break;
      case LassoPolygon::Overlap::kStraddles:
        break;
    }
    if (!mVisibility) return v;
    // Visible: the pixels under the box decide. All hidden prunes; all in front keeps a whole
    // node whole.
    const auto [l_lo, l_hi] = mVisibility->limits(
        int(std::floor(std::max(vlo.x, -1.0))), int(std::floor(std::max(vlo.y, -1.0))),
        int(std::min(vhi.x, double(mViewport.x))), int(std::min(vhi.y, double(mViewport.y))));
    const double slack = 1e-9 * std::max(std::abs(e_lo), std::abs(e_hi));
    if (e_lo - slack > l_hi) return Verdict::kOutside;
    if (v == Verdict::kWhole && e_hi + slack > l_lo) v = Verdict::kStraddles;
    return v;
  }

  void visit(lod::NodeId id) {
    ++mResult.stats.nodes_visited;
    const lod::NodeInfo n = mTree.node(id);
    switch (classify(id, n)) {
      case Verdict::kOutside:
        ++mResult.stats.nodes_pruned;
        return;
      case Verdict::kWhole:
        ++mResult.stats.nodes_whole;
        takeWhole(id, n);
        return;
      case Verdict::kStraddles:
        break;
    }
    if (n.leaf()) {
      if (n.points > 0) mLeaves.emplace_back(id, n.points);
      return;
    }
    for (lod::NodeId c : children(id)) visit(c);
  }

  std::vector<lod::NodeId> children(lod::NodeId id) {
    try {
      return mTree.children(id);
    } catch (const lod::StoreError&) {
      ++mResult.stats.corrupt_pages;
      return {};
    }
  }

  /// Every leaf below a node, all its elements, from the hierarchy alone.
  void takeWhole(lod::NodeId id, const lod::NodeInfo& n) {
    if (n.leaf()) {
      if (n.points > 0) mResult.selection.set(id, NodeSelection::all(n.points));
      return;
    }
    for (lod::NodeId c : children(id)) takeWhole(c, mTree.node(c));
  }

  struct LeafResult {
    NodeSelection selection;
    uint32_t tested = 0;
    bool corrupt = false;
  };

  /// Reads one leaf and tests its elements. Thread-safe (the stores' reads are).
  LeafResult testLeaf(lod::NodeId id, uint32_t points) const {
    LeafResult out;
    std::vector<uint64_t> bits((size_t(points) + 63) / 64, 0);
    try {
      out.tested = mSource.forEach(id, [&](uint32_t i, const glm::dvec3& p) {
        if (size_t(i) / 64 >= bits.size()) bits.resize(size_t(i) / 64 + 1, 0);
        const LassoProjector::Projected q = mProjector.project(p);
        if (!q.in_front || !onScreen(q.pixel) || !mPolygon.contains(q.pixel)) return;
        if (mVisibility && !mVisibility->visible(q.pixel, mProjector.eyeDepth(p))) return;
        bits[i / 64] |= 1ull << (i % 64);
      });
    } catch (const lod::StoreError&) {
      out.corrupt = true;
      return out;
    }
    if (out.tested == 0) return out;
    bits.resize((size_t(out.tested) + 63) / 64);
    out.selection = NodeSelection::fromBits(out.tested, std::move(bits));
    return out;
  }

  /// Tests the leaves the traversal left, on `threads` threads, and merges in leaf order.
  void testLeaves(unsigned threads) {
    std::vector<LeafResult> results(mLeaves.size());
    std::atomic<size_t> next{0};
    std::mutex failure_mutex;
    std::exception_ptr failure;  // anything but a corrupt leaf (out of memory...): rethrown here
    auto work = [&] {
      try {
        for (size_t k; (k = next.fetch_add(1)) < mLeaves.size();)
          results[k] = testLeaf(mLeaves[k].first, mLeaves[k].second);
      } catch (...) {
        next = mLeaves.size();  // the others stop too
        std::lock_guard lock(failure_mutex);
        if (!failure) failure = std::current_exception();
      }
    };
    threads = std::max(1u, std::min<unsigned>(threads, unsigned(mLeaves.size())));
    runWorkers(threads, [&](unsigned) { work(); });
    if (failure) std::rethrow_exception(failure);
    for (size_t k = 0; k < mLeaves.size(); ++k) {
      if (results[k].corrupt) {
        ++mResult.stats.corrupt_chunks;
        mResult.stats.corrupt_nodes.push_back(mLeaves[k].first);
        continue;
      }
      ++mResult.stats.leaves_read;
      mResult.stats.elements_tested += results[k].tested;
      mResult.selection.set(mLeaves[k].first, std::move(results[k].selection));
    }
  }

  bool onScreen(const glm::dvec2& p) const {
    return p.x >= 0.0 && p.y >= 0.0 && p.x < mViewport.x && p.y < mViewport.y;
  }

  lod::LodHierarchy& mTree;
  const Source& mSource;
  const LassoPolygon& mPolygon;
  LassoMode mMode;
  LassoProjector mProjector;
  glm::uvec2 mViewport;
  std::optional<VisibilityMap> mVisibility;
  glm::dvec2 mNdcLo, mNdcHi;
  std::vector<std::pair<lod::NodeId, uint32_t>> mLeaves;  ///< straddling leaves, to read
  LassoResult mResult;
};

unsigned threadCount(const LassoOptions& o) {
  TESSERA_CHECK(o.threads <= 256, "lasso: at most 256 threads");
  return tessera::threadCount(int(o.threads));
}

}  // namespace

LassoResult lassoPoints(lod::PointStore& store, const LassoView& view, const LassoPolygon& lasso,
                        const LassoOptions& options) {
  const glm::dmat4 model =
      options.model.value_or(glm::translate(glm::dmat4(1.0), store.summary().origin));
  const PointSource source{store};
  return Lasso<PointSource>(store, source, view, lasso, options, model, SelectionElements::kPoints)
      .run(threadCount(options));
}

LassoResult lassoTriangles(lod::MeshStore& store, const LassoView& view, const LassoPolygon& lasso,
                           const LassoOptions& options) {
  const glm::dmat4 model =
      options.model.value_or(glm::translate(glm::dmat4(1.0), store.summary().origin));
  const MeshSource source(store);
  return Lasso<MeshSource>(store, source, view, lasso, options, model,
                           SelectionElements::kTriangles)
      .run(threadCount(options));
}

}  // namespace tessera::annotate
