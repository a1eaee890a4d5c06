#include <tessera/sync/config.h>
#include <tessera/sync/scene_graph.h>
#include <tessera/sync/viewer_head.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "config_json.h"

namespace tessera::sync {
namespace {

using detail::parseConfigJson;

/// Bounds of the whole-wall picture (render::wholeWallView()): 2^28 pixels are 1 GiB of RGBA.
constexpr double kMaxWallPixelsPerSide = 65536.0;
constexpr double kMaxWallPixels = double(1u << 28);

[[noreturn]] void fail(const char* fn, const std::string& file, const std::string& field,
                       const std::string& what) {
  detail::failConfig(fn, file, field, what);
}

/// A tile's own plane: finite origin, right and up; the axes non-zero and orthogonal within
/// 1e-4 (as cosines).
void checkTilePlane(const config::Tile& t, const char* fn, const std::string& name,
                    const std::string& f, const config::WallConfig&) {
  if (t.has_origin() && !finite(t.origin()))
    fail(fn, name, f + ".origin", "needs finite x, y and z (metres)");
  for (const auto* axis : {&t.right(), &t.up()}) {
    const bool has = axis == &t.right() ? t.has_right() : t.has_up();
    const std::string field = f + (axis == &t.right() ? ".right" : ".up");
    if (!has) continue;
    if (!finite(*axis)) fail(fn, name, field, "needs finite x, y and z");
    if (!(glm::length(vec(*axis)) > 1e-9)) fail(fn, name, field, "is zero: give a unit axis");
  }
  const glm::dvec3 r = t.has_right() ? glm::normalize(vec(t.right())) : glm::dvec3(1, 0, 0);
  const glm::dvec3 u = t.has_up() ? glm::normalize(vec(t.up())) : glm::dvec3(0, 1, 0);
  const double c = glm::dot(r, u);
  if (!(std::abs(c) <= 1e-4)) {
    char what[160];
    std::snprintf(what, sizeof what,
                  "right and up must be orthogonal (the cosine between them is %.6g, at most "
                  "1e-4)",
                  c);
    fail(fn, name, f + ".up", what);
  }
}

/// The foveal insets: names unique among tiles and insets (no '/', which names an eye's slot),
/// sizes finite and positive, the rectangle inside the wall's extent, pixels 1..16384, eye
/// separation in (0, 1] m, blend band in [0, half the smaller side], the border under half the
/// smaller pixel side. Fills in the defaults (eye separation 0.065 m, band width / 20).
void checkInsets(config::WallConfig& wall, const char* fn, const std::string& name,
                 std::set<std::string>& names, bool room) {
  if (wall.insets_size() == 0) return;
  if (room)
    fail(fn, name, "insets", "foveal insets need a planar wall (no tile with a plane of its own)");
  for (const auto& t : wall.tiles())
    if (!t.blend().empty() || !t.warp().empty() || !wall.mpcdi().empty())
      fail(fn, name, "insets",
           "foveal insets need a wall without projector files (tile '" + t.name() +
               "' has a blend, a warp or the wall an MPCDI file)");
  if (wall.insets_size() > 64) fail(fn, name, "insets", "at most 64");
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const auto& t : wall.tiles()) {
    x0 = std::min(x0, t.x());
    y0 = std::min(y0, t.y());
    x1 = std::max(x1, t.x() + t.width());
    y1 = std::max(y1, t.y() + t.height());
  }
  for (int i = 0; i < wall.insets_size(); ++i) {
    config::Inset& in = *wall.mutable_insets(i);
    const std::string f = "insets[" + std::to_string(i) + "]";
    if (in.name().empty() || in.name().size() > 64)
      fail(fn, name, f + ".name", "every inset needs a name (1..64 bytes)");
    if (in.name().find('/') != std::string::npos)
      fail(fn, name, f + ".name", "'" + in.name() + "' holds '/', which names a stereo eye's slot");
    if (!names.insert(in.name()).second)
      fail(fn, name, f + ".name", "'" + in.name() + "' already names a tile or an inset");
    if (in.stereo() &&
        (!names.insert(in.name() + "/left").second || !names.insert(in.name() + "/right").second))
      fail(fn, name, f + ".name", "'" + in.name() + "/left' or '/right' already names a tile");
    if (!(in.width() > 0) || !(in.height() > 0) || !std::isfinite(in.width()) ||
        !std::isfinite(in.height()))
      fail(fn, name, f, "width and height must be finite and positive (metres)");
    if (!std::isfinite(in.x()) || !std::isfinite(in.y()))
      fail(fn, name, f, "x and y must be finite (metres)");
    if (in.pixel_width() == 0 || in.pixel_height() == 0 || in.pixel_width() > 16384 ||
        in.pixel_height() > 16384)
      fail(fn, name, f, "pixelWidth and pixelHeight must be 1..16384");
    if (!(in.x() >= x0 && in.y() >= y0 && in.x() + in.width() <= x1 &&
          in.y() + in.height() <= y1)) {
      char what[256];
      std::snprintf(what, sizeof what,
                    "the inset [%.6g, %.6g] x [%.6g, %.6g] m must lie inside the wall's extent "
                    "[%.6g, %.6g] x [%.6g, %.6g] m",
                    in.x(), in.x() + in.width(), in.y(), in.y() + in.height(), x0, x1, y0, y1);
      fail(fn, name, f, what);
    }
    if (!in.has_eye_separation()) in.set_eye_separation(0.065);
    if (!(in.eye_separation() > 0 && in.eye_separation() <= 1))
      fail(fn, name, f + ".eyeSeparation", "must be in (0, 1] metres (absent: 0.065)");
    if (!in.has_blend_band()) in.set_blend_band(in.width() / 20.0);
    const double half = 0.5 * std::min(in.width(), in.height());
    if (!(in.blend_band() >= 0 && in.blend_band() <= half))
      fail(fn, name, f + ".blendBand",
           "must be in [0, " + std::to_string(half) +
               "] metres, half the inset's smaller side (absent: a twentieth of its width)");
    if (uint64_t(in.border()) * 2 >= std::min(in.pixel_width(), in.pixel_height()))
      fail(fn, name, f + ".border", "must be under half the inset's smaller pixel side");
  }
}

}  // namespace

