#include <tessera/render/lod_selector.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <optional>
#include <queue>
#include <unordered_set>

namespace tessera::render {
namespace {

/// A box's rectangle on the screen, pixels (x0, y0, x1, y1; y up), unclipped.
struct ScreenRect {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  double area() const { return (x1 - x0) * (y1 - y0); }
  ScreenRect grown(double r) const { return {x0 - r, y0 - r, x1 + r, y1 + r}; }
};

/// The bounding rectangle of the box's eight projected corners; false when a corner lies on or
/// behind the eye's plane (the box then has no bounded rectangle).
bool screenRect(const glm::dmat4& clip_from_local, const glm::dvec3& lo, const glm::dvec3& hi,
                const ViewSetup& view, ScreenRect& rect) {
  rect = {std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
          std::numeric_limits<double>::lowest(), std::numeric_limits<double>::lowest()};
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 p(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
    const glm::dvec4 c = clip_from_local * glm::dvec4(p, 1.0);
    if (!(c.w > 0.0)) return false;
    const double x = (c.x / c.w * 0.5 + 0.5) * view.width;
    const double y = (c.y / c.w * 0.5 + 0.5) * view.height;
    rect = {std::min(rect.x0, x), std::min(rect.y0, y), std::max(rect.x1, x), std::max(rect.y1, y)};
  }
  return true;
}

/// Splat area (pixels) that the cut nodes chosen so far put on each cell of a coarse screen grid.
class CoverageGrid {
 public:
  CoverageGrid(uint32_t width, uint32_t height, uint32_t cell_px)
      : mWidth(width),
        mHeight(height),
        mCell(std::max(cell_px, 1u)),
        mCols((width + mCell - 1) / mCell),
        mRows((height + mCell - 1) / mCell),
        mArea(size_t(mCols) * mRows, 0.0) {}

  /// Spreads `splat_area` pixels evenly over `rect` (only the part on the screen is kept).
  void add(const ScreenRect& rect, double splat_area) {
    const double area = rect.area();
    if (!(area > 0.0)) return;
    forCells(rect, [&](size_t cell, double overlap, double) {
      mArea[cell] += splat_area * overlap / area;
      return true;
    });
  }

  /// Whether splats cover every cell under the on-screen part of `rect` `layers` times over.
  bool covered(const ScreenRect& rect, double layers) const {
    bool any = false;
    const bool all = forCells(rect, [&](size_t cell, double, double cell_area) {
      any = true;
      return mArea[cell] >= layers * cell_area;
    });
    return any && all;
  }

  /// The screen area, pixels, of the cells splats cover `layers` times over.
  double coveredArea(double layers) const {
    double area = 0.0;
    forCells({0.0, 0.0, double(mWidth), double(mHeight)}, [&](size_t cell, double, double a) {
      if (mArea[cell] >= layers * a) area += a;
      return true;
    });
    return area;
  }

 private:
  /// Calls f(cell index, overlap with rect, cell area on screen) for every cell that `rect`
  /// overlaps, until f returns false; returns whether it never did.
  template <typename F>
  bool forCells(const ScreenRect& r, F&& f) const {
    const double x0 = std::max(r.x0, 0.0), y0 = std::max(r.y0, 0.0);
    const double x1 = std::min(r.x1, double(mWidth)), y1 = std::min(r.y1, double(mHeight));
    if (!(x1 > x0 && y1 > y0)) return true;
    const auto c0 = uint32_t(x0 / mCell), r0 = uint32_t(y0 / mCell);
    const uint32_t c1 = std::min(mCols - 1, uint32_t(x1 / mCell));
    const uint32_t r1 = std::min(mRows - 1, uint32_t(y1 / mCell));
    for (uint32_t row = r0; row <= r1; ++row) {
      const double cy0 = double(row) * mCell, cy1 = std::min(cy0 + mCell, double(mHeight));
      const double oy = std::min(y1, cy1) - std::max(y0, cy0);
      for (uint32_t col = c0; col <= c1; ++col) {
        const double cx0 = double(col) * mCell, cx1 = std::min(cx0 + mCell, double(mWidth));
        const double ox = std::min(x1, cx1) - std::max(x0, cx0);
        if (ox <= 0.0 || oy <= 0.0) continue;
        if (!f(size_t(row) * mCols + col, ox * oy, (cx1 - cx0) * (cy1 - cy0))) return false;
      }
    }
    return true;
  }

