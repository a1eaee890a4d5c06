// The annotation database as part of the scene ("Information",
// "Annotation"): tessera-master --annotations FILE opens an AnnotationDb (annotation_db.h) beside
// the scene and keeps the two in step, so what people learn is on every tile and site, and
// what they measure and select on the wall survives the session.
//
// From the database to the scene (load(), and after every edit):
//   layer "a/b"        nested GROUP nodes under the root, "a" then "b" (sync::layerPath), visible
//                      as the layer's own flag: hiding a layer hides its sublayers' notes on
//                      every tile (render::placeNode: a hidden ancestor hides the subtree)
//   point, hot spot    one ANNOTATION node per place and layer of its items, under that layer's
//                      group: the place's position (its transform, double), the items (id,
//                      kind, title, text cut to 4 KiB, number and unit, link, author,
//                      revision), a hot spot's radius and stored view
//   measurement        a MEASUREMENT node (its points, value and uncertainty as measured)
//   lasso selection    a SELECTION node on the model of that name
// From the scene to the database (sync(), before every frame): MEASUREMENT and SELECTION nodes
// made by the console or a site are stored (a selection place holding the node's payload, and
// for a measurement a number item with its value, unit and uncertainty in the layer
// "measurements", so full-text search finds "distance"); removed ones are deleted; a layer
// group's visibility, changed by anyone, becomes the layer's flag.
//
// Other programs' commits (tessera-annotate while the master runs) come in through refresh(),
// which sync() calls at most every quarter second: only what differs changes in the scene.
//
// Edits (the console's panels, sites' SiteNote requests) commit to the database first and then
// change the scene: an edit is acknowledged (returns) only once committed, so an acknowledged
// item survives kill -9 of the master (tests/master/annotation_scene_test.cpp). Two edits of
// one item resolve by the database's rule: the master applies them in its order and the one
// based on a stale revision is refused (AnnotationError::Kind::kConflict), whoever sent it.
//
// Not thread-safe: the master's loop thread uses it.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <tessera/annotate/annotation_db.h>
#include <tessera/annotate/note_picture.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::annotate {


class AnnotationScene {
 public:
  using NodeId = sync::SceneGraph::NodeId;

  /// Opens (or creates) the database. Throws AnnotationError naming the file.
  explicit AnnotationScene(const std::filesystem::path& file, AnnotationDbOptions options = {});

  /// Puts the database's layers, places and items into `graph` (see above). A stored
  /// measurement or selection that no longer fits the scene (its model is gone, its payload
  /// does not check) is left in the database and reported in the returned messages.
  std::vector<std::string> load(sync::SceneGraph& graph);

  /// Before each frame: stores the measurements and selections made since, deletes removed
  /// ones, and stores layer visibility changes. Cost: nothing when the scene's version did not
  /// change; else one pass over the nodes, one commit per change. Then, at most every
  /// `external_poll` (below), takes in what other programs committed to the file meanwhile
  /// (refresh()).
  void sync(sync::SceneGraph& graph);

  /// What other connections (tessera-annotate, another tool) changed since load() or the last
  /// refresh, into the scene: new, edited and removed notes, layers shown or hidden, stored
  /// measurements and selections added or deleted. Only what differs is touched. Cost: one
  /// PRAGMA (microseconds) when nothing changed; else a read of every place and its items.
  /// Returns the problems of stored places the scene cannot take, as load() does.
  std::vector<std::string> refresh(sync::SceneGraph& graph);
  /// How often sync() looks for other programs' commits (0: every frame).
  void setExternalPoll(std::chrono::milliseconds every) { mPollEvery = every; }

  // --- Edits: committed, then applied to the scene (throw AnnotationError) --------------------
  /// A new item at a new place (`place.id` ignored), or at the existing place `at` (> 0).
  /// Returns {item, place}.
  std::pair<int64_t, int64_t> addNote(sync::SceneGraph& graph, const Place& place,
                                      const Item& item, const std::string& author,
                                      int64_t at = 0);
  /// The item's new content if `base_revision` is current; returns the new revision.
  int64_t updateItem(sync::SceneGraph& graph, const Item& item, int64_t base_revision,
                     const std::string& author);
  void removeItem(sync::SceneGraph& graph, int64_t item, int64_t base_revision);
  void setLayerVisible(sync::SceneGraph& graph, const std::string& layer, bool visible,
                       const std::string& author);
  /// Shows a place's items on every tile (open) or only its label. Not stored: a view state.
  /// An open note carries its image items' pictures (note_picture.h, at most kNotePicturePx a
  /// side, decoded once per item revision), so tiles and sites show them under its text.
  void setOpen(sync::SceneGraph& graph, int64_t place, bool open, const std::string& author);

  /// The ANNOTATION nodes of a place (one per layer of its items).
  std::vector<NodeId> nodesOf(int64_t place) const;
  /// The database place behind a MEASUREMENT or SELECTION node, if stored.
  std::optional<int64_t> placeOfNode(NodeId node) const;

  AnnotationDb& db() { return mDb; }

  /// The side an open note's pictures are scaled to fit.
  static constexpr uint32_t kNotePicturePx = 192;

 private:
  /// Rebuilds the ANNOTATION nodes of `place` from the database (none when it has no items);
  /// `open` changes their open state (else kept). A node whose payload would not change is
  /// left alone.
  void refreshPlace(sync::SceneGraph& graph, int64_t place, const std::string& author,
                    std::optional<bool> open = std::nullopt);
  /// A stored measurement or selection as its scene node (load(), refresh()); throws saying
  /// why the scene cannot take it.
  void loadStored(sync::SceneGraph& graph, const Place& place);
  /// Sets an image item's picture (or the reason there is none) on its scene item.
  void addPicture(const Item& item, scene::AnnotationItem& shown, size_t& budget);
  NodeId layerNode(sync::SceneGraph& graph, const std::string& layer, const std::string& author);
  void storeNode(sync::SceneGraph& graph, NodeId node);

  AnnotationDb mDb;
  std::map<std::pair<int64_t, std::string>, NodeId> mNotes;  // (place, layer) -> ANNOTATION
  std::map<std::string, NodeId> mLayers;                     // layer path -> its GROUP
  std::map<std::string, bool> mLayerShown;                   // as last stored
  struct Stored {
    int64_t place = 0, item = 0;
  };
  std::map<NodeId, Stored> mStoredNodes;  // MEASUREMENT and SELECTION nodes in the database
  std::set<NodeId> mRefused;              // nodes that could not be stored (said once)
  uint64_t mSyncedVersion = UINT64_MAX;
  struct Picture {
    NotePicture picture;
    std::string problem;
  };
  static constexpr size_t kMaxPictures = 256;
  std::map<std::pair<int64_t, int64_t>, Picture> mPictures;  // (item, revision) ->
  int64_t mDataVersion = 0;  // the file's data_version when last read
  std::chrono::milliseconds mPollEvery{250};
  std::chrono::steady_clock::time_point mPolled{};
};

}  // namespace tessera::annotate
