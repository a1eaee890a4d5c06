// The lasso (annotate/lasso_selection.h) against brute force: every leaf element of a store
// projected and tested against every edge of the polygon. The sets must be identical, element
// for element, whatever the hierarchy pruned or took whole. Then the selection type
// (annotate/selection.h): set algebra, its byte form, and corrupt input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <optional>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/annotate/lasso_selection.h>
#include <tessera/annotate/selection.h>
#include <tessera/core/check.h>
#include <tessera/lod/mesh_builder.h>
#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/lod/store_format.h>

#include "../../fuzz/selection_fuzz.h"
#include "../support/random_cube.h"
#include "../support/temp_dir.h"

namespace tessera::annotate {
namespace {

namespace fs = std::filesystem;
using glm::dvec2;
using glm::dvec3;

const fs::path kData = TESSERA_DATA_DIR;
constexpr glm::uvec2 kViewport{800, 600};

// --- Brute force --------------------------------------------------------------------------------

/// Even-odd over every edge, written out again here (the library bands its edges).
bool insideAllEdges(const std::vector<dvec2>& poly, const dvec2& p) {
  bool inside = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const dvec2 a = poly[j], b = poly[i];
    if ((a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) * ((b.x - a.x) / (b.y - a.y)))
      inside = !inside;
  }
  return inside;
}

/// Every leaf of a hierarchy, by walking all of it.
std::vector<lod::NodeId> allLeaves(lod::LodHierarchy& tree) {
  std::vector<lod::NodeId> leaves, open = {tree.root()};
  while (!open.empty()) {
    const lod::NodeId id = open.back();
    open.pop_back();
    if (tree.node(id).leaf()) {
      leaves.push_back(id);
      continue;
    }
    try {
      for (lod::NodeId c : tree.children(id)) open.push_back(c);
    } catch (const lod::StoreError&) {  // a corrupt page: its subtree is unreachable
    }
  }
  return leaves;
}

struct Brute {
  Selection selection;
  uint64_t elements = 0;  ///< tested
  uint64_t corrupt = 0;
  /// Points outside their leaf's box grown by its error bound: what the lasso's pruning assumes
  /// never happens (lasso_selection.cpp, PointSource::bounds).
  uint64_t outside_box = 0;
};

/// The element test of lasso_selection.h applied to every element (per-element arithmetic
/// through LassoProjector, the only shared code).
template <class ForEach>
Brute bruteForce(lod::LodHierarchy& tree, SelectionElements kind, const LassoView& view,
                 const glm::dmat4& model, const std::vector<dvec2>& poly,
                 const VisibilityMap* visibility, ForEach&& forEach) {
  const LassoProjector proj(view, model);
  Brute out{Selection(kind)};
  for (lod::NodeId leaf : allLeaves(tree)) {
    std::vector<uint64_t> bits;
    uint32_t n = 0;
    try {
      n = forEach(leaf, [&](uint32_t i, const dvec3& p) {
        if (bits.size() <= i / 64) bits.resize(i / 64 + 1, 0);
        const auto q = proj.project(p);
        const bool on_screen = q.pixel.x >= 0 && q.pixel.y >= 0 && q.pixel.x < view.viewport.x &&
                               q.pixel.y < view.viewport.y;
        if (q.in_front && on_screen && insideAllEdges(poly, q.pixel) &&
            (!visibility || visibility->visible(q.pixel, proj.eyeDepth(p))))
          bits[i / 64] |= 1ull << (i % 64);
      });
    } catch (const lod::StoreError&) {
      ++out.corrupt;
      continue;
    }
    out.elements += n;
    if (n == 0) continue;
    bits.resize((n + 63) / 64, 0);
    out.selection.set(leaf, NodeSelection::fromBits(n, std::move(bits)));
  }
  return out;
}

Brute brutePoints(lod::PointStore& store, const LassoView& view, const std::vector<dvec2>& poly,
                  const VisibilityMap* visibility = nullptr,
                  std::optional<glm::dmat4> model_matrix = std::nullopt) {
  const glm::dmat4 model =
      model_matrix.value_or(glm::translate(glm::dmat4(1.0), store.summary().origin));
  uint64_t outside = 0;
  Brute b = bruteForce(store, SelectionElements::kPoints, view, model, poly, visibility,
                       [&](lod::NodeId id, auto&& f) {
                         const auto c = store.decodeChunk(id);  // not the cache the lasso used
                         const lod::NodeInfo n = store.node(id);
                         const dvec3 pad(n.error_bound);
                         for (size_t i = 0; i < c->size(); ++i) {
                           const dvec3 p = c->offset + dvec3(c->positions[i]);
                           outside += glm::any(glm::lessThan(p, n.box_min - pad)) ||
                                      glm::any(glm::greaterThan(p, n.box_max + pad));
                           f(uint32_t(i), p);
                         }
                         return uint32_t(c->size());
                       });
  b.outside_box = outside;
  EXPECT_EQ(outside, 0u) << "stored points outside their leaf box and error bound";
  return b;
}

Brute bruteTriangles(lod::MeshStore& store, const LassoView& view, const std::vector<dvec2>& poly,
                     const VisibilityMap* visibility = nullptr) {
  const glm::dmat4 model = glm::translate(glm::dmat4(1.0), store.summary().origin);
  return bruteForce(store, SelectionElements::kTriangles, view, model, poly, visibility,
                    [&](lod::NodeId id, auto&& f) {
                      const lod::MeshPatch p = store.readPatch(id);
                      for (size_t t = 0; t < p.triangles(); ++t) {
                        dvec3 sum(0.0);
                        for (int k = 0; k < 3; ++k)
                          sum += p.offset + dvec3(p.positions[p.indices[3 * t + k]]);
                        f(uint32_t(t), sum / 3.0);
                      }
                      return uint32_t(p.triangles());
                    });
}

// --- Views and polygons ---------------------------------------------------------------------

/// A perspective view from `eye` towards `target` (world frame).
LassoView lookAt(const dvec3& eye, const dvec3& target, double fov_deg = 50.0) {
  LassoView v;
  v.view =
      glm::lookAt(eye, target,
                  std::abs(glm::normalize(target - eye).z) > 0.9 ? dvec3(0, 1, 0) : dvec3(0, 0, 1));
  v.projection =
      glm::perspective(glm::radians(fov_deg), double(kViewport.x) / kViewport.y,
                       1e-3 * glm::length(target - eye), 10.0 * glm::length(target - eye));
  v.viewport = kViewport;
  return v;
}

/// A wavy closed curve around the centre (concave: 7 lobes), like a freehand lasso.
std::vector<dvec2> wavy(dvec2 centre, double r, int n = 240) {
  std::vector<dvec2> p;
  for (int i = 0; i < n; ++i) {
    const double t = 2 * M_PI * i / n;
    const double rr = r * (1.0 + 0.35 * std::sin(7 * t));
    p.push_back(centre + rr * dvec2(std::cos(t), std::sin(t)));
  }
  return p;
}

/// A five-pointed star drawn as one stroke (every second vertex): its centre pentagon is wound
/// twice, so outside by the even-odd rule.
std::vector<dvec2> pentagram(dvec2 centre, double r) {
  std::vector<dvec2> p;
  for (int i = 0; i < 5; ++i) {
    const double t = -M_PI / 2 + 2 * M_PI * (2 * i % 5) / 5.0;
    p.push_back(centre + r * dvec2(std::cos(t), std::sin(t)));
  }
  return p;
}

/// A polygon that runs past the viewport's left, top and bottom edges.
std::vector<dvec2> pastTheEdge() {
  return {{-80, -40}, {420, -60}, {250, 300}, {500, 680}, {-30, 650}, {120, 300}};
}

dvec3 centreOf(const lod::StoreSummary& s) {
  return s.origin + 0.5 * (s.bbox_min + s.bbox_max);
}

/// A point store built from `inputs` into `dir`, opened.
std::unique_ptr<lod::PointStore> buildPoints(const test::TempDir& dir, const fs::path& input,
                                             uint32_t leaf_max) {
  lod::BuildOptions o;
  o.quiet = true;
  o.leaf_max = leaf_max;
  const fs::path out = dir / (input.stem().string() + ".tlod");
  lod::buildStore({input}, out, o);
  return lod::PointStore::open(out);
}

void expectSame(const LassoResult& lasso, const Brute& brute) {
  EXPECT_EQ(lasso.selection.count(), brute.selection.count());
  EXPECT_TRUE(lasso.selection == brute.selection) << "the sets differ";
  // The selection must differ from brute force by no element, even where forms coincide.
  EXPECT_EQ(lasso.selection.subtract(brute.selection).count(), 0u);
  EXPECT_EQ(brute.selection.subtract(lasso.selection).count(), 0u);
}

// --- Points -------------------------------------------------------------------------------------

class LassoCubeTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    path_ = test::randomCubeStore(dir_->path(), 300000, 2048);
  }
  static void TearDownTestSuite() { delete dir_; }
  static test::TempDir* dir_;
  static fs::path path_;
};
test::TempDir* LassoCubeTest::dir_ = nullptr;
fs::path LassoCubeTest::path_;

