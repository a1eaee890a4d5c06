// The scene overlay: the scene graph's SKETCH, AVATAR and ANNOTATION nodes as overlay
// primitives (overlay_pass.h), so every tile of every wall and the master's console draw the
// same sketches, remote participants' glyphs and notes, depth-tested against the models. Render
// nodes, the console and `tessera-render --scene` all build it here, as they build their models
// with scene_draw_list.h.
//
// Frames: a node's payload is in its node frame; its world transform is its ancestors'
// transforms times its own, multiplied in double, and payload positions (floats) are taken to
// the world in double, so a sketch 10^6 m from the origin keeps its millimetres. A node is
// hidden when it or an ancestor is invisible; its colours' alpha is multiplied by its own and
// its ancestors' opacities (a node at opacity 0 adds nothing).
//
// What each kind becomes:
//  - SKETCH: its points as a polyline of OverlayLines, `width` pixels (0: sketch_width_px), an
//    OverlayPoint of the line's width on each interior vertex where it turns by more than 25
//    degrees, for round joins; a single point is
//    one dot. Joins blend twice where a see-through sketch overlaps itself.
//  - AVATAR: the participant's camera pose is its transform (columns right, up, back, eye): a
//    head (a dot at the eye over a dark ring), its view frustum out to `reach` metres (the 4
//    edges from the eye and the far rectangle; left out when fovy_deg, aspect or reach is 0),
//    and its name (the payload's site, else the node's name) centred above the head.
//  - ANNOTATION: its text at its anchor over a dark box, and a small dot at the anchor; an open
//    database note lists its items and shows its image items' pictures under them.
//  - MEASUREMENT: lines through its points (closed for an area), a dot on each, and
//    its label (measurementLabel()) at the distance's middle, the angle's vertex, the area's
//    centroid or the path's end.
//  - CLIP: faint white lines where the cut is: a box's 12 edges, or a square of
//    half-width `outline` on each plane around its point nearest the node origin.
//  - VIDEO_INSET: the picture of its source's stream (options.video_texture; a dark
//    quad until one is decoded). In the world: an OverlayQuad width x height metres centred on
//    the node frame's origin in its xy plane, depth-tested. On the screen: a ScreenRect placed
//    in fractions of options.screen_wall, drawn where this view (options.screen_view, in the
//    same units, options.view_px pixels) shows that part of it, so tiles continue each other;
//    its height, when the payload gives none, keeps the picture's aspect (4:3 until decoded).
//
// Cost: one pass over the scene's node ids, plus for each overlay node its ancestors (the tree's
// depth) and its payload (a sketch's points); no GL. Cheap enough to rebuild per frame;
// SceneOverlay rebuilds only on frames that changed nodes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <set>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/render/overlay_pass.h>
#include <tessera/render/screen_passes.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::render {

/// Sizes of what the scene overlay draws, pixels.
struct SceneOverlayOptions {
  float sketch_width_px = 2.0f;  ///< a sketch whose width is 0
  float avatar_head_px = 14.0f;  ///< the head dot's diameter
  float avatar_ring_px = 3.0f;   ///< the dark ring around it (0: none)
  float avatar_frustum_px = 1.5f;
  float label_px = 16.0f;  ///< avatar names and annotation texts, the text's height
  float annotation_dot_px = 7.0f;
  float note_picture_px = 160.0f;  ///< an open note's pictures fit this square (smaller: 1:1)
  float measure_width_px = 2.0f;  ///< a measurement's lines
  float measure_dot_px = 6.0f;    ///< its picked points
  /// A site's own view: its own avatar (payload site == hide_site) is not drawn ("": all are),
  /// nor any avatar whose eye is within hide_near_m metres of viewer_eye (0: none), such as a
  /// leader's seen by its follower.
  std::string hide_site;
  glm::dvec3 viewer_eye{0.0};
  double hide_near_m = 0.0;
  /// Video insets: the texture showing participant `source`'s stream, or null (none decoded
  /// yet). Unset: every inset is a dark quad. Textures must outlive the overlay's frames.
  std::function<const GlTexture*(uint32_t source)> video_texture;
  /// Screen-pinned insets: the whole screen's rectangle (a wall's extent on its plane, metres:
  /// min x, min y, max x, max y; y up), this view's part of it in the same units, and the view's
  /// size in pixels. A view_px of 0 draws no screen-pinned insets.
  glm::dvec4 screen_wall{0.0, 0.0, 1.0, 1.0};
  glm::dvec4 screen_view{0.0, 0.0, 1.0, 1.0};
  glm::dvec2 view_px{0.0};
};

