// A site's edits of the annotation database (site.proto SiteNote): checked messages
// (site_messages.h) become edits of the master's AnnotationScene (annotate/annotation_scene.h),
// committed and then applied to the scene, with the answer the site gets. The site hub calls
// it for every SiteNote; the author of each edit is the site's name.
#pragma once

#include <string>

#include <tessera/annotate/annotation_scene.h>
#include <tessera/site.pb.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::collab {

/// Applies one checked SiteNote for `author`. `notes` null: the master keeps no database, and
/// the answer says so. Every refusal (unknown item, stale revision, a layer path or URI the
/// database refuses) is an answer with ok false and the reason; nothing throws, and a refused
/// edit changes neither the database nor the scene.
site::SiteNoteAnswer applySiteNote(annotate::AnnotationScene* notes, sync::SceneGraph& graph,
                                   const std::string& author, const site::SiteNote& note);

}  // namespace tessera::collab
