// Clip planes and boxes (render/clip_planes.h, the scene's CLIP nodes): the rule and
// its precision on the CPU; the scene draw list collecting visible CLIP nodes per model; then
// on the bunny (scans and reconstruction) through real GL: a plane synced to a replica removes
// exactly its half-space (kept pixels unchanged, removed ones show the background or what lies
// behind, nothing drawn beyond the plane), a box keeps its inside (or, inverted, its outside),
// a hidden CLIP node changes nothing, see-through ensembles are cut too; and a selection's tint
// stays on its own model when the lasso covers two.
//
// Every expectation is computed by the test itself from the unclipped frame's pick ids (each
// pixel's surface point) and the plane or box written here, not by the code under test.
// TESSERA_TEST_PICTURES=DIR writes the pictures (clip_*.png) there, to look at.
#include <tessera/render/clip_planes.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <numbers>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <tessera/render/scene_draw_list.h>
#include <tessera/render/scene_overlay.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/wire.h>

#include "../support/bunny_store_test.h"
#include "../support/lasso_payload.h"

namespace tessera::render {
namespace {

using sync::SceneGraph;

void setVec(config::Vec3& v, const glm::dvec3& d) {
  v.set_x(d.x);
  v.set_y(d.y);
  v.set_z(d.z);
}

/// A box payload: centre and half extents, node frame.
scene::ClipPayload boxPayload(const glm::dvec3& centre, const glm::dvec3& half) {
  scene::ClipPayload b;
  setVec(*b.mutable_box_center(), centre);
  setVec(*b.mutable_box_half_extents(), half);
  return b;
}

/// Two MODEL nodes drawing the same store.
std::pair<SceneGraph::NodeId, SceneGraph::NodeId> addTwoModels(SceneGraph& g,
                                                               const std::string& store) {
  scene::ModelPayload m;
  m.set_store(store);
  const auto a = g.add(scene::SceneNode::MODEL);
  const auto b = g.add(scene::SceneNode::MODEL);
  g.setPayload(a, m);
  g.setPayload(b, m);
  return {a, b};
}

// ---- The rule and its precision (no GL).

TEST(ClipPlanes, GroupsKeepTheirInsideOrWithInvertTheirOutside) {
  ClipPlanes c;
  const auto box = boxPlanes({0, 0, 0}, {1, 2, 3});
  ASSERT_TRUE(c.addGroup(box, false));
  EXPECT_TRUE(c.keeps({0.9, -1.9, 2.9}));
  EXPECT_FALSE(c.keeps({1.1, 0, 0}));
  EXPECT_FALSE(c.keeps({0, 0, -3.1}));
  // A second group, a half-space z <= 1: both must keep.
  const glm::dvec4 below(0, 0, -1, 1);
  ASSERT_TRUE(c.addGroup(std::span(&below, 1), false));
  EXPECT_TRUE(c.keeps({0, 0, 0.5}));
  EXPECT_FALSE(c.keeps({0, 0, 1.5}));
  // Inverted: a box that keeps its outside.
  ClipPlanes out;
  ASSERT_TRUE(out.addGroup(box, true));
  EXPECT_FALSE(out.keeps({0, 0, 0}));
  EXPECT_TRUE(out.keeps({1.5, 0, 0}));
  EXPECT_TRUE(out.keeps({0, 0, -3.5}));
  // Two boxes fit (12 planes), a third plane does not and adds nothing.
  ASSERT_TRUE(out.addGroup(box, false));
  EXPECT_EQ(out.count, kMaxClipPlanes);
  EXPECT_FALSE(out.addGroup(std::span(&below, 1), false));
  EXPECT_EQ(out.count, kMaxClipPlanes);
  EXPECT_EQ(out.group_count, 2u);
}

TEST(ClipPlanes, GeoreferencedPlanesKeepMicrometresInTheBatchFrame) {
  // A plane through a point 10^6 m out, tilted; a batch (chunk) whose frame sits there too.
  const glm::dvec3 site(1234567.891, -2345678.123, 345.5);
  const glm::dvec3 n = glm::normalize(glm::dvec3(0.3, -0.2, 1.0));
  const glm::dvec4 world_plane(n, -glm::dot(n, site));
  ClipPlanes world;
  ASSERT_TRUE(world.addGroup(std::span(&world_plane, 1), false));
  const glm::dmat4 world_from_local =
      glm::translate(glm::dmat4(1.0), site + glm::dvec3(0.7, 0.1, -0.2));
  const GpuClipPlanes gpu = gpuClipPlanes(world, world_from_local);
  ASSERT_EQ(gpu.count, 1u);
  // Float positions in the batch's frame, 1 um either side of the plane: the float test (as
  // the shader does it) tells them apart.
  const glm::dvec3 on_plane_local = site - glm::dvec3(world_from_local[3]);
  for (double side : {-1.0, 1.0}) {
    const glm::vec3 p(on_plane_local + side * 1e-6 * n);
    const float s = glm::dot(glm::vec3(gpu.planes[0]), p) + gpu.planes[0].w;
    EXPECT_EQ(s > 0.0f, side > 0.0) << s;
  }
  // The same through a node transform: a CLIP node at the site with a plane in its own frame.
  scene::ClipPayload c;
  for (double v : {0.0, 0.0, 1.0, 0.0}) c.add_planes(v);
  const std::vector<glm::dvec4> placed =
      SceneDrawList::clipPlanesOf(c, glm::translate(glm::dmat4(1.0), site));
  ASSERT_EQ(placed.size(), 1u);
  EXPECT_NEAR(glm::dot(glm::dvec3(placed[0]), site + glm::dvec3(5, 5, 2e-6)) + placed[0].w, 2e-6,
              1e-9);
}

TEST(ClipPlanes, TheOverlayOutlinesBoxesAndPlanes) {
  SceneGraph g;
  const auto box = g.add(scene::SceneNode::CLIP);
  g.setPayload(box, boxPayload({0, 0, 0}, {1, 2, 3}));
  Overlay o;
  appendSceneOverlay(g, o);
  ASSERT_EQ(o.lines.size(), 12u);
  for (const OverlayLine& l : o.lines) {
    const glm::dvec3 d = glm::abs(l.b - l.a);
    EXPECT_NEAR(d.x + d.y + d.z, d.x > 0 ? 2.0 : d.y > 0 ? 4.0 : 6.0, 1e-12);  // along an axis
  }
  // A plane: a square of half-width `outline` lying in it; none without an outline.
  const auto plane = g.add(scene::SceneNode::CLIP);
  g.setTransform(plane,
                 std::span<const double>(
                     glm::value_ptr(glm::translate(glm::dmat4(1.0), glm::dvec3(10, 0, 0))), 16));
  scene::ClipPayload p;
  for (double v : {1.0, 1.0, 0.0, -2.0}) p.add_planes(v);
  p.set_outline(0.5f);
  g.setPayload(plane, p);
  Overlay o2;
  appendSceneOverlay(g, o2);
  ASSERT_EQ(o2.lines.size(), 16u);
  for (size_t i = 12; i < 16; ++i) {
    for (const glm::dvec3& q : {o2.lines[i].a, o2.lines[i].b})
      EXPECT_NEAR((q.x - 10.0) + q.y - 2.0, 0.0, 1e-9);  // on the plane, in the node frame
    EXPECT_NEAR(glm::length(o2.lines[i].b - o2.lines[i].a), 1.0, 1e-9);
  }
  p.set_outline(0.0f);
  g.setPayload(plane, p);
  Overlay o3;
  appendSceneOverlay(g, o3);
  EXPECT_EQ(o3.lines.size(), 12u);
}

// ---- On the bunny.

class ClipRenderTest : public test::BunnyMeshStoreTest {
 public:
  static constexpr uint32_t kW = 320, kH = 240;

