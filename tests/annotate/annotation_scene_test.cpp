// The annotation database as part of the scene (annotate/annotation_scene.h): layers as nested
// groups with their visibility, notes as ANNOTATION nodes that reach a replica, measurements
// and selections stored and brought back in a later session, edits committed before they
// return, and conflicting edits refused without touching the scene.
#include <tessera/annotate/annotation_scene.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <numbers>

#include <tessera/sync/scene_edits.h>
#include <tessera/sync/transform.h>

#include "../../fuzz/picture_fuzz.h"
#include "../support/temp_dir.h"

namespace tessera::annotate {
namespace {

namespace fs = std::filesystem;
using sync::SceneGraph;

class AnnotationSceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() /
          ("tessera_annotation_scene_" + std::to_string(getpid()) + "_" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    fs::create_directories(dir);
    file = dir / "scene.tadb";
  }
  void TearDown() override { fs::remove_all(dir); }

  /// A scene with one model named "statue".
  static SceneGraph sceneWithModel(SceneGraph::NodeId* model = nullptr, int filler = 0) {
    SceneGraph g;
    for (int i = 0; i < filler; ++i) g.add(scene::SceneNode::GROUP, SceneGraph::kRoot, "filler");
    const auto id = g.add(scene::SceneNode::MODEL, SceneGraph::kRoot, "statue");
    scene::ModelPayload m;
    m.set_store("/nowhere/statue.tlod");
    g.setPayload(id, m);
    if (model) *model = id;
    return g;
  }

  /// The ANNOTATION nodes of `g` in ascending id.
  static std::vector<const scene::SceneNode*> notes(const SceneGraph& g) {
    std::vector<const scene::SceneNode*> out;
    for (auto id : g.ids())
      if (g.node(id).kind() == scene::SceneNode::ANNOTATION) out.push_back(&g.node(id));
    return out;
  }

  static Item text(const std::string& layer, const std::string& title) {
    Item it;
    it.layer = layer;
    it.title = title;
    it.text = "seen on site";
    return it;
  }

  static Place point(glm::dvec3 at) {
    Place p;
    p.kind = PlaceKind::kPoint;
    p.model = "statue";
    p.position = at;
    return p;
  }

