// Wall and scene configurations: the shipped files load, and bad files name the file and field.
#include <gtest/gtest.h>

#include <tessera/sync/config.h>
#include <tessera/sync/scene_graph.h>
#include <tessera/sync/transform.h>

namespace tessera::sync {
namespace {

const std::string kConfigs = TESSERA_CONFIG_DIR;

std::string errorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(WallConfig, ShippedWallsLoad) {
  auto desktop = loadWallConfig(kConfigs + "/walls/desktop.json");
  ASSERT_EQ(desktop.tiles_size(), 1);
  EXPECT_EQ(desktop.tiles(0).pixel_width(), 1280u);
  auto w22 = loadWallConfig(kConfigs + "/walls/2x2.json");
  ASSERT_EQ(w22.tiles_size(), 4);
  for (const auto& t : w22.tiles()) {
    EXPECT_EQ(t.pixel_width(), 960u);
    EXPECT_EQ(t.pixel_height(), 540u);
  }
  // 2 cm bezels between the columns.
  EXPECT_NEAR(w22.tiles(1).x() - (w22.tiles(0).x() + w22.tiles(0).width()), 0.02, 1e-9);
  EXPECT_EQ(loadWallConfig(kConfigs + "/walls/3x2.json").tiles_size(), 6);
}

TEST(WallConfig, BadFilesNameTheField) {
  auto err = [](const std::string& json) {
    return errorOf([&] { parseWallConfig(json, "w.json"); });
  };
  EXPECT_NE(err("{").find("w.json: not a valid WallConfig"), std::string::npos) << err("{");
  EXPECT_NE(err(R"({"tilez": []})").find("tilez"), std::string::npos) << err(R"({"tilez": []})");
  EXPECT_NE(err(R"({"eye": {"z": 2}})").find("w.json: tiles: a wall needs at least one tile"),
            std::string::npos);
  const std::string tile =
      R"({"name": "a", "width": 1, "height": 1, "pixelWidth": 10, "pixelHeight": 10})";
  EXPECT_NE(err(R"({"tiles": [)" + tile + "," + tile + R"(], "eye": {"z": 2}})")
                .find("tiles[1].name: duplicate"),
            std::string::npos);
  EXPECT_NE(
      err(R"({"tiles": [{"name": "a", "width": 1, "height": 1, "pixelWidth": 0, "pixelHeight": 10}], "eye": {"z": 2}})")
          .find("tiles[0]: pixelWidth and pixelHeight"),
      std::string::npos);
  EXPECT_NE(err(R"({"tiles": [)" + tile + R"(], "eye": {"z": -1}})")
                .find("eye: the viewer's eye must be in front"),
            std::string::npos);
  EXPECT_NE(errorOf([] {
              loadWallConfig("/nonexistent/wall.json");
            }).find("/nonexistent/wall.json: cannot open"),
            std::string::npos);
}

// Passive stereo walls: a node per eye (slots NAME/left, NAME/right) or one for both; their
// checks name the field.
TEST(WallConfig, StereoWallsLoadAndBadOnesNameTheField) {
  const config::WallConfig shipped = loadWallConfig(kConfigs + "/walls/stereo-1x2.json");
  EXPECT_TRUE(shipped.stereo());
  EXPECT_EQ(shipped.eye_separation(), 0.065);
  auto err = [](const std::string& wall) {
    return errorOf([&] { parseWallConfig(wall, "w.json"); });
  };
  auto wall = [](const std::string& name, const std::string& extra) {
    return R"({"tiles": [{"name": ")" + name +
           R"(", "width": 1, "height": 1, "pixelWidth": 10, "pixelHeight": 10)" + extra +
           R"(}], "eye": {"x": 0.5, "y": 0.5, "z": 2}, "stereo": true)";
  };
  EXPECT_EQ(err(wall("a", "") + "}"), "");
  EXPECT_NE(err(wall("a/b", "") + "}").find("w.json: tiles[0].name: 'a/b' holds '/'"),
            std::string::npos);
  EXPECT_NE(err(wall("a", R"(, "blend": "auto")") + "}").find("a stereo wall takes no projector"),
            std::string::npos);
  EXPECT_NE(
      err(wall("a", "") + R"(, "eyeSeparation": 1.5})").find("eyeSeparation: must be in (0, 1]"),
      std::string::npos);
  EXPECT_NE(err(R"({"tiles": [{"name": "a", "width": 1, "height": 1, "pixelWidth": 10,
                "pixelHeight": 10}], "eye": {"z": 2}, "eyesOnOneNode": true})")
                .find("eyesOnOneNode: needs \"stereo\": true"),
            std::string::npos);
  EXPECT_NE(err(R"({"tiles": [{"name": "a", "width": 1, "height": 1, "pixelWidth": 9000,
                "pixelHeight": 10}], "eye": {"z": 2}, "stereo": true, "eyesOnOneNode": true})")
                .find("tiles[0].pixelWidth: at most 8192 with eyesOnOneNode"),
            std::string::npos);
}

