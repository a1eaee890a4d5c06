// The master's console (--console): a GLFW window showing the whole wall at low resolution with
// the nodes' renderer, one-button navigation (one_button_navigation.h) and keys for the models'
// opacity and visibility. Its camera and opacity changes go into the master's scene graph, and
// so to the nodes with the next frame. The window's GL context is current on the master's
// thread for the console's life.
#pragma once

#include <chrono>
#include <memory>
#include <vector>

#include <tessera/master/measure_tool.h>
#include <tessera/master/one_button_navigation.h>
#include <tessera/render/scene_draw_list.h>
#include <tessera/render/scene_overlay.h>
#include <tessera/render/video_textures.h>
#include <tessera/render/view_renderer.h>
#include <tessera/render/window.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::master {

class Console {
 public:
  /// Opens the window, at most `max_width` pixels wide with the wall's aspect. Throws
  /// render::RenderError when there is no display or no GL 4.5.
  Console(const config::WallConfig& wall, uint32_t max_width, float splat_scale);
  ~Console();

  /// Renders the scene as it is now (draw(): never waits for data) and shows it.
  /// One frame of `graph`, after `changes` (what the frame just taken changed).
  void draw(const sync::SceneGraph& graph, const sync::SceneChanges& changes);
  /// The sites' video packets of the frame just taken (cluster.proto FrameMessage.media): the
  /// insets the console shows are decoded as on the nodes (render/video_textures.h).
  /// Call before draw() with the same graph.
  void video(const sync::SceneGraph& graph,
             const google::protobuf::RepeatedPtrField<std::string>& packets);
  /// Writes what the window shows (its framebuffer) as a PNG. Throws render::RenderError.
  void save(const std::string& path) const;
  /// Applies the input since the last call to `graph`: navigation to the camera, keys 1-9 select
  /// a model, + / - change its opacity by 0.1, H toggles its visibility, E toggles eye-dome
  /// lighting; a right-button drag draws a sketch on the model (layer "sketches/console"), U
  /// undoes the newest, C clears them; L makes the console lead the view (a site that led stops
  /// moving it), again gives it back; M cycles the measuring tool (distance, path, angle, area,
  /// off): clicks then pick points on the model instead of navigating, Enter ends a path or an
  /// area, Backspace drops the last point or else the newest measurement (layer
  /// "measurements"); S toggles the lasso: a left drag selects what of the current model it
  /// encloses (layer "selections", tinted on every tile), Backspace removes the newest.
  /// Returns false once the window is closed (or Escape).
  bool handleInput(sync::SceneGraph& graph);

 private:
  render::ViewSetup view(const config::Camera& camera) const;
  /// The scene's overlay (sketches, avatars, annotations) with the navigation's bar and the
  /// target marker on top.
  render::Overlay overlay(const render::Overlay& scene) const;

  config::WallConfig mWall;
  float mSplatScale;
  uint32_t mWidth = 0, mHeight = 0;
  std::unique_ptr<render::Window> mWindow;
  std::unique_ptr<render::ViewRenderer> mRenderer;
  render::SceneDrawList mModels;  // after mRenderer: its stores close once the renderer is gone
  std::span<const render::ModelInstance> mInstances;  // mModels', until its next update
  render::SceneOverlay mSceneOverlay;
  std::unique_ptr<render::VideoTextures> mVideos;  // destroyed with the context current
  render::ViewSetup mLastView;
  OneButtonNavigation mNavigation;
  size_t mSelected = 0;           // index among the MODEL nodes
  std::vector<glm::dvec2> mDrag;  // the right-button drag's pixels so far
  bool mRightHeld = false;
  std::vector<sync::SceneGraph::NodeId> mSketches;  // the console's, oldest first
  MeasureTool mTool;
  glm::dvec2 mPressAt{0.0};  // where the left button went down (a click measures)
  std::vector<sync::SceneGraph::NodeId> mMeasurements;  // the console's, oldest first
  bool mLassoing = false;              // S: left drags draw a lasso
  std::vector<glm::dvec2> mLasso;      // its pixels so far
  std::vector<sync::SceneGraph::NodeId> mSelections;  // the console's, oldest first
  std::chrono::steady_clock::time_point mLastInput = std::chrono::steady_clock::now();
};

}  // namespace tessera::master