TEST_F(LassoCubeTest, ConcaveLassoEqualsBruteForceAndPrunes) {
  auto store = lod::PointStore::open(path_);
  const dvec3 c = centreOf(store->summary());
  const LassoView view = lookAt(c + dvec3(1.4, -2.0, 1.1), c);
  const auto poly = wavy({400, 300}, 170);
  const LassoResult r = lassoPoints(*store, view, LassoPolygon(poly));
  const Brute b = brutePoints(*store, view, poly);
  EXPECT_EQ(b.elements, store->summary().points);  // brute force saw every input point
  expectSame(r, b);
  EXPECT_GT(r.selection.count(), 10000u);
  EXPECT_LT(r.selection.count(), store->summary().points);
  // The hierarchy did its work: whole nodes were taken unread, some pruned, fewer points read.
  EXPECT_GT(r.stats.nodes_whole, 0u);
  EXPECT_GT(r.stats.nodes_pruned, 0u);
  EXPECT_LT(r.stats.elements_tested, store->summary().points);
  EXPECT_EQ(r.stats.corrupt_chunks, 0u);
}

TEST_F(LassoCubeTest, LassoPastTheScreenEdgeEqualsBruteForce) {
  auto store = lod::PointStore::open(path_);
  const dvec3 c = centreOf(store->summary());
  const LassoView view = lookAt(c + dvec3(0.9, -1.2, 0.5), c);  // the cube fills the view
  const auto poly = pastTheEdge();
  const LassoResult r = lassoPoints(*store, view, LassoPolygon(poly));
  expectSame(r, brutePoints(*store, view, poly));
  EXPECT_GT(r.selection.count(), 0u);
}

