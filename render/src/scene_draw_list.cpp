#include <tessera/render/scene_draw_list.h>

#include <glm/gtc/type_ptr.hpp>

namespace tessera::render {

namespace {

glm::dmat4 transformOf(const scene::SceneNode& node) {
  if (node.transform().m_size() != 16) return glm::dmat4(1.0);
  return glm::make_mat4(node.transform().m().data());
}

}  // namespace

std::vector<ModelInstance> SceneDrawList::update(const sync::SceneGraph& graph,
                                                 std::span<ChunkStreamer* const> streamers) {
  std::vector<ModelInstance> instances;
  std::map<std::string, std::unique_ptr<lod::PointStore>> kept;
  for (const sync::SceneGraph::NodeId id : graph.ids()) {
    const scene::SceneNode& node = graph.node(id);
    if (node.kind() != scene::SceneNode::MODEL) continue;
    const std::string& path = node.model().store();
    auto open = mStores.find(path);
    if (open != mStores.end()) {
      kept.emplace(path, std::move(open->second));
      mStores.erase(open);
    } else if (!kept.count(path)) {
      try {
        kept.emplace(path, lod::PointStore::open(path));
      } catch (const lod::StoreError& e) {
        // Left as it was: the stores taken over so far go back.
        for (auto& [p, st] : kept) mStores.emplace(p, std::move(st));
        throw lod::StoreError("render::SceneDrawList::update(): model " + std::to_string(id) +
                              " '" + node.name() + "': " + e.what());
      }
    }
    // Up the tree: parents' transforms apply after the node's own; any hidden one hides it.
    bool visible = node.visible();
    float opacity = node.opacity();
    glm::dmat4 world = transformOf(node);
    for (auto parent = node.parent(); visible && parent != sync::SceneGraph::kRoot;) {
      const scene::SceneNode& p = graph.node(parent);
      visible = p.visible();
      opacity *= p.opacity();
      world = transformOf(p) * world;
      parent = p.parent();
    }
    if (!visible || opacity <= 0.0f) continue;
    lod::PointStore* store = kept.at(path).get();
    glm::u8vec3 color(0);
    if (node.model().has_color()) {
      const scene::Color& c = node.model().color();
      color = glm::u8vec3(glm::clamp(glm::vec3(c.r(), c.g(), c.b()), 0.0f, 1.0f) * 255.0f + 0.5f);
    }
    instances.push_back({store, world * storeModel(*store), opacity, color});
  }
  // Stores no model uses any more: the loaders let go of them first, then they close.
  for (auto& [path, store] : mStores)
    for (ChunkStreamer* s : streamers)
      if (s) s->forget(*store);
  mStores = std::move(kept);
  return instances;
}

void SceneDrawList::clear(std::span<ChunkStreamer* const> streamers) {
  for (auto& [path, store] : mStores)
    for (ChunkStreamer* s : streamers)
      if (s) s->forget(*store);
  mStores.clear();
}

uint64_t SceneDrawList::storeBytes() const {
  uint64_t bytes = 0;
  for (const auto& [path, store] : mStores) bytes += store->summary().file_bytes;
  return bytes;
}

RenderOptions SceneDrawList::options(const sync::SceneGraph& graph, float splat_scale) {
  const scene::Settings& s = graph.settings();
  RenderOptions o;
  o.lod_pixels = s.lod_pixels();
  o.background = glm::vec3(s.background().r(), s.background().g(), s.background().b());
  o.edl.strength = s.shading() == scene::SHADING_EDL ? 1.0f : 0.0f;
  o.splat_scale = splat_scale;
  o.spbr.ensembles = std::max<uint32_t>(1, s.spbr_ensembles());
  return o;
}

}  // namespace tessera::render
