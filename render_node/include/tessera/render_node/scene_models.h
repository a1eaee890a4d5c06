// What a scene graph replica (sync/scene_graph.h) asks the renderer to draw: its MODEL nodes as
// render::ModelInstances with their stores open, and the wall-level settings as
// render::RenderOptions. Render nodes and the master's console use it, so both draw one scene the
// same way, and the way `tessera-render --scene` does: the same stores, transforms and options.
//
// Not thread-safe; the stores it opens are shared with the renderer's loader thread (PointStore
// is thread-safe).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include <tessera/lod/point_store.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::render_node {

class SceneModels {
 public:
  /// The visible MODEL nodes in ascending id (the scene file's order), each drawn with
  /// world = (ancestors' transforms) * (its transform) * storeModel(store) and
  /// opacity = the product of its own and its ancestors' opacities; a node is hidden when it or
  /// an ancestor is. Opens each store path once (paths of models that are gone are closed).
  /// Throws lod::StoreError naming the model when a store cannot be opened. Cost: the scene's
  /// size, plus opening new stores (their header and root page).
  std::vector<render::ModelInstance> update(const sync::SceneGraph& graph);

  /// The open stores' file sizes together, bytes.
  uint64_t storeBytes() const;

  /// The wall-level settings: background, eye-dome lighting (strength 1) when the shading is
  /// EDL, LOD threshold; `splat_scale` as tessera-render's --splat-scale. Per-node shading and
  /// LOD thresholds are not used yet (one RenderOptions per view).
  static render::RenderOptions options(const sync::SceneGraph& graph, float splat_scale);

 private:
  std::map<std::string, std::unique_ptr<lod::PointStore>> mStores;  // by store path
};

}  // namespace tessera::render_node