TEST_F(LassoCubeTest, SelfIntersectingLassoUsesEvenOdd) {
  auto store = lod::PointStore::open(path_);
  const dvec3 c = centreOf(store->summary());
  const LassoView view = lookAt(c + dvec3(0.0, -2.2, 0.3), c);
  const auto poly = pentagram({400, 300}, 250);
  const LassoPolygon lasso(poly);
  EXPECT_FALSE(lasso.contains({400, 300}));  // the doubly wound centre
  EXPECT_TRUE(lasso.contains({400, 80}));    // a tip
  const LassoResult r = lassoPoints(*store, view, lasso);
  expectSame(r, brutePoints(*store, view, poly));
  // A figure eight too: two lobes crossing at the middle.
  const std::vector<dvec2> eight = {{150, 150}, {650, 450}, {650, 150}, {150, 450}};
  expectSame(lassoPoints(*store, view, LassoPolygon(eight)), brutePoints(*store, view, eight));
}

TEST_F(LassoCubeTest, EyeInsideTheModelSelectsNothingBehindIt) {
  auto store = lod::PointStore::open(path_);
  const dvec3 c = centreOf(store->summary());
  // The eye at the cube's centre looking along +x: half the points are behind it, and boxes
  // cross the eye plane.
  const LassoView view = lookAt(c, c + dvec3(1, 0, 0), 90.0);
  const std::vector<dvec2> poly = {{-10, -10}, {810, -10}, {810, 610}, {-10, 610}};
  const LassoResult r = lassoPoints(*store, view, LassoPolygon(poly));
  const Brute b = brutePoints(*store, view, poly);
  expectSame(r, b);
  // Nothing behind the eye: every selected point has x > the eye's x.
  const lod::StoreSummary& s = store->summary();
  for (const auto& [id, sel] : r.selection.nodes()) {
    const auto chunk = store->decodeChunk(id);
    for (const ElementRange& e : sel.ranges())
      for (uint32_t i = e.begin; i < e.end; ++i)
        ASSERT_GT(s.origin.x + chunk->offset.x + chunk->positions[i].x, c.x);
  }
  EXPECT_GT(r.selection.count(), 0u);
  EXPECT_LT(r.selection.count(), s.points / 2 + s.points / 50);
  // Very wide views from inside: boxes across the eye plane whose corners, some behind the eye,
  // still project onto the screen (mirrored) must not be taken whole.
  const std::vector<dvec2> inner = {{5, 5}, {795, 5}, {795, 595}, {5, 595}};
  for (const dvec3& at : {dvec3(0.03, 0.01, 0.02), dvec3(-0.21, 0.17, 0.05), dvec3(0.3, -0.3, 0.3)})
    for (double fov : {120.0, 150.0}) {
      const LassoView wide = lookAt(c + at, c + at + dvec3(0.3, 1, 0.2), fov);
      expectSame(lassoPoints(*store, wide, LassoPolygon(inner)), brutePoints(*store, wide, inner));
    }
  // And a wavy lasso from just inside the cube's corner.
  const LassoView corner = lookAt(c + dvec3(-0.45, -0.45, -0.45), c, 70.0);
  const auto w = wavy({400, 300}, 250);
  expectSame(lassoPoints(*store, corner, LassoPolygon(w)), brutePoints(*store, corner, w));
}