  /// The bunny's centre (world) and a view of it from the front-right, a little above.
  static glm::dvec3 centre() {
    auto s = lod::PointStore::open(*sDir / "b.tlod");
    return s->summary().origin + 0.5 * (s->summary().bbox_min + s->summary().bbox_max);
  }
  static ViewSetup view() {
    const glm::dvec3 c = centre();
    return test::lookingAt(c + glm::dvec3(0.22, 0.08, 0.3), c, kW, kH);
  }

  /// A frame and each pixel's surface (the frame's pick ids).
  struct Shot {
    Image image;
    std::vector<std::optional<PickHit>> hits;
    const uint8_t* rgb(size_t i) const { return &image.rgba[4 * i]; }
    bool same(const Shot& o, size_t i) const { return std::memcmp(rgb(i), o.rgb(i), 3) == 0; }
  };
  static Shot shoot(ViewRenderer& r, std::span<const ModelInstance> models,
                    RenderOptions opt = {}) {
    opt.pick_ids = true;
    Shot s;
    s.image = r.renderSettled(models, view(), opt);
    s.hits.resize(size_t(kW) * kH);
    for (uint32_t y = 0; y < kH; ++y)
      for (uint32_t x = 0; x < kW; ++x) s.hits[size_t(y) * kW + x] = r.pick(x, y);
    return s;
  }

