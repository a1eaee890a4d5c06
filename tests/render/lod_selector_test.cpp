// View-dependent LOD selection on the real bunny scans: far views take few points, near views
// more; the cut covers every visible leaf exactly once and respects the pixel threshold.
#include <gtest/gtest.h>

#include <map>

#include <glm/gtc/constants.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/store_builder.h>
#include <tessera/render/lod_selector.h>

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

TEST_F(LodSelector, CutCoversEveryVisibleLeafOnceWithinTheThreshold) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ViewSetup v = view(*s, 0.3);
  Cut cut = selectCut(*s, glm::dmat4(1.0), v);
  std::map<lod::NodeId, bool> selected;
  for (const CutNode& n : cut.nodes) {
    selected[n.id] = true;
    if (!s->node(n.id).leaf()) {
      EXPECT_LE(n.projected_spacing_px, 1.0);
    }
  }
  // Walk the whole hierarchy: each visible leaf has exactly one selected node on its path.
  const Frustum f = Frustum::fromMatrix(v.projection * v.view);
  size_t leaves = 0;
  std::vector<std::pair<lod::NodeId, int>> stack{{s->root(), 0}};
  while (!stack.empty()) {
    auto [id, above] = stack.back();
    stack.pop_back();
    lod::NodeInfo n = s->node(id);
    int here = above + (selected.count(id) ? 1 : 0);
    if (n.leaf()) {
      if (f.intersects(n.box_min, n.box_max)) {
        EXPECT_EQ(here, 1) << "leaf " << id;
        ++leaves;
      }
      continue;
    }
    for (lod::NodeId c : s->children(id)) stack.push_back({c, here});
  }
  EXPECT_GT(leaves, 5u);
  // Nearest first.
  for (size_t i = 1; i < cut.nodes.size(); ++i)
    EXPECT_LE(cut.nodes[i - 1].distance, cut.nodes[i].distance);
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