TEST_F(LassoCubeTest, OrthographicOffAxisAndModelMatricesEqualBruteForce) {
  auto store = lod::PointStore::open(path_);
  const dvec3 c = centreOf(store->summary());
  const auto poly = wavy({380, 320}, 200);
  LassoView view = lookAt(c + dvec3(1.0, -1.5, 0.8), c);
  // Orthographic (clip.w = 1 everywhere: nothing is behind the eye).
  view.projection = glm::ortho(-0.8, 0.8, -0.6, 0.6, 0.01, 10.0);
  LassoResult r = lassoPoints(*store, view, LassoPolygon(poly));
  expectSame(r, brutePoints(*store, view, poly));
  EXPECT_GT(r.stats.nodes_whole, 0u);
  // Off-axis, as a wall tile's frustum: the view's right third.
  view.projection = glm::frustum(0.02, 0.09, -0.03, 0.03, 0.1, 10.0);
  r = lassoPoints(*store, view, LassoPolygon(poly));
  expectSame(r, brutePoints(*store, view, poly));
  EXPECT_GT(r.selection.count(), 0u);
  // A model instance turned and scaled (LassoOptions::model, local -> world): the same as
  // brute force through the same matrix.
  LassoOptions o;
  o.model = glm::rotate(glm::scale(glm::translate(glm::dmat4(1.0), c), dvec3(1.5)), 0.7,
                        glm::normalize(dvec3(1, 2, 3))) *
            glm::translate(glm::dmat4(1.0),
                           -0.5 * (store->summary().bbox_min + store->summary().bbox_max));
  view = lookAt(c + dvec3(1.6, -2.2, 1.3), c);
  r = lassoPoints(*store, view, LassoPolygon(poly), o);
  const Brute b = brutePoints(*store, view, poly, nullptr, *o.model);
  expectSame(r, b);
  EXPECT_GT(r.selection.count(), 0u);
}

TEST_F(LassoCubeTest, CorruptChunksAreCountedAndSkipped) {
  const fs::path copy = dir_->path() / "corrupt.tlod";
  auto bytes = test::readBytes(path_);
  lod::store::FileHeader h;
  std::memcpy(&h, bytes.data(), sizeof h);
  // A flipped byte every 20 KB of payload: most chunks fail their CRC.
  for (uint64_t at = h.payload_offset + 100; at < h.payload_offset + h.payload_size; at += 20000)
    bytes[at] ^= 0x5A;
  test::writeBytes(copy, bytes);
  auto store = lod::PointStore::open(copy);
  const dvec3 c = centreOf(store->summary());
  const LassoView view = lookAt(c + dvec3(1.4, -2.0, 1.1), c);
  const auto poly = wavy({400, 300}, 170);
  LassoResult r;
  ASSERT_NO_THROW(r = lassoPoints(*store, view, LassoPolygon(poly)));
  const Brute b = brutePoints(*store, view, poly);
  EXPECT_GT(r.stats.corrupt_chunks, 0u);
  EXPECT_EQ(r.stats.corrupt_nodes.size(), r.stats.corrupt_chunks);
  EXPECT_GT(b.corrupt, 0u);
  // The leaves read whole agree with brute force; corrupt ones contribute nothing.
  for (lod::NodeId id : r.stats.corrupt_nodes) EXPECT_EQ(r.selection.node(id), nullptr);
  for (const auto& [id, sel] : b.selection.nodes()) {
    const NodeSelection* mine = r.selection.node(id);
    ASSERT_NE(mine, nullptr) << "node " << id;
    EXPECT_TRUE(*mine == sel) << "node " << id;
  }
}

TEST(LassoCorrupt, CorruptHierarchyPageIsCountedEveryTime) {
  test::TempDir dir;  // a surface in small leaves: a hierarchy deeper than one page
  lod::BuildOptions o;
  o.quiet = true;
  o.leaf_max = 400;
  o.chunk_points = 20000;
  lod::buildStore({kData / "stanford-bunny/scans/bun.conf"}, dir / "bunny.tlod", o);
  auto bytes = test::readBytes(dir / "bunny.tlod");
  lod::store::FileHeader h;
  std::memcpy(&h, bytes.data(), sizeof h);
  lod::store::PageHeader root;
  std::memcpy(&root, bytes.data() + h.root_page_offset, sizeof root);
  uint64_t page = 0;  // the first child page the root page points to
  for (uint32_t i = 0; i < root.nodes && page == 0; ++i) {
    lod::store::NodeRecord r;
    std::memcpy(&r, bytes.data() + h.root_page_offset + sizeof root + i * sizeof r, sizeof r);
    if (r.flags & lod::store::kHasPage) page = r.page_offset;
  }
  ASSERT_NE(page, 0u) << "the store has no child pages";
  bytes[page + sizeof(lod::store::PageHeader) + 5] ^= 0x5A;
  const fs::path copy = dir / "bad-page.tlod";
  test::writeBytes(copy, bytes);
  auto store = lod::PointStore::open(copy);
  const dvec3 c = centreOf(store->summary());
  const LassoView view = lookAt(c + dvec3(0.05, 0.08, 0.25), c);
  const std::vector<dvec2> all = {{0, 0}, {800, 0}, {800, 600}, {0, 600}};
  for (int call = 0; call < 2; ++call) {  // the store refuses the page once; both calls say so
    const LassoResult r = lassoPoints(*store, view, LassoPolygon(all));
    EXPECT_EQ(r.stats.corrupt_pages, 1u) << "call " << call;
    EXPECT_GT(r.selection.count(), 0u);
    const Brute b = brutePoints(*store, view, all);
    EXPECT_LT(b.elements, store->summary().points);  // the subtree below the page is gone
    expectSame(r, b);
  }
}

