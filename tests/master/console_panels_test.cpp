// The console's panels: first what they do with notes, without a window
// (console_notes.h); then a real tessera-master --console --annotations on a virtual X server,
// driven with xdotool as an operator's mouse and keys would: the Models panel's slider fades the
// bunny, "Add note" and a click on the bunny open the form, the title typed and Enter store the
// note in the SQLite file, O over it opens it on the wall, an edit is saved and a stale one
// refused, a malformed search is answered, and the note's layer's checkbox hides the layer in
// the database.
#include <gtest/gtest.h>

#include <csignal>
#include <regex>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <tessera/annotate/annotation_db.h>
#include <tessera/annotate/annotation_scene.h>
#include <tessera/interact/console_notes.h>
#include <tessera/render/clip_planes.h>
#include <tessera/render/image.h>
#include <tessera/render/scene_draw_list.h>

#include "../support/site_scripts.h"
#include "../support/small_wall.h"
#include "../support/temp_dir.h"
#include "../support/virtual_display.h"

namespace {

namespace fs = std::filesystem;
using namespace tessera::annotate;
using namespace tessera::interact;
using tessera::sync::SceneGraph;
using tessera::test::Process;

NoteDraft draftAt(glm::dvec3 at) {
  NoteDraft d;
  d.position = at;
  d.model = "bunny";
  d.title = "crack";
  d.view.eye = at + glm::dvec3(0, 0, 2);
  d.view.target = at;
  return d;
}

TEST(ConsoleNotes, ADraftBecomesAPointOrAHotSpotWithTheItemOfItsKind) {
  NoteDraft d = draftAt({1, 2, 3});
  auto [place, item] = noteOf(d);
  EXPECT_EQ(place.kind, PlaceKind::kPoint);
  EXPECT_FALSE(place.view);
  EXPECT_EQ(item.kind, ItemKind::kText);
  EXPECT_EQ(item.layer, "notes");

  d.number = 4.5;
  d.unit = "cm";
  d.radius = 0.1;
  std::tie(place, item) = noteOf(d);
  EXPECT_EQ(place.kind, PlaceKind::kHotSpot);
  ASSERT_TRUE(place.view);
  EXPECT_EQ(place.view->eye, glm::dvec3(1, 2, 5));
  EXPECT_EQ(item.kind, ItemKind::kNumber);
  EXPECT_EQ(item.number, 4.5);

  d.link = "https://example.org/report.pdf";  // a link wins over the number
  EXPECT_EQ(noteOf(d).second.kind, ItemKind::kLink);

  d.title.clear();
  try {
    (void)noteOf(d);
    FAIL() << "a note without title and text";
  } catch (const AnnotationError& e) {
    EXPECT_EQ(e.kind(), AnnotationError::Kind::kBadInput);
  }
}

// K's section: a plane through the point under the cursor, facing the view; what is nearer
// than the point is cut away on every view (render::ClipPlanes, the renderer's rule), what is at
// or beyond it kept, whatever the camera's distance to the model.
TEST(ConsoleNotes, ASectionCutsAwayWhatIsNearerThanThePointFacingTheView) {
  tessera::sync::SceneGraph graph;
  tessera::config::Camera camera;
  camera.mutable_eye()->set_x(3.0);
  camera.mutable_eye()->set_y(1.0);
  camera.mutable_eye()->set_z(5.0);
  camera.mutable_up()->set_y(1.0);  // looking at the origin
  const glm::dvec3 at(0.5, -0.2, 0.25);
  const auto id = addSectionClip(graph, at, camera, "console");
  const auto& n = graph.node(id);
  ASSERT_EQ(n.kind(), tessera::scene::SceneNode::CLIP);
  EXPECT_EQ(n.author(), "console");
  EXPECT_EQ(graph.node(n.parent()).name(), "clips");
  // The plane, placed by the node's transform, through the CPU rule the renderer follows.
  const tessera::render::NodePlacement placed = tessera::render::placeNode(graph, id);
  const auto& c = n.clip();
  ASSERT_EQ(c.planes_size(), 4);
  const glm::dvec4 local(c.planes(0), c.planes(1), c.planes(2), c.planes(3));
  // A plane a x + d >= 0 in the node frame is (a, d) * inverse(world) in the world frame.
  const glm::dvec4 world_plane = local * glm::inverse(placed.world);
  tessera::render::ClipPlanes cut;
  ASSERT_TRUE(cut.addGroup(std::span(&world_plane, 1), false));
  const glm::dvec3 eye(3.0, 1.0, 5.0), forward = glm::normalize(-eye);
  EXPECT_TRUE(cut.keeps(at + 1e-6 * forward));
  EXPECT_TRUE(cut.keeps(at + 0.3 * forward));
  EXPECT_FALSE(cut.keeps(at - 0.01 * forward)) << "nearer than the point: cut away";
  EXPECT_FALSE(cut.keeps(eye * 0.5));
  // Sideways along the plane the cut is the same: the plane faces the view.
  const glm::dvec3 side = glm::normalize(glm::cross(forward, glm::dvec3(0, 1, 0)));
  EXPECT_TRUE(cut.keeps(at + 0.7 * side + 1e-6 * forward));
  EXPECT_FALSE(cut.keeps(at + 0.7 * side - 1e-3 * forward));
  EXPECT_NEAR(c.outline(), 0.25 * glm::length(at - eye), 1e-6);
}

TEST(ConsoleNotes, AddedNotesAreFoundNearTheCursorAndFlownTo) {
  tessera::test::TempDir dir;
  SceneGraph g;
  const auto model = g.add(tessera::scene::SceneNode::MODEL, SceneGraph::kRoot, "bunny");
  (void)model;
  AnnotationScene scene(dir.path() / "notes.tadb");
  scene.load(g);
  NoteDraft point = draftAt({1.5, 0, 0});
  const auto [item_a, place_a] = addNote(scene, g, point, "console");
  NoteDraft spot = draftAt({-1.5, 0, 0});
  spot.radius = 0.2;
  spot.view.eye = {-1.5, 1.0, 3.0};
  const auto [item_b, place_b] = addNote(scene, g, spot, "console");
  {
    AnnotationDb db(dir.path() / "notes.tadb", {.read_only = true});
    ASSERT_TRUE(db.item(item_a));
    EXPECT_EQ(db.item(item_a)->title, "crack");
    EXPECT_EQ(db.item(item_a)->author, "console");
    EXPECT_EQ(db.place(place_b)->kind, PlaceKind::kHotSpot);
  }
  ASSERT_EQ(scene.nodesOf(place_a).size(), 1u);
  ASSERT_EQ(scene.nodesOf(place_b).size(), 1u);
  const auto node_a = scene.nodesOf(place_a)[0], node_b = scene.nodesOf(place_b)[0];

  // A 200 x 100 view looking down -z at the origin from z = 2: x = +-1.5 lands left and right.
  tessera::render::ViewSetup view;
  view.width = 200;
  view.height = 100;
  view.view = glm::lookAt(glm::dvec3(0, 0, 2), glm::dvec3(0), glm::dvec3(0, 1, 0));
  view.projection = glm::perspective(glm::radians(60.0), 2.0, 0.1, 10.0);
  const glm::dvec4 clip = view.projection * view.view * glm::dvec4(1.5, 0, 0, 1);
  const glm::dvec2 at_a((clip.x / clip.w + 1) * 100, (1 - clip.y / clip.w) * 50);
  EXPECT_EQ(noteNear(g, view, at_a + glm::dvec2(5, -5), 24.0), std::optional(node_a));
  EXPECT_EQ(noteNear(g, view, glm::dvec2(200 - at_a.x, at_a.y), 24.0), std::optional(node_b));
  EXPECT_FALSE(noteNear(g, view, glm::dvec2(100, 50), 24.0)) << "no note at the middle";
  g.setVisible(g.node(node_a).parent(), false);  // its layer hidden: not picked
  EXPECT_FALSE(noteNear(g, view, at_a, 24.0));

  tessera::config::Camera current;
  current.mutable_eye()->set_z(3.0);
  current.mutable_up()->set_y(1.0);
  // A point: looked at from the current distance and direction.
  const auto fly_a = flyToNote(g, node_a, current);
  EXPECT_NEAR(fly_a.target().x(), 1.5, 1e-9);
  EXPECT_NEAR(fly_a.eye().x(), 1.5, 1e-9);
  EXPECT_NEAR(fly_a.eye().z(), 3.0, 1e-9);
  // A hot spot: its stored view.
  const auto fly_b = flyToNote(g, node_b, current);
  EXPECT_NEAR(fly_b.eye().y(), 1.0, 1e-9);
  EXPECT_NEAR(fly_b.eye().z(), 3.0, 1e-9);
  EXPECT_NEAR(fly_b.target().x(), -1.5, 1e-9);
}

// The panels in a real console. The master runs alone (no render node: its tiles are lost,
// the console renders anyway), holding the camera on the bunny.
class ConsolePanels : public ::testing::Test {
 protected:
  void SetUp() override {
    tessera::test::writeText(dir.path() / "wall.json", tessera::test::smallWallJson());
    const std::string camera = tessera::test::cameraJson({-0.027, 0.11, 0.5}, {-0.027, 0.1, 0.0});
    const std::string bunny = R"("model": {"store": ")" + std::string(TESSERA_DATA_DIR) +
                              R"(/stanford-bunny/scans/bun.conf"})";
    const std::string rest = R"(], "camera": )" + camera +
                             R"(, "settings": {"background": {"r": 0.05, "g": 0.05, "b": 0.08}}})";
    tessera::test::writeText(
        dir.path() / "scene.json",
        R"({"nodes": [{"kind": "MODEL", "name": "bunny", )" + bunny + "}" + rest);
    // The bunny in a group "scans": a layer when there is no database.
    tessera::test::writeText(dir.path() / "grouped.json",
                             R"({"nodes": [{"id": 1, "kind": "GROUP", "name": "scans"},
        {"id": 2, "kind": "MODEL", "name": "bunny", "parent": 1, )" +
                                 bunny + "}" + rest);
    tessera::test::writeText(dir.path() / "hold.json",
                             R"({"name": "hold", "keyframes": [{"time": 0, )" +
                                 camera.substr(1, camera.size() - 2) + R"(}, {"time": 600, )" +
                                 camera.substr(1, camera.size() - 2) + "}]}");
  }

  /// The master alone with its console on `scene`, and `extra` options.
  std::unique_ptr<Process> startMaster(const std::string& scene,
                                       const std::vector<std::string>& extra) {
    std::vector<std::string> argv =
        tessera::test::zmqMaster(TESSERA_MASTER, dir.path() / "wall.json", dir.path() / scene);
    argv.insert(argv.end(), {"--script", (dir.path() / "hold.json").string(), "--join-wait", "0.5",
                             "--max-fps", "20", "--console", "--console-width", "640",
                             "--console-screenshot", (dir.path() / "console.png").string()});
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, dir.path() / "master.log");
  }

  tessera::test::TempDir dir;
};

