#include <tessera/interact/console_notes.h>

#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/render/scene_draw_list.h>
#include <tessera/sync/scene_edits.h>

#include <tessera/sync/vec3.h>

namespace tessera::interact {

namespace {

using sync::set;
using sync::vec;

/// The note's anchor in the world (its node's placement applied to the payload's anchor).
glm::dvec3 anchorOf(const sync::SceneGraph& graph, sync::SceneGraph::NodeId note) {
  const auto& a = graph.node(note).annotation();
  return glm::dvec3(render::placeNode(graph, note).world * glm::dvec4(vec(a.anchor()), 1.0));
}

}  // namespace

std::pair<annotate::Place, annotate::Item> noteOf(const NoteDraft& draft) {
  if (draft.title.empty() && draft.text.empty())
    throw annotate::AnnotationError(annotate::AnnotationError::Kind::kBadInput,
                          "console: a note needs a title or a text");
  annotate::Place place;
  place.kind = draft.radius > 0.0 ? annotate::PlaceKind::kHotSpot : annotate::PlaceKind::kPoint;
  place.model = draft.model;
  place.position = draft.position;
  if (draft.radius > 0.0) {
    place.radius = draft.radius;
    place.view = draft.view;
  }
  annotate::Item item;
  item.layer = draft.layer;
  item.title = draft.title;
  item.text = draft.text;
  if (!draft.link.empty()) {
    item.kind = annotate::ItemKind::kLink;
    item.link_uri = draft.link;
  } else if (draft.number) {
    if (!std::isfinite(*draft.number))
      throw annotate::AnnotationError(annotate::AnnotationError::Kind::kBadInput,
                            "console: the note's number is not finite");
    item.kind = annotate::ItemKind::kNumber;
    item.number = *draft.number;
    item.unit = draft.unit;
  }
  return {place, item};
}

std::pair<int64_t, int64_t> addNote(annotate::AnnotationScene& annotations, sync::SceneGraph& graph,
                                    const NoteDraft& draft, const std::string& author) {
  const auto [place, item] = noteOf(draft);
  return annotations.addNote(graph, place, item, author);
}

config::Camera flyToNote(const sync::SceneGraph& graph, sync::SceneGraph::NodeId note,
                         const config::Camera& current) {
  const auto& a = graph.node(note).annotation();
  config::Camera c;
  if (a.view_size() == 10) {  // eye, target, up: the view stored with the hot spot
    set(c.mutable_eye(), {a.view(0), a.view(1), a.view(2)});
    set(c.mutable_target(), {a.view(3), a.view(4), a.view(5)});
    set(c.mutable_up(), {a.view(6), a.view(7), a.view(8)});
    return c;
  }
  // The place from where the camera stands now: the same distance and direction.
  const glm::dvec3 at = anchorOf(graph, note);
  const glm::dvec3 eye = vec(current.eye()), target = vec(current.target());
  const double dist = glm::length(target - eye);
  const glm::dvec3 dir = dist > 0.0 ? (target - eye) / dist : glm::dvec3(0.0, 0.0, -1.0);
  set(c.mutable_eye(), at - dir * (dist > 0.0 ? dist : 1.0));
  set(c.mutable_target(), at);
  *c.mutable_up() = current.up();
  return c;
}

std::optional<sync::SceneGraph::NodeId> noteNear(const sync::SceneGraph& graph,
                                                 const render::ViewSetup& view, glm::dvec2 cursor,
                                                 double max_px) {
  const glm::dmat4 clip_from_world = view.projection * view.view;
  std::optional<sync::SceneGraph::NodeId> best;
  double best_d = max_px;
  for (auto id : graph.ids()) {
    const auto& n = graph.node(id);
    if (n.kind() != scene::SceneNode::ANNOTATION || n.annotation().place() == 0) continue;
    if (!render::placeNode(graph, id).visible) continue;
    const glm::dvec4 clip = clip_from_world * glm::dvec4(anchorOf(graph, id), 1.0);
    if (clip.w <= 0.0) continue;  // behind the camera
    const glm::dvec2 px((clip.x / clip.w + 1.0) * 0.5 * view.width,
                        (1.0 - clip.y / clip.w) * 0.5 * view.height);
    const double d = glm::length(px - cursor);
    if (d <= best_d) {
      best_d = d;
      best = id;
    }
  }
  return best;
}

sync::SceneGraph::NodeId addSectionClip(sync::SceneGraph& graph, const glm::dvec3& at,
                                        const config::Camera& camera, const std::string& author) {
  // Keep where dot(forward, x - at) >= 0. The node sits at `at`, so its plane passes through
  // the node origin and the outline is drawn around the point.
  const glm::dvec3 eye = sync::vec(camera.eye());
  glm::dvec3 forward = sync::vec(camera.target()) - eye;
  forward = glm::length(forward) > 0.0 ? glm::normalize(forward) : glm::dvec3(0.0, 0.0, -1.0);
  const auto layer = sync::layerGroup(graph, "clips", author);
  const glm::dmat4 t = glm::translate(glm::dmat4(1.0), at);
  scene::ClipPayload clip;
  for (double v : {forward.x, forward.y, forward.z, 0.0}) clip.add_planes(v);
  clip.set_outline(float(0.25 * glm::length(at - eye)));
  return graph.add(scene::SceneNode::CLIP, layer, author + " section", std::move(clip), author,
                   std::span<const double>(&t[0][0], 16));
}

}  // namespace tessera::interact
