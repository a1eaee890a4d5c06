// The master's console (--console): a GLFW window showing the whole wall at low resolution with
// the nodes' renderer, one-button navigation (one_button_navigation.h), keys for the models'
// opacity and visibility, and Dear ImGui panels over the picture (console_panels.cpp: models,
// tools, layers, notes; their logic in console_notes.h). Its camera and opacity changes go into
// the master's scene graph, and so to the nodes with the next frame. The window's GL context is
// current on the master's thread for the console's life.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <tessera/annotate/annotation_scene.h>
#include <tessera/interact/console_notes.h>
#include <tessera/interact/keys.h>
#include <tessera/interact/measure_tool.h>
#include <tessera/interact/one_button_navigation.h>
#include <tessera/master/selection_worker.h>
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
  /// The annotation database the panels show and edit (the master's, annotation_scene.h), or
  /// null: then the Layers panel shows the scene's GROUP nodes and says that notes are not kept.
  /// Not owned; must outlive the console.
  void setAnnotations(annotate::AnnotationScene* annotations) { mAnnotations = annotations; }
  /// Applies the input since the last call to `graph`. First the panels (Models: each model's
  /// visibility and opacity; Tools: the measuring mode, the lasso, the measurements and
  /// selections with a delete button each; Layers: the database's layer tree with visibility;
  /// Notes: search, a note's items, fly to it, open it on the wall, edit, delete, add one at a
  /// point clicked on the model): input the panels take (the mouse over them, the keyboard in a
  /// text field) does nothing else. Then navigation to the camera, keys 1-9 select
  /// a model, + / - change its opacity by 0.1, H toggles its visibility, E toggles eye-dome
  /// lighting; a right-button drag draws a sketch on the model (layer "sketches/console"), U
  /// undoes the newest, C clears them; L makes the console lead the view (a site that led stops
  /// moving it), again gives it back; M cycles the measuring tool (distance, path, angle, area,
  /// off): clicks then pick points on the model instead of navigating, Enter ends a path or an
  /// area, Backspace drops the last point or else the newest measurement (layer
  /// "measurements"); S toggles the lasso: a left drag selects what of the current model it
  /// encloses (layer "selections", tinted on every tile), Backspace removes the newest; N
  /// toggles lazy snapping (snap_tool.h): a left drag strokes what to select, a right drag what
  /// not to (instead of a sketch), Enter selects on a worker thread (the wall does not wait;
  /// with no background stroke, the left stroke around the region is a robust lasso 16 px
  /// wide), Backspace drops the strokes, else the newest snapped selection; K cuts the models
  /// with a plane through the surface under the cursor, facing the view (a section: what is
  /// nearer is cut away on every tile), K again removes it; O opens
  /// or closes the note nearest the cursor (within 24 px) on the wall (with --annotations).
  /// Returns false once the window is closed (or Escape outside a text field).
  bool handleInput(sync::SceneGraph& graph);

 private:
  render::ViewSetup view(const config::Camera& camera) const;
  /// The contour interval T switches on: a round number near a 25th of the largest model.
  double contourInterval() const;
  /// The scene's overlay (sketches, avatars, annotations) with the navigation's bar and the
  /// target marker on top.
  render::Overlay overlay(const render::Overlay& scene) const;
  /// The panels (console_panels.cpp), built between the window's beginUi() and endUi().
  void panels(sync::SceneGraph& graph);
  void modelsPanel(sync::SceneGraph& graph);
  void toolsPanel(sync::SceneGraph& graph);
  void layersPanel(sync::SceneGraph& graph);
  void notesPanel(sync::SceneGraph& graph);
  /// Shading: eye-dome lighting, ambient occlusion, relative depth and contour lines with their
  /// parameters, at the bottom right, folded until opened.
  void shadingPanel(sync::SceneGraph& graph);
  /// View: the viewer's head (eye point, turn, eye separation) and each foveal inset's centre
  /// and switch (interact/wall_view.h), at the bottom beside Shading, folded until opened.
  void viewPanel(sync::SceneGraph& graph);
  /// A shading edit (a key, the Shading panel) applied to the scene and said.
  void applyShading(sync::SceneGraph& graph, const interact::SettingsEdit& edit);
  void noteForm(sync::SceneGraph& graph);
  void shownNote(sync::SceneGraph& graph);
  /// A line on stdout ("tessera-master: console: ...") and in the panels.
  void say(const std::string& text);
  /// A measurement made by `make` (said with its label), or refused (said why): the console
  /// goes on whatever a click or a store does.
  void measured(const std::function<std::optional<sync::SceneGraph::NodeId>()>& make);

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
  interact::OneButtonNavigation mNavigation;
  size_t mSelected = 0;           // index among the MODEL nodes
  std::vector<glm::dvec2> mDrag;  // the right-button drag's pixels so far
  bool mRightHeld = false;
  std::vector<sync::SceneGraph::NodeId> mSketches;  // the console's, oldest first
  interact::MeasureTool mTool;
  glm::dvec2 mPressAt{0.0};  // where the left button went down (a click measures)
  std::vector<sync::SceneGraph::NodeId> mMeasurements;  // the console's, oldest first
  std::vector<glm::dvec2> mLasso;                       // its pixels so far
  std::vector<sync::SceneGraph::NodeId> mSelections;    // the console's, oldest first
  std::vector<glm::dvec2> mSnapFg, mSnapBg;             // the strokes, the view's pixels
  std::unique_ptr<SelectionWorker> mSnaps;              // made with the first snap
  std::vector<sync::SceneGraph::NodeId> mClips;         // K: the console's section
  /// Which tool is on (A, M, S, N, or a panel): one at a time.
  interact::ToolKeys mTools;
  using Tool = interact::ToolKeys::Tool;
  bool on(Tool tool) const { return mTools.tool() == tool; }
  /// Makes the rest of the console follow mTools: the measuring mode, and the strokes of a tool
  /// that is off dropped.
  void toolsChanged();
  /// Turns `tool` on (the others off), or every tool off with Tool::kNone.
  void only(Tool tool) {
    mTools.choose(tool);
    toolsChanged();
  }
  /// The current model's MODEL node and its index among the drawn instances, if drawn.
  std::optional<std::pair<sync::SceneGraph::NodeId, size_t>> currentModel(
      const sync::SceneGraph& graph) const;
  /// Backspace: the snap strokes or the newest snap, the newest lasso selection, the last
  /// measuring point or the newest measurement, by the tool that is on.
  void back(sync::SceneGraph& graph);
  /// Sends the snap strokes to the worker (N, then Enter).
  void snap(const sync::SceneGraph& graph);
  std::chrono::steady_clock::time_point mLastInput = std::chrono::steady_clock::now();

  // The panels' state.
  annotate::AnnotationScene* mAnnotations = nullptr;
  struct NoteFormState {
    interact::NoteDraft draft;
    char layer[256] = "notes", title[1025] = "", text[2048] = "", unit[32] = "", link[512] = "";
    bool with_number = false;
    double number = 0.0;
    float radius = 0.0f;
    bool focus = true;  // the title field takes the keyboard when the form opens
  };
  std::optional<NoteFormState> mNoteForm;
  char mSearch[256] = "";
  std::string mSearchRan;               // the query mHits answer
  std::vector<int64_t> mHitPlaces;      // the places of the search's items, best first
  std::string mSearchError;             // a malformed query's reason
  sync::SceneGraph::NodeId mShown = 0;  // the note whose items the panel shows
  struct ItemEditState {
    int64_t item = 0, base_revision = 0;
    char title[1025] = "", text[2048] = "";
    bool text_fits = true;  // a longer text is kept as it is, not cut to the field
    bool with_number = false;
    double number = 0.0;
  };
  std::optional<ItemEditState> mEdit;
  std::string mStatus;  // the last thing said
};

}  // namespace tessera::master
