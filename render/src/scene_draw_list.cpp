#include <tessera/render/scene_draw_list.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <stdexcept>

#include <tessera/lod/store_cache.h>
#include <tessera/sync/config.h>
#include <tessera/sync/transform.h>
#include <tessera/sync/vec3.h>

namespace tessera::render {

namespace {

glm::dmat4 transformOf(const scene::SceneNode& node) {
  return sync::transformMatrix(node.transform());
}

}  // namespace

NodePlacement placeNode(const sync::SceneGraph& graph, sync::SceneGraph::NodeId id) {
  const scene::SceneNode& node = graph.node(id);
  // Up the tree: parents' transforms apply after the node's own; any hidden one hides it.
  NodePlacement p;
  p.visible = node.visible();
  p.opacity = node.opacity();
  p.world = transformOf(node);
  for (auto parent = node.parent(); p.visible && parent != sync::SceneGraph::kRoot;) {
    const scene::SceneNode& up = graph.node(parent);
    p.visible = up.visible();
    p.opacity *= up.opacity();
    p.world = transformOf(up) * p.world;
    parent = up.parent();
  }
  return p;
}

sync::SceneGraph loadSceneWithStores(const std::string& path, const std::string& who) {
  scene::SceneFile scene = sync::loadSceneFile(path);
  for (int i = 0; i < scene.nodes_size(); ++i) {
    scene::SceneNode& n = *scene.mutable_nodes(i);
    if (n.kind() != scene::SceneNode::MODEL) continue;
    scene::ModelPayload& m = *n.mutable_model();
    if (SceneDrawList::isMeshPath(m.store())) {
      // A see-through mesh is drawn from points on its triangles: build them now, before any
      // node needs them (they are built on first use when a mesh turns see-through later).
      if (n.has_opacity() && n.opacity() < 1.0f) {
        try {
          lod::cachedStoreFor(m.store(), who);
        } catch (const std::exception& e) {
          throw std::runtime_error(who + ": " + path + ": nodes[" + std::to_string(i) +
                                   "].model.store: " + m.store() +
                                   ": cannot sample the mesh for see-through drawing: " + e.what());
        }
      }
      continue;
    }
    if (std::filesystem::path(m.store()).extension() == ".tlod") continue;
    try {
      m.set_store(lod::cachedStoreFor(m.store(), who).string());
    } catch (const std::exception& e) {
      throw std::runtime_error(who + ": " + path + ": nodes[" + std::to_string(i) +
                               "].model.store: " + m.store() +
                               " is neither a .tlod store nor a scan that can be built into "
                               "one: " +
                               e.what());
    }
  }
  return sync::SceneGraph::fromFile(scene);
}

bool SceneDrawList::isMeshPath(const std::string& path) {
  return std::filesystem::path(path).extension() == ".tmesh";
}

namespace {
constexpr std::string_view kPointsSuffix = "#points";
}  // namespace

std::optional<std::string> SceneDrawList::meshOfPointsKey(const std::string& key) {
  if (!key.ends_with(kPointsSuffix)) return std::nullopt;
  std::string mesh = key.substr(0, key.size() - kPointsSuffix.size());
  if (!isMeshPath(mesh)) return std::nullopt;
  return mesh;
}

std::unique_ptr<lod::PointStore> SceneDrawList::openLocalStore(const std::string& key) {
  if (const auto mesh = meshOfPointsKey(key))  // a see-through mesh's points
    return lod::PointStore::open(lod::cachedStoreFor(*mesh, "render::SceneDrawList", true));
  return lod::PointStore::open(key);
}

std::string SceneDrawList::storeKey(const sync::SceneGraph& graph, uint32_t id) {
  const std::string& path = graph.node(id).model().store();
  if (isMeshPath(path) && placeNode(graph, id).opacity < 1.0f)
    return path + std::string(kPointsSuffix);
  return path;
}

const std::vector<ModelInstance>& SceneDrawList::update(const sync::SceneGraph& graph,
                                                        const sync::SceneChanges& changes,
                                                        std::span<ChunkStreamer* const> streamers) {
  mVisited = 0;
  const bool everything = changes.everything || !mStarted;
  // Samplings that ended: their models are looked at again; one no model waits for any more is
  // let go.
  std::vector<uint32_t> nodes = changes.nodes;
  for (auto it = mSampling.begin(); it != mSampling.end();) {
    if (it->second.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
      ++it;
      continue;
    }
    bool waited = false;
    for (const auto& [id, key] : mWaiting) {
      if (key != it->first) continue;
      nodes.push_back(id);
      waited = true;
    }
    if (waited) {
      ++it;
    } else {
      try {
        it->second.get();
      } catch (const std::exception&) {  // nobody needs it
      }
      it = mSampling.erase(it);
    }
  }
  if (!everything && nodes.empty()) return mInstances;

  // The nodes to look at again: every node, or the changed ones and their subtrees (a group's
  // transform, opacity or visibility reaches all models under it). Deleted ones go.
  std::set<uint32_t> dirty, gone;
  std::vector<uint32_t> stack;
  if (everything) {
    for (const auto& [id, e] : mEntries) gone.insert(id);
    stack = graph.children(sync::SceneGraph::kRoot);
  } else {
    for (const uint32_t id : nodes) {
      if (graph.contains(id)) {
        stack.push_back(id);
      } else {
        gone.insert(id);
      }
    }
  }
  while (!stack.empty()) {
    const uint32_t id = stack.back();
    stack.pop_back();
    if (!dirty.insert(id).second) continue;
    gone.erase(id);
    for (const uint32_t c : graph.children(id)) stack.push_back(c);
  }
  mVisited = dirty.size();

  // New stores first, so a failure leaves everything as it was.
  std::map<std::string, std::unique_ptr<lod::PointStore>> opened;
  std::map<std::string, std::unique_ptr<lod::MeshStore>> opened_meshes;
  for (const uint32_t id : dirty) {
    const scene::SceneNode& node = graph.node(id);
    if (node.kind() != scene::SceneNode::MODEL) continue;
    const std::string path = storeKey(graph, id);
    if (mStores.count(path) || opened.count(path) || mMeshStores.count(path) ||
        opened_meshes.count(path))
      continue;
    try {
      if (isMeshPath(path)) {
        opened_meshes.emplace(path, mMeshOpener ? mMeshOpener(path) : lod::MeshStore::open(path));
      } else if (const auto mesh = meshOfPointsKey(path); mesh && !mOpener) {
        // Samples: from the store cache when it holds them, else built off the frame while
        // the mesh is drawn opaque.
        auto it = mSampling.find(path);
        if (it == mSampling.end() && lod::cachedStoreReady(*mesh)) {
          opened.emplace(path, openLocalStore(path));
          continue;
        }
        if (it == mSampling.end()) {
          mSampling.emplace(path, std::async(std::launch::async,
                                             [path] { return openLocalStore(path); }));
        } else if (it->second.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
          auto future = std::move(it->second);
          mSampling.erase(it);
          opened.emplace(path, future.get());  // throws what the build threw
          continue;
        }
        if (!mMeshStores.count(*mesh) && !opened_meshes.count(*mesh))
          opened_meshes.emplace(*mesh, mMeshOpener ? mMeshOpener(*mesh)
                                                   : lod::MeshStore::open(*mesh));
      } else {
        opened.emplace(path, mOpener ? mOpener(path) : openLocalStore(path));
      }
    } catch (const std::runtime_error& e) {
      throw lod::StoreError("render::SceneDrawList::update(): model " + std::to_string(id) + " '" +
                            node.name() + "': " + e.what());
    }
  }
  mStores.merge(opened);
  mMeshStores.merge(opened_meshes);
  mStarted = true;

  for (const uint32_t id : gone) {
    mEntries.erase(id);
    mClips.erase(id);
    mWaiting.erase(id);
  }
  for (const uint32_t id : dirty) {
    const scene::SceneNode& node = graph.node(id);
    if (node.kind() == scene::SceneNode::CLIP) {
      // A hidden CLIP node (or one under a hidden group) cuts nothing.
      const NodePlacement placed = placeNode(graph, id);
      if (placed.visible) {
        mClips[id] = {clipPlanesOf(node.clip(), placed.world),
                      node.clip().invert(),
                      {node.clip().models().begin(), node.clip().models().end()}};
      } else {
        mClips.erase(id);
      }
    } else {
      mClips.erase(id);
    }
    if (node.kind() != scene::SceneNode::MODEL) {
      mEntries.erase(id);
      mWaiting.erase(id);
      continue;
    }
    NodePlacement placed = placeNode(graph, id);
    Entry& e = mEntries[id];
    e.path = storeKey(graph, id);
    mWaiting.erase(id);
    if (mSampling.count(e.path)) {  // its samples are being built: the mesh, opaque, meanwhile
      mWaiting[id] = e.path;
      e.path = *meshOfPointsKey(e.path);
      placed.opacity = 1.0f;
    }
    glm::u8vec3 color(0);
    if (node.model().has_color()) {
      const scene::Color& c = node.model().color();
      color = glm::u8vec3(glm::clamp(glm::vec3(c.r(), c.g(), c.b()), 0.0f, 1.0f) * 255.0f + 0.5f);
    }
    if (isMeshPath(e.path)) {
      lod::MeshStore* mesh = mMeshStores.at(e.path).get();
      e.instance = {nullptr, placed.world * storeModel(*mesh), placed.opacity, color, mesh};
    } else {
      lod::PointStore* store = mStores.at(e.path).get();
      e.instance = {store, placed.world * storeModel(*store), placed.opacity, color};
    }
    e.visible = placed.visible && placed.opacity > 0.0f;
  }

  // Stores no model uses any more: the loaders let go of them first, then they close.
  std::set<std::string> used;
  mInstances.clear();
  mInstanceNodes.clear();
  mDroppedClips = 0;
  for (auto& [id, e] : mEntries) {
    used.insert(e.path);
    if (!e.visible) continue;
    e.instance.node = id;
    e.instance.clip = {};
    for (const auto& [clip_id, c] : mClips) {
      // An empty CLIP node (no planes, no box yet) cuts nothing.
      if (c.planes.empty()) continue;
      if (!c.models.empty() && std::find(c.models.begin(), c.models.end(), id) == c.models.end())
        continue;
      if (!e.instance.clip.addGroup(c.planes, c.invert)) ++mDroppedClips;
    }
    mInstances.push_back(e.instance);
    mInstanceNodes.push_back(id);
  }
  auto close_unused = [&](auto& stores) {
    for (auto it = stores.begin(); it != stores.end();) {
      if (used.count(it->first)) {
        ++it;
        continue;
      }
      for (ChunkStreamer* s : streamers)
        if (s) s->forget(*it->second);
      it = stores.erase(it);
    }
  };
  close_unused(mStores);
  close_unused(mMeshStores);
  return mInstances;
}

std::vector<glm::dvec4> SceneDrawList::clipPlanesOf(const scene::ClipPayload& clip,
                                                    const glm::dmat4& world) {
  ClipPlanes node;  // one group, the node frame
  if (clip.has_box_half_extents()) {
    const auto& c = clip.box_center();
    const auto& h = clip.box_half_extents();
    node.addGroup(boxPlanes({c.x(), c.y(), c.z()}, {h.x(), h.y(), h.z()}), false);
  } else {
    std::vector<glm::dvec4> planes;
    for (int i = 0; i + 3 < clip.planes_size(); i += 4)
      planes.emplace_back(clip.planes(i), clip.planes(i + 1), clip.planes(i + 2),
                          clip.planes(i + 3));
    node.addGroup(planes, false);
  }
  // The node frame's planes for world positions: x_node = inverse(world) x_world.
  const ClipPlanes in_world = node.transformed(glm::inverse(world));
  return {in_world.planes.begin(), in_world.planes.begin() + in_world.count};
}

const std::vector<ModelInstance>& SceneDrawList::finishSampling(
    const sync::SceneGraph& graph, std::span<ChunkStreamer* const> streamers) {
  for (auto& [key, build] : mSampling) build.wait();
  return update(graph, sync::SceneChanges(), streamers);
}

void SceneDrawList::clear(std::span<ChunkStreamer* const> streamers) {
  for (auto& [key, build] : mSampling) build.wait();
  mSampling.clear();
  mWaiting.clear();
  for (auto& [path, store] : mStores)
    for (ChunkStreamer* s : streamers)
      if (s) s->forget(*store);
  for (auto& [path, store] : mMeshStores)
    for (ChunkStreamer* s : streamers)
      if (s) s->forget(*store);
  mStores.clear();
  mMeshStores.clear();
  mEntries.clear();
  mClips.clear();
  mInstances.clear();
  mInstanceNodes.clear();
  mStarted = false;
}

uint64_t SceneDrawList::storeBytes() const {
  uint64_t bytes = 0;
  for (const auto& [path, store] : mStores) bytes += store->summary().file_bytes;
  for (const auto& [path, store] : mMeshStores) bytes += store->summary().file_bytes;
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
  if (s.has_points_per_pixel()) o.budget_per_covered_pixel = s.points_per_pixel();
  const scene::Analysis& a = s.analysis();
  if (a.relative_depth_radius() > 0 || a.relative_depth_radius_m() > 0.0f) {
    o.relative_depth.enabled = true;
    o.relative_depth.radius = int(std::clamp<uint32_t>(a.relative_depth_radius(), 1,
                                                       uint32_t(kMaxRelativeDepthRadius)));
    if (a.relative_depth_radius_m() > 0.0f) {  // metres at the camera's distance to its target
      const config::Camera& c = graph.camera();
      o.relative_depth.radius_m = a.relative_depth_radius_m();
      o.relative_depth.radius_depth =
          std::max(1e-9, glm::length(sync::vec(c.target()) - sync::vec(c.eye())));
    }
    if (a.has_relative_depth_lo() && a.relative_depth_lo() < a.relative_depth_hi())
      o.relative_depth.range = glm::vec2(a.relative_depth_lo(), a.relative_depth_hi());
  }
  o.stored_ao = a.stored_ao() == scene::Analysis::STORED_AO_OFF     ? StoredAo::kOff
                : a.stored_ao() == scene::Analysis::STORED_AO_ALONE ? StoredAo::kAlone
                                                                     : StoredAo::kModulate;
  if (a.ao_strength() > 0.0f) {
    o.ao.enabled = true;
    o.ao.strength = a.ao_strength();
    o.ao.radius = a.ao_radius();
    if (a.has_ao_radius_px()) o.ao.radius_px = a.ao_radius_px();
    if (a.has_ao_slices()) o.ao.slices = int(a.ao_slices());
    o.ao.half_resolution = !a.has_ao_half_resolution() || a.ao_half_resolution();
    o.ao_grid.enabled = a.ao_grid();
  }
  if (a.contour_interval() > 0.0) {
    o.contours.enabled = true;
    o.contours.interval = a.contour_interval();
    o.contours.phase = a.contour_phase();
    const glm::dvec3 axis(a.contour_axis().x(), a.contour_axis().y(), a.contour_axis().z());
    if (glm::length(axis) > 0.0) {
      o.contours.height = true;
      o.contours.axis = axis;
    }
  }
  return o;
}

}  // namespace tessera::render
