#include <tessera/master/script_player.h>

#include <tessera/sync/camera_path.h>

namespace tessera::master {

std::vector<std::string> ScriptPlayer::advance(sync::SceneGraph& graph, double t) {
  graph.setCamera(sync::cameraAt(mPath, t));
  std::vector<std::string> screenshots;
  // Model names were checked against the scene when the script was loaded; a model the
  // console deleted since is skipped.
  for (const config::PathAction& a : sync::actionsIn(mPath, mLast, t)) {
    if (a.has_set_opacity()) {
      if (auto id = graph.findByName(a.set_opacity().model()))
        graph.setOpacity(*id, float(a.set_opacity().opacity()));
    } else if (a.has_set_visible()) {
      if (auto id = graph.findByName(a.set_visible().model()))
        graph.setVisible(*id, a.set_visible().visible());
    } else if (a.has_set_shading()) {
      graph.setShading(a.set_shading() == "edl" ? scene::SHADING_EDL : scene::SHADING_COLOR);
    } else if (a.has_set_analysis()) {
      graph.setAnalysis(a.set_analysis());
    } else if (a.has_set_inset()) {
      // Checked against the wall when the script was loaded (render::checkPathInsets()).
      graph.setInset(a.set_inset());
    } else if (a.has_set_head()) {
      // Checked against the wall when the script was loaded (sync::pathHeadProblem()).
      graph.setHead(a.set_head());
    } else if (a.has_screenshot()) {
      screenshots.push_back(a.screenshot());
    }
  }
  mLast = t;
  return screenshots;
}

}  // namespace tessera::master
