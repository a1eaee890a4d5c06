// The scene draw list (DESIGN.md, "Scene path"): what a scene graph (sync/scene_graph.h) asks the
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

#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <tessera/lod/point_store.h>
#include <tessera/render/chunk_streamer.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::render {

class SceneDrawList {
 public:
  /// The visible MODEL nodes in ascending id (the scene file's order), each drawn with
  /// world = (ancestors' transforms) * (its transform) * storeModel(store) and
  /// opacity = the product of its own and its ancestors' opacities; a node is hidden when it or
  /// an ancestor is. Opens each store path once; a store no model uses any more is forgotten by
  /// every streamer in `streamers` (ChunkStreamer::forget: waits for a chunk in flight), then
  /// closed. Throws lod::StoreError naming the model when a store cannot be opened (the list is
  /// left as it was). Cost: the scene's size, plus opening new stores (their header and root
  /// page). The instances' store pointers stay valid until the next update().
  std::vector<ModelInstance> update(const sync::SceneGraph& graph,
                                    std::span<ChunkStreamer* const> streamers = {});

  /// Forgets and closes every store (before the streamers go).
  void clear(std::span<ChunkStreamer* const> streamers);

  /// The open stores' file sizes together, bytes.
  uint64_t storeBytes() const;

  /// The wall-level settings: background, eye-dome lighting (strength 1) when the shading is
  /// EDL, LOD threshold; `splat_scale` as tessera-render's --splat-scale. Per-node shading and
  /// LOD thresholds are not used yet (one RenderOptions per view).
  static RenderOptions options(const sync::SceneGraph& graph, float splat_scale);

 private:
  std::map<std::string, std::unique_ptr<lod::PointStore>> mStores;  // by store path
};

}  // namespace tessera::render