  fs::path dir, file;
};

TEST_F(AnnotationSceneTest, LoadsLayersAsNestedGroupsAndPlacesAsNotesThatReachAReplica) {
  const glm::dvec3 georef(512345.678, 5403210.123, 212.004);  // UTM metres: doubles needed
  {
    AnnotationDb db(file);
    const int64_t p = db.addPlace(point(georef));
    for (const auto& [layer, title] : {std::pair{"damage/cracks", "crack A"},
                                       {"damage/cracks", "crack B"},
                                       {"history", "Edo"}}) {
      db.attach(db.addItem(text(layer, title), "kyoto"), p);
    }
    Place hot = point({1, 2, 3});
    hot.kind = PlaceKind::kHotSpot;
    hot.radius = 0.25;
    hot.view = StoredView{{1, 2, 10}, {1, 2, 3}, {0, 1, 0}, 30.0};
    const int64_t h = db.addPlace(hot);
    Item n;
    n.kind = ItemKind::kNumber;
    n.layer = "history";
    n.title = "height";
    n.number = 2.5;
    n.unit = "m";
    db.attach(db.addItem(n, "wall"), h);
    db.setLayerVisible("damage/cracks", false);
  }
  SceneGraph g = sceneWithModel();
  AnnotationScene scene(file);
  EXPECT_TRUE(scene.load(g).empty());

  // damage -> cracks, the inner one hidden; history visible.
  const auto damage = g.findByName("damage");
  ASSERT_TRUE(damage);
  const auto cracks = g.children(*damage);
  ASSERT_EQ(cracks.size(), 1u);
  EXPECT_EQ(g.node(cracks[0]).name(), "cracks");
  EXPECT_FALSE(g.node(cracks[0]).visible());
  EXPECT_TRUE(g.node(*damage).visible());

  const auto n = notes(g);
  ASSERT_EQ(n.size(), 3u);  // the point in two layers, the hot spot in one
  int cracks_node = 0, hot_node = 0;
  for (const scene::SceneNode* node : n) {
    const auto& a = node->annotation();
    if (a.layer() == "damage/cracks") {
      ++cracks_node;
      EXPECT_EQ(node->parent(), cracks[0]);
      ASSERT_EQ(a.items_size(), 2);
      EXPECT_EQ(a.text(), "crack A (+1)");
      EXPECT_EQ(a.items(1).title(), "crack B");
      EXPECT_EQ(a.items(0).author(), "kyoto");
      EXPECT_EQ(a.items(0).revision(), 1u);
      // The place's position exactly, in the transform's doubles.
      const glm::dmat4 place = sync::transformMatrix(node->transform());
      EXPECT_EQ(place[3][0], georef.x);
      EXPECT_EQ(place[3][1], georef.y);
      EXPECT_EQ(place[3][2], georef.z);
    } else if (a.radius() > 0) {
      ++hot_node;
      EXPECT_EQ(a.radius(), 0.25);
      ASSERT_EQ(a.view_size(), 10);
      EXPECT_EQ(a.view(2), 10.0);
      EXPECT_EQ(a.view(9), 30.0);
      EXPECT_EQ(a.text(), "height: 2.5 m");
      EXPECT_EQ(a.items(0).kind(), "number");
    }
  }
  EXPECT_EQ(cracks_node, 1);
  EXPECT_EQ(hot_node, 1);

  // A node replicates them: the snapshot a late joiner gets, then a frame with an edit.
  g.takeFrame(1, 0);
  (void)g.takeFrame(1, 0);
  SceneGraph replica;
  replica.apply(g.snapshot());
  EXPECT_EQ(notes(replica).size(), 3u);
  const int64_t place = int64_t(n[0]->annotation().place());
  scene.addNote(g, {}, text(n[0]->annotation().layer(), "another"), "lyon", place);
  replica.apply(g.takeFrame(2, 1000));
  EXPECT_TRUE(replica == g);
}

TEST_F(AnnotationSceneTest, AnEditIsCommittedBeforeItReturnsAndAStaleOneChangesNothing) {
  SceneGraph g = sceneWithModel();
  AnnotationScene scene(file);
  scene.load(g);
  const auto [item, place] = scene.addNote(g, point({1, 1, 1}), text("notes", "first"), "kyoto");
  {
    // Another connection (another process would see the same) finds it committed.
    AnnotationDb other(file, {.read_only = true});
    ASSERT_TRUE(other.item(item));
    EXPECT_EQ(other.item(item)->author, "kyoto");
    EXPECT_EQ(other.itemsAt(place), std::vector<int64_t>{item});
  }
  ASSERT_EQ(notes(g).size(), 1u);

  // Two sites edit revision 1: the first reaching the master wins, the second is refused.
  Item a = *scene.db().item(item);
  a.title = "kyoto's title";
  EXPECT_EQ(scene.updateItem(g, a, 1, "kyoto"), 2);
  Item b = a;
  b.title = "lyon's title";
  g.takeFrame(1, 0);
  try {
    scene.updateItem(g, b, 1, "lyon");
    FAIL() << "a stale edit was applied";
  } catch (const AnnotationError& e) {
    EXPECT_EQ(e.kind(), AnnotationError::Kind::kConflict);
  }
  EXPECT_FALSE(g.hasPendingChanges());
  EXPECT_EQ(notes(g)[0]->annotation().items(0).title(), "kyoto's title");
  EXPECT_EQ(notes(g)[0]->author(), "kyoto");

  // Moving the item to another layer moves its note; removing the last item removes it.
  a.layer = "elsewhere/deeper";
  EXPECT_EQ(scene.updateItem(g, a, 2, "kyoto"), 3);
  ASSERT_EQ(notes(g).size(), 1u);
  EXPECT_EQ(g.node(notes(g)[0]->parent()).name(), "deeper");
  scene.removeItem(g, item, 3);
  EXPECT_TRUE(notes(g).empty());
  EXPECT_TRUE(scene.nodesOf(place).empty());
}

TEST_F(AnnotationSceneTest, MeasurementsAndSelectionsOfOneSessionComeBackInTheNext) {
  SceneGraph::NodeId model = 0;
  scene::MeasurementPayload measured;
  scene::SelectionPayload selected;
  {
    SceneGraph g = sceneWithModel(&model);
    AnnotationScene scene(file);
    scene.load(g);
    const auto layer = sync::layerGroup(g, "measurements", "");
    const std::vector<glm::dvec3> pts{{512000.001, 5403000.002, 10.0}, {512000.5, 5403000.0, 10.0}};
    const auto m = sync::addMeasurement(g, layer, "kyoto", scene::MeasurementPayload::DISTANCE, pts,
                                        0.4990, 0.0003);
    const auto angle_pts = std::vector<glm::dvec3>{{1, 0, 0}, {0, 0, 0}, {0, 1, 0}};
    const auto angle = sync::addMeasurement(g, layer, "", scene::MeasurementPayload::ANGLE,
                                            angle_pts, std::numbers::pi / 2, 0.001);
    measured = g.node(m).measurement();
    scene::SelectionPayload s;
    s.set_model(model);
    for (int k = 0; k < 16; ++k) s.add_lasso_clip_from_world(k % 5 == 0 ? 1.0 : 0.0);
    for (double v : {-0.5, -0.5, 0.5, -0.5, 0.0, 0.5}) s.add_lasso(v);
    s.set_elements("some bytes");
    s.set_count(42);
    const auto sel =
        g.add(scene::SceneNode::SELECTION, sync::layerGroup(g, "selections", ""), "selection 1");
    g.setPayload(sel, s);
    selected = s;
    scene.sync(g);
    ASSERT_TRUE(scene.placeOfNode(m));
    ASSERT_TRUE(scene.placeOfNode(sel));

    // Searchable as numbers with units: the angle in degrees.
    const auto hits = scene.db().search("distance");
    ASSERT_EQ(hits.size(), 1u);
    const Item item = *scene.db().item(hits[0].item);
    EXPECT_EQ(item.number, 0.4990);
    EXPECT_EQ(item.unit, "m");
    EXPECT_EQ(item.author, "kyoto");
    const auto angles = scene.db().search("angle");
    ASSERT_EQ(angles.size(), 1u);
    EXPECT_NEAR(scene.db().item(angles[0].item)->number, 90.0, 1e-9);
    EXPECT_EQ(scene.db().item(angles[0].item)->unit, "deg");

    // Removed in the session: gone from the database too.
    g.remove(angle);
    scene.sync(g);
    EXPECT_TRUE(scene.db().search("angle").empty());
    // Hiding the layer group hides the layer in the database.
    g.setVisible(layer, false);
    scene.sync(g);
    bool hidden = false;
    for (const Layer& l : scene.db().layers())
      if (l.path == "measurements") hidden = !l.visible;
    EXPECT_TRUE(hidden);
  }
  // The next session's scene gives the model another id: the selection follows its name.
  SceneGraph::NodeId model2 = 0;
  SceneGraph g = sceneWithModel(&model2, 3);
  ASSERT_NE(model2, model);
  AnnotationScene scene(file);
  EXPECT_TRUE(scene.load(g).empty());
  int measurements = 0, selections = 0;
  for (auto id : g.ids()) {
    const scene::SceneNode& n = g.node(id);
    if (n.kind() == scene::SceneNode::MEASUREMENT) {
      ++measurements;
      EXPECT_EQ(n.measurement().SerializeAsString(), measured.SerializeAsString());
      EXPECT_EQ(n.name(), "distance 1");
      EXPECT_EQ(n.author(), "kyoto");
      EXPECT_FALSE(g.node(n.parent()).visible());  // the layer stayed hidden
    }
    if (n.kind() == scene::SceneNode::SELECTION) {
      ++selections;
      EXPECT_EQ(n.selection().model(), model2);
      EXPECT_EQ(n.selection().elements(), selected.elements());
      EXPECT_EQ(n.selection().count(), 42u);
    }
  }
  EXPECT_EQ(measurements, 1);
  EXPECT_EQ(selections, 1);
  // Loaded nodes are not stored twice.
  scene.sync(g);
  EXPECT_EQ(scene.db().places().size(), 2u);
}

TEST_F(AnnotationSceneTest, AStoredPlaceTheSceneCannotTakeIsReportedAndKept) {
  {
    AnnotationDb db(file);
    Place p;
    p.kind = PlaceKind::kSelection;
    p.model = "statue";
    p.selection_id = kMeasurementBlob;
    p.selection = {0xff, 0xff, 0xff, 0x07};  // not a measurement
    db.addPlace(p);
    p.selection_id = kSelectionBlob;
    scene::SelectionPayload s;
    s.set_model(1);
    p.model = "a model this scene does not have";
    const std::string bytes = s.SerializeAsString();
    p.selection.assign(bytes.begin(), bytes.end());
    db.addPlace(p);
    // A measurement whose payload parses but does not check: NaN value.
    scene::MeasurementPayload m;
    m.set_type(scene::MeasurementPayload::DISTANCE);
    for (double v : {0.0, 0.0, 0.0, 1.0, 0.0, 0.0}) m.add_points(v);
    m.set_value(std::nan(""));
    const std::string mb = m.SerializeAsString();
    p.selection_id = kMeasurementBlob;
    p.model = "scene";
    p.selection.assign(mb.begin(), mb.end());
    db.addPlace(p);
  }
  SceneGraph g = sceneWithModel();
  const size_t before = g.size();
  AnnotationScene scene(file);
  const auto problems = scene.load(g);
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_NE(problems[0].find("does not parse"), std::string::npos) << problems[0];
  EXPECT_NE(problems[1].find("no model named"), std::string::npos) << problems[1];
  EXPECT_NE(problems[2].find("measurement.value"), std::string::npos) << problems[2];
  // Nothing half-made: at most the layer groups were added.
  for (auto id : g.ids()) {
    if (g.node(id).kind() != scene::SceneNode::GROUP) {
      EXPECT_LE(id, before);
    }
  }
  EXPECT_EQ(scene.db().places().size(), 3u);
}

}  // namespace
}  // namespace tessera::annotate