  uint32_t mWidth, mHeight, mCell, mCols, mRows;
  std::vector<double> mArea;
};

/// What every node test of one selection needs.
struct Selection {
  lod::LodHierarchy& store;
  const ViewSetup& view;
  const CutOptions& options;
  glm::dmat4 clip_from_local;
  Frustum frustum;
  glm::dvec3 eye;  ///< local frame
  double unit;     ///< world units per store unit
  double k;        ///< pixels per world unit at distance one

  /// Splat radius, pixels, for a node's projected spacing `px`.
  double splatRadius(double px) const {
    return std::min(px * options.splat_radius_per_spacing, options.max_splat_radius_px);
  }

  /// Distance from the eye to the box's farthest point, world units.
  double farDistance(const lod::NodeInfo& n) const {
    const glm::dvec3 centre = 0.5 * (n.box_min + n.box_max);
    const glm::dvec3 farthest =
        glm::mix(n.box_max, n.box_min, glm::dvec3(glm::greaterThan(eye, centre)));
    return glm::length(eye - farthest) * unit;
  }

  /// The summed area of a node's splats, pixels, each sized at the box's farthest point (the
  /// smallest) and covering at least its own pixel.
  double splatArea(const lod::NodeInfo& n, double far) const {
    const double r = splatRadius(double(n.spacing) * k / far);
    return double(n.points) * std::max(std::numbers::pi * r * r, 1.0);
  }

