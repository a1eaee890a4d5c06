// The scene draw list ("Scene path"): what a scene graph (sync/scene_graph.h) asks the
// renderer to draw: its MODEL nodes as render::ModelInstances with their stores open, and the
// wall-level settings as render::RenderOptions. Render nodes, the master's console and
// `tessera-render --scene` use it, so all draw one scene the same way: the same stores,
// transforms and options.
//
// It owns the stores' lifetimes: a store that no model uses any more is closed only after the
// chunk streamers that drew it forgot it (their loader's work on it cancelled, its resident
// chunks freed), so a loader never decodes into a closed store.
//
// Not thread-safe; the stores it opens are shared with the renderer's loader thread (PointStore
// is thread-safe).
#pragma once

#include <functional>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_store.h>
#include <tessera/render/chunk_streamer.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::render {

/// A scene file (sync::loadSceneFile) as a scene graph with every model's store ready: a model
/// naming a raw scan (PLY, LAS, .conf ...) is built into the cached store for it on first use
/// (lod/store_cache.h), shared by every program of this host, and the model then names that
/// store. `who` prefixes progress lines. Throws std::runtime_error (sync::ConfigError for the
/// file itself) naming the file, the node and why.
sync::SceneGraph loadSceneWithStores(const std::string& path, const std::string& who);

/// Where a scene node is and how it shows: world = (ancestors' transforms) * (its transform),
/// multiplied in double; opacity the product of its own and its ancestors'; visible false when
/// it or an ancestor is hidden (then world and opacity stop at the hidden one). Every scene
/// consumer (the draw list, scene_overlay.h) places nodes with it. Cost: the node's depth.
/// Precondition: graph.contains(id).
struct NodePlacement {
  glm::dmat4 world{1.0};
  float opacity = 1.0f;
  bool visible = true;
};
NodePlacement placeNode(const sync::SceneGraph& graph, sync::SceneGraph::NodeId id);

class SceneDrawList {
 public:
  /// Whether a scene's store path names a mesh store (.tmesh, lod/mesh_store.h): opened as a
  /// MeshStore and drawn by the mesh pass.
  static bool isMeshPath(const std::string& path);
  /// What a MODEL node is drawn from: its store path, or for a mesh whose opacity (with its
  /// ancestors') is below 1, PATH#points: a point store of samples on its triangles
  /// (lod/mesh_samples.h, cached by lod::cachedStoreFor), drawn see-through like any scan.
  static std::string storeKey(const sync::SceneGraph& graph, uint32_t id);
  /// The mesh path of a storeKey() that names a see-through mesh's points (MESH#points); none
  /// for any other key.
  static std::optional<std::string> meshOfPointsKey(const std::string& key);
  /// The point store of a storeKey() from this host (the default StoreOpener below):
  /// lod::PointStore::open(key), or for MESH#points the store sampled from the mesh
  /// (lod::cachedStoreFor, made on first use).
  static std::unique_ptr<lod::PointStore> openLocalStore(const std::string& key);

  /// Opens the (point) store a MODEL node names (its path exactly as in the scene, or a
  /// see-through mesh's storeKey(), MESH#points). Throws lod::StoreError naming the store and
  /// why. The default is openLocalStore(); a remote site opens through the master's chunk
  /// server (collab/chunk_client.h).
  using StoreOpener = std::function<std::unique_ptr<lod::PointStore>(const std::string& path)>;

  /// Sets how update() opens stores from now on (stores already open stay). Empty: the default.
  void setStoreOpener(StoreOpener opener) { mOpener = std::move(opener); }

  /// The same for mesh stores (.tmesh; default lod::MeshStore::open(path)): a remote site opens
  /// them through the chunk server too.
  using MeshStoreOpener = std::function<std::unique_ptr<lod::MeshStore>(const std::string& path)>;
  void setMeshStoreOpener(MeshStoreOpener opener) { mMeshOpener = std::move(opener); }

