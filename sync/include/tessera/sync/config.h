// Loading wall and scene configurations (JSON through protobuf's JSON mapping) with checks: a bad
// file gives a ConfigError naming the file and the field, never a half-usable config.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

#include "tessera/config.pb.h"

namespace tessera::sync {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Reads and validates a wall: at least one tile, unique names, positive sizes and pixel
/// counts, the eye in front of the wall (z > 0), 0 < near < far. Fills defaults (near 0.05,
/// far 1000). Throws ConfigError "sync::loadWallConfig(): FILE: FIELD: what".
config::WallConfig loadWallConfig(const std::filesystem::path& path);
/// Same from JSON text (`name` is used in messages).
config::WallConfig parseWallConfig(const std::string& json, const std::string& name);

/// Reads and validates a scene: models with a store path, opacity in (0, 1], transforms of 16
/// numbers, a camera whose eye differs from its target and whose up is not along the view,
/// background of 3 numbers in [0, 1], lod_pixels > 0. Store paths are made absolute relative to
/// the scene file's folder.
config::SceneConfig loadSceneConfig(const std::filesystem::path& path);
config::SceneConfig parseSceneConfig(const std::string& json, const std::string& name,
                                     const std::filesystem::path& base_dir = {});

}  // namespace tessera::sync
