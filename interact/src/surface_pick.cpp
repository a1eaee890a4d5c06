#include <tessera/interact/surface_pick.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <vector>

#include <tessera/core/symmetric_eigen.h>
#include <tessera/lod/mesh_store.h>
#include <tessera/lod/triangle_geometry.h>

#include "ray_box.h"

namespace tessera::interact {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// A model's frame: local = inverse * world; lengths scale by `world_per_local` (the scenes'
/// transforms are similarities: rotation, translation, one scale).
struct Frame {
  glm::dmat4 model{1.0}, inverse{1.0};
  double world_per_local = 1.0;
  explicit Frame(const glm::dmat4& m)
      : model(m),
        inverse(glm::inverse(m)),
        world_per_local(std::cbrt(std::abs(glm::determinant(glm::dmat3(m))))) {}
  glm::dvec3 local(const glm::dvec3& w) const { return glm::dvec3(inverse * glm::dvec4(w, 1.0)); }
  glm::dvec3 world(const glm::dvec3& l) const { return glm::dvec3(model * glm::dvec4(l, 1.0)); }
};


double boxDistance(const glm::dvec3& p, const glm::dvec3& lo, const glm::dvec3& hi) {
  return glm::length(glm::max(glm::max(lo - p, glm::dvec3(0.0)), p - hi));
}

/// Nearest-first traversal of the nodes a ray (widened by `margin(info, t)` around it) enters.
/// `visit(id, info, t_enter)` returns false to stop; only leaves are visited.
void alongRay(lod::LodHierarchy& h, const glm::dvec3& o, const glm::dvec3& d,
              const std::function<double(const lod::NodeInfo&)>& margin,
              const std::function<bool(lod::NodeId, const lod::NodeInfo&, double)>& visit) {
  using Entry = std::pair<double, lod::NodeId>;
  std::vector<Entry> open;
  auto push = [&](lod::NodeId id) {
    const lod::NodeInfo info = h.node(id);
    const glm::dvec3 m(margin(info));
    if (auto t = enter(o, d, info.box_min - m, info.box_max + m)) {
      open.emplace_back(*t, id);
      std::push_heap(open.begin(), open.end(), std::greater<>());
    }
  };
  push(h.root());
  while (!open.empty()) {
    std::pop_heap(open.begin(), open.end(), std::greater<>());
    const auto [t, id] = open.back();
    open.pop_back();
    const lod::NodeInfo info = h.node(id);
    if (!info.leaf()) {
      try {
        for (lod::NodeId c : h.children(id)) push(c);
      } catch (const std::exception&) {  // a corrupt hierarchy page: its subtree is skipped
      }
      continue;
    }
    if (!visit(id, info, t)) return;
  }
}

struct PointCandidate {
  double t = kInf, perp_px = kInf;
  lod::NodeId node = lod::kNoNode;
  uint32_t index = 0;
  glm::dvec3 local{0.0};
  double uncertainty = 0.0;  // local units
};

std::optional<SurfacePick> pickPoints(lod::PointStore& store, const Frame& f,
                                      const render::ClipPlanes& clip, const glm::dvec3& origin,
                                      const glm::dvec3& dir, const PickOptions& options) {
  const glm::dvec3 o = f.local(origin);
  const glm::dvec3 d = glm::normalize(glm::dvec3(f.inverse * glm::dvec4(dir, 0.0)));
  const double per_px = options.pixel_angle;  // radians a pixel: the cone's width at distance t
  auto cone = [&](double t) { return per_px * options.radius_px * std::max(t, 0.0); };
  std::vector<PointCandidate> hits;
  double front = kInf, slab = 0.0;
  size_t chunks = 0;
  alongRay(
      store, o, d,
      [&](const lod::NodeInfo& info) {
        const glm::dvec3 c = 0.5 * (info.box_min + info.box_max);
        const double far = glm::length(c - o) + 0.5 * glm::length(info.box_max - info.box_min);
        return cone(far) + double(info.spacing);
      },
      [&](lod::NodeId id, const lod::NodeInfo& info, double t_enter) {
        if (t_enter > front + slab || chunks >= options.max_chunks) return false;
        std::shared_ptr<const lod::ChunkPoints> pts;
        try {
          pts = store.loadChunk(id);
        } catch (const lod::StoreError&) {
          return true;
        }
        ++chunks;
        for (size_t i = 0; i < pts->positions.size(); ++i) {
          const glm::dvec3 p = pts->offset + glm::dvec3(pts->positions[i]);
          const glm::dvec3 q = p - o;
          const double t = glm::dot(q, d);
          if (t <= 0.0) continue;
          if (!clip.empty() && !clip.keeps(p)) continue;  // cut away: not there to pick
          const double r = std::max(cone(t), double(info.spacing));
          const double perp2 = std::max(glm::dot(q, q) - t * t, 0.0);
          if (perp2 > r * r) continue;
          PointCandidate c;
          c.t = t;
          c.perp_px = std::sqrt(perp2) / std::max(per_px * t, 1e-300);
          c.node = id;
          c.index = uint32_t(i);
          c.local = p;
          c.uncertainty = double(info.error_bound) + 0.5 * double(info.spacing);
          hits.push_back(c);
          if (t < front) {
            front = t;
            slab = 2.0 * std::max(double(info.spacing), cone(t) / options.radius_px);
          }
        }
        return true;
      });
  const PointCandidate* best = nullptr;
  for (const PointCandidate& c : hits)
    if (c.t <= front + slab && (!best || c.perp_px < best->perp_px)) best = &c;
  if (!best) return std::nullopt;
  SurfacePick pick;
  pick.point.world = f.world(best->local);
  pick.point.uncertainty = best->uncertainty * f.world_per_local;
  pick.node = best->node;
  pick.index = best->index;
  return pick;
}

/// Möller and Trumbore 1997: the ray parameter of the hit, or nullopt.
std::optional<double> rayTriangle(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& a,
                                  const glm::dvec3& b, const glm::dvec3& c) {
  const glm::dvec3 e1 = b - a, e2 = c - a;
  const glm::dvec3 pv = glm::cross(d, e2);
  const double det = glm::dot(e1, pv);
  if (std::abs(det) < 1e-300) return std::nullopt;
  const double inv = 1.0 / det;
  const glm::dvec3 tv = o - a;
  const double u = glm::dot(tv, pv) * inv;
  if (u < 0.0 || u > 1.0) return std::nullopt;
  const glm::dvec3 qv = glm::cross(tv, e1);
  const double v = glm::dot(d, qv) * inv;
  if (v < 0.0 || u + v > 1.0) return std::nullopt;
  const double t = glm::dot(e2, qv) * inv;
  if (t <= 0.0) return std::nullopt;
  return t;
}

glm::dvec3 vertex(const lod::MeshPatch& p, uint32_t i) {
  return p.offset + glm::dvec3(p.positions[i]);
}

std::optional<SurfacePick> pickTriangles(lod::MeshStore& store, const Frame& f,
                                         const render::ClipPlanes& clip, const glm::dvec3& origin,
                                         const glm::dvec3& dir, const PickOptions& options) {
  const glm::dvec3 o = f.local(origin);
  const glm::dvec3 d = glm::normalize(glm::dvec3(f.inverse * glm::dvec4(dir, 0.0)));
  double best_t = kInf;
  SurfacePick pick;
  size_t patches = 0;
  alongRay(
      store, o, d, [](const lod::NodeInfo&) { return 0.0; },
      [&](lod::NodeId id, const lod::NodeInfo&, double t_enter) {
        if (t_enter > best_t || patches >= options.max_chunks) return false;
        lod::MeshPatch patch;
        try {
          patch = store.readPatch(id);
        } catch (const lod::StoreError&) {
          return true;
        }
        ++patches;
        for (size_t t = 0; t < patch.triangles(); ++t) {
          const glm::dvec3 a = vertex(patch, patch.indices[3 * t]),
                           b = vertex(patch, patch.indices[3 * t + 1]),
                           c = vertex(patch, patch.indices[3 * t + 2]);
          // A hit where the cut removed the surface goes on to what lies behind it.
          if (auto hit = rayTriangle(o, d, a, b, c);
              hit && *hit < best_t && (clip.empty() || clip.keeps(o + *hit * d))) {
            best_t = *hit;
            pick.node = id;
            pick.index = uint32_t(t);
            const glm::dvec3 n = glm::cross(b - a, c - a);
            // Normals go through the inverse transpose (a similarity: the rotation part).
            pick.normal =
                glm::normalize(glm::dvec3(glm::transpose(f.inverse) * glm::dvec4(n, 0.0)));
          }
        }
        return true;
      });
  if (!(best_t < kInf)) return std::nullopt;
  pick.triangle = true;
  pick.point.world = f.world(o + best_t * d);
  pick.point.uncertainty = 0.5 * std::sqrt(3.0) * store.summary().step * f.world_per_local;
  return pick;
}

/// Every leaf whose box lies within `r` of `q`.
void leavesNear(lod::LodHierarchy& h, const glm::dvec3& q, double r,
                const std::function<void(lod::NodeId)>& visit) {
  std::vector<lod::NodeId> stack = {h.root()};
  while (!stack.empty()) {
    const lod::NodeId id = stack.back();
    stack.pop_back();
    const lod::NodeInfo info = h.node(id);
    if (boxDistance(q, info.box_min, info.box_max) > r) continue;
    if (info.leaf()) {
      visit(id);
      continue;
    }
    try {
      for (lod::NodeId c : h.children(id)) stack.push_back(c);
    } catch (const std::exception&) {
    }
  }
}

/// Leaves in order of their boxes' distance to `q`, up to `reach`; `visit(id)` returns the
/// distance of the nearest element found so far, and the search stops at boxes farther.
void leavesNearestFirst(lod::LodHierarchy& h, const glm::dvec3& q, double reach,
                        const std::function<double(lod::NodeId)>& visit) {
  using Entry = std::pair<double, lod::NodeId>;
  std::vector<Entry> open = {{0.0, h.root()}};
  double best = reach;
  while (!open.empty()) {
    std::pop_heap(open.begin(), open.end(), std::greater<>());
    const auto [d, id] = open.back();
    open.pop_back();
    if (d > best) break;
    const lod::NodeInfo info = h.node(id);
    if (info.leaf()) {
      best = std::min(best, visit(id));
      continue;
    }
    try {
      for (lod::NodeId c : h.children(id)) {
        const lod::NodeInfo ci = h.node(c);
        const double dc = boxDistance(q, ci.box_min, ci.box_max);
        if (dc > best) continue;
        open.emplace_back(dc, c);
        std::push_heap(open.begin(), open.end(), std::greater<>());
      }
    } catch (const std::exception&) {
    }
  }
}

}  // namespace