  /// Brings the list up to date with `graph` after `changes` (what SceneGraph::apply() returned,
  /// or SceneChanges::of() the frame the master took; SceneChanges::all() rebuilds). The list
  /// holds the visible MODEL nodes in ascending id (the scene file's order), each drawn with
  /// world = (ancestors' transforms) * (its transform) * storeModel(store) and opacity = the
  /// product of its own and its ancestors' opacities; a node is hidden when it or an ancestor
  /// is. Opens each store path once; a store no model uses any more is forgotten by every
  /// streamer in `streamers` (ChunkStreamer::forget: cancels the loader's work on it, waits for
  /// a chunk in flight, frees its resident chunks), then closed. Throws lod::StoreError naming
  /// the model when a store cannot be opened (the list is left as it was).
  /// Cost: nothing for a frame that changed no node; else the changed nodes' subtrees, plus
  /// opening new stores (their header and root page) and one pass over the models.
  /// The returned instances (and their store pointers) stay valid until the next update().
  const std::vector<ModelInstance>& update(const sync::SceneGraph& graph,
                                           const sync::SceneChanges& changes,
                                           std::span<ChunkStreamer* const> streamers = {});

  /// Forgets and closes every store (before the streamers go), after any sampling below ended.
  void clear(std::span<ChunkStreamer* const> streamers);

  /// A mesh that turns see-through needs its samples (storeKey(): MESH#points). With the default
  /// opener, a store the store cache does not hold yet is built on a thread of its own, off the
  /// frame: meanwhile update() draws the mesh opaque, and the first update() after the build
  /// draws its samples. Whether such a build is under way:
  bool sampling() const { return !mSampling.empty(); }
  /// Waits for every build under way, then brings the models that waited up to date: what a
  /// settled frame (a screenshot, a deterministic run) draws. Throws as update().
  const std::vector<ModelInstance>& finishSampling(const sync::SceneGraph& graph,
                                                   std::span<ChunkStreamer* const> streamers = {});

  /// Clip planes and boxes (the scene's visible CLIP nodes): each instance's
  /// ModelInstance::clip holds, in the world frame (double), the planes of every visible CLIP
  /// node that cuts it (its `models`, or all models when empty), one group per node in
  /// ascending id, as long as they fit in kMaxClipPlanes; a node that does not fit is left out
  /// whole for that model and counted here (the last update() that changed nodes).
  size_t droppedClips() const { return mDroppedClips; }
  /// The world planes of a CLIP node's payload (node frame, placed by `world`): its planes, or
  /// its box's six (boxPlanes()). Plane' = plane * inverse(world), in double.
  static std::vector<glm::dvec4> clipPlanesOf(const scene::ClipPayload& clip,
                                              const glm::dmat4& world);

  /// The MODEL node of each instance of the last update(), in the same order.
  const std::vector<uint32_t>& instanceNodes() const { return mInstanceNodes; }

  /// The open stores' file sizes together, bytes.
  uint64_t storeBytes() const;
  /// Scene nodes the last update() looked at (0 for a frame that changed no node).
  size_t lastVisited() const { return mVisited; }

  /// The wall-level settings: background, eye-dome lighting (strength 1) when the shading is
  /// EDL, LOD threshold; `splat_scale` as tessera-render's --splat-scale. Per-node shading and
  /// LOD thresholds are not used yet (one RenderOptions per view).
  static RenderOptions options(const sync::SceneGraph& graph, float splat_scale);

 private:
  /// A MODEL node as drawn: its store path and instance (`visible` false: hidden, not drawn).
  struct Entry {
    std::string path;
    ModelInstance instance;
    bool visible = false;
  };
  std::map<std::string, std::unique_ptr<lod::PointStore>> mStores;     // by store path
  std::map<std::string, std::unique_ptr<lod::MeshStore>> mMeshStores;  // .tmesh, by path
  std::map<uint32_t, Entry> mEntries;                                  // by node id
  /// Samples of see-through meshes being built (by storeKey()), and the models drawn opaque
  /// until theirs are ready (node id -> storeKey()).
  std::map<std::string, std::future<std::unique_ptr<lod::PointStore>>> mSampling;
  std::map<uint32_t, std::string> mWaiting;
  /// A visible CLIP node: its planes in the world, whether it keeps their outside, the models
  /// it cuts (empty: all).
  struct ClipEntry {
    std::vector<glm::dvec4> planes;
    bool invert = false;
    std::vector<uint32_t> models;
  };
  std::map<uint32_t, ClipEntry> mClips;  // visible CLIP nodes by id
  size_t mDroppedClips = 0;
  std::vector<ModelInstance> mInstances;
  std::vector<uint32_t> mInstanceNodes;  // parallel to mInstances
  bool mStarted = false;
  size_t mVisited = 0;
  StoreOpener mOpener;
  MeshStoreOpener mMeshOpener;
};

}  // namespace tessera::render