  CutNode measure(lod::NodeId id, const lod::NodeInfo& n, int32_t parent) const {
    const glm::dvec3 nearest = glm::clamp(eye, n.box_min, n.box_max);
    const double d = glm::length(eye - nearest) * unit;
    const double px =
        d > 0 ? double(n.spacing) * unit * k / d : std::numeric_limits<double>::infinity();
    CutNode c;
    c.id = id;
    c.projected_spacing_px = std::isfinite(px) ? px : std::numeric_limits<double>::max();
    c.distance = d;
    c.spacing = double(n.spacing) * unit;
    c.level = n.level;
    c.cell = n.cell;
    c.parent = parent;
    return c;
  }
};

/// Whether `a` names a node before `b` (level, then cell): the same in every process.
bool namedBefore(const CutNode& a, const CutNode& b) {
  if (a.level != b.level) return a.level < b.level;
  if (a.cell.x != b.cell.x) return a.cell.x < b.cell.x;
  if (a.cell.y != b.cell.y) return a.cell.y < b.cell.y;
  return a.cell.z < b.cell.z;
}

struct Pending {
  CutNode node;
  lod::NodeInfo info;
};

/// The visible (in the frustum, not hidden) children of a refined node, measured, and their
/// points.
uint64_t visibleChildren(const Selection& s, lod::NodeId id, int32_t parent,
                         const std::unordered_set<lod::NodeId>& hidden,
                         std::vector<Pending>& children) {
  children.clear();
  uint64_t points = 0;
  for (lod::NodeId c : s.store.children(id)) {
    const lod::NodeInfo n = s.store.node(c);
    if (hidden.count(c) || !s.frustum.intersects(n.box_min, n.box_max)) continue;
    children.push_back({s.measure(c, n, parent), n});
    points += n.points;
  }
  return points;
}

/// The spacing test, nearest node first, with the coverage stop when asked for.
void refineNearestFirst(const Selection& s, Cut& cut, std::unordered_set<lod::NodeId>& refined,
                        std::unordered_set<lod::NodeId>& hidden) {
  const CutOptions& o = s.options;
  auto later = [](const Pending& a, const Pending& b) {  // heap order: nearest, then by name
    return a.node.distance != b.node.distance ? a.node.distance > b.node.distance
                                              : namedBefore(b.node, a.node);
  };
  std::priority_queue<Pending, std::vector<Pending>, decltype(later)> queue(later);
  auto push = [&](lod::NodeId id, int32_t parent) {
    ++cut.visited;
    const lod::NodeInfo n = s.store.node(id);
    if (!s.frustum.intersects(n.box_min, n.box_max)) {
      ++cut.culled;
      return;
    }
    queue.push({s.measure(id, n, parent), n});
  };
  std::optional<CoverageGrid> grid;
  if (o.coverage_stop) grid.emplace(s.view.width, s.view.height, o.coverage_cell_px);
  // A cut node covers the nodes it lies entirely in front of: its splats join the grid once the
  // traversal has passed its farthest point (a node within its depth range, as in a thick or
  // noisy surface, may still show through).
  struct Deposit {
    double far;
    ScreenRect rect;
    double area;
    bool operator>(const Deposit& b) const { return far > b.far; }
  };
  std::priority_queue<Deposit, std::vector<Deposit>, std::greater<>> deposits;
  push(s.store.root(), -1);
  while (!queue.empty()) {
    const Pending e = queue.top();
    queue.pop();
    const lod::NodeInfo& n = e.info;
    for (; !deposits.empty() && deposits.top().far <= e.node.distance; deposits.pop())
      grid->add(deposits.top().rect, deposits.top().area);
    bool refine = !n.leaf() && e.node.projected_spacing_px > o.pixel_threshold &&
                  cut.nodes.size() < o.max_nodes;
    ScreenRect rect;
    const bool bounded = grid && screenRect(s.clip_from_local, n.box_min, n.box_max, s.view, rect);
    if (bounded) {
      // What nodes entirely in front drew over the rectangle this node's own splats reach.
      const ScreenRect reach = rect.grown(s.splatRadius(e.node.projected_spacing_px));
      if (o.coverage_hide_layers > 0 && grid->covered(reach, o.coverage_hide_layers)) {
        ++cut.hidden;
        hidden.insert(e.node.id);
        continue;
      }
      if (refine && grid->covered(reach, o.coverage_layers)) {
        refine = false;
        ++cut.covered;
      }
    }
    if (refine && o.may_load_children && !s.store.childrenLoaded(e.node.id) &&
        !o.may_load_children(e.node.id)) {
      refine = false;
      ++cut.pages_deferred;
    }
    if (!refine) {
      cut.nodes.push_back(e.node);
      cut.points += n.points;
      if (bounded) {
        const double far = s.farDistance(n);
        deposits.push({far, rect, s.splatArea(n, far)});
      }
      continue;
    }
    cut.above.push_back(e.node);
    refined.insert(e.node.id);
    const auto index = int32_t(cut.above.size() - 1);
    for (lod::NodeId c : s.store.children(e.node.id)) push(c, index);
  }
  if (!grid) return;
  for (; !deposits.empty(); deposits.pop()) grid->add(deposits.top().rect, deposits.top().area);
  cut.covered_px = grid->coveredArea(1.0);
}

/// A cut without nodes that keeps `full`'s traversal counters (what a cut redone from the same
/// traversal reports).
Cut emptyCutOf(const Cut& full) {
  Cut cut;
  cut.visited = full.visited;
  cut.culled = full.culled;
  cut.pages_deferred = full.pages_deferred;
  cut.covered = full.covered;
  cut.hidden = full.hidden;
  cut.covered_px = full.covered_px;
  return cut;
}

/// Redoes the refinements of `refined` in order of projected spacing, largest first, while the
/// cut stays within `budget` points; the first that does not fit ends the refinement (Potree).
Cut refineWithinBudget(const Selection& s, const Cut& full,
                       const std::unordered_set<lod::NodeId>& refined,
                       const std::unordered_set<lod::NodeId>& hidden, uint64_t budget) {
  Cut cut = emptyCutOf(full);
  auto lower = [](const Pending& a, const Pending& b) {  // heap order: largest spacing first
    if (a.node.projected_spacing_px != b.node.projected_spacing_px)
      return a.node.projected_spacing_px < b.node.projected_spacing_px;
    if (a.node.distance != b.node.distance) return a.node.distance > b.node.distance;
    return namedBefore(b.node, a.node);
  };
  std::priority_queue<Pending, std::vector<Pending>, decltype(lower)> queue(lower);
  const lod::NodeInfo root = s.store.node(s.store.root());
  if (!s.frustum.intersects(root.box_min, root.box_max)) return cut;
  queue.push({s.measure(s.store.root(), root, -1), root});
  cut.points = root.points;
  bool full_budget = false;
  std::vector<Pending> children;
  while (!queue.empty()) {
    const Pending e = queue.top();
    queue.pop();
    if (refined.count(e.node.id)) {
      if (!full_budget) {
        const uint64_t points =
            visibleChildren(s, e.node.id, int32_t(cut.above.size()), hidden, children);
        if (cut.points - e.info.points + points <= budget) {
          cut.points = cut.points - e.info.points + points;
          cut.above.push_back(e.node);
          for (const Pending& c : children) queue.push(c);
          continue;
        }
        full_budget = true;
      }
      ++cut.over_budget;
    }
    cut.nodes.push_back(e.node);
  }
  return cut;
}

/// The cut of the refinements of `refined` that `allowed` also holds (another view's refined
/// nodes: CutOptions::refine_only).
Cut refineOnly(const Selection& s, const Cut& full, const std::unordered_set<lod::NodeId>& refined,
               const std::unordered_set<lod::NodeId>& hidden,
               const std::unordered_set<lod::NodeId>& allowed) {
  Cut cut = emptyCutOf(full);
  const lod::NodeInfo root = s.store.node(s.store.root());
  if (!s.frustum.intersects(root.box_min, root.box_max)) return cut;
  std::vector<Pending> queue{{s.measure(s.store.root(), root, -1), root}}, children;
  for (size_t i = 0; i < queue.size(); ++i) {  // breadth first: parents before children
    const Pending e = queue[i];
    if (refined.count(e.node.id)) {
      if (allowed.count(e.node.id)) {
        cut.above.push_back(e.node);
        visibleChildren(s, e.node.id, int32_t(cut.above.size() - 1), hidden, children);
        queue.insert(queue.end(), children.begin(), children.end());
        continue;
      }
      ++cut.over_budget;
    }
    cut.nodes.push_back(e.node);
    cut.points += e.info.points;
  }
  return cut;
}

}  // namespace

double pixelsPerUnitAtDistanceOne(const ViewSetup& view) {
  // projection[1][1] = 2 n / (t - b): NDC height of one unit at distance one; half the
  // viewport height in pixels per NDC unit.
  return view.projection[1][1] * 0.5 * double(view.height);
}

Cut selectCut(lod::LodHierarchy& store, const glm::dmat4& model, const ViewSetup& view,
              const CutOptions& options) {
  const glm::dmat4 clip_from_local = view.projection * view.view * model;
  const glm::dmat4 local_from_world = glm::inverse(model);
  // Distances are measured in store units; scale them to world units for the projection.
  const Selection s{store,
                    view,
                    options,
                    clip_from_local,
                    Frustum::fromMatrix(clip_from_local),
                    glm::dvec3(local_from_world * glm::dvec4(view.eye_world, 1.0)),
                    std::cbrt(std::abs(glm::determinant(glm::dmat3(model)))),
                    pixelsPerUnitAtDistanceOne(view)};
  Cut cut;
  std::unordered_set<lod::NodeId> refined, hidden;
  refineNearestFirst(s, cut, refined, hidden);
  uint64_t budget = options.point_budget;
  if (budget == 0 && options.budget_per_covered_px > 0.0) {
    const double covered = cut.covered_px > 0.0 ? cut.covered_px : double(view.width) * view.height;
    budget = std::max(uint64_t(std::min(std::ceil(options.budget_per_covered_px * covered), 1e18)),
                      options.budget_floor);
  }
  if (options.refine_only) {
    cut = refineOnly(s, cut, refined, hidden, *options.refine_only);
  } else if (budget > 0 && cut.points > budget) {
    cut = refineWithinBudget(s, cut, refined, hidden, budget);
  }
  cut.point_budget = budget;
  // A node around the eye has no bound: it is always refined, and reported as 0.
  for (auto* list : {&cut.nodes, &cut.above})
    for (CutNode& n : *list)
      if (n.projected_spacing_px == std::numeric_limits<double>::max()) n.projected_spacing_px = 0;
  // Nearest first: the order a loader should fetch them in (ties by name: the same every time).
  std::sort(cut.nodes.begin(), cut.nodes.end(), [](const CutNode& a, const CutNode& b) {
    return a.distance != b.distance ? a.distance < b.distance : namedBefore(a, b);
  });
  return cut;
}

}  // namespace tessera::render