// Where the panels are in the 640 x 366 console (console_panels.cpp: fixed positions, DejaVu
// Sans 14 px): the Models panel's first row at the top left (its slider from x 72 to 250), the
// Layers panel's first checkbox at the bottom left (the panel at 0.64 of the height), the Notes
// panel's "Add note" and search field at the top right.
constexpr int kSliderY = 46;
constexpr int kLayerX = 26, kLayerY = 272;
constexpr int kGroupLayerY = 304;  // without a database, below the panel's note
constexpr int kAddNoteX = 367, kAddNoteY = 37, kSearchX = 450, kSearchY = 61;
// The new note's items under the list: its "edit" button, then in edit mode the title field
// (its text ends before x 495) and "save".
constexpr int kEditX = 352, kEditY = 271, kTitleEndX = 495, kTitleY = 238, kSaveX = 355,
              kSaveY = 303;

TEST_F(ConsolePanels, TheSliderFadesAModelAndANoteTypedInIsStored) {
  using tessera::test::VirtualDisplay;
  if (!VirtualDisplay::available())
    GTEST_SKIP() << "needs Xvfb and xdotool (scripts/deps.sh installs them)";
  const VirtualDisplay xdo(dir.path() / "xvfb.log");
  auto master = startMaster("scene.json", {"--annotations", (dir.path() / "notes.tadb").string()});
  ASSERT_TRUE(master->waitFor("console open", 120)) << master->output();
  const std::string wid = xdo.window("tessera-master");
  ASSERT_FALSE(wid.empty()) << "no console window on " << xdo.name;
  ASSERT_TRUE(master->waitFor("0 of 4 tiles have a node", 60)) << master->output();
  std::this_thread::sleep_for(std::chrono::seconds(2));  // the console's first frames

  // (a) A click near the slider's left end: the bunny nearly transparent.
  xdo("mousemove --window " + wid + " 90 " + std::to_string(kSliderY) + " click 1");
  ASSERT_TRUE(master->waitFor("console: model bunny: opacity 0\\.[0-2]\\d", 30))
      << master->output();

  // (b) Add note, a click on the bunny, the title typed (the field has the keyboard), Enter.
  xdo("mousemove --window " + wid + " " + std::to_string(kAddNoteX) + " " +
      std::to_string(kAddNoteY) + " click 1");
  ASSERT_TRUE(master->waitFor("console: add note: click on the model", 30)) << master->output();
  xdo("mousemove --window " + wid + " 280 230 click 1");  // the bunny's body
  ASSERT_TRUE(master->waitFor("console: note at \\S+ \\S+ \\S+ on model bunny", 30))
      << master->output();
  xdo.typeAndEnter(wid, "Measure its crack");  // the form has the keyboard
  ASSERT_TRUE(master->waitFor("console: note (\\d+) added \\(item (\\d+), layer notes\\)", 30))
      << master->output();
  std::smatch m;
  const std::string log = master->output();
  ASSERT_TRUE(std::regex_search(log, m, std::regex("note (\\d+) added \\(item (\\d+)")));
  const int64_t place = std::stoll(m[1].str()), item = std::stoll(m[2].str());

  // O with the cursor on the note (placed where the bunny was clicked) opens it on the wall.
  xdo("mousemove --window " + wid + " 282 228");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  xdo("key --window " + wid + " o");
  ASSERT_TRUE(master->waitFor("console: opened note " + std::to_string(place) + " on the wall", 30))
      << master->output();

  // (c) Edited in the panel: "edit", the end of the title clicked, typed at, "save".
  auto click = [&](int x, int y) {
    xdo("mousemove --window " + wid + " " + std::to_string(x) + " " + std::to_string(y) +
        " click 1");
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // a frame or more
  };
  click(kEditX, kEditY);
  click(kTitleEndX, kTitleY);
  xdo("type --window " + wid + " --delay 60 ' wide'");
  click(kSaveX, kSaveY);
  ASSERT_TRUE(
      master->waitFor("console: item " + std::to_string(item) + " saved \\(revision 2\\)", 30))
      << master->output();
  // An edit begun on revision 2 while another writer (a site, a tool) makes revision 3: saving
  // it is refused and said, nothing overwritten.
  click(kEditX, kEditY);
  {
    AnnotationDb other(dir.path() / "notes.tadb");
    Item changed = *other.item(item);
    changed.text = "changed meanwhile";
    ASSERT_EQ(other.updateItem(changed, 2, "kyoto"), 3);
  }
  click(kSaveX, kSaveY);
  ASSERT_TRUE(master->waitFor("console: not saved, changed meanwhile", 30)) << master->output();

  // (d) A malformed search typed into the search field: the reason said, the session goes on.
  xdo("mousemove --window " + wid + " " + std::to_string(kSearchX) + " " +
      std::to_string(kSearchY) + " click 1");
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // the field takes the keyboard
  xdo("type --window " + wid + " --delay 60 '\"crack'");
  ASSERT_TRUE(master->waitFor("console: search: AnnotationDb: .*", 30)) << master->output();

  // (e) Its layer, now in the Layers panel, hidden there: stored in the database.
  xdo("mousemove --window " + wid + " " + std::to_string(kLayerX) + " " + std::to_string(kLayerY) +
      " click 1");
  ASSERT_TRUE(master->waitFor("console: layer notes hidden", 30)) << master->output();

  master->signal(SIGTERM);
  ASSERT_EQ(master->wait(60), std::optional<int>(0)) << master->output();
  // Nothing typed reached the view's keys (M, S, H ... are in the title).
  EXPECT_EQ(log.find("console: measuring"), std::string::npos) << log;
  EXPECT_EQ(log.find("console: lasso"), std::string::npos) << log;

  // The note in the SQLite file, by another connection, on the bunny near the click.
  AnnotationDb db(dir.path() / "notes.tadb", {.read_only = true});
  const auto stored = db.item(item);
  ASSERT_TRUE(stored) << "item " << item;
  EXPECT_EQ(stored->title, "Measure its crack wide");
  EXPECT_EQ(stored->text, "changed meanwhile");
  EXPECT_EQ(stored->revision, 3);
  EXPECT_EQ(stored->author, "kyoto");
  EXPECT_EQ(stored->layer, "notes");
  const auto at = db.place(place);
  ASSERT_TRUE(at);
  EXPECT_EQ(at->model, "bunny");
  EXPECT_EQ(at->kind, PlaceKind::kPoint);
  EXPECT_LT(glm::length(at->position - glm::dvec3(-0.027, 0.1, 0.0)), 0.12) << "on the bunny";
  EXPECT_EQ(db.itemsAt(place), std::vector<int64_t>{item});
  EXPECT_EQ(db.layers(), (std::vector<Layer>{{"notes", false}}));

  // The console's last picture shows the panels: the slider's blue frame at the top left.
  const tessera::render::Image shot = tessera::render::readPng(dir.path() / "console.png");
  ASSERT_EQ(shot.width, 640u);
  const uint8_t* frame = &shot.rgba[(size_t(kSliderY - 6) * shot.width + 220) * 4];
  EXPECT_GT(int(frame[2]), int(frame[0]) + 40) << dir.path() / "console.png";
}