config::WallConfig parseWallConfig(const std::string& json, const std::string& name,
                                   const std::filesystem::path& base_dir) {
  const char* fn = "sync::loadWallConfig()";
  config::WallConfig wall;
  parseConfigJson(json, name, fn, wall);
  // Projector files are named relative to the wall file's folder.
  auto resolve = [&](const std::string& file) {
    const std::filesystem::path p(file);
    return p.is_relative() && !base_dir.empty() ? (base_dir / p).lexically_normal().string()
                                                : file;
  };
  if (!wall.mpcdi().empty()) wall.set_mpcdi(resolve(wall.mpcdi()));
  bool room = false;
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
    if (t.has_origin() || t.has_right() || t.has_up()) {
      room = true;
      checkTilePlane(t, fn, name, f, wall);
    }
    if (!std::isfinite(t.gamma()) || t.gamma() < 0 || t.gamma() > 10)
      fail(fn, name, f + ".gamma", "must be in (0, 10] (0 or absent: 2.2)");
    if (t.blend() != "auto" && !t.blend().empty()) t.set_blend(resolve(t.blend()));
    if (!t.warp().empty()) t.set_warp(resolve(t.warp()));
  }
  if (room) {
    // A room's screenshot is its net: the tiles side by side (render::roomNetSize()).
    double w = 0, h = 0;
    for (const auto& t : wall.tiles()) {
      w += t.pixel_width() + 16.0;
      h = std::max(h, double(t.pixel_height()));
    }
    if (!(w <= kMaxWallPixelsPerSide && w * h <= kMaxWallPixels))
      fail(fn, name, "tiles",
           "the room's net (its tiles side by side) would be " + std::to_string(int64_t(w)) +
               " x " + std::to_string(int64_t(h)) + " pixels: at most 65536 a side, 2^28 in all");
  } else {
    // The whole wall as one picture (screenshots, --mosaic, --whole) at the first tile's pixel
    // density: bounded, so tiles far apart are refused here, not by std::bad_alloc later.
    const config::Tile& first = wall.tiles(0);
    double x0 = first.x(), y0 = first.y(), x1 = x0 + first.width(), y1 = y0 + first.height();
    for (const auto& t : wall.tiles()) {
      x0 = std::min(x0, t.x());
      y0 = std::min(y0, t.y());
      x1 = std::max(x1, t.x() + t.width());
      y1 = std::max(y1, t.y() + t.height());
    }
    const double w = (x1 - x0) * first.pixel_width() / first.width();
    const double h = (y1 - y0) * first.pixel_height() / first.height();
    if (!(w <= kMaxWallPixelsPerSide && h <= kMaxWallPixelsPerSide && w * h <= kMaxWallPixels)) {
      char what[256];
      std::snprintf(what, sizeof what,
                    "the tiles span %.6g x %.6g m, %.0f x %.0f pixels at tiles[0]'s density: "
                    "the whole-wall picture may have at most %.0f pixels a side and %.0f in all",
                    x1 - x0, y1 - y0, w, h, kMaxWallPixelsPerSide, kMaxWallPixels);
      fail(fn, name, "tiles", what);
    }
  }
  if (!wall.has_eye() || !finite(wall.eye()))
    fail(fn, name, "eye", "the viewer's eye needs finite x, y and z (metres)");
  if (room) {
    if (const int i = tileNotFacing(wall, vec(wall.eye())); i >= 0)
      fail(fn, name, "eye",
           "the viewer's eye must be in front of tiles[" + std::to_string(i) + "] ('" +
               wall.tiles(i).name() + "'): on the side right x up points to");
  } else if (!(wall.eye().z() > 0)) {
    fail(fn, name, "eye", "the viewer's eye must be in front of the wall (z > 0, metres)");
  }
  if (wall.min_live_tiles() > uint32_t(wall.tiles_size()))
    fail(fn, name, "minLiveTiles",
         "is " + std::to_string(wall.min_live_tiles()) + " but the wall has only " +
             std::to_string(wall.tiles_size()) + " tiles");
  checkInsets(wall, fn, name, names, room);
  if (wall.has_eye_separation() && !(wall.eye_separation() > 0 && wall.eye_separation() <= 1))
    fail(fn, name, "eyeSeparation", "must be in (0, 1] metres (absent: 0.065)");
  if (wall.stereo()) {
    // A node per eye: the slots "<tile>/left" and "<tile>/right" (render::wallSlots()).
    for (int i = 0; i < wall.tiles_size(); ++i) {
      const config::Tile& t = wall.tiles(i);
      const std::string f = "tiles[" + std::to_string(i) + "]";
      if (t.name().find('/') != std::string::npos)
        fail(fn, name, f + ".name",
             "'" + t.name() + "' holds '/', which names a stereo eye's slot on a stereo wall");
      if (!names.insert(t.name() + "/left").second || !names.insert(t.name() + "/right").second)
        fail(fn, name, f + ".name", "'" + t.name() + "/left' or '/right' already names a slot");
      if (!t.blend().empty() || !t.warp().empty())
        fail(fn, name, f, "a stereo wall takes no projector blend or warp");
    }
    if (!wall.mpcdi().empty()) fail(fn, name, "mpcdi", "a stereo wall takes no projector files");
    for (int i = 0; wall.eyes_on_one_node() && i < wall.tiles_size(); ++i)
      if (wall.tiles(i).pixel_width() > 8192)
        fail(fn, name, "tiles[" + std::to_string(i) + "].pixelWidth",
             "at most 8192 with eyesOnOneNode (its node's outputs are twice as wide)");
  } else if (wall.eyes_on_one_node()) {
    fail(fn, name, "eyesOnOneNode", "needs \"stereo\": true");
  }
  if (wall.near() == 0) wall.set_near(0.05);
  if (wall.far() == 0) wall.set_far(1000.0);
  if (!(wall.near() > 0) || !(wall.far() > wall.near()))
    fail(fn, name, "near/far", "need 0 < near < far");
  return wall;
}