std::optional<SurfacePick> pickSurface(std::span<const render::ModelInstance> models,
                                       const glm::dvec3& origin, const glm::dvec3& dir,
                                       const PickOptions& options,
                                       std::optional<size_t> only_model) {
  if (!(glm::length(dir) > 0.0) || !std::isfinite(glm::length(dir)) ||
      !std::isfinite(glm::length(origin)))
    return std::nullopt;
  std::optional<SurfacePick> best;
  double best_distance = kInf;
  for (size_t i = 0; i < models.size(); ++i) {
    if (only_model && *only_model != i) continue;
    const render::ModelInstance& m = models[i];
    const Frame f(m.model);
    if (!(f.world_per_local > 0.0) || !std::isfinite(f.world_per_local)) continue;
    // The model's CLIP nodes in its store's frame (double): what they cut away is not picked.
    const render::ClipPlanes clip = m.clip.transformed(m.model);
    std::optional<SurfacePick> p = m.mesh    ? pickTriangles(*m.mesh, f, clip, origin, dir, options)
                                   : m.store ? pickPoints(*m.store, f, clip, origin, dir, options)
                                             : std::nullopt;
    if (!p) continue;
    const double distance = glm::length(p->point.world - origin);
    if (distance < best_distance) {
      best_distance = distance;
      p->model = i;
      best = p;
    }
  }
  return best;
}