// The Shading panel, folded at the bottom right: opened by its arrow, its relative depth switch
// colours the wall's picture; the keys T and G switch contour lines and ambient occlusion.
constexpr int kShadingArrowX = 393, kShadingArrowY = 348;   // the folded panel's title bar
constexpr int kShadingCheckX = 399, kRelativeDepthY = 316;  // opened: its second-last switch

TEST_F(ConsolePanels, TheShadingPanelAndKeysSwitchTheWallsFilters) {
  using tessera::test::VirtualDisplay;
  if (!VirtualDisplay::available())
    GTEST_SKIP() << "needs Xvfb and xdotool (scripts/deps.sh installs them)";
  const VirtualDisplay xdo(dir.path() / "xvfb.log");
  auto master = startMaster("scene.json", {});
  ASSERT_TRUE(master->waitFor("console open", 120)) << master->output();
  const std::string wid = xdo.window("tessera-master");
  ASSERT_FALSE(wid.empty()) << "no console window on " << xdo.name;
  ASSERT_TRUE(master->waitFor("0 of 4 tiles have a node", 60)) << master->output();
  std::this_thread::sleep_for(std::chrono::seconds(2));
  xdo("mousemove --window " + wid + " " + std::to_string(kShadingArrowX) + " " +
      std::to_string(kShadingArrowY) + " click 1");
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  xdo("mousemove --window " + wid + " " + std::to_string(kShadingCheckX) + " " +
      std::to_string(kRelativeDepthY) + " click 1");
  ASSERT_TRUE(master->waitFor("console: relative depth on", 30)) << master->output();
  xdo("mousemove --window " + wid + " 320 150");  // off the panels, over the bunny
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  xdo("key --window " + wid + " t");
  ASSERT_TRUE(master->waitFor("console: contour lines every", 30)) << master->output();
  xdo("key --window " + wid + " g");
  ASSERT_TRUE(master->waitFor("console: ambient occlusion on", 30)) << master->output();
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  master->signal(SIGTERM);
  ASSERT_EQ(master->wait(60), std::optional<int>(0)) << master->output();
  // The bunny in the relative depth's colour map (viridis: blue, green and yellow, never grey):
  // the middle of the view has coloured pixels where it was grey.
  const tessera::render::Image shot = tessera::render::readPng(dir.path() / "console.png");
  int coloured = 0;
  for (uint32_t y = 100; y < 260; y += 4)
    for (uint32_t x = 240; x < 360; x += 4) {
      const uint8_t* p = &shot.rgba[(size_t(y) * shot.width + x) * 4];
      coloured += std::abs(int(p[2]) - int(p[0])) > 30 || std::abs(int(p[1]) - int(p[0])) > 30;
    }
  EXPECT_GT(coloured, 100) << dir.path() / "console.png";
}