TEST(SceneFile, ShippedScenesLoadWithPathsBesideTheFile) {
  const scene::SceneFile bunny = loadSceneFile(kConfigs + "/scenes/bunny.json");
  ASSERT_EQ(bunny.nodes_size(), 1);
  EXPECT_EQ(bunny.nodes(0).id(), 1u) << "ids assigned in file order";
  EXPECT_EQ(bunny.nodes(0).kind(), scene::SceneNode::MODEL);
  EXPECT_NE(bunny.nodes(0).model().store().find("out/demo/stores/bunny.tlod"), std::string::npos);
  EXPECT_TRUE(std::filesystem::path(bunny.nodes(0).model().store()).is_absolute());
  EXPECT_EQ(bunny.settings().shading(), scene::SHADING_EDL);
  EXPECT_EQ(loadSceneFile(kConfigs + "/scenes/autzen.json").settings().lod_pixels(), 1.0f);
  EXPECT_EQ(loadSceneFile(kConfigs + "/scenes/bunny-fused.json").nodes_size(), 2);
  // A clip plane through the scene file's JSON mapping, checked as the wire's.
  const scene::SceneFile clip = loadSceneFile(kConfigs + "/scenes/bunny-clip.json");
  ASSERT_EQ(clip.nodes_size(), 6);
  EXPECT_EQ(clip.nodes(2).kind(), scene::SceneNode::CLIP);
  EXPECT_EQ(clip.nodes(2).clip().planes_size(), 4);
  EXPECT_EQ(clip.nodes(2).clip().planes(0), -1.0);
  const SceneGraph g = SceneGraph::fromFile(clip);
  EXPECT_EQ(g.node(3).clip().models_size(), 1);
  EXPECT_EQ(g.node(3).clip().models(0), 2u);  // the scans' MODEL node
  EXPECT_EQ(g.node(12).clip().outline(), 0.09f);
}

TEST(SceneFile, EveryNodeKindAndGroupsLoad) {
  const scene::SceneFile f = parseSceneFile(R"({"camera": {"eye": {"z": 1}, "target": {},
      "up": {"y": 1}}, "nodes": [
        {"id": 5, "kind": "GROUP", "name": "site", "transform": {"m": [1,0,0,0, 0,1,0,0,
         0,0,1,0, 2,0,0,1]}},
        {"kind": "MODEL", "parent": 5, "model": {"store": "a.tlod"}, "opacity": 0.5},
        {"kind": "ANNOTATION", "parent": 5, "annotation": {"text": "crack", "anchor": {"x": 1},
         "layer": "survey/2026"}},
        {"kind": "SKETCH", "sketch": {"points": [0, 0, 0, 1, 1, 1], "width": 2},
         "transform": {"translation": [636590, 847900, 3], "rotation": [0, 0, 0, 1]}}]})",
                                            "s.json", "/data");
  ASSERT_EQ(f.nodes_size(), 4);
  EXPECT_EQ(f.nodes(1).id(), 6u);
  EXPECT_EQ(f.nodes(1).model().store(), "/data/a.tlod");
  const SceneGraph g = SceneGraph::fromFile(f);
  EXPECT_EQ(g.size(), 4u);
  EXPECT_EQ(g.node(6).parent(), 5u);
  EXPECT_EQ(g.node(7).annotation().text(), "crack");
  EXPECT_EQ(g.node(6).opacity(), 0.5f);
  // A transform in the rigid form (sync/transform.h): a half turn about z, then the translation.
  EXPECT_EQ(transformMatrix(g.node(8).transform()),
            glm::dmat4(-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 0, 636590, 847900, 3, 1));
}