annotate::SurfaceProjector pointSurfaceProjector(const render::ModelInstance& model, double radius,
                                       double reach) {
  if (!model.store) throw annotate::MeasureError("interact::pointSurfaceProjector(): not a point model");
  lod::PointStore* store = model.store;
  const Frame f(model.model);
  const lod::StoreSummary& s = store->summary();
  const double fixed_r = radius > 0.0 ? radius / f.world_per_local : 0.0;
  const double far = reach > 0.0 ? reach / f.world_per_local
                                 : 0.1 * glm::length(s.bbox_max - s.bbox_min);
  return [store, f, fixed_r, far](const glm::dvec3& p) -> std::optional<glm::dvec3> {
    glm::dvec3 q = f.local(p);
    double r = fixed_r;
    // The nearest sample first (the point may lie far off the surface, e.g. the middle of a
    // flat triangulation spanning a curved region), then a plane fitted around it, twice: the
    // second fit is centred where the first projection landed (a moving least-squares step).
    std::optional<glm::dvec3> nearest;
    leavesNearestFirst(*store, q, far, [&](lod::NodeId id) {
      double best = far;
      if (nearest) best = glm::length(*nearest - q);
      std::shared_ptr<const lod::ChunkPoints> pts;
      try {
        pts = store->loadChunk(id);
      } catch (const lod::StoreError&) {
        return best;
      }
      for (const glm::vec3& v : pts->positions) {
        const glm::dvec3 sample = pts->offset + glm::dvec3(v);
        const double d = glm::length(sample - q);
        if (d < best) {
          best = d;
          nearest = sample;
          if (fixed_r <= 0.0) r = 4.0 * double(store->node(id).spacing);  // the local density
        }
      }
      return best;
    });
    if (!nearest) return std::nullopt;
    glm::dvec3 centre = *nearest;
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<glm::dvec3> near;
      for (int widen = 0; widen < 3 && near.size() < 8; ++widen, r *= 2.0) {
        near.clear();
      leavesNear(*store, centre, r, [&](lod::NodeId id) {
        std::shared_ptr<const lod::ChunkPoints> pts;
        try {
          pts = store->loadChunk(id);
        } catch (const lod::StoreError&) {
          return;
        }
        for (const glm::vec3& v : pts->positions) {
          const glm::dvec3 sample = pts->offset + glm::dvec3(v);
          if (glm::dot(sample - centre, sample - centre) <= r * r) near.push_back(sample);
        }
      });
      }
      if (near.size() < 8) return std::nullopt;
      glm::dvec3 c(0.0);
      for (const glm::dvec3& sample : near) c += sample;
      c /= double(near.size());
      glm::dmat3 cov(0.0);
      for (const glm::dvec3& sample : near) cov += glm::outerProduct(sample - c, sample - c);
      const glm::dvec3 n = smallestEigenvector(cov);
      centre = q - n * glm::dot(q - c, n);
    }
    return f.world(centre);
  };
}