namespace tessera::annotate {
namespace {

/// A 24-bit BMP of w x h: left half red, right half blue, a green top row (BMP rows are stored
/// bottom up, so the orientation is checked too).
std::vector<uint8_t> bmp(int w, int h) {
  const int row = (w * 3 + 3) & ~3;
  std::vector<uint8_t> out(54 + size_t(row) * h, 0);
  auto put32 = [&](size_t at, uint32_t v) {
    for (int k = 0; k < 4; ++k) out[at + k] = uint8_t(v >> (8 * k));
  };
  out[0] = 'B';
  out[1] = 'M';
  put32(2, uint32_t(out.size()));
  put32(10, 54);
  put32(14, 40);
  put32(18, uint32_t(w));
  put32(22, uint32_t(h));
  out[26] = 1;
  out[28] = 24;
  put32(34, uint32_t(row) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint8_t* p = &out[54 + size_t(h - 1 - y) * row + size_t(x) * 3];  // BGR
      const bool top = y == 0;
      p[0] = !top && x >= w / 2 ? 255 : 0;
      p[1] = top ? 255 : 0;
      p[2] = !top && x < w / 2 ? 255 : 0;
    }
  return out;
}

TEST(NotePicture, DecodesAndScalesAndSaysWhyItCannot) {
  const NotePicture p = decodeNotePicture(bmp(600, 300), 192);
  ASSERT_EQ(p.width, 192u);
  ASSERT_EQ(p.height, 96u);
  auto px = [&](uint32_t x, uint32_t y) { return &p.rgba[(size_t(y) * p.width + x) * 4]; };
  EXPECT_GT(px(40, 48)[0], 240);  // red on the left
  EXPECT_LT(px(40, 48)[2], 15);
  EXPECT_GT(px(150, 48)[2], 240);  // blue on the right
  EXPECT_LT(px(150, 48)[0], 15);
  EXPECT_GT(px(40, 0)[1], 60);  // the green top row, averaged with red below it
  EXPECT_EQ(px(40, 0)[3], 255);
  // Never enlarged.
  const NotePicture small = decodeNotePicture(bmp(20, 10), 192);
  EXPECT_EQ(small.width, 20u);
  EXPECT_EQ(small.height, 10u);

  auto why = [](std::span<const uint8_t> bytes) {
    try {
      decodeNotePicture(bytes, 192);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("decoded");
  };
  const std::string text = "just text, not a picture";
  EXPECT_NE(why({reinterpret_cast<const uint8_t*>(text.data()), text.size()}).find("not an image"),
            std::string::npos);
  // A PNG signature over garbage, and a truncated picture: the decoder's reason, no crash.
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 1, 2, 3, 4, 5};
  EXPECT_NE(why(png), "decoded");
  std::vector<uint8_t> cut = bmp(64, 64);
  cut.resize(200);
  EXPECT_NE(why(cut), "decoded");
  // A small file declaring a huge picture is refused before it is allocated.
  std::vector<uint8_t> bomb = bmp(4, 4);
  for (int k = 0; k < 4; ++k)
    bomb[18 + k] = uint8_t(100000u >> (8 * k)), bomb[22 + k] = uint8_t(100000u >> (8 * k));
  EXPECT_NE(why(bomb), "decoded");
}

// The fuzz target's seeds (one tiny picture per format) and every input it ever crashed on
// (fuzz/picture_fuzz.h), through the same checks; the seeds must decode.
TEST(NotePictureFuzz, SeedsAndRegressionsReplay) {
  const fs::path fuzz_dir = TESSERA_FUZZ_DIR;
  size_t decoded = 0, replayed = 0;
  for (const char* dir : {"seeds/picture", "regressions/picture"}) {
    if (!fs::exists(fuzz_dir / dir)) continue;
    for (const auto& entry : fs::directory_iterator(fuzz_dir / dir)) {
      const auto bytes = tessera::test::readBytes(entry.path());
      SCOPED_TRACE(entry.path().string());
      tessera::fuzz::decodePicture(bytes.data(), bytes.size());  // aborts on a broken rule
      ++replayed;
      if (std::string(dir) == "seeds/picture") {
        EXPECT_NO_THROW(decodeNotePicture(bytes, 64));
        ++decoded;
      }
    }
  }
  EXPECT_EQ(decoded, 5u) << "png, jpeg, gif, bmp, tiff";
  EXPECT_GE(replayed, decoded);
}

TEST_F(AnnotationSceneTest, AnOpenNoteCarriesItsPicturesAndAClosedOneNone) {
  int64_t place = 0;
  {
    AnnotationDb db(file);
    place = db.addPlace(point({1, 2, 3}));
    Item embedded = text("docs", "1962 photo");
    embedded.kind = ItemKind::kImage;
    embedded.data = bmp(600, 300);
    embedded.mime = "image/bmp";
    db.attach(db.addItem(embedded, "kyoto"), place);
    // A file beside the database, named relatively.
    const std::vector<uint8_t> bytes = bmp(100, 200);
    FILE* f = std::fopen((dir / "sketch.bmp").c_str(), "wb");
    ASSERT_TRUE(f);
    std::fwrite(bytes.data(), 1, bytes.size(), f);
    std::fclose(f);
    Item by_path = text("docs", "sketch");
    by_path.kind = ItemKind::kImage;
    by_path.path = "sketch.bmp";
    by_path.mime = "image/bmp";
    db.attach(db.addItem(by_path, "kyoto"), place);
    Item missing = text("docs", "lost scan");
    missing.kind = ItemKind::kImage;
    missing.path = "nowhere/scan.jpg";
    missing.mime = "image/jpeg";
    db.attach(db.addItem(missing, "kyoto"), place);
  }
  AnnotationScene notes(file);
  SceneGraph g = sceneWithModel();
  notes.load(g);
  ASSERT_EQ(notes.nodesOf(place).size(), 1u);
  const auto node = notes.nodesOf(place)[0];
  auto items = [&] { return g.node(node).annotation().items(); };
  ASSERT_EQ(items().size(), 3);
  for (const auto& it : items()) EXPECT_TRUE(it.picture().empty()) << "a closed note sends none";

  notes.setOpen(g, place, true, "A");
  ASSERT_EQ(items().size(), 3);
  EXPECT_EQ(items()[0].picture_width(), 192u);
  EXPECT_EQ(items()[0].picture_height(), 96u);
  EXPECT_EQ(items()[0].picture().size(), 192u * 96 * 4);
  EXPECT_EQ(items()[1].picture_width(), 96u);
  EXPECT_EQ(items()[1].picture_height(), 192u);
  EXPECT_TRUE(items()[2].picture().empty());
  EXPECT_NE(items()[2].picture_problem().find("nowhere/scan.jpg"), std::string::npos)
      << items()[2].picture_problem();
  // The payload passes the scene graph's checks on a replica.
  (void)g.takeFrame(1, 0);
  SceneGraph replica;
  replica.apply(g.snapshot());
  EXPECT_EQ(replica.node(node).annotation().items(1).picture(), items()[1].picture());

  // Opening again changes nothing; closing drops the pictures.
  const uint64_t version = g.version();
  notes.setOpen(g, place, true, "A");
  EXPECT_FALSE(g.hasPendingChanges()) << "an unchanged payload is not sent again";
  notes.setOpen(g, place, false, "A");
  for (const auto& it : items()) EXPECT_TRUE(it.picture().empty());
  EXPECT_GE(g.version(), version);
}

TEST_F(AnnotationSceneTest, WhatOtherProgramsCommitReachesTheScene) {
  AnnotationScene notes(file);
  notes.setExternalPoll(std::chrono::milliseconds(0));
  SceneGraph g = sceneWithModel();
  notes.load(g);
  notes.sync(g);
  (void)g.takeFrame(2, 0);
  // Nothing changed elsewhere: nothing changes here.
  EXPECT_TRUE(notes.refresh(g).empty());
  EXPECT_FALSE(g.hasPendingChanges());

  AnnotationDb other(file);  // tessera-annotate, say
  const int64_t place = other.addPlace(point({4, 5, 6}));
  const int64_t item = other.addItem(text("survey/north", "crack"), "tool");
  other.attach(item, place);
  notes.sync(g);
  ASSERT_EQ(notes.nodesOf(place).size(), 1u);
  const auto node = notes.nodesOf(place)[0];
  EXPECT_EQ(g.node(node).annotation().text(), "crack");
  EXPECT_EQ(g.node(node).annotation().items(0).author(), "tool");

  Item edited = *other.item(item);
  edited.title = "crack, 14 cm";
  other.updateItem(edited, 1, "tool");
  other.setLayerVisible("survey", false);
  notes.sync(g);
  EXPECT_EQ(g.node(node).annotation().text(), "crack, 14 cm");
  const auto survey = g.findByName("survey");
  ASSERT_TRUE(survey);
  EXPECT_FALSE(g.node(*survey).visible());
  // Hiding it here is stored, and is not mistaken for another program's edit.
  notes.setLayerVisible(g, "survey", true, "A");
  notes.sync(g);
  EXPECT_TRUE(g.node(*survey).visible());
  EXPECT_TRUE(other.layerShown("survey/north"));

  // A measurement stored by another session's tool comes in; deleted, it goes.
  scene::MeasurementPayload m;
  m.set_type(scene::MeasurementPayload::DISTANCE);
  for (double v : {0.0, 0.0, 0.0, 1.0, 0.0, 0.0}) m.add_points(v);
  m.set_value(1.0);
  m.set_uncertainty(0.001);
  Place stored;
  stored.kind = PlaceKind::kSelection;
  stored.model = "scene";
  stored.selection_id = kMeasurementBlob;
  const std::string bytes = m.SerializeAsString();
  stored.selection.assign(bytes.begin(), bytes.end());
  const int64_t stored_place = other.addPlace(stored);
  notes.sync(g);
  int measurements = 0;
  for (auto id : g.ids()) measurements += g.node(id).kind() == scene::SceneNode::MEASUREMENT;
  EXPECT_EQ(measurements, 1);
  other.removePlace(stored_place);
  other.removeItem(item, 2);
  notes.sync(g);
  measurements = 0;
  for (auto id : g.ids()) measurements += g.node(id).kind() == scene::SceneNode::MEASUREMENT;
  EXPECT_EQ(measurements, 0);
  EXPECT_TRUE(notes.nodesOf(place).empty());
  EXPECT_FALSE(g.contains(node));
  // Nor was anything written back by taking these in.
  EXPECT_EQ(other.places().size(), 1u);  // the point, now without items
}

}  // namespace
}  // namespace tessera::annotate