// The View panel, left of Shading (folded until its title bar is clicked), on a wall with a
// foveal inset: rows from the bottom, 23 px apart: the inset's y and x sliders, its switch, the
// eye separation, the head's turn; above the head's fields, the points a pixel.
constexpr int kViewArrowX = 135, kViewArrowY = 348;
constexpr int kViewCheckX = 141, kInsetSwitchY = 293, kInsetXSliderY = 316, kHeadTurnY = 247;
constexpr int kPointsPerPixelY = 178;

// The View panel switches the inset off and on and moves it, turns the head and sets the points a
// pixel: each through the scene (the same calls as a script's setInset and setHead), said once
// it is done.
TEST_F(ConsolePanels, TheViewPanelSwitchesAndMovesTheInsetTurnsTheHeadAndSetsTheBudget) {
  using tessera::test::VirtualDisplay;
  if (!VirtualDisplay::available())
    GTEST_SKIP() << "needs Xvfb and xdotool (scripts/deps.sh installs them)";
  tessera::test::writeText(
      dir.path() / "wall.json",
      tessera::test::smallWallJson("", R"(, "insets": [{"name": "fovea", "x": 0.37, "y": 0.2,
          "width": 0.24, "height": 0.16, "pixelWidth": 160, "pixelHeight": 100}])"));
  const VirtualDisplay xdo(dir.path() / "xvfb.log");
  auto master = startMaster("scene.json", {});
  ASSERT_TRUE(master->waitFor("console open", 120)) << master->output();
  const std::string wid = xdo.window("tessera-master");
  ASSERT_FALSE(wid.empty()) << "no console window on " << xdo.name;
  ASSERT_TRUE(master->waitFor("0 of 5 tiles have a node", 60)) << master->output();
  std::this_thread::sleep_for(std::chrono::seconds(2));
  auto click = [&](int x, int y) {
    xdo("mousemove --window " + wid + " " + std::to_string(x) + " " + std::to_string(y) +
        " click 1");
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  };
  click(kViewArrowX, kViewArrowY);
  click(kViewCheckX, kInsetSwitchY);
  ASSERT_TRUE(master->waitFor("console: inset fovea switched off", 30)) << master->output();
  click(kViewCheckX, kInsetSwitchY);
  ASSERT_TRUE(master->waitFor("console: inset fovea shown", 30)) << master->output();
  // The x slider's right end: the inset's centre as far right as the wall lets it go.
  click(290, kInsetXSliderY);
  ASSERT_TRUE(master->waitFor("console: inset fovea at \\(0\\.", 30)) << master->output();
  EXPECT_EQ(master->output().find("console: inset fovea at (0.490"), std::string::npos)
      << "the inset did not move from the wall's middle: " << master->output();
  click(290, kHeadTurnY);
  ASSERT_TRUE(master->waitFor("console: head turned", 30)) << master->output();
  EXPECT_EQ(master->output().find("console: head turned 0 degrees"), std::string::npos)
      << master->output();
  // The points a pixel: the slider's right end is the finest budget, its left end every level.
  click(290, kPointsPerPixelY);
  ASSERT_TRUE(master->waitFor("console: [5-8]\\.[0-9] points a covered pixel", 30))
      << master->output();
  click(kViewCheckX - 6, kPointsPerPixelY);
  ASSERT_TRUE(master->waitFor("console: every level the pixels ask for", 30)) << master->output();
  EXPECT_EQ(master->output().find("refused"), std::string::npos) << master->output();
  master->signal(SIGTERM);
  ASSERT_EQ(master->wait(60), std::optional<int>(0)) << master->output();
}

