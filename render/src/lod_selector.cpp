#include <tessera/render/lod_selector.h>

#include <algorithm>
#include <limits>

namespace tessera::render {

double pixelsPerUnitAtDistanceOne(const ViewSetup& view) {
  // projection[1][1] = 2 n / (t - b): NDC height of one unit at distance one; half the
  // viewport height in pixels per NDC unit.
  return view.projection[1][1] * 0.5 * double(view.height);
}

Cut selectCut(lod::LodHierarchy& store, const glm::dmat4& model, const ViewSetup& view,
              const CutOptions& options) {
  Cut cut;
  const glm::dmat4 clip_from_local = view.projection * view.view * model;
  const Frustum frustum = Frustum::fromMatrix(clip_from_local);
  const glm::dmat4 local_from_world = glm::inverse(model);
  const glm::dvec3 eye = glm::dvec3(local_from_world * glm::dvec4(view.eye_world, 1.0));
  // Distances are measured in store units; scale them to world units for the projection.
  const double unit = std::cbrt(std::abs(glm::determinant(glm::dmat3(model))));
  const double k = pixelsPerUnitAtDistanceOne(view);

  struct Entry {
    lod::NodeId id;
    int32_t parent;
  };
  std::vector<Entry> stack{{store.root(), -1}};
  while (!stack.empty()) {
    const auto [id, parent] = stack.back();
    stack.pop_back();
    ++cut.visited;
    const lod::NodeInfo n = store.node(id);
    if (!frustum.intersects(n.box_min, n.box_max)) {
      ++cut.culled;
      continue;
    }
    const glm::dvec3 nearest = glm::clamp(eye, n.box_min, n.box_max);
    const double d = glm::length(eye - nearest) * unit;
    const double px =
        d > 0 ? double(n.spacing) * unit * k / d : std::numeric_limits<double>::infinity();
    const CutNode here{id,    std::isfinite(px) ? px : 0.0, d, double(n.spacing) * unit, n.level,
                       parent};
    bool refine = !n.leaf() && px > options.pixel_threshold && cut.nodes.size() < options.max_nodes;
    if (refine && options.may_load_children && !store.childrenLoaded(id) &&
        !options.may_load_children(id)) {
      refine = false;
      ++cut.pages_deferred;
    }
    if (!refine) {
      cut.nodes.push_back(here);
      cut.points += n.points;
      continue;
    }
    cut.above.push_back(here);
    const auto index = int32_t(cut.above.size() - 1);
    for (lod::NodeId c : store.children(id)) stack.push_back({c, index});
  }
  // Nearest first: the order a loader should fetch them in.
  std::sort(cut.nodes.begin(), cut.nodes.end(),
            [&](const CutNode& a, const CutNode& b) { return a.distance < b.distance; });
  return cut;
}

}  // namespace tessera::render
