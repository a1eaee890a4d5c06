#include <tessera/interact/select_tool.h>

#include <tessera/annotate/lasso_selection.h>
#include <tessera/render/scene_overlay.h>
#include <tessera/sync/scene_edits.h>

namespace tessera::interact {

LassoSelection lassoSelection(const render::ModelInstance& instance, uint32_t model_node,
                              const render::ViewSetup& view, std::span<const glm::dvec2> pixels,
                              unsigned threads) {
  LassoSelection out;
  if (pixels.size() < 3 || view.width == 0 || view.height == 0) return out;
  for (const glm::dvec2& p : pixels)
    if (!std::isfinite(p.x) || !std::isfinite(p.y)) return out;
  // At most 4096 vertices (the scene's limit): a long drag is thinned evenly.
  std::vector<glm::dvec2> kept;
  const size_t step = (pixels.size() + 4095) / 4096;
  for (size_t i = 0; i < pixels.size(); i += step) kept.push_back(pixels[i]);
  if (kept.size() < 3) return out;
  pixels = kept;
  const annotate::LassoView lv{view.view, view.projection, {view.width, view.height}};
  const annotate::LassoPolygon lasso(kept);
  annotate::LassoOptions o;
  o.model = instance.model;
  o.threads = threads;
  if (!instance.mesh && !instance.store) return out;
  const annotate::LassoResult r = instance.mesh ? annotate::lassoTriangles(*instance.mesh, lv, lasso, o)
                                      : annotate::lassoPoints(*instance.store, lv, lasso, o);
  out.corrupt = r.stats.corrupt_chunks;
  out.count = r.selection.count();
  if (out.count == 0) return out;
  scene::SelectionPayload& s = out.payload;
  s.set_model(model_node);
  render::setSelectionLasso(s, view, pixels);
  const std::vector<uint8_t> bytes = r.selection.serialize();
  s.set_elements(std::string(bytes.begin(), bytes.end()));
  s.set_count(out.count);
  return out;
}

sync::SceneGraph::NodeId addSelection(sync::SceneGraph& graph,
                                      const scene::SelectionPayload& payload,
                                      const std::string& author) {
  const auto layer = sync::layerGroup(graph, "selections", author);
  return graph.add(scene::SceneNode::SELECTION, layer,
                   sync::freshName(graph, layer, "selection"), payload, author);
}

LassoSelectResult selectWithLasso(sync::SceneGraph& graph, const render::ModelInstance& instance,
                                  uint32_t model_node, const render::ViewSetup& view,
                                  std::span<const glm::dvec2> pixels, const std::string& author) {
  const LassoSelection s = lassoSelection(instance, model_node, view, pixels);
  LassoSelectResult out;
  out.count = s.count;
  out.corrupt = s.corrupt;
  if (s.count > 0) out.node = addSelection(graph, s.payload, author);
  return out;
}

}  // namespace tessera::interact