// --- Visible only -----------------------------------------------------------------------------

/// Two parallel planes facing the camera, grids of points: the back one (z = 0, 2 x 2) and a
/// smaller front one (z = 0.5, 0.8 x 0.8) that hides part of it.
class LassoPlanesTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    lod::PointBatch b;
    b.reset(0);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int i = 0; i < 200000; ++i) b.positions.push_back({2 * u(rng) - 1, 2 * u(rng) - 1, 0.0});
    for (int i = 0; i < 60000; ++i)
      b.positions.push_back({0.8 * u(rng) - 0.5, 0.8 * u(rng) - 0.3, 0.5});
    lod::writePly(dir_->path() / "planes.ply", b, dvec3(0.0));
    buildPoints(*dir_, dir_->path() / "planes.ply", 2048);
  }
  static void TearDownTestSuite() { delete dir_; }
  static test::TempDir* dir_;
};
test::TempDir* LassoPlanesTest::dir_ = nullptr;

TEST_F(LassoPlanesTest, VisibleModeEqualsBruteForceAndHidesTheBackPlane) {
  auto store = lod::PointStore::open(dir_->path() / "planes.tlod");
  const dvec3 origin = store->summary().origin;
  LassoView view;
  const dvec3 eye(0.1, 0.05, 3.0);
  view.view = glm::lookAt(eye, dvec3(0.1, 0.05, 0.0), dvec3(0, 1, 0));
  view.projection = glm::perspective(glm::radians(45.0), 800.0 / 600.0, 0.5, 10.0);
  view.viewport = kViewport;
  // The depth image the renderer would give: per pixel centre, the nearest plane hit (the
  // front square where the ray meets it, else the back square), window depth, raster order.
  std::vector<float> depth(size_t(kViewport.x) * kViewport.y, std::nanf(""));
  const glm::dmat4 inv = glm::inverse(view.projection * view.view);
  for (uint32_t row = 0; row < kViewport.y; ++row)
    for (uint32_t x = 0; x < kViewport.x; ++x) {
      const double ndc_x = 2.0 * (x + 0.5) / kViewport.x - 1.0;
      const double ndc_y = 2.0 * (row + 0.5) / kViewport.y - 1.0;  // raster: row 0 at the bottom
      glm::dvec4 far = inv * glm::dvec4(ndc_x, ndc_y, 1.0, 1.0);
      const dvec3 dir = glm::normalize(dvec3(far) / far.w - eye);
      for (const auto& [z, lo, hi] : {std::tuple{0.5, dvec2(-0.5, -0.3), dvec2(0.3, 0.5)},
                                      std::tuple{0.0, dvec2(-1, -1), dvec2(1, 1)}}) {
        const dvec3 hit = eye + dir * ((z - eye.z) / dir.z);
        if (hit.x < lo.x || hit.y < lo.y || hit.x > hi.x || hit.y > hi.y) continue;
        const glm::dvec4 clip = view.projection * view.view * glm::dvec4(hit, 1.0);
        depth[size_t(row) * kViewport.x + x] = float((clip.z / clip.w + 1.0) * 0.5);
        break;
      }
    }
  LassoOptions o;
  o.mode = LassoMode::kVisible;
  o.depth = DepthImage{kViewport.x, kViewport.y, depth};
  o.visibility.relative_tolerance = 0.02;
  const auto poly = wavy({400, 300}, 230);
  const LassoResult r = lassoPoints(*store, view, LassoPolygon(poly), o);
  const VisibilityMap vis(*o.depth, view, o.visibility);
  expectSame(r, brutePoints(*store, view, poly, &vis));
  EXPECT_GT(r.stats.nodes_whole, 0u);
  EXPECT_GT(r.stats.nodes_pruned, 0u);
  // What it means: front points inside the lasso are selected; back points right behind the
  // front square's middle are not, back points clear of it are (when inside the lasso).
  const LassoResult through = lassoPoints(*store, view, LassoPolygon(poly));
  uint64_t front = 0, back_hidden = 0, back_clear = 0, back_clear_through = 0;
  for (const auto& [id, sel] : through.selection.nodes()) {
    const auto chunk = store->decodeChunk(id);
    for (const ElementRange& e : sel.ranges())
      for (uint32_t i = e.begin; i < e.end; ++i) {
        const dvec3 p = origin + chunk->offset + dvec3(chunk->positions[i]);
        const bool picked = r.selection.contains(id, i);
        if (p.z > 0.25) {
          front += picked ? 0 : 1;  // counts misses
        } else if (p.x > -0.35 && p.x < 0.15 && p.y > -0.15 && p.y < 0.35) {
          back_hidden += picked;
        } else if (p.x < -0.9 || p.x > 0.9) {
          back_clear_through += 1;
          back_clear += picked;
        }
      }
  }
  EXPECT_EQ(front, 0u) << "front points inside the lasso missed";
  EXPECT_EQ(back_hidden, 0u) << "hidden back points selected";
  EXPECT_GT(back_clear_through, 0u);
  EXPECT_EQ(back_clear, back_clear_through);
  EXPECT_LT(r.selection.count(), through.selection.count());
}

