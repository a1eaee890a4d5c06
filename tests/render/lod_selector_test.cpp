// View-dependent LOD selection on the real bunny scans: far views take few points, near views
// more; the cut covers every visible leaf exactly once and respects the pixel threshold. The
// point budget bounds the cut; the coverage stop thins a volume of points, not a surface; both
// give the same cut whatever the order pages arrive in.
#include <gtest/gtest.h>

#include <set>

#include <glm/gtc/constants.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/store_builder.h>
#include <tessera/render/lod_selector.h>

#include "../support/random_cube.h"
#include "../support/temp_dir.h"

namespace tessera::render {
namespace {

const std::string kData = TESSERA_DATA_DIR;

class LodSelector : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new test::TempDir();
    lod::BuildOptions o;
    o.quiet = true;
    o.leaf_max = 1000;  // a deeper hierarchy than the default, so refinement has room
    lod::buildStore({kData + "/stanford-bunny/scans/bun.conf"}, *sDir / "b.tlod", o);
  }
  static void TearDownTestSuite() { delete sDir; }
  static test::TempDir* sDir;

  /// A 1280x720, 45 degree view from `distance` metres in front of the bunny.
  static ViewSetup view(lod::PointStore& s, double distance) {
    const lod::StoreSummary& sum = s.summary();
    glm::dvec3 c = 0.5 * (sum.bbox_min + sum.bbox_max);
    config::WallConfig wall;
    auto* t = wall.add_tiles();
    t->set_width(0.64);
    t->set_height(0.36);
    t->set_pixel_width(1280);
    t->set_pixel_height(720);
    wall.mutable_eye()->set_x(0.32);
    wall.mutable_eye()->set_y(0.18);
    wall.mutable_eye()->set_z(0.18 / std::tan(glm::radians(22.5)));
    wall.set_near(0.001);
    wall.set_far(100);
    config::Camera cam;
    cam.mutable_eye()->set_x(c.x);
    cam.mutable_eye()->set_y(c.y);
    cam.mutable_eye()->set_z(c.z + distance);
    cam.mutable_target()->set_x(c.x);
    cam.mutable_target()->set_y(c.y);
    cam.mutable_target()->set_z(c.z);
    cam.mutable_up()->set_y(1);
    return tileView(wall, wall.tiles(0), cam);
  }
};
test::TempDir* LodSelector::sDir = nullptr;

TEST_F(LodSelector, FarViewsTakeFewPointsNearViewsMore) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  const glm::dmat4 model(1.0);
  Cut far = selectCut(*s, model, view(*s, 5.0));
  Cut mid = selectCut(*s, model, view(*s, 1.5));
  Cut near = selectCut(*s, model, view(*s, 0.5));
  EXPECT_LT(far.points, 20000u);
  EXPECT_LT(far.points, mid.points);
  EXPECT_LT(mid.points, near.points);
  // Close up, part of the model leaves the view: fewer points than the whole at full density,
  // but from deeper nodes.
  Cut close = selectCut(*s, model, view(*s, 0.1));
  EXPECT_LT(close.points, 362272u);
  auto deepest = [&](const Cut& c) {
    int d = 0;
    for (const CutNode& n : c.nodes) d = std::max(d, int(s->node(n.id).level));
    return d;
  };
  EXPECT_GT(deepest(close), deepest(far));
  // A coarser threshold never takes more points.
  CutOptions coarse;
  coarse.pixel_threshold = 4.0;
  EXPECT_LE(selectCut(*s, model, view(*s, 0.5), coarse).points, mid.points);
  // Looking away from the model: everything culled.
  ViewSetup away = view(*s, 0.5);
  away.view = glm::rotate(glm::dmat4(1.0), glm::pi<double>(), glm::dvec3(0, 1, 0)) * away.view;
  EXPECT_EQ(selectCut(*s, model, away).nodes.size(), 0u);
}