TEST(SceneFile, BadScenesNameTheField) {
  auto err = [](const std::string& json) {
    return errorOf([&] { parseSceneFile(json, "s.json"); });
  };
  const std::string cam = R"("camera": {"eye": {"z": 1}, "target": {}, "up": {"y": 1}})";
  auto model = [&](const std::string& fields) {
    return R"({"nodes": [{"kind": "MODEL", "model": {"store": "a.tlod"})" + fields + "}], " + cam +
           "}";
  };
  EXPECT_NE(err(model(R"(, "opacity": 1.5)")).find("s.json: nodes[0] (node 1): opacity"),
            std::string::npos)
      << err(model(R"(, "opacity": 1.5)"));
  EXPECT_NE(err(model(R"(, "opacity": "NaN")")).find("nodes[0] (node 1): opacity"),
            std::string::npos);
  EXPECT_NE(err(model(R"(, "transform": {"m": [1, 2]})")).find("nodes[0] (node 1): transform"),
            std::string::npos);
  EXPECT_NE(err(model(R"(, "transform": {"translation": [1, 2, 3], "rotation": [2, 0, 0, 0]})"))
                .find("nodes[0] (node 1): transform: rotation must be a unit quaternion"),
            std::string::npos);
  EXPECT_NE(err(model(R"(, "parent": 9)")).find("s.json: node 1: parent 9 does not exist"),
            std::string::npos);
  EXPECT_NE(err(R"({"nodes": [{"kind": "MODEL"}], )" + cam + "}").find("nodes[0].model.store"),
            std::string::npos);
  EXPECT_NE(err(R"({"nodes": [{"name": "x"}], )" + cam + "}").find("nodes[0].kind"),
            std::string::npos);
  EXPECT_NE(
      err(R"({"nodes": [{"id": 2, "kind": "GROUP"}, {"id": 2, "kind": "GROUP"}], )" + cam + "}")
          .find("twice"),
      std::string::npos);
  EXPECT_NE(err(R"({"nodes": [{"id": 1, "kind": "GROUP", "parent": 2}, {"id": 2, "kind":
                "GROUP", "parent": 1}], )" +
                cam + "}")
                .find("cycle"),
            std::string::npos);
  EXPECT_NE(err(R"({"camera": {"eye": {"z": 1}, "target": {}, "up": {"z": 1}}})").find("camera.up"),
            std::string::npos);
  EXPECT_NE(err("{" + cam + R"(, "settings": {"shading": "toon"}})").find("s.json"),
            std::string::npos);
  EXPECT_NE(err("{" + cam + R"(, "settings": {"background": {"r": 2}}})").find("background"),
            std::string::npos);
  EXPECT_NE(err(R"({"models": []})").find("not a valid SceneFile"), std::string::npos);
  EXPECT_NE(err("{}").find("camera: a scene needs an initial camera"), std::string::npos);
}