annotate::SurfaceProjector meshSurfaceProjector(const render::ModelInstance& model, double reach) {
  if (!model.mesh) throw annotate::MeasureError("interact::meshSurfaceProjector(): not a mesh model");
  lod::MeshStore* store = model.mesh;
  const Frame f(model.model);
  const lod::MeshSummary& s = store->summary();
  const double far =
      reach > 0.0 ? reach / f.world_per_local : 0.1 * glm::length(s.bbox_max - s.bbox_min);
  auto patches = std::make_shared<std::map<lod::NodeId, std::shared_ptr<lod::MeshPatch>>>();
  return [store, f, far, patches](const glm::dvec3& p) -> std::optional<glm::dvec3> {
    const glm::dvec3 q = f.local(p);
    double best = far;
    std::optional<glm::dvec3> out;
    leavesNearestFirst(*store, q, far, [&](lod::NodeId id) {
      auto it = patches->find(id);
      if (it == patches->end()) {
        if (patches->size() > 512) patches->clear();  // bounded: about 100 MB at most
        std::shared_ptr<lod::MeshPatch> decoded;
        try {
          decoded = std::make_shared<lod::MeshPatch>(store->readPatch(id));
        } catch (const lod::StoreError&) {
          return best;
        }
        it = patches->emplace(id, std::move(decoded)).first;
      }
      const lod::MeshPatch& patch = *it->second;
      for (size_t t = 0; t < patch.triangles(); ++t) {
        const glm::dvec3 c =
            lod::closestOnTriangle(q, vertex(patch, patch.indices[3 * t]),
                              vertex(patch, patch.indices[3 * t + 1]),
                              vertex(patch, patch.indices[3 * t + 2]));
        const double d = glm::length(c - q);
        if (d <= best) {
          best = d;
          out = c;
        }
      }
      return best;
    });
    if (!out) return std::nullopt;
    return f.world(*out);
  };
}

double dataResolution(const render::ModelInstance& model) {
  const Frame f(model.model);
  if (model.mesh) return model.mesh->summary().step * f.world_per_local;
  if (model.store) return model.store->summary().spacing_finest * f.world_per_local;
  return 0.0;
}

PickOptions pickOptionsFor(const render::ViewSetup& view) {
  PickOptions options;
  // Perspective: the vertical field of view over the height (projection[1][1] = cot(fovy/2)).
  options.pixel_angle = 2.0 * std::atan(1.0 / view.projection[1][1]) / view.height;
  return options;
}

std::optional<SurfacePick> pickUnderPixel(const render::ViewRenderer& renderer,
                                          std::span<const render::ModelInstance> models,
                                          const render::ViewSetup& view, glm::dvec2 px) {
  if (!(px.x >= 0 && px.y >= 0 && px.x < view.width && px.y < view.height)) return std::nullopt;
  const auto hit = renderer.pick(uint32_t(px.x), uint32_t(px.y));
  const glm::dmat4 world_from_clip = glm::inverse(view.projection * view.view);
  const glm::dvec2 centre = glm::floor(px) + 0.5;
  const double nx = centre.x / view.width * 2.0 - 1.0, ny = 1.0 - centre.y / view.height * 2.0;
  const glm::dvec4 a = world_from_clip * glm::dvec4(nx, ny, -1.0, 1.0);
  const glm::dvec4 b = world_from_clip * glm::dvec4(nx, ny, 1.0, 1.0);
  const glm::dvec3 from = glm::dvec3(a) / a.w, dir = glm::normalize(glm::dvec3(b) / b.w - from);
  const PickOptions options = pickOptionsFor(view);
  // A see-through frame has no pick ids: then every model's data along the ray.
  if (!hit) return pickSurface(models, from, dir, options);
  std::optional<SurfacePick> at = pickSurface(models, from, dir, options, hit->model);
  if (!at) {
    at = SurfacePick{};
    at->point.world = hit->world;
    at->point.uncertainty = glm::length(hit->world - from) * options.pixel_angle;
    at->model = hit->model;
  }
  return at;
}

}  // namespace tessera::interact
