#include <tessera/collab/site_notes.h>

#include <glm/glm.hpp>

namespace tessera::collab {

namespace {

annotate::Item itemOf(const site::NoteContent& c) {
  annotate::Item it;
  it.layer = c.layer();
  it.kind = annotate::parseItemKind(c.kind()).value_or(annotate::ItemKind::kText);
  it.title = c.title();
  it.text = c.text();
  if (it.kind == annotate::ItemKind::kNumber) {
    it.number = c.number();
    it.unit = c.unit();
  }
  if (it.kind == annotate::ItemKind::kLink) {
    it.link_uri = c.uri();
    it.link_item = int64_t(c.link_item());
  }
  return it;
}

annotate::Place placeOf(const site::NoteAdd& a) {
  annotate::Place p;
  p.kind = a.radius() > 0.0 ? annotate::PlaceKind::kHotSpot : annotate::PlaceKind::kPoint;
  p.model = a.model().empty() ? "scene" : a.model();
  if (a.position_size() == 3) p.position = {a.position(0), a.position(1), a.position(2)};
  p.radius = a.radius();
  if (a.view_size() == 10) {
    const auto& v = a.view();
    p.view = annotate::StoredView{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}, {v[6], v[7], v[8]}, v[9]};
  }
  return p;
}

}  // namespace

site::SiteNoteAnswer applySiteNote(annotate::AnnotationScene* notes, sync::SceneGraph& graph,
                                   const std::string& author, const site::SiteNote& note) {
  site::SiteNoteAnswer out;
  out.set_request(note.request());
  if (!notes) {
    out.set_error("the master keeps no annotations (it runs without --annotations)");
    return out;
  }
  try {
    switch (note.edit_case()) {
      case site::SiteNote::kAdd: {
        const auto [item, place] = notes->addNote(graph, placeOf(note.add()),
                                                  itemOf(note.add().item()), author,
                                                  int64_t(note.add().place()));
        out.set_item(uint64_t(item));
        out.set_place(uint64_t(place));
        out.set_revision(1);
        break;
      }
      case site::SiteNote::kUpdate: {
        // A site writes text, numbers and links: an image item stays as tessera-annotate or
        // the console left it, and an empty layer keeps the item's own.
        const int64_t id = int64_t(note.update().item());
        const std::optional<annotate::Item> now = notes->db().item(id);
        if (now && now->kind == annotate::ItemKind::kImage)
          throw annotate::AnnotationError(
              annotate::AnnotationError::Kind::kBadInput,
              "item " + std::to_string(id) +
                  " is an image: a site does not edit it (the console or tessera-annotate does)");
        annotate::Item it = itemOf(note.update().content());
        it.id = id;
        if (it.layer.empty() && now) it.layer = now->layer;
        out.set_item(note.update().item());
        out.set_revision(uint64_t(
            notes->updateItem(graph, it, int64_t(note.update().base_revision()), author)));
        break;
      }
      case site::SiteNote::kRemove:
        notes->removeItem(graph, int64_t(note.remove().item()),
                          int64_t(note.remove().base_revision()));
        out.set_item(note.remove().item());
        break;
      case site::SiteNote::kLayer:
        notes->setLayerVisible(graph, note.layer().layer(), note.layer().visible(), author);
        break;
      case site::SiteNote::kOpen:
        notes->setOpen(graph, int64_t(note.open().place()), note.open().open(), author);
        out.set_place(note.open().place());
        break;
      default:
        out.set_error("note: no edit");
        return out;
    }
    out.set_ok(true);
  } catch (const annotate::AnnotationError& e) {
    out.set_conflict(e.kind() == annotate::AnnotationError::Kind::kConflict);
    out.set_error(e.what());
  }
  return out;
}

}  // namespace tessera::collab