/// A note's label (an ANNOTATION node): its text, or for an open database note one line per
/// item ("crack: 14 cm", "Edo restoration: seen in the 1962 photo", "report -> https://..."),
/// long texts cut, at most 12 lines.
std::string noteText(const scene::AnnotationPayload& a);

/// An open note's pictures (its image items' RGBA from the master, AnnotationItem.picture) as
/// label pictures, each scaled to fit `max_px` (never enlarged), keyed by a hash of its pixels.
std::vector<LabelPicture> notePictures(const scene::AnnotationPayload& a, float max_px);

/// A measurement's label: the value in a unit that keeps it readable and the bound of its
/// error, "14.2 cm ± 0.3 mm", "path 2.315 m ± 4 mm", "37.52° ± 0.41°",
/// "area 0.3 m² ± 20 cm²" (UTF-8).
std::string measurementLabel(const scene::MeasurementPayload& m);

/// A selection's region mask (SelectionPayload.mask, sync/selection_mask.h) resampled to the
/// highlight's kHighlightMaskSize^2 bits (nearest cell). Null when the mask does not check.
std::shared_ptr<const std::vector<uint32_t>> highlightMaskOf(const scene::SelectionPayload& s);

/// The graph's visible SELECTION nodes as highlights (RenderOptions::highlights): each lasso
/// rasterised into its mask (rasterizeLasso()), or its region mask resampled
/// (highlightMaskOf()), tinted with its colour (amber when unset), on
/// its model only (Highlight::model_node: the SceneDrawList's instances carry their node).
/// Cost: about a millisecond per selection (the mask's 1024 rows).
std::vector<Highlight> sceneHighlights(const sync::SceneGraph& graph);

/// Sets a SELECTION payload's lasso: the view it was drawn in (lasso_clip_from_world: `view`'s
/// projection times its view) and the polygon `px`, in that view's pixels (x right, y down from
/// the top-left), as the view's NDC (lasso).
void setSelectionLasso(scene::SelectionPayload& selection, const ViewSetup& view,
                       std::span<const glm::dvec2> px);

/// Whether the node kind is one the scene overlay draws (SKETCH, AVATAR, ANNOTATION,
/// VIDEO_INSET, MEASUREMENT, CLIP).
bool isOverlayKind(sync::SceneGraph::Kind kind);

/// The sources of the visible VIDEO_INSET nodes that `view` shows at least in part (world quads
/// by a conservative frustum test, screen rectangles against the view's pixels): the streams
/// this view must decode.
std::set<uint32_t> shownVideoSources(const sync::SceneGraph& graph, const ViewSetup& view,
                                     const SceneOverlayOptions& options);

/// Appends the primitives of the graph's visible SKETCH, AVATAR and ANNOTATION nodes (in
/// ascending id) to `out`, whose other content and depth_bias are left as they are. Returns how
/// many nodes it drew.
size_t appendSceneOverlay(const sync::SceneGraph& graph, Overlay& out,
                          const SceneOverlayOptions& options = {});

/// A scene overlay kept up to date with a replica: update() rebuilds it when a frame changed
/// nodes (any node: a group's transform, visibility or opacity moves what is below it) and
/// keeps it otherwise, so a frame that moved only the camera costs nothing.
class SceneOverlay {
 public:
  explicit SceneOverlay(const SceneOverlayOptions& options = {}) : mOptions(options) {}
  /// New options: the next update() rebuilds.
  void setOptions(const SceneOverlayOptions& options) {
    mOptions = options;
    mStarted = false;
  }
  const SceneOverlayOptions& options() const { return mOptions; }
  /// The next update() rebuilds (a video texture appeared or changed size).
  void invalidate() { mStarted = false; }
  /// `changes` as for SceneDrawList::update(). The reference stays valid until the next call.
  const Overlay& update(const sync::SceneGraph& graph, const sync::SceneChanges& changes);
  const Overlay& overlay() const { return mOverlay; }
  /// The overlay to pass to ViewRenderer::draw(): null while it is empty.
  const Overlay* drawn() const { return mOverlay.empty() ? nullptr : &mOverlay; }
  /// The selections to tint (sceneHighlights()), rebuilt with the overlay.
  const std::vector<Highlight>& highlights() const { return mHighlights; }

 private:
  SceneOverlayOptions mOptions;
  Overlay mOverlay;
  std::vector<Highlight> mHighlights;
  bool mStarted = false;
};

}  // namespace tessera::render