// Without --annotations the Layers panel lists the scene's groups: hiding "scans" there hides
// the bunny in it (the console's last picture shows none of it).
TEST_F(ConsolePanels, WithoutADatabaseTheScenesGroupsAreTheLayers) {
  using tessera::test::VirtualDisplay;
  if (!VirtualDisplay::available())
    GTEST_SKIP() << "needs Xvfb and xdotool (scripts/deps.sh installs them)";
  const VirtualDisplay xdo(dir.path() / "xvfb.log");
  auto master = startMaster("grouped.json", {});
  ASSERT_TRUE(master->waitFor("without --annotations notes are not kept", 120)) << master->output();
  const std::string wid = xdo.window("tessera-master");
  ASSERT_FALSE(wid.empty()) << "no console window on " << xdo.name;
  ASSERT_TRUE(master->waitFor("0 of 4 tiles have a node", 60)) << master->output();
  std::this_thread::sleep_for(std::chrono::seconds(2));
  xdo("mousemove --window " + wid + " " + std::to_string(kLayerX) + " " +
      std::to_string(kGroupLayerY) + " click 1");
  ASSERT_TRUE(master->waitFor("console: layer scans hidden", 30)) << master->output();
  xdo("mousemove --window " + wid + " 320 150");  // off the panels, over where the bunny was
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  master->signal(SIGTERM);
  ASSERT_EQ(master->wait(60), std::optional<int>(0)) << master->output();
  // The middle of the view, where the bunny stood: the background only.
  const tessera::render::Image shot = tessera::render::readPng(dir.path() / "console.png");
  int bright = 0;
  for (uint32_t y = 100; y < 260; y += 4)
    for (uint32_t x = 270; x < 330; x += 4)
      bright += shot.rgba[(size_t(y) * shot.width + x) * 4 + 1] > 60;
  EXPECT_EQ(bright, 0) << dir.path() / "console.png";
}

}  // namespace
