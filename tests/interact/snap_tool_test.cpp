// The lazy snapping tool (interact/src/snap_tool.cpp): strokes on the bunny's ear and head, drawn
// in pixels of a known view, select the ear's elements of the mesh store and of the scans' point
// store; the SELECTION node's region mask tints the ear and not the head from the stroke view
// and from 30 degrees aside. The region mask's code (sync/selection_mask.h) is checked here too.
// TESSERA_TEST_PICTURES=DIR writes the tinted pictures (snap_tool_*.png) there.
#include <tessera/interact/snap_tool.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/mesh.h>
#include <tessera/annotate/selection.h>
#include <tessera/render/image.h>
#include <tessera/render/scene_overlay.h>
#include <tessera/sync/selection_mask.h>

#include "../support/bunny_store_test.h"
#include "../support/ear_labels.h"
#include "../support/snapping_models.h"

namespace tessera::interact {
namespace {

using render::ViewSetup;

/// snapping_models.h's bunnyView() as the renderer's view (540 x 540, orthographic from +z).
ViewSetup strokeView() {
  const annotate::ScreenView s = test::bunnyView();
  ViewSetup v;
  v.view = s.view;
  v.projection = s.projection;
  v.width = s.viewport.x;
  v.height = s.viewport.y;
  v.eye_world = glm::dvec3(0, 0, 1);
  return v;
}

/// The bunny's head and ear from `angle` radians around y (the stroke view at 0), 540 x 540.
ViewSetup asideView(double angle) {
  const glm::dvec3 c(-0.02, 0.11, 0.0), dir(std::sin(angle), 0.0, std::cos(angle));
  ViewSetup v;
  v.eye_world = c + dir;
  v.view = glm::lookAt(v.eye_world, c, glm::dvec3(0, 1, 0));
  v.projection = glm::ortho(-0.09, 0.09, -0.09, 0.09, 0.1, 2.0);
  v.width = v.height = 540;
  return v;
}

/// A store drawn where its file puts it.
render::ModelInstance instanceOf(lod::MeshStore& mesh) {
  render::ModelInstance m;
  m.mesh = &mesh;
  m.model = render::storeModel(mesh);
  return m;
}
render::ModelInstance instanceOf(lod::PointStore& store) {
  render::ModelInstance m;
  m.store = &store;
  m.model = render::storeModel(store);
  return m;
}

/// ScreenView pixels (y up) as the tool's (y down).
std::vector<glm::dvec2> yDown(std::vector<glm::dvec2> px, const ViewSetup& v) {
  for (glm::dvec2& p : px) p.y = double(v.height) - p.y;
  return px;
}

class SnapToolTest : public test::BunnyMeshStoreTest {
 public:
  static void SetUpTestSuite() {
    BunnyMeshStoreTest::SetUpTestSuite();
    sEar = new test::EarLabels(TESSERA_DATA_DIR);
  }
  static void TearDownTestSuite() {
    delete sEar;
    BunnyMeshStoreTest::TearDownTestSuite();
  }
  static inline test::EarLabels* sEar = nullptr;

  /// Renders `m` from `view` plain and with `payload` tinted; counts ear and other pixels
  /// (away from the ear's base) and how many of each changed.
  struct Tint {
    size_t ear = 0, ear_tinted = 0, other = 0, other_tinted = 0;
  };
  static Tint tintOf(render::ModelInstance m, const ViewSetup& view,
                     const scene::SelectionPayload& payload, const std::string& name) {
    sync::SceneGraph g;
    const auto model = g.add(scene::SceneNode::MODEL);
    const auto sel = g.add(scene::SceneNode::SELECTION);
    scene::SelectionPayload p = payload;
    p.set_model(model);
    g.setPayload(sel, p);
    m.node = model;
    render::ViewRenderer r(view.width, view.height);
    render::RenderOptions opt;
    opt.pick_ids = true;
    const render::ModelInstance models[] = {m};
    const render::Image plain = r.renderSettled(models, view, opt);
    std::vector<std::optional<render::PickHit>> hits(size_t(view.width) * view.height);
    for (uint32_t y = 0; y < view.height; ++y)
      for (uint32_t x = 0; x < view.width; ++x) hits[size_t(y) * view.width + x] = r.pick(x, y);
    opt.highlights = render::sceneHighlights(g);
    EXPECT_EQ(opt.highlights.size(), 1u);
    const render::Image tinted = r.renderSettled(models, view, opt);
    if (const char* dir = std::getenv("TESSERA_TEST_PICTURES"))
      render::writePng(std::string(dir) + "/snap_tool_" + name + ".png", tinted);
    Tint t;
    for (size_t i = 0; i < hits.size(); ++i) {
      if (!hits[i]) continue;
      const int label = sEar->label(hits[i]->world, 0.004);
      if (label < 0) continue;
      const bool changed =
          !std::equal(&plain.rgba[4 * i], &plain.rgba[4 * i + 3], &tinted.rgba[4 * i]);
      if (label == 1) {
        ++t.ear;
        t.ear_tinted += changed;
      } else {
        ++t.other;
        t.other_tinted += changed;
      }
    }
    return t;
  }

