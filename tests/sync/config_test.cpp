// Wall and scene configurations: the shipped files load, and bad files name the file and field.
#include <gtest/gtest.h>

#include <tessera/sync/config.h>

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

TEST(SceneConfig, ShippedScenesLoadWithPathsBesideTheFile) {
  auto bunny = loadSceneConfig(kConfigs + "/scenes/bunny.json");
  ASSERT_EQ(bunny.models_size(), 1);
  EXPECT_NE(bunny.models(0).store().find("out/demo/stores/bunny.tlod"), std::string::npos);
  EXPECT_TRUE(std::filesystem::path(bunny.models(0).store()).is_absolute());
  EXPECT_EQ(bunny.shading(), "edl");
  EXPECT_EQ(loadSceneConfig(kConfigs + "/scenes/autzen.json").lod_pixels(), 1.0);
}

TEST(SceneConfig, BadScenesNameTheField) {
  auto err = [](const std::string& json) {
    return errorOf([&] { parseSceneConfig(json, "s.json"); });
  };
  const std::string cam = R"("camera": {"eye": {"z": 1}, "target": {}, "up": {"y": 1}})";
  EXPECT_NE(err(R"({"models": [{"store": "a.tlod", "opacity": 1.5}], )" + cam + "}")
                .find("models[0].opacity"),
            std::string::npos);
  EXPECT_NE(err(R"({"models": [{"store": "a.tlod", "color": [1, 0.5]}], )" + cam + "}")
                .find("models[0].color"),
            std::string::npos);
  EXPECT_NE(err(R"({"models": [{"store": "a.tlod", "color": [1, 0.5, 2]}], )" + cam + "}")
                .find("models[0].color"),
            std::string::npos);
  EXPECT_NE(err(R"({"models": [{"store": "a.tlod", "transform": [1, 2]}], )" + cam + "}")
                .find("models[0].transform"),
            std::string::npos);
  EXPECT_NE(err(R"({"models": [{}], )" + cam + "}").find("models[0].store"), std::string::npos);
  EXPECT_NE(err(R"({"camera": {"eye": {"z": 1}, "target": {}, "up": {"z": 1}}})").find("camera.up"),
            std::string::npos);
  EXPECT_NE(err("{" + cam + R"(, "shading": "toon"})").find("shading: 'toon' is not one of"),
            std::string::npos);
  EXPECT_NE(err("{" + cam + R"(, "background": [2, 0, 0]})").find("background"), std::string::npos);
  EXPECT_NE(err("{}").find("camera: a scene needs an initial camera"), std::string::npos);
}

}  // namespace
}  // namespace tessera::sync