TEST(LassoVisibility, DepthImageOfTheWrongSizeIsRefused) {
  LassoView view;
  view.viewport = kViewport;
  std::vector<float> depth(10, 0.5f);
  EXPECT_THROW(VisibilityMap(DepthImage{10, 1, depth}, view, {}), PreconditionError);
  EXPECT_THROW(VisibilityMap(DepthImage{800, 600, depth}, view, {}), PreconditionError);
  EXPECT_THROW(LassoPolygon({{0, 0}, {1, 1}}), PreconditionError);
  EXPECT_THROW(LassoPolygon({{0, 0}, {1, 1}, {NAN, 0}}), PreconditionError);
}

// --- Real data ----------------------------------------------------------------------------------

TEST(LassoRealData, GeoreferencedLidarEqualsBruteForce) {
  test::TempDir dir;
  auto store = buildPoints(dir, kData / "lidar/autzen_trim.las", 4096);
  const lod::StoreSummary& s = store->summary();
  ASSERT_GT(std::abs(s.origin.x) + std::abs(s.origin.y), 1e5);  // georeferenced: far from 0
  const dvec3 c = centreOf(s);
  const dvec3 size = s.bbox_max - s.bbox_min;
  // An oblique view over the terrain, in world coordinates (feet, state plane).
  const LassoView view = lookAt(c + dvec3(-0.6 * size.x, -0.9 * size.y, 0.5 * size.x), c);
  for (const auto& poly : {wavy({400, 300}, 200), pentagram({380, 320}, 260), pastTheEdge()}) {
    const LassoResult r = lassoPoints(*store, view, LassoPolygon(poly));
    const Brute b = brutePoints(*store, view, poly);
    EXPECT_EQ(b.elements, s.points);
    expectSame(r, b);
    EXPECT_GT(r.selection.count(), 0u);
  }
}

TEST(LassoRealData, BunnyScansEqualBruteForce) {
  test::TempDir dir;
  auto store = buildPoints(dir, kData / "stanford-bunny/scans/bun.conf", 2048);
  const dvec3 c = centreOf(store->summary());
  const LassoView view = lookAt(c + dvec3(0.05, 0.08, 0.25), c);
  const auto poly = wavy({420, 260}, 160);
  const LassoResult r = lassoPoints(*store, view, LassoPolygon(poly));
  expectSame(r, brutePoints(*store, view, poly));
  EXPECT_GT(r.stats.nodes_whole, 0u);
}

TEST(LassoMesh, BunnyTrianglesEqualBruteForce) {
  test::TempDir dir;
  lod::MeshBuildOptions o;
  o.patch_triangles = 1024;
  o.quiet = true;
  lod::buildMeshStore(std::vector<fs::path>{kData / "stanford-bunny/reconstruction/bun_zipper.ply"},
                      dir / "bunny.tmesh", o);
  auto store = lod::MeshStore::open(dir / "bunny.tmesh");
  const lod::MeshSummary& s = store->summary();
  const dvec3 c = s.origin + 0.5 * (s.bbox_min + s.bbox_max);
  for (const LassoView& view : {lookAt(c + dvec3(0.05, 0.08, 0.25), c),
                                lookAt(c + dvec3(0.0, 0.0, 0.01), c + dvec3(0, 0, 1), 80.0)}) {
    for (const auto& poly : {wavy({420, 260}, 160), pentagram({400, 300}, 280)}) {
      const LassoResult r = lassoTriangles(*store, view, LassoPolygon(poly));
      const Brute b = bruteTriangles(*store, view, poly);
      EXPECT_EQ(b.elements, s.input_triangles);
      EXPECT_EQ(r.selection.elements(), SelectionElements::kTriangles);
      expectSame(r, b);
    }
  }
  const LassoResult r = lassoTriangles(*store, lookAt(c + dvec3(0.05, 0.08, 0.25), c),
                                       LassoPolygon(wavy({420, 260}, 160)));
  EXPECT_GT(r.selection.count(), 1000u);
  EXPECT_GT(r.stats.nodes_pruned, 0u);

  // Visible only, behind a wall: the left half of the image holds a surface at the depth of the
  // bunny's centre (what is behind it is hidden), the right half nothing (all visible), with a
  // ragged edge of empty pixels that the gap radius fills.
  const LassoView view = lookAt(c + dvec3(0.05, 0.08, 0.25), c);
  const glm::dvec4 mid = view.projection * view.view * glm::dvec4(c, 1.0);
  const float wall = float((mid.z / mid.w + 1.0) * 0.5);
  std::vector<float> depth(size_t(kViewport.x) * kViewport.y, std::nanf(""));
  for (uint32_t row = 0; row < kViewport.y; ++row)
    for (uint32_t x = 0; x < 400 + row % 3; ++x)
      if ((x + row) % 7 != 0) depth[size_t(row) * kViewport.x + x] = wall;
  LassoOptions visible;
  visible.mode = LassoMode::kVisible;
  visible.depth = DepthImage{kViewport.x, kViewport.y, depth};
  visible.visibility.gap_radius_px = 2;
  const VisibilityMap vis(*visible.depth, view, visible.visibility);
  for (const auto& poly : {wavy({420, 260}, 160), pentagram({400, 300}, 280)}) {
    const LassoResult v = lassoTriangles(*store, view, LassoPolygon(poly), visible);
    expectSame(v, bruteTriangles(*store, view, poly, &vis));
    const LassoResult through = lassoTriangles(*store, view, LassoPolygon(poly));
    EXPECT_GT(v.selection.count(), 0u);
    EXPECT_LT(v.selection.count(), through.selection.count());
  }
}