/// Every leaf in the view's frustum has exactly one cut node on its path from the root (at most
/// one where the coverage stop hid nodes).
void expectCoversEveryVisibleLeafOnce(lod::PointStore& s, const ViewSetup& v, const Cut& cut,
                                      size_t min_leaves = 5) {
  std::set<lod::NodeId> selected;
  for (const CutNode& n : cut.nodes) selected.insert(n.id);
  const Frustum f = Frustum::fromMatrix(v.projection * v.view);
  size_t leaves = 0;
  std::vector<std::pair<lod::NodeId, int>> stack{{s.root(), 0}};
  while (!stack.empty()) {
    auto [id, above] = stack.back();
    stack.pop_back();
    lod::NodeInfo n = s.node(id);
    int here = above + (selected.count(id) ? 1 : 0);
    if (n.leaf()) {
      if (f.intersects(n.box_min, n.box_max)) {
        if (cut.hidden > 0) {
          EXPECT_LE(here, 1) << "leaf " << id;
        } else {
          EXPECT_EQ(here, 1) << "leaf " << id;
        }
        leaves += here;
      }
      continue;
    }
    for (lod::NodeId c : s.children(id)) stack.push_back({c, here});
  }
  EXPECT_GT(leaves, min_leaves);
}

TEST_F(LodSelector, CutCoversEveryVisibleLeafOnceWithinTheThreshold) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ViewSetup v = view(*s, 0.3);
  Cut cut = selectCut(*s, glm::dmat4(1.0), v);
  for (const CutNode& n : cut.nodes) {
    if (!s->node(n.id).leaf()) {
      EXPECT_LE(n.projected_spacing_px, 1.0);
    }
  }
  // Walk the whole hierarchy: each visible leaf has exactly one selected node on its path.
  expectCoversEveryVisibleLeafOnce(*s, v, cut);
  // Nearest first.
  for (size_t i = 1; i < cut.nodes.size(); ++i)
    EXPECT_LE(cut.nodes[i - 1].distance, cut.nodes[i].distance);
}

/// A `width` x `height` view with a 45 degree vertical field of view from `eye` to `target`.
ViewSetup lookAt(glm::dvec3 eye, glm::dvec3 target, uint32_t width, uint32_t height) {
  ViewSetup v;
  v.view = glm::lookAt(eye, target, glm::dvec3(0, 0, 1));
  v.projection = glm::perspective(glm::radians(45.0), double(width) / height, 0.01, 100.0);
  v.width = width;
  v.height = height;
  v.eye_world = eye;
  return v;
}

TEST_F(LodSelector, PointBudgetBoundsTheCutRefiningTheLargestErrorsFirst) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  const ViewSetup v = view(*s, 0.3);
  const Cut free = selectCut(*s, glm::dmat4(1.0), v);
  ASSERT_GT(free.points, 100000u);
  const uint64_t root = s->node(s->root()).points;
  uint64_t previous = 0;
  for (uint64_t budget : {root + 1, free.points / 20, free.points / 5, free.points / 2}) {
    CutOptions o;
    o.point_budget = budget;
    const Cut cut = selectCut(*s, glm::dmat4(1.0), v, o);
    uint64_t sum = 0;
    for (const CutNode& n : cut.nodes) sum += s->node(n.id).points;
    EXPECT_EQ(sum, cut.points);
    EXPECT_LE(cut.points, budget);
    EXPECT_GE(cut.points, previous) << "a larger budget never draws fewer points";
    EXPECT_GT(cut.over_budget, 0u);
    previous = cut.points;
    // Still a complete cut, only coarser; what was left refinable has no larger error than
    // what was refined (the order of refinement is the order of projected spacing).
    expectCoversEveryVisibleLeafOnce(*s, v, cut);
    double refined_min = 1e300;
    for (const CutNode& n : cut.above) refined_min = std::min(refined_min, n.projected_spacing_px);
    for (const CutNode& n : cut.nodes) {
      if (!s->node(n.id).leaf() && n.projected_spacing_px > 1.0) {
        EXPECT_LE(n.projected_spacing_px, refined_min + 1e-9);
      }
    }
    std::printf("budget %llu: %llu points in %zu nodes\n", (unsigned long long)budget,
                (unsigned long long)cut.points, cut.nodes.size());
  }
  // A budget the free cut fits in changes nothing; one below the root keeps the root.
  CutOptions o;
  o.point_budget = free.points;
  const Cut same = selectCut(*s, glm::dmat4(1.0), v, o);
  EXPECT_EQ(same.points, free.points);
  EXPECT_EQ(same.nodes.size(), free.nodes.size());
  o.point_budget = 1;
  const Cut coarsest = selectCut(*s, glm::dmat4(1.0), v, o);
  ASSERT_EQ(coarsest.nodes.size(), 1u);
  EXPECT_EQ(coarsest.nodes[0].id, s->root());
}