// A zero or 1e300 model transform gave a blank picture while reporting points drawn.
TEST(SceneFile, DegenerateTransformsAreRefusedWhenRead) {
  auto err = [](const std::string& m) {
    return errorOf([&] {
      parseSceneFile(
          R"({"nodes": [{"kind": "MODEL", "model": {"store": "a.tlod"}, "transform": {"m": [)" + m +
              R"(]}}], "camera": {"eye": {"z": 1}, "target": {}, "up": {"y": 1}}})",
          "s.json");
    });
  };
  const std::string zero = "0,0,0,0, 0,0,0,0, 0,0,0,0, 0,0,0,1";
  EXPECT_NE(err(zero).find("s.json: nodes[0] (node 1): transform: singular"), std::string::npos)
      << err(zero);
  const std::string huge = "1e300,0,0,0, 0,1e300,0,0, 0,0,1e300,0, 0,0,0,1";
  EXPECT_NE(err(huge).find("transform: 1e+300 is beyond"), std::string::npos) << err(huge);
  const std::string flat = "1,0,0,0, 0,1,0,0, 0,0,0,0, 0,0,0,1";  // squashed onto a plane
  EXPECT_NE(err(flat).find("singular"), std::string::npos) << err(flat);
  const std::string projective = "1,0,0,0.5, 0,1,0,0, 0,0,1,0, 0,0,0,1";
  EXPECT_NE(err(projective).find("affine"), std::string::npos) << err(projective);
  // Still fine: a small uniform scale (millimetres to metres), a rotation, a georeferenced move.
  EXPECT_EQ(err("0.001,0,0,0, 0,0.001,0,0, 0,0,0.001,0, 636590,847900,10,1"), "");
  EXPECT_EQ(err("0,1,0,0, -1,0,0,0, 0,0,1,0, 0,0,0,1"), "");
}

TEST(SceneFile, SettingsLimitsAreCheckedWhenRead) {
  // A scene of these settings and a camera.
  auto scene = [](const std::string& settings) {
    return R"({"settings": )" + settings +
           R"(, "camera": {"eye": {"z": 1}, "target": {}, "up": {"y": 1}}})";
  };
  const std::string e =
      errorOf([&] { parseSceneFile(scene(R"({"spbrEnsembles": 100000})"), "s.json"); });
  EXPECT_NE(e.find("s.json"), std::string::npos) << e;
  EXPECT_NE(e.find("spbr_ensembles"), std::string::npos) << e;
  const std::string b =
      errorOf([&] { parseSceneFile(scene(R"({"pointsPerPixel": -2})"), "b.json"); });
  EXPECT_NE(b.find("b.json"), std::string::npos) << b;
  EXPECT_NE(b.find("settings.points_per_pixel"), std::string::npos) << b;
  EXPECT_EQ(
      parseSceneFile(scene(R"({"pointsPerPixel": 0})"), "z.json").settings().points_per_pixel(),
      0.0f);
}

// Tiles 100 km apart made --mosaic and the master's screenshot die of std::bad_alloc
// (at 1 km they allocated 4 to 9 GB and wrote a 0-byte PNG).
TEST(WallConfig, AWallTooLargeToPictureIsRefusedWhenRead) {
  auto wall = [](double x) {
    return R"({"tiles": [{"name": "a", "width": 0.5, "height": 0.3, "pixelWidth": 960,
               "pixelHeight": 540}, {"name": "b", "x": )" +
           std::to_string(x) + R"(, "width": 0.5, "height": 0.3, "pixelWidth": 960,
               "pixelHeight": 540}], "eye": {"z": 2}})";
  };
  for (double x : {100000.0, 1000.0, 40.0}) {
    const std::string e = errorOf([&] { parseWallConfig(wall(x), "w.json"); });
    EXPECT_NE(e.find("w.json: tiles: the tiles span"), std::string::npos) << x << ": " << e;
    EXPECT_NE(e.find("at most 65536 pixels a side"), std::string::npos) << e;
  }
  EXPECT_NO_THROW(parseWallConfig(wall(0.52), "w.json"));
  EXPECT_NO_THROW(parseWallConfig(wall(10.0), "w.json"));  // 20160 pixels wide
}

}  // namespace
}  // namespace tessera::sync
