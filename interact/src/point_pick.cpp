#include <tessera/interact/point_pick.h>

#include <algorithm>
#include <limits>
#include <vector>

#include "ray_box.h"

namespace tessera::interact {


std::optional<glm::dvec3> pickPoint(std::span<const render::ModelInstance> models,
                                    const glm::dvec3& origin, const glm::dvec3& dir,
                                    const PickOptions& options) {
  double best_world = std::numeric_limits<double>::infinity();
  std::optional<glm::dvec3> best;
  for (const render::ModelInstance& m : models) {
    if (!m.store) continue;  // meshes are picked through the frame's pick ids
    lod::PointStore& store = *m.store;
    // Into the store's local frame; distances there are scaled by the model's scale, which the
    // hit test absorbs by comparing in local units and ranking hits in world units.
    const glm::dmat4 inv = glm::inverse(m.model);
    const glm::dvec3 o = glm::dvec3(inv * glm::dvec4(origin, 1.0));
    glm::dvec3 d = glm::dvec3(inv * glm::dvec4(dir, 0.0));
    const double local_per_world = glm::length(d) / glm::length(dir);
    d = glm::normalize(d);
    // What the model's CLIP nodes cut away is not there to pick (the store's frame, double).
    const render::ClipPlanes clip = m.clip.transformed(m.model);
    double best_t = std::numeric_limits<double>::infinity();
    // Nearest boxes first, so far chunks are skipped once a hit is closer.
    std::vector<std::pair<double, lod::NodeId>> open = {{0.0, store.root()}};
    size_t chunks = 0;
    while (!open.empty() && chunks < options.max_chunks) {
      std::pop_heap(open.begin(), open.end(), std::greater<>());
      const auto [t_enter, id] = open.back();
      open.pop_back();
      if (t_enter > best_t) break;
      const lod::NodeInfo info = store.node(id);
      // Refine while the node's samples are sparser than the pick cone is wide at the box.
      const double cone = options.pixel_angle * options.radius_px * std::max(t_enter, 1e-9);
      if (!info.leaf() && info.spacing > cone) {
        try {
          for (lod::NodeId c : store.children(id)) {
            const lod::NodeInfo ci = store.node(c);
            if (auto t = enter(o, d, ci.box_min, ci.box_max)) {
              open.emplace_back(*t, c);
              std::push_heap(open.begin(), open.end(), std::greater<>());
            }
          }
          continue;
        } catch (const lod::StoreError&) {  // a corrupt page: use this node's own samples
        }
      }
      std::shared_ptr<const lod::ChunkPoints> pts;
      try {
        pts = store.loadChunk(id);
      } catch (const lod::StoreError&) {
        continue;
      }
      ++chunks;
      for (const glm::vec3& p : pts->positions) {
        const glm::dvec3 q = pts->offset + glm::dvec3(p) - o;
        const double t = glm::dot(q, d);
        if (t <= 0.0 || t >= best_t) continue;
        if (!clip.empty() && !clip.keeps(pts->offset + glm::dvec3(p))) continue;
        const double r =
            std::max(double(info.spacing), options.pixel_angle * options.radius_px * t);
        if (glm::dot(q, q) - t * t <= r * r) best_t = t;
      }
    }
    if (best_t < std::numeric_limits<double>::infinity() && best_t / local_per_world < best_world) {
      best_world = best_t / local_per_world;
      best = origin + glm::normalize(dir) * best_world;
    }
  }
  return best;
}

}  // namespace tessera::interact