class LodSelectorCube : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new test::TempDir();
    test::randomCubeStore(sDir->path(), 1'000'000, 100);  // deep: several pages
  }
  static void TearDownTestSuite() { delete sDir; }
  static test::TempDir* sDir;
};
test::TempDir* LodSelectorCube::sDir = nullptr;

TEST_F(LodSelectorCube, CoverageStopThinsAVolumeButStillCoversEveryLeaf) {
  auto s = lod::PointStore::open(*sDir / "cube.tlod");
  // About 130 px across: ~60 points per covered pixel, each leaf's spacing still above 1 px.
  const ViewSetup v = lookAt({4.5, -4.5, 3.8}, {0.5, 0.5, 0.5}, 640, 480);
  const Cut spacing_only = selectCut(*s, glm::dmat4(1.0), v);
  CutOptions o;
  o.coverage_stop = true;
  const Cut covered = selectCut(*s, glm::dmat4(1.0), v, o);
  std::printf(
      "cube, 640x480: %llu points by spacing, %llu with the coverage stop (%zu stops, %zu "
      "hidden)\n",
      (unsigned long long)spacing_only.points, (unsigned long long)covered.points, covered.covered,
      covered.hidden);
  EXPECT_GT(covered.covered, 0u);
  EXPECT_GT(covered.hidden, 0u);
  EXPECT_LT(double(covered.points), 0.4 * double(spacing_only.points));  // measured 0.34
  expectCoversEveryVisibleLeafOnce(*s, v, covered);
}

TEST_F(LodSelectorCube, CutIsTheSameWhateverOrderPagesArriveIn) {
  CutOptions o;
  o.coverage_stop = true;
  o.point_budget = 200000;
  const ViewSetup v = lookAt({1.9, -1.2, 1.4}, {0.5, 0.5, 0.5}, 800, 600);
  auto reference_store = lod::PointStore::open(*sDir / "cube.tlod");
  const Cut reference = selectCut(*reference_store, glm::dmat4(1.0), v, o);
  ASSERT_GT(reference.over_budget, 0u);
  ASSERT_GT(reference.covered, 0u);
  // A streaming renderer: pages arrive a few per frame, in an order of their own.
  for (uint32_t stride : {1u, 3u, 7u}) {
    auto s = lod::PointStore::open(*sDir / "cube.tlod");
    Cut cut;
    size_t frames = 0;
    for (bool deferred = true; deferred; ++frames) {
      std::vector<lod::NodeId> asked;
      CutOptions streaming = o;
      streaming.may_load_children = [&](lod::NodeId id) {
        asked.push_back(id);
        return false;
      };
      cut = selectCut(*s, glm::dmat4(1.0), v, streaming);
      deferred = cut.pages_deferred > 0;
      for (size_t i = 0; i < asked.size(); i += stride) s->children(asked[i]);
      ASSERT_LT(frames, 1000u);
    }
    EXPECT_GT(frames, 2u);
    ASSERT_EQ(cut.nodes.size(), reference.nodes.size()) << "stride " << stride;
    EXPECT_EQ(cut.points, reference.points);
    // Node ids are given out as pages load: compare the nodes by name (level and cell).
    for (size_t i = 0; i < cut.nodes.size(); ++i) {
      EXPECT_EQ(cut.nodes[i].level, reference.nodes[i].level) << "stride " << stride << ", " << i;
      EXPECT_EQ(cut.nodes[i].cell, reference.nodes[i].cell) << "stride " << stride << ", " << i;
    }
  }
}

}  // namespace
}  // namespace tessera::render

