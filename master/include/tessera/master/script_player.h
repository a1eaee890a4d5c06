// Plays a camera path (sync/camera_path.h, configs/paths/*.json) into the master's scene graph:
// the camera at each moment and the timed actions, each exactly once.
#pragma once

#include <string>
#include <vector>

#include <tessera/camera_path.pb.h>
#include <tessera/sync/camera_path.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::master {

class ScriptPlayer {
 public:
  /// `path` validated by sync::loadCameraPath and checked against the scene's model names
  /// (sync::checkPathModels).
  explicit ScriptPlayer(config::CameraPath path) : mPath(std::move(path)) {}

  /// Moves the graph's camera to the path at `t` seconds and applies the actions with
  /// previous t < time <= t (all up to t on the first call): setOpacity and setVisible on the
  /// first model node with that name, setShading on the wall settings. Returns the paths of the
  /// screenshot actions among them, for the caller to take. Precondition: t does not decrease.
  std::vector<std::string> advance(sync::SceneGraph& graph, double t);

  /// When the last keyframe or action is reached, seconds.
  double duration() const { return sync::pathDuration(mPath); }

 private:
  config::CameraPath mPath;
  double mLast = -1e300;
};

}  // namespace tessera::master
