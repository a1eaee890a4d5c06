// Loading wall configurations and scene files (JSON through protobuf's JSON mapping) with checks: a
// bad file gives a ConfigError naming the file and the field, never a half-usable config.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

#include "tessera/config.pb.h"
#include "tessera/scene.pb.h"

namespace tessera::sync {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Reads and validates a wall: at least one tile, unique names, positive sizes and pixel
/// counts, the whole wall at most 65536 pixels a side and 2^28 in all at the first tile's pixel
/// density (its screenshot; a room's net of tiles side by side), the eye in front of the wall
/// (z > 0) or, for tiles with planes of their own, in front of every tile; a tile's origin, right
/// and up finite, the axes non-zero and orthogonal (cosine within 1e-4); gamma in (0, 10];
/// 0 < near < far. Fills defaults (near 0.05, far 1000; gamma 0 means 2.2) and makes the projector files
/// (blend PNG, warp PFM, mpcdi) absolute relative to the file's folder; their contents are read
/// by render::loadProjectorMaps(). Only regular files are read (a FIFO would block). Throws
/// ConfigError "sync::loadWallConfig(): FILE: FIELD: what".
config::WallConfig loadWallConfig(const std::filesystem::path& path);
/// Same from JSON text (`name` is used in messages; relative projector files are taken from
/// `base_dir`, or left as they are when it is empty).
config::WallConfig parseWallConfig(const std::string& json, const std::string& name,
                                   const std::filesystem::path& base_dir = {});

/// Reads and validates a scene file (scene.proto SceneFile: the scene schema in JSON): a camera
/// whose eye differs from its target and whose up is not along the view; nodes with a kind,
/// unique ids (0: assigned), parents that exist and no cycle, every field as the scene graph
/// checks it (sync::SceneGraph::apply()); MODEL nodes with a store path, made absolute relative
/// to the file's folder. Throws ConfigError "sync::loadSceneFile(): FILE: FIELD: what".
scene::SceneFile loadSceneFile(const std::filesystem::path& path);
scene::SceneFile parseSceneFile(const std::string& json, const std::string& name,
                                const std::filesystem::path& base_dir = {});

}  // namespace tessera::sync
