// The annotation database as part of the scene (master/annotation_scene.h): layers as nested
// groups with their visibility, notes as ANNOTATION nodes that reach a replica, measurements
// and selections stored and brought back in a later session, edits committed before they
// return, and conflicting edits refused without touching the scene.
#include <tessera/master/annotation_scene.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <numbers>

#include <tessera/sync/scene_edits.h>

namespace tessera::master {
namespace {

namespace fs = std::filesystem;
using sync::SceneGraph;

class AnnotationSceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() / ("tessera_annotation_scene_" + std::to_string(getpid()) +
                                       "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
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
    for (const auto& [layer, title] :
         {std::pair{"damage/cracks", "crack A"}, {"damage/cracks", "crack B"}, {"history", "Edo"}}) {
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
      ASSERT_EQ(node->transform().m_size(), 16);
      EXPECT_EQ(node->transform().m(12), georef.x);
      EXPECT_EQ(node->transform().m(13), georef.y);
      EXPECT_EQ(node->transform().m(14), georef.z);
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
    const auto m = sync::addMeasurement(g, layer, "kyoto", scene::MeasurementPayload::DISTANCE,
                                        pts, 0.4990, 0.0003);
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
    const auto sel = g.add(scene::SceneNode::SELECTION, sync::layerGroup(g, "selections", ""),
                           "selection 1");
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
}  // namespace tessera::master