  static void maybeWrite(const std::string& name, const Image& img) {
    if (const char* dir = std::getenv("TESSERA_TEST_PICTURES"))
      writePng(std::string(dir) + "/clip_" + name + ".png", img);
  }

  /// A master's scene (a MODEL node of `store`, a CLIP node with `clip` placed by
  /// `clip_transform`, hidden at first) and a replica fed with the master's frames through their
  /// bytes, drawn by the replica's draw list: what a render node does.
  struct SyncedScene {
    SceneGraph master, replica;
    SceneDrawList list;
    ViewRenderer renderer{kW, kH};
    SceneGraph::NodeId model = 0, clip = 0;
    std::vector<ModelInstance> models;

    SyncedScene(const std::string& store, const scene::ClipPayload& payload,
                const glm::dmat4& clip_transform) {
      model = master.add(scene::SceneNode::MODEL, SceneGraph::kRoot, "bunny");
      scene::ModelPayload m;
      m.set_store(store);
      master.setPayload(model, m);
      clip = master.add(scene::SceneNode::CLIP, SceneGraph::kRoot, "cut");
      master.setTransform(clip, std::span<const double>(glm::value_ptr(clip_transform), 16));
      master.setPayload(clip, payload);
      master.setVisible(clip, false);
      sync();
    }
    ~SyncedScene() {
      ChunkStreamer* s[] = {&renderer.streamer()};
      list.clear(s);
    }
    /// The master's pending changes to the replica (serialised and parsed, as on the wire), then
    /// to the draw list.
    void sync() {
      const scene::Frame f = master.takeFrame(master.frameNumber() + 1, 0);
      const sync::SceneChanges changes = replica.apply(sync::parseFrame(sync::serializeFrame(f)));
      ChunkStreamer* s[] = {&renderer.streamer()};
      models = list.update(replica, changes, s);
    }
  };
};

/// A plane through the bunny, rotated 30 degrees about y and placed at its centre by the CLIP
/// node's transform, keeping x' <= 0 (the node frame's x): synced from the master to a replica,
/// hidden it changes nothing; shown, every pixel whose surface was on the kept side (beyond a
/// margin for splat size) is unchanged, every pixel whose surface was cut shows the background
/// or a surface farther away, and no pixel shows a surface beyond the plane. Points and mesh.
void expectPlaneCut(ClipRenderTest::SyncedScene& s, const glm::dvec3& c, const glm::dmat4& place,
                    double margin, const std::string& name) {
  const glm::dvec3 keep_normal = glm::dvec3(place * glm::dvec4(-1, 0, 0, 0));  // world
  auto side = [&](const glm::dvec3& w) { return glm::dot(keep_normal, w - c); };

  ASSERT_EQ(s.models.size(), 1u);
  EXPECT_TRUE(s.models[0].clip.empty()) << "a hidden CLIP node cuts nothing";
  ModelInstance unclipped = s.models[0];
  unclipped.clip = {};
  const auto hidden = ClipRenderTest::shoot(s.renderer, s.models);
  const auto plain = ClipRenderTest::shoot(s.renderer, std::span(&unclipped, 1));
  EXPECT_EQ(hidden.image.rgba, plain.image.rgba) << "a hidden CLIP node changes nothing";

  s.master.setVisible(s.clip, true);
  s.sync();
  ASSERT_EQ(s.models[0].clip.count, 1u) << "the plane reached the replica's draw list";
  const auto cut = ClipRenderTest::shoot(s.renderer, s.models);
  ClipRenderTest::maybeWrite(name + "_plain", plain.image);
  ClipRenderTest::maybeWrite(name + "_cut", cut.image);

  size_t kept = 0, removed = 0, behind = 0, wrong_kept = 0, wrong_removed = 0, beyond = 0;
  for (size_t i = 0; i < plain.hits.size(); ++i) {
    if (const auto& h = cut.hits[i]; h && side(h->world) < -margin) ++beyond;
    const auto& p = plain.hits[i];
    if (!p) {
      wrong_kept += !cut.same(plain, i);  // background stays background
      continue;
    }
    const double d = side(p->world);
    if (d > margin) {
      ++kept;
      wrong_kept += !cut.same(plain, i);
    } else if (d < -margin) {
      ++removed;
      const auto& h = cut.hits[i];
      if (h) {
        ++behind;
        wrong_removed += !(h->depth > p->depth);
      } else {
        const uint8_t* px = cut.rgb(i);
        wrong_removed += px[0] != 0 || px[1] != 0 || px[2] != 0;  // the background (black)
      }
    }
  }
  EXPECT_GT(kept, 3000u);
  EXPECT_GT(removed, 3000u);
  EXPECT_GT(behind, 100u) << "the inside of the far half shows through the cut";
  EXPECT_EQ(wrong_kept, 0u);
  EXPECT_EQ(wrong_removed, 0u);
  EXPECT_EQ(beyond, 0u) << "a surface beyond the plane was drawn";

  // Hidden again: the picture is the unclipped one.
  s.master.setVisible(s.clip, false);
  s.sync();
  EXPECT_EQ(ClipRenderTest::shoot(s.renderer, s.models).image.rgba, plain.image.rgba);
}

scene::ClipPayload planePayload() {
  scene::ClipPayload p;
  for (double v : {-1.0, 0.0, 0.0, 0.0}) p.add_planes(v);  // keep x <= 0 in the node frame
  return p;
}

glm::dmat4 planePlace(const glm::dvec3& c) {
  return glm::rotate(glm::translate(glm::dmat4(1.0), c), glm::radians(30.0), glm::dvec3(0, 1, 0));
}

TEST_F(ClipRenderTest, APlaneSyncedToAReplicaCutsThePointsExactly) {
  const glm::dvec3 c = centre();
  SyncedScene s((*sDir / "b.tlod").string(), planePayload(), planePlace(c));
  // Splats reach a couple of spacings (about a millimetre each) beyond their points.
  expectPlaneCut(s, c, planePlace(c), 0.004, "points");
}

TEST_F(ClipRenderTest, APlaneSyncedToAReplicaCutsTheMeshExactly) {
  const glm::dvec3 c = centre();
  SyncedScene s((*sDir / "b.tmesh").string(), planePayload(), planePlace(c));
  // Fragments are cut per pixel: the margin is the unprojection's, far below a millimetre.
  expectPlaneCut(s, c, planePlace(c), 0.0005, "mesh");
}

TEST_F(ClipRenderTest, ABoxKeepsItsInsideAndInvertedItsOutside) {
  const glm::dvec3 c = centre();
  const glm::dvec3 half(0.035, 0.03, 0.05);
  const glm::dvec3 mid(0.01, 0.02, 0.0);  // around the upper body and head, node frame
  scene::ClipPayload box = boxPayload(mid, half);
  const glm::dmat4 place = glm::translate(glm::dmat4(1.0), c);
  SyncedScene s((*sDir / "b.tlod").string(), box, place);
  const double margin = 0.004;
  // How far inside the box a world point is (negative: outside), by the test's own arithmetic.
  auto inside = [&](const glm::dvec3& w) {
    const glm::dvec3 q = glm::abs(w - c - mid);
    return std::min({half.x - q.x, half.y - q.y, half.z - q.z});
  };
  const auto plain = shoot(s.renderer, s.models);
  for (bool invert : {false, true}) {
    box.set_invert(invert);
    s.master.setPayload(s.clip, box);
    s.master.setVisible(s.clip, true);
    s.sync();
    ASSERT_EQ(s.models[0].clip.count, 6u);
    const auto cut = shoot(s.renderer, s.models);
    maybeWrite(invert ? "box_outside" : "box_inside", cut.image);
    size_t kept = 0, removed = 0, wrong = 0, drawn_removed = 0;
    for (size_t i = 0; i < plain.hits.size(); ++i) {
      if (const auto& h = cut.hits[i]) {
        const double in = inside(h->world);
        drawn_removed += invert ? in > margin : in < -margin;
      }
      const auto& p = plain.hits[i];
      if (!p) continue;
      const double in = invert ? -inside(p->world) : inside(p->world);
      if (in > margin) {
        ++kept;
        wrong += !cut.same(plain, i);
      } else if (in < -margin) {
        ++removed;
      }
    }
    EXPECT_GT(kept, 1000u) << invert;
    EXPECT_GT(removed, 1000u) << invert;
    EXPECT_EQ(wrong, 0u) << invert;
    EXPECT_EQ(drawn_removed, 0u) << "drawn where the box removes, invert " << invert;
  }
}

/// See-through ensembles are cut too: where the opaque cut shows the background through the
/// removed half, the see-through picture is the background as well; where the kept half is,
/// it shows the model.
TEST_F(ClipRenderTest, SeeThroughEnsemblesAreCut) {
  const glm::dvec3 c = centre();
  SyncedScene s((*sDir / "b.tlod").string(), planePayload(), planePlace(c));
  s.master.setVisible(s.clip, true);
  s.sync();
  const auto opaque_cut = shoot(s.renderer, s.models);
  ModelInstance unclipped = s.models[0];
  unclipped.clip = {};
  const auto plain = shoot(s.renderer, std::span(&unclipped, 1));
  s.master.setOpacity(s.model, 0.5f);
  s.sync();
  ASSERT_LT(s.models[0].opacity, 1.0f);
  RenderOptions opt;
  opt.spbr.ensembles = 16;
  const Image see_through = s.renderer.renderSettled(s.models, view(), opt);
  maybeWrite("see_through", see_through);
  // See-through frames draw a coarser cut with larger discs: a pixel counts as emptied only
  // when no kept surface lies within 6 pixels of it.
  auto near_kept = [&](size_t i) {
    const int x = int(i % kW), y = int(i / kW);
    for (int dy = -6; dy <= 6; ++dy)
      for (int dx = -6; dx <= 6; ++dx) {
        const int qx = x + dx, qy = y + dy;
        if (qx >= 0 && qy >= 0 && qx < int(kW) && qy < int(kH) &&
            opaque_cut.hits[size_t(qy) * kW + size_t(qx)])
          return true;
      }
    return false;
  };
  size_t emptied = 0, wrong = 0, kept = 0, shown = 0;
  for (size_t i = 0; i < plain.hits.size(); ++i) {
    const uint8_t* px = &see_through.rgba[4 * i];
    const bool background = px[0] == 0 && px[1] == 0 && px[2] == 0;
    if (plain.hits[i] && !near_kept(i)) {  // only the removed half was there
      ++emptied;
      wrong += !background;
    } else if (opaque_cut.hits[i] && plain.hits[i] &&
               opaque_cut.hits[i]->depth == plain.hits[i]->depth) {
      ++kept;
      shown += !background;
    }
  }
  EXPECT_GT(emptied, 500u);
  EXPECT_EQ(wrong, 0u) << "see-through points of the removed half were drawn";
  EXPECT_GT(kept, 3000u);
  EXPECT_GT(double(shown), 0.95 * double(kept));
}

/// The draw list gives each model the visible CLIP nodes that name it (or all models when
/// none are named), one group each in ascending id, up to kMaxClipPlanes; hidden ones and those
/// under a hidden group cut nothing; a node that does not fit is left out and counted.
TEST_F(ClipRenderTest, TheDrawListCollectsTheClipsOfEachModel) {
  SceneGraph g;
  const auto [a, b] = addTwoModels(g, (*sDir / "b.tlod").string());
  const scene::ClipPayload box = boxPayload({0, 0, 0}, {1, 1, 1});
  const auto all = g.add(scene::SceneNode::CLIP);
  g.setPayload(all, box);
  scene::ClipPayload only_b = planePayload();
  only_b.add_models(b);
  const auto on_b = g.add(scene::SceneNode::CLIP);
  g.setPayload(on_b, only_b);
  g.add(scene::SceneNode::CLIP);  // empty (as created): cuts nothing, not counted as dropped
  const auto group = g.add(scene::SceneNode::GROUP);
  const auto under = g.add(scene::SceneNode::CLIP, group);
  g.setPayload(under, planePayload());
  g.setVisible(group, false);
  SceneDrawList list;
  auto models = list.update(g, sync::SceneChanges::all());
  ASSERT_EQ(models.size(), 2u);
  EXPECT_EQ(models[0].node, a);
  EXPECT_EQ(models[0].clip.count, 6u);
  EXPECT_EQ(models[1].clip.count, 7u);
  EXPECT_EQ(models[1].clip.group_count, 2u);
  EXPECT_EQ(list.droppedClips(), 0u);
  // The group shown: its plane cuts both; a second box on b no longer fits (6 + 1 + 1 + 6).
  g.setVisible(group, true);
  const auto second = g.add(scene::SceneNode::CLIP);
  scene::ClipPayload box_b = box;
  box_b.add_models(b);
  g.setPayload(second, box_b);
  models = list.update(g, sync::SceneChanges::of(g.takeFrame(1, 0)));
  EXPECT_EQ(models[0].clip.count, 7u);
  EXPECT_EQ(models[1].clip.count, 8u);
  EXPECT_EQ(list.droppedClips(), 1u);
  // Hidden, a CLIP node is gone from every model.
  g.setVisible(all, false);
  models = list.update(g, sync::SceneChanges::of(g.takeFrame(2, 0)));
  EXPECT_EQ(models[0].clip.count, 1u);
  EXPECT_EQ(models[1].clip.count, 8u);  // the second box fits now
  EXPECT_EQ(list.droppedClips(), 0u);
  list.clear({});
}

/// Two bunnies side by side, one lasso over both, a selection on the left one: only the left
/// one's pixels inside the lasso are tinted; the right one's inside the lasso are unchanged.
TEST_F(ClipRenderTest, ASelectionTintsOnlyItsOwnModel) {
  const glm::dvec3 c = centre();
  SceneGraph g;
  const auto [left, right] = addTwoModels(g, (*sDir / "b.tlod").string());
  const glm::dmat4 shift = glm::translate(glm::dmat4(1.0), glm::dvec3(0.17, 0.0, -0.05));
  g.setTransform(right, std::span<const double>(glm::value_ptr(shift), 16));
  const ViewSetup v = test::lookingAt(c + glm::dvec3(0.085, 0.05, 0.45),
                                      c + glm::dvec3(0.085, 0.0, 0.0), kW, kH, 40.0);
  // A lasso across the middle of the picture, over both bunnies (pixels, y down).
  const std::vector<glm::dvec2> px = {{20, 70}, {300, 70}, {300, 170}, {20, 170}};
  const auto sel = g.add(scene::SceneNode::SELECTION);
  g.setPayload(sel, test::lassoPayload(left, v, px));
  SceneDrawList list;
  const auto models = list.update(g, sync::SceneChanges::all());
  ASSERT_EQ(models.size(), 2u);
  ViewRenderer r(kW, kH);
  RenderOptions opt;
  opt.pick_ids = true;
  const Image plain = r.renderSettled(models, v, opt);
  std::vector<std::optional<PickHit>> hits(size_t(kW) * kH);
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) hits[size_t(y) * kW + x] = r.pick(x, y);
  opt.pick_ids = false;  // the highlight asks for them itself
  opt.highlights = sceneHighlights(g);
  ASSERT_EQ(opt.highlights.size(), 1u);
  const Image tinted = r.renderSettled(models, v, opt);
  maybeWrite("selection_two_models", tinted);
  size_t own = 0, other = 0, wrong = 0;
  for (uint32_t y = 0; y < kH; ++y) {
    for (uint32_t x = 0; x < kW; ++x) {
      const size_t i = size_t(y) * kW + x;
      const bool changed = std::memcmp(&plain.rgba[4 * i], &tinted.rgba[4 * i], 3) != 0;
      const bool in = x > 21 && x < 298 && y > 71 && y < 168;  // inside, off the lasso's edge
      const bool out = x < 19 || x > 301 || y < 69 || y > 171;
      if (!hits[i] || !(in || out)) {
        wrong += !hits[i] && changed;
        continue;
      }
      const bool is_left = models[hits[i]->model].node == left;
      if (in && is_left) {
        ++own;
        wrong += !changed;
      } else {
        other += in;
        wrong += changed;
      }
    }
  }
  EXPECT_GT(own, 2000u);
  EXPECT_GT(other, 2000u) << "the other model lies inside the lasso too";
  EXPECT_EQ(wrong, 0u);
  ChunkStreamer* streamers[] = {&r.streamer()};
  list.clear(streamers);
}

}  // namespace
}  // namespace tessera::render
