// What the console's panels do with notes ("Information"), apart from how the panels
// look (master/src/console_panels.cpp), so tests drive it without a window: a note drafted at a
// picked point becomes a database place and item, a note's node gives the camera to fly to, and
// the note nearest the cursor is found for the O key. Window-free, no GL.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>

#include <glm/glm.hpp>

#include <tessera/annotate/annotation_scene.h>
#include <tessera/render/tile_frustum.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::interact {

/// A note as the "Add note" form holds it.
struct NoteDraft {
  glm::dvec3 position{0.0};  ///< the picked point, world metres
  std::string model;         ///< the MODEL node's name the point was picked on
  std::string layer = "notes";
  std::string title, text;
  /// A number with its unit (the item is a kNumber), when set.
  std::optional<double> number;
  std::string unit;
  std::string link;     ///< a document URI: the item is a kLink (number ignored)
  double radius = 0.0;  ///< > 0: a hot spot of this radius (metres) with `view`; else a point
  annotate::StoredView view;      ///< the console's camera when the note was made
};

/// The place and item `draft` makes (the item's kind: link, number or text, in that order).
/// Throws AnnotationError (kBadInput) when it has neither title nor text, or a bad number.
std::pair<annotate::Place, annotate::Item> noteOf(const NoteDraft& draft);

/// Adds the note to the database and the scene (AnnotationScene::addNote); returns {item,
/// place}. Throws AnnotationError as noteOf() and addNote() do.
std::pair<int64_t, int64_t> addNote(annotate::AnnotationScene& annotations, sync::SceneGraph& graph,
                                    const NoteDraft& draft, const std::string& author);

/// Where to look at the ANNOTATION node `note` from: its hot spot's stored view when it has one
/// (10 numbers), else its place seen from `current`'s eye distance along `current`'s view
/// direction. Precondition: graph.contains(note).
config::Camera flyToNote(const sync::SceneGraph& graph, sync::SceneGraph::NodeId note,
                         const config::Camera& current);

/// The shown ANNOTATION node of a database place (payload place != 0) whose anchor projects
/// nearest to `cursor` (pixels of `view`, y down) within `max_px`, in front of the camera;
/// nullopt when none is that close.
std::optional<sync::SceneGraph::NodeId> noteNear(const sync::SceneGraph& graph,
                                                 const render::ViewSetup& view, glm::dvec2 cursor,
                                                 double max_px);

/// A section (the console's K): a CLIP node (layer "clips", by `author`) whose plane passes
/// through `at` facing `camera`'s view, keeping what lies at or beyond it (what is nearer is cut
/// away), its outline a square a quarter of the eye's distance across around `at`.
sync::SceneGraph::NodeId addSectionClip(sync::SceneGraph& graph, const glm::dvec3& at,
                                        const config::Camera& camera, const std::string& author);

}  // namespace tessera::interact