config::WallConfig loadWallConfig(const std::filesystem::path& path) {
  return parseWallConfig(detail::readConfigFile(path, "sync::loadWallConfig()"), path.string(),
                         path.parent_path());
}

scene::SceneFile parseSceneFile(const std::string& json, const std::string& name,
                                const std::filesystem::path& base_dir) {
  const char* fn = "sync::loadSceneFile()";
  scene::SceneFile file;
  parseConfigJson(json, name, fn, file);
  if (!file.has_camera())
    fail(fn, name, "camera", "a scene needs an initial camera (eye, target, up)");
  detail::checkConfigCamera(file.camera(), fn, name, "camera");
  uint32_t next = 1;
  for (const scene::SceneNode& n : file.nodes()) next = std::max(next, n.id() + 1);
  for (int i = 0; i < file.nodes_size(); ++i) {
    scene::SceneNode& n = *file.mutable_nodes(i);
    const std::string f = "nodes[" + std::to_string(i) + "]";
    if (!n.has_kind() || n.kind() == scene::SceneNode::KIND_UNSPECIFIED)
      fail(fn, name, f + ".kind", "every node needs a kind (GROUP, MODEL, ANNOTATION, ...)");
    if (n.id() == 0) {
      if (next == 0) fail(fn, name, f + ".id", "no free id left");
      n.set_id(next++);
    }
    if (n.kind() == scene::SceneNode::MODEL) {
      if (n.model().store().empty()) fail(fn, name, f + ".model.store", "a model needs a store");
      const std::filesystem::path p(n.model().store());
      if (p.is_relative() && !base_dir.empty())
        n.mutable_model()->set_store((base_dir / p).lexically_normal().string());
    }
  }
  // Everything else as the scene graph checks a snapshot (ranges, payloads, parents, cycles).
  try {
    (void)SceneGraph::fromFile(file);
  } catch (const SyncError& e) {
    // "sync::SceneGraph::apply(): snapshot at version 0: scene.nodes[i] (node N): field: what",
    // named as the file names it: "nodes[i] (node N): field: what".
    std::string why = e.what();
    const size_t context = why.find("snapshot at version ");
    if (context != std::string::npos) why = why.substr(why.find(": ", context) + 2);
    if (why.rfind("scene.", 0) == 0) why = why.substr(6);
    fail(fn, name, "", why);
  }
  return file;
}

scene::SceneFile loadSceneFile(const std::filesystem::path& path) {
  return parseSceneFile(detail::readConfigFile(path, "sync::loadSceneFile()"), path.string(),
                        path.parent_path());
}

}  // namespace tessera::sync
