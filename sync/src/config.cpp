#include <tessera/sync/config.h>

#include <cmath>
#include <set>

#include "config_json.h"

namespace tessera::sync {
namespace {

using detail::parseConfigJson;

[[noreturn]] void fail(const char* fn, const std::string& file, const std::string& field,
                       const std::string& what) {
  detail::failConfig(fn, file, field, what);
}

}  // namespace

config::WallConfig parseWallConfig(const std::string& json, const std::string& name) {
  const char* fn = "sync::loadWallConfig()";
  config::WallConfig wall;
  parseConfigJson(json, name, fn, wall);
  if (wall.tiles_size() == 0) fail(fn, name, "tiles", "a wall needs at least one tile");
  std::set<std::string> names;
  for (int i = 0; i < wall.tiles_size(); ++i) {
    config::Tile& t = *wall.mutable_tiles(i);
    const std::string f = "tiles[" + std::to_string(i) + "]";
    if (t.name().empty()) fail(fn, name, f + ".name", "every tile needs a name");
    if (!names.insert(t.name()).second)
      fail(fn, name, f + ".name", "duplicate tile name '" + t.name() + "'");
    if (!(t.width() > 0) || !(t.height() > 0) || !std::isfinite(t.width()) ||
        !std::isfinite(t.height())) {
      fail(fn, name, f, "width and height must be positive (metres)");
    }
    if (!std::isfinite(t.x()) || !std::isfinite(t.y()))
      fail(fn, name, f, "x and y must be finite (metres)");
    if (t.pixel_width() == 0 || t.pixel_height() == 0 || t.pixel_width() > 16384 ||
        t.pixel_height() > 16384) {
      fail(fn, name, f, "pixelWidth and pixelHeight must be 1..16384");
    }
  }
  if (!wall.has_eye() || !detail::finite(wall.eye()) || !(wall.eye().z() > 0)) {
    fail(fn, name, "eye", "the viewer's eye must be in front of the wall (z > 0, metres)");
  }
  if (wall.min_live_tiles() > uint32_t(wall.tiles_size()))
    fail(fn, name, "minLiveTiles",
         "is " + std::to_string(wall.min_live_tiles()) + " but the wall has only " +
             std::to_string(wall.tiles_size()) + " tiles");
  if (wall.near() == 0) wall.set_near(0.05);
  if (wall.far() == 0) wall.set_far(1000.0);
  if (!(wall.near() > 0) || !(wall.far() > wall.near()))
    fail(fn, name, "near/far", "need 0 < near < far");
  return wall;
}

config::WallConfig loadWallConfig(const std::filesystem::path& path) {
  return parseWallConfig(detail::readConfigFile(path, "sync::loadWallConfig()"), path.string());
}

config::SceneConfig parseSceneConfig(const std::string& json, const std::string& name,
                                     const std::filesystem::path& base_dir) {
  const char* fn = "sync::loadSceneConfig()";
  config::SceneConfig scene;
  parseConfigJson(json, name, fn, scene);
  for (int i = 0; i < scene.models_size(); ++i) {
    config::Model& m = *scene.mutable_models(i);
    const std::string f = "models[" + std::to_string(i) + "]";
    if (m.store().empty()) fail(fn, name, f + ".store", "every model needs a store path");
    std::filesystem::path p(m.store());
    if (p.is_relative() && !base_dir.empty())
      m.set_store((base_dir / p).lexically_normal().string());
    if (m.opacity() == 0) m.set_opacity(1.0);
    if (!(m.opacity() > 0 && m.opacity() <= 1)) fail(fn, name, f + ".opacity", "must be in (0, 1]");
    if (m.color_size() != 0 && m.color_size() != 3)
      fail(fn, name, f + ".color", "needs 3 numbers r, g, b in [0, 1]");
    for (double c : m.color())
      if (!(c >= 0 && c <= 1)) fail(fn, name, f + ".color", "components must be in [0, 1]");
    if (m.transform_size() != 0 && m.transform_size() != 16) {
      fail(fn, name, f + ".transform",
           "needs 16 numbers (column-major 4x4), got " + std::to_string(m.transform_size()));
    }
    for (double v : m.transform()) {
      if (!std::isfinite(v)) fail(fn, name, f + ".transform", "numbers must be finite");
    }
  }
  if (!scene.has_camera())
    fail(fn, name, "camera", "a scene needs an initial camera (eye, target, up)");
  detail::checkConfigCamera(scene.camera(), fn, name, "camera");
  if (scene.background_size() == 0) {
    for (int k = 0; k < 3; ++k) scene.add_background(0.0);
  }
  if (scene.background_size() != 3)
    fail(fn, name, "background", "needs 3 numbers (r g b in [0, 1])");
  for (double v : scene.background()) {
    if (!(v >= 0 && v <= 1)) fail(fn, name, "background", "components must be in [0, 1]");
  }
  if (scene.lod_pixels() == 0) scene.set_lod_pixels(1.0);
  if (!(scene.lod_pixels() > 0) || !std::isfinite(scene.lod_pixels()))
    fail(fn, name, "lodPixels", "must be > 0");
  if (scene.shading().empty()) scene.set_shading("color");
  if (scene.shading() != "color" && scene.shading() != "edl") {
    fail(fn, name, "shading", "'" + scene.shading() + "' is not one of color, edl");
  }
  return scene;
}

config::SceneConfig loadSceneConfig(const std::filesystem::path& path) {
  return parseSceneConfig(detail::readConfigFile(path, "sync::loadSceneConfig()"), path.string(),
                          path.parent_path());
}

}  // namespace tessera::sync