// --- Large -------------------------------------------------------------------------------------

/// The 10^7-point store (TESSERA_LASSO_TEST_POINTS overrides the size): a random cube
/// built here, against brute force over all 10^7 points. The whole test took 32 s on this
/// 2-core machine shared with other builds (store build included; 0.5 GB resident).
TEST(LassoLarge, TenMillionPointsEqualBruteForce) {
  const char* env = std::getenv("TESSERA_LASSO_TEST_POINTS");
  const size_t n = env ? size_t(std::strtoull(env, nullptr, 10)) : 10000000;
  test::TempDir dir;
  const fs::path path = test::randomCubeStore(dir.path(), n);
  auto store = lod::PointStore::open(path, 256ull << 20);
  ASSERT_EQ(store->summary().points, n);
  const dvec3 c = centreOf(store->summary());
  const LassoView view = lookAt(c + dvec3(1.3, -1.9, 1.2), c);
  const auto poly = wavy({400, 300}, 190, 400);
  const LassoResult r = lassoPoints(*store, view, LassoPolygon(poly));
  const Brute b = brutePoints(*store, view, poly);
  EXPECT_EQ(b.elements, n);
  expectSame(r, b);
  EXPECT_GT(r.stats.nodes_whole, 0u);
}

// --- The selection type -----------------------------------------------------------------------

NodeSelection fromIndices(uint32_t size, std::initializer_list<uint32_t> set) {
  std::vector<uint64_t> bits((size + 63) / 64, 0);
  for (uint32_t i : set) bits[i / 64] |= 1ull << (i % 64);
  return NodeSelection::fromBits(size, bits);
}

TEST(Selection, PicksTheSmallestForm) {
  EXPECT_EQ(NodeSelection::all(100).form(), NodeSelection::Form::kAll);
  EXPECT_EQ(fromIndices(100, {0, 1, 2, 3}).form(), NodeSelection::Form::kRanges);
  std::vector<uint64_t> alternate(16, 0x5555555555555555ull);  // 512 runs: bits are smaller
  const NodeSelection alt = NodeSelection::fromBits(1024, alternate);
  EXPECT_EQ(alt.form(), NodeSelection::Form::kBits);
  EXPECT_EQ(alt.count(), 512u);
  EXPECT_TRUE(alt.contains(0));
  EXPECT_FALSE(alt.contains(1));
  EXPECT_FALSE(alt.contains(5000));
  const NodeSelection r = fromIndices(200, {5, 6, 7, 63, 64, 65, 199});
  EXPECT_EQ(r.ranges(), (std::vector<ElementRange>{{5, 8}, {63, 66}, {199, 200}}));
  EXPECT_EQ(r.count(), 7u);
  EXPECT_TRUE(r.contains(64) && r.contains(199) && !r.contains(8) && !r.contains(62));
  std::vector<uint64_t> full(2, ~0ull);
  full[1] = (1ull << 36) - 1;  // 100 bits
  EXPECT_EQ(NodeSelection::fromBits(100, full).form(), NodeSelection::Form::kAll);
  EXPECT_TRUE(NodeSelection::fromBits(100, {0, 0}).empty());
  EXPECT_THROW(NodeSelection::fromBits(100, {0, 1ull << 40}), PreconditionError);
}