namespace tessera::render {
namespace {

/// A hierarchy that is not a point store (a stand-in for mesh patches): a quadtree over the
/// unit square at z = 0, depth 6, spacing halving per level, every page in memory.
class QuadHierarchy : public lod::LodHierarchy {
 public:
  QuadHierarchy() { add(0, {0, 0}, 1.0); }
  const std::filesystem::path& path() const override { return mPath; }
  lod::NodeId root() const override { return 0; }
  lod::NodeInfo node(lod::NodeId id) const override { return mNodes.at(id).info; }
  std::vector<lod::NodeId> children(lod::NodeId id) override { return mNodes.at(id).children; }
  bool childrenLoaded(lod::NodeId) const override { return true; }
  uint32_t chunkBytes(lod::NodeId) const override { return 1000; }

 private:
  struct Node {
    lod::NodeInfo info;
    std::vector<lod::NodeId> children;
  };
  lod::NodeId add(uint8_t level, glm::dvec2 lo, double size) {
    const auto id = lod::NodeId(mNodes.size());
    mNodes.emplace_back();
    lod::NodeInfo& n = mNodes.back().info;
    n.level = level;
    n.box_min = {lo, 0.0};
    n.box_max = {lo + size, 0.0};
    n.points = 64;
    n.spacing = float(size / 8.0);
    if (level < 6) {
      std::vector<lod::NodeId> kids;
      for (int k = 0; k < 4; ++k)
        kids.push_back(
            add(uint8_t(level + 1), lo + 0.5 * size * glm::dvec2(k & 1, k >> 1), 0.5 * size));
      mNodes[id].children = kids;
      mNodes[id].info.child_mask = 0xF;
    }
    return id;
  }
  std::vector<Node> mNodes;
  std::filesystem::path mPath = "quadtree";
};

TEST(LodHierarchy, TheCutSelectionWorksOnAnyHierarchy) {
  // The same selection code on a hierarchy that is not a point store: seen obliquely, the near
  // edge of the square refines deeper than the far one, and every cut node meets the threshold
  // or is a leaf.
  QuadHierarchy q;
  ViewSetup v;
  v.eye_world = {0.5, -0.6, 0.4};
  v.view = glm::lookAt(v.eye_world, glm::dvec3(0.5, 0.5, 0.0), glm::dvec3(0, 0, 1));
  v.projection = glm::perspective(glm::radians(50.0), 16.0 / 9.0, 0.01, 10.0);
  v.width = 1280;
  v.height = 720;
  CutOptions o;
  o.pixel_threshold = 16.0;
  const Cut cut = selectCut(q, glm::dmat4(1.0), v, o);
  ASSERT_FALSE(cut.nodes.empty());
  int near_level = 0, far_level = 99;
  for (const CutNode& n : cut.nodes) {
    const lod::NodeInfo info = q.node(n.id);
    EXPECT_TRUE(n.projected_spacing_px <= o.pixel_threshold || info.leaf()) << n.id;
    if (info.box_min.y == 0.0) near_level = std::max(near_level, int(info.level));
    if (info.box_max.y == 1.0) far_level = std::min(far_level, int(info.level));
  }
  EXPECT_GT(near_level, far_level);
  EXPECT_LT(near_level, 6) << "the threshold stops refinement before the leaves";
}

}  // namespace
}  // namespace tessera::render
