// The lasso on the wall (thesis 4.1): a lasso drawn over a view becomes a SELECTION
// node of the scene (layer "selections"): the exact leaf elements inside it (lasso_selection.h,
// through the whole depth) and the lasso with its view, from which every tile, console and site
// tints the region (render/scene_overlay.h sceneHighlights()). Window-free: the console feeds
// it a drag, a test a polygon.
#pragma once

#include <optional>
#include <span>
#include <string>

#include <glm/glm.hpp>

#include <tessera/render/tile_frustum.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::interact {

struct LassoSelectResult {
  sync::SceneGraph::NodeId node = 0;  ///< the SELECTION node made (0: nothing selected)
  uint64_t count = 0;                 ///< points or triangles selected
  uint64_t corrupt = 0;               ///< leaves that could not be read (not selected)
};

/// The lasso's selection without a scene (thread-safe over the stores, which are): what
/// selectWithLasso() records. `payload` is empty when nothing is inside. `threads`: as
/// LassoOptions::threads (0: one per core).
struct LassoSelection {
  scene::SelectionPayload payload;
  uint64_t count = 0, corrupt = 0;
};
LassoSelection lassoSelection(const render::ModelInstance& instance, uint32_t model_node,
                              const render::ViewSetup& view, std::span<const glm::dvec2> pixels,
                              unsigned threads = 0);
/// Records a selection as a SELECTION node in the layer "selections" by `author`. Throws
/// PreconditionError when the payload does not check (more than 16 MiB of elements).
sync::SceneGraph::NodeId addSelection(sync::SceneGraph& graph,
                                      const scene::SelectionPayload& payload,
                                      const std::string& author);

/// Selects what of `model` (the MODEL node `model_node`, drawn as `instance`) lies inside the
/// lasso `pixels` (the view's pixels, x right, y down from the top-left; at least 3, a longer
/// one than 4096 thinned evenly) seen in
/// `view`, and records it as a SELECTION node by `author`. Nothing is made when nothing is
/// inside. Throws PreconditionError when the selection's bytes pass 16 MiB.
LassoSelectResult selectWithLasso(sync::SceneGraph& graph, const render::ModelInstance& instance,
                                  uint32_t model_node, const render::ViewSetup& view,
                                  std::span<const glm::dvec2> pixels, const std::string& author);

}  // namespace tessera::interact