TEST(Selection, SetAlgebraMatchesElementwiseLogic) {
  std::mt19937 rng(3);
  const uint32_t sizes[] = {1, 63, 64, 65, 1000, 5000};
  Selection a, b;
  for (uint32_t node = 0; node < 6; ++node) {
    const uint32_t n = sizes[node];
    auto random = [&](int mode) {
      std::vector<uint64_t> bits((n + 63) / 64, 0);
      for (uint32_t i = 0; i < n; ++i) {
        bool on = mode == 0 ? rng() % 2 : mode == 1 ? (i / 97) % 2 : true;
        if (on) bits[i / 64] |= 1ull << (i % 64);
      }
      return NodeSelection::fromBits(n, bits);
    };
    a.set(node, random(int(node % 3)));
    b.set(node, random(int((node + 1) % 3)));
  }
  b.set(17, NodeSelection::all(10));  // only in b
  const Selection u = a.unite(b), x = a.intersect(b), d = a.subtract(b);
  uint64_t nu = 0, nx = 0, nd = 0;
  for (lod::NodeId node : {0u, 1u, 2u, 3u, 4u, 5u, 17u}) {
    const uint32_t n = node == 17 ? 10 : sizes[node];
    for (uint32_t i = 0; i < n; ++i) {
      const bool in_a = a.contains(node, i), in_b = b.contains(node, i);
      ASSERT_EQ(u.contains(node, i), in_a || in_b);
      ASSERT_EQ(x.contains(node, i), in_a && in_b);
      ASSERT_EQ(d.contains(node, i), in_a && !in_b);
      nu += in_a || in_b;
      nx += in_a && in_b;
      nd += in_a && !in_b;
    }
  }
  EXPECT_EQ(u.count(), nu);
  EXPECT_EQ(x.count(), nx);
  EXPECT_EQ(d.count(), nd);
  EXPECT_TRUE(a.subtract(a).empty());
  EXPECT_TRUE(a.unite(a) == a);
  EXPECT_TRUE(u.subtract(b) == d);
  Selection wrong;
  wrong.set(4, NodeSelection::all(7));  // node 4 has 1000 elements in a
  EXPECT_THROW(a.unite(wrong), PreconditionError);
  EXPECT_THROW(a.unite(Selection(SelectionElements::kTriangles)), PreconditionError);
}

TEST(Selection, SerialisationRoundTripsAndRefusesCorruptBytes) {
  Selection s(SelectionElements::kTriangles);
  s.set(3, NodeSelection::all(100));
  s.set(9, fromIndices(300, {1, 2, 3, 250}));
  s.set(12, NodeSelection::fromBits(1024, std::vector<uint64_t>(16, 0x3333333333333333ull)));
  const std::vector<uint8_t> bytes = s.serialize();
  const Selection back = Selection::deserialize(bytes);
  EXPECT_TRUE(back == s);
  EXPECT_EQ(back.elements(), SelectionElements::kTriangles);
  EXPECT_EQ(back.serialize(), bytes);
  EXPECT_TRUE(Selection::deserialize(Selection().serialize()).empty());
  // Every truncation and every flipped byte is refused with a SelectionError.
  for (size_t n = 0; n < bytes.size(); ++n)
    EXPECT_THROW(Selection::deserialize(std::span(bytes).first(n)), SelectionError) << n;
  for (size_t i = 0; i < bytes.size(); ++i) {
    std::vector<uint8_t> bad = bytes;
    bad[i] ^= 0x10;
    EXPECT_THROW(Selection::deserialize(bad), SelectionError) << i;
  }
  // Structure checked behind a valid checksum: unsorted ranges, a bit past the size.
  auto withChecksum = [](std::vector<uint8_t> b) {
    fuzz::fixSelectionChecksum(b.data(), b.size());
    return b;
  };
  Selection r;
  r.set(1, fromIndices(300, {10, 11, 200}));
  std::vector<uint8_t> rb = r.serialize();
  // Header 12, node header 9, count 4, then ranges: swap the two ranges.
  std::swap_ranges(rb.begin() + 25, rb.begin() + 33, rb.begin() + 33);
  try {
    Selection::deserialize(withChecksum(rb));
    ADD_FAILURE() << "unsorted ranges accepted";
  } catch (const SelectionError& e) {
    EXPECT_NE(std::string(e.what()).find("not sorted"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("Selection::deserialize(): ", 0), 0u);
  }
  // Random bytes with a valid checksum never crash (the fuzz target's check).
  std::mt19937 rng(11);
  for (int t = 0; t < 20000; ++t) {
    std::vector<uint8_t> junk(rng() % 64);
    for (uint8_t& v : junk) v = uint8_t(rng() % 4 == 0 ? rng() : rng() % 3);
    if (junk.size() >= 5) std::copy_n("TSEL\x01", 5, junk.begin());
    fuzz::readSelection(junk.data(), junk.size());
  }
}

TEST(Selection, FuzzRegressionsAreHandled) {
  const fs::path folder = fs::path(TESSERA_FUZZ_REGRESSIONS) / "selection";
  size_t replayed = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const auto bytes = test::readBytes(entry.path());
    SCOPED_TRACE(entry.path().string());
    fuzz::readSelection(bytes.data(), bytes.size());
    ++replayed;
  }
  EXPECT_GT(replayed, 0u);
}

}  // namespace
}  // namespace tessera::annotate