  static void expectEarTinted(const render::ModelInstance& m, const scene::SelectionPayload& p,
                              const std::string& name) {
    for (const auto& [view, what] :
         {std::pair{strokeView(), "stroke_view"}, {asideView(M_PI / 6), "aside"}}) {
      const Tint t = tintOf(m, view, p, name + "_" + what);
      SCOPED_TRACE(what);
      std::printf("%s %s: ear %zu of %zu pixels tinted, elsewhere %zu of %zu\n", name.c_str(), what,
                  t.ear_tinted, t.ear, t.other_tinted, t.other);
      ASSERT_GT(t.ear, 1500u);
      ASSERT_GT(t.other, 20000u);
      // Measured (mesh / points): of the ear's pixels (away from its base) 0.984 / 0.990 are
      // tinted from the stroke view, 0.985 / 0.989 aside (the rest: the ear's rim the stroke
      // view saw edge-on, and the mask's 1024^2 cells); elsewhere 0 / 2 pixels of 1.2e5. The
      // bounds leave room for the renderer's level of detail, not for a dotted tint nor for one
      // spilling over the head.
      EXPECT_GE(double(t.ear_tinted) / double(t.ear), 0.95) << t.ear_tinted << " of " << t.ear;
      EXPECT_LE(double(t.other_tinted) / double(t.other), 0.002)
          << t.other_tinted << " of " << t.other;
    }
  }
};

// The ear's IoU bound: lazy_snapping_test.cpp measures 0.95 on the reconstruction's vertices
// with these strokes and asks 0.90 (the ear's base is a smooth saddle, +-2 mm). Through the tool
// the cut runs on the store's leaves (welded patches, or the scans' 3.6e5 points with PCA
// normals, where the ear is labelled by the nearest reconstruction vertex): measured 0.948 to
// 0.952 on the mesh store (a store built anew has other patches, so other watershed ties), 0.945
// on the point store, 0.954 to 0.958 for the robust lasso; the same 0.90 bound.
/// Snaps the ear with the strokes of lazy_snapping_test.cpp on `m` (`store`: its mesh or point
/// store), checks the payload, the elements' IoU against the ear and the tint.
template <class Store>
void snapsTheEar(const render::ModelInstance& m, Store& store, annotate::SelectionElements elements,
                 const std::string& name, test::EarLabels& ear) {
  const ViewSetup view = strokeView();
  const SnapSelection s = snapSelection(m, 7, view, yDown(test::bunnyEarStroke(), view),
                                        yDown(test::bunnyHeadStroke(), view));
  ASSERT_GT(s.count, 0u);
  EXPECT_EQ(s.corrupt, 0u);
  EXPECT_EQ(s.payload.model(), 7u);
  EXPECT_TRUE(s.payload.visible_only());
  EXPECT_EQ(s.payload.lasso_size(), 0);
  EXPECT_EQ(s.payload.mask_width(), 540u);
  const annotate::Selection sel = test::selectionOf(s.payload.elements());
  EXPECT_EQ(sel.elements(), elements);
  EXPECT_EQ(sel.count(), s.count);
  // Expected: the leaf triangles whose three vertices are the ear's, or the leaf points whose
  // nearest reconstruction vertex (within 2 mm) is the ear's (scan noise left out).
  const double i = test::earIoU(store, sel, ear);
  std::printf("%s: %llu elements selected, IoU %.3f, %llu samples, %.0f ms\n", name.c_str(),
              (unsigned long long)s.count, i, (unsigned long long)s.stats.samples,
              s.stats.gather_ms + s.stats.cut_ms + s.stats.map_ms + s.stats.mask_ms);
  EXPECT_GE(i, 0.90);
  SnapToolTest::expectEarTinted(m, s.payload, name);
}

TEST_F(SnapToolTest, SnapsTheBunnysEarOnTheMeshStore) {
  auto mesh = lod::MeshStore::open(*sDir / "b.tmesh");
  const render::ModelInstance m = instanceOf(*mesh);
  snapsTheEar(m, *mesh, annotate::SelectionElements::kTriangles, "mesh", *sEar);
}

TEST_F(SnapToolTest, SnapsTheBunnysEarOnThePointStore) {
  auto store = lod::PointStore::open(*sDir / "b.tlod");
  const render::ModelInstance m = instanceOf(*store);
  snapsTheEar(m, *store, annotate::SelectionElements::kPoints, "points", *sEar);
}

TEST_F(SnapToolTest, RobustLassoAroundTheEarOnTheMeshStore) {
  auto mesh = lod::MeshStore::open(*sDir / "b.tmesh");
  const render::ModelInstance m = instanceOf(*mesh);
  const ViewSetup view = strokeView();
  const annotate::ScreenView sv = test::bunnyView();
  const std::vector<uint8_t> visible = annotate::visibleSamples(sEar->samples(), sv, 3.0, 0.003);
  const std::vector<uint8_t> ear = test::bunnyEar(sEar->samples());
  const auto outline = yDown(test::earOutline(sEar->samples(), ear, visible, sv), view);
  const SnapSelection s = robustLassoSelection(m, 7, view, outline, 16.0);
  ASSERT_GT(s.count, 0u);
  const double i = test::earIoU(*mesh, test::selectionOf(s.payload.elements()), *sEar);
  std::printf("robust lasso, mesh store: IoU %.3f\n", i);
  EXPECT_GE(i, 0.90);
}

TEST_F(SnapToolTest, RefusesStrokesOffTheModelAndTooManySamples) {
  auto mesh = lod::MeshStore::open(*sDir / "b.tmesh");
  const render::ModelInstance m = instanceOf(*mesh);
  const ViewSetup view = strokeView();
  const std::vector<glm::dvec2> off = {{5, 5}, {20, 5}};
  try {
    snapSelection(m, 7, view, off, yDown(test::bunnyHeadStroke(), view));
    FAIL() << "a foreground stroke off the model selected";
  } catch (const annotate::SnappingError& e) {
    EXPECT_NE(std::string(e.what()).find("foreground"), std::string::npos) << e.what();
  }
  SnapToolOptions few;
  few.max_samples = 1000;
  try {
    snapSelection(m, 7, view, yDown(test::bunnyEarStroke(), view),
                  yDown(test::bunnyHeadStroke(), view), few);
    FAIL() << "more samples than allowed were cut";
  } catch (const annotate::SnappingError& e) {
    EXPECT_NE(std::string(e.what()).find("zoom in"), std::string::npos) << e.what();
  }
  const std::vector<glm::dvec2> nan = {{NAN, 3}};
  EXPECT_THROW(snapSelection(m, 7, view, nan, off), annotate::SnappingError);
}

// The region mask on a known picture: a plane of samples 2 pixels apart whose left half is
// selected, and a small unselected square nearer the eye over that half. The mask is solid over
// the selected half (the closing fills the gaps between splats), empty over the other half and
// wherever the nearer unselected square is seen, its borders within 2 cells of the truth.
TEST(SelectionMask, SolidOverTheSelectedSurfaceAndNeverWhereUnselectedSurfaceIsNearer) {
  annotate::SurfaceSamples s;
  std::vector<uint8_t> selected;
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 200; ++x) {
      s.positions.emplace_back(x * 0.01 + 0.0025, y * 0.01 + 0.0025, 0.0);
      selected.push_back(x * 0.01 < 1.0);
    }
  for (int y = 60; y <= 80; ++y)  // the occluder: x, y in [0.6, 0.8], 0.5 nearer
    for (int x = 60; x <= 80; ++x) {
      s.positions.emplace_back(x * 0.01 + 0.0025, y * 0.01 + 0.0025, 0.5);
      selected.push_back(0);
    }
  annotate::ScreenView v;  // 200 pixels per unit, pixel (i, j) centred on (i + 0.5, j + 0.5) / 200
  v.view = glm::lookAt(glm::dvec3(1, 1, 5), glm::dvec3(1, 1, 0), glm::dvec3(0, 1, 0));
  v.projection = glm::ortho(-1.0, 1.0, -1.0, 1.0, 0.1, 10.0);
  v.viewport = {400, 400};
  const SnapMask m = selectionMask(s, selected, 0.01, v, {});
  ASSERT_EQ(m.width, 400u);
  ASSERT_EQ(m.height, 400u);
  size_t wrong = 0, checked = 0;
  for (uint32_t r = 0; r < m.height; ++r)
    for (uint32_t c = 0; c < m.width; ++c) {
      const double x = (c + 0.5) / 200.0, y = (r + 0.5) / 200.0;
      auto near = [](double a, double b) { return std::abs(a - b) < 0.01 + 1e-9; };
      if (near(x, 1.0) || near(x, 0.0) || near(y, 0.0) || near(y, 1.99) || near(x, 1.99)) continue;
      const bool occluder = x >= 0.6 && x <= 0.8 && y >= 0.6 && y <= 0.8;
      if (near(x, 0.6) || near(x, 0.8) || near(y, 0.6) || near(y, 0.8)) continue;
      if (x > 1.99 || y > 1.99) continue;  // past the last samples
      const bool want = x < 1.0 && !occluder;
      ++checked;
      wrong += (m.cells[size_t(r) * m.width + c] != 0) != want;
    }
  EXPECT_GT(checked, 140000u);
  EXPECT_EQ(wrong, 0u);
  // Splats of half a cell (a spacing given too small) leave 3 cells in 4 empty on this grid
  // (samples on every other cell's centre): the closing is what fills them.
  SnapToolOptions open;
  open.close_cells = 0;
  const SnapMask dotted = selectionMask(s, selected, 0.002, v, open);
  size_t holes = 0;
  for (uint32_t r = 20; r < 100; ++r)
    for (uint32_t c = 20; c < 100; ++c) holes += dotted.cells[size_t(r) * m.width + c] == 0;
  EXPECT_GT(holes, 1000u);
  const SnapMask closed = selectionMask(s, selected, 0.002, v, {});
  holes = 0;
  for (uint32_t r = 20; r < 100; ++r)
    for (uint32_t c = 20; c < 100; ++c) holes += closed.cells[size_t(r) * m.width + c] == 0;
  EXPECT_EQ(holes, 0u);
}

// The mask's code: round trips, and what is not a mask is refused by name, never crashes.
TEST(SelectionMask, RoundTripsAndRefusesGarbage) {
  std::mt19937 rng(5);
  for (const auto& [w, h] : {std::pair{1u, 1u}, {7u, 3u}, {640u, 480u}}) {
    std::vector<uint8_t> cells(size_t(w) * h);
    for (size_t i = 0; i < cells.size(); ++i) cells[i] = (i / 37 + rng() % 7 / 6) % 2;
    const std::string code = sync::encodeSelectionMask(cells);
    std::vector<uint8_t> back;
    ASSERT_FALSE(sync::decodeSelectionMask(code, w, h, &back));
    EXPECT_EQ(back, cells);
    EXPECT_TRUE(sync::decodeSelectionMask(code, w + 1, h, nullptr));  // runs do not cover it
  }
  EXPECT_TRUE(sync::decodeSelectionMask("", 4, 4, nullptr));
  EXPECT_TRUE(sync::decodeSelectionMask("\x80", 4, 4, nullptr));  // ends inside a varint
  EXPECT_TRUE(sync::decodeSelectionMask("\xff\xff\xff\xff\xff\x01", 4, 4, nullptr));
  EXPECT_TRUE(sync::decodeSelectionMask("\x10", 0, 16, nullptr));
  EXPECT_TRUE(sync::decodeSelectionMask("\x10", 5000, 1, nullptr));
  std::vector<uint8_t> cells;
  for (int i = 0; i < 2000; ++i) {
    std::string junk(rng() % 16, '\0');
    for (char& c : junk) c = char(rng());
    const auto p = sync::decodeSelectionMask(junk, 1 + rng() % 64, 1 + rng() % 64, &cells);
    if (p) {
      EXPECT_EQ(p->rfind("selection.mask", 0), 0u) << *p;
    }
  }
  // The scene graph refuses a selection with a bad mask, naming the field.
  sync::SceneGraph g;
  const auto model = g.add(scene::SceneNode::MODEL);
  const auto sel = g.add(scene::SceneNode::SELECTION);
  scene::SelectionPayload s;
  s.set_model(model);
  for (int k = 0; k < 16; ++k) s.add_lasso_clip_from_world(k % 5 == 0 ? 1.0 : 0.0);
  s.set_mask("\x05");
  s.set_mask_width(2);
  s.set_mask_height(2);
  try {
    g.setPayload(sel, s);
    FAIL() << "a mask of 5 cells passed as 2 x 2";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("selection.mask"), std::string::npos) << e.what();
  }
  s.set_mask(sync::encodeSelectionMask(std::vector<uint8_t>{0, 1, 1, 0}));
  g.setPayload(sel, s);
  EXPECT_EQ(render::sceneHighlights(g).size(), 1u);
}

}  // namespace
}  // namespace tessera::interact
