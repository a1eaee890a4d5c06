// View-dependent LOD: the cut of a point store's hierarchy that one view (a tile, an eye)
// needs (Bettio et al. 2009, section 4.1). Nodes outside the frustum are culled; a node is
// refined while its projected sample spacing exceeds the pixel threshold, measured as the
// apparent size of a sphere as wide as the spacing at the node box's point nearest the eye
// (a consistent upper bound). Nodes are self-contained, so a cut is drawn from its nodes only.
//
// Two bounds on top of the spacing test, both off by default here (RenderOptions turns the
// coverage stop on for opaque frames):
// - a point budget per view, as Potree users set one: refinements are taken in order of
//   projected spacing (the largest screen error first) while the cut's points stay within it;
//   views that share a picture (a wall's tiles) agree on one cut by refining only what the
//   whole picture's cut refined (CutOptions::refine_only);
// - a coverage stop: nodes are visited nearest first and every cut node's splats are spread over
//   a coarse grid of screen cells; a node whose footprint lies on cells that nearer cut nodes
//   already cover many times over is not refined (an opaque, depth-tested render shows little
//   of it), and one behind still more layers is left out. A volume of points then keeps its
//   front instead of every leaf; a surface, whose layers each cover a pixel about three times,
//   is refined as before unless several of its layers lie in front. The cut then covers every
//   visible leaf at most once (exactly once but for the hidden ones).
// Both depend only on the store and the view, never on timing, so a settled cut is the same
// whatever the loader did.
#pragma once

#include <cstdint>
#include <functional>
#include <unordered_set>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/lod/point_store.h>
#include <tessera/render/tile_frustum.h>

namespace tessera::render {

struct CutOptions {
  double pixel_threshold = 1.0;  ///< refine while projected spacing > this many pixels
  size_t max_nodes = 1 << 20;    ///< stop refining beyond this many nodes (a safety bound)
  /// Most points the cut may hold (0: no limit). Refinements go largest projected spacing first
  /// (ties: nearest, then node id) and stop at the first one that would exceed the budget, as
  /// Potree does; the cut is never coarser than the root, so a budget below the root's points
  /// gives the root.
  uint64_t point_budget = 0;
  /// Without point_budget: a budget of this many points per pixel the cut covers (0: none).
  /// The pixels are the coverage grid's (Cut::covered_px) with the coverage stop, else the
  /// view's: a model seen small gets a small budget, one filling the view a large one.
  double budget_per_covered_px = 0.0;
  /// The budget budget_per_covered_px gives is at least this many points (0: no floor): a cut
  /// that small is cheap to draw, so the budget has nothing to save there and the view keeps
  /// every level its pixels ask for (a small model, a close view of a few scans).
  uint64_t budget_floor = 0;
  /// When set: refine only nodes it holds, in place of a budget. A wall tile passes the ids of
  /// the whole wall's refined nodes (Cut::above of the same store), so every tile draws the
  /// whole wall's budget-limited cut, not a budget of its own. Not owned; outlives the call.
  const std::unordered_set<lod::NodeId>* refine_only = nullptr;
  /// Stop refining where nearer cut nodes already cover the screen (see the top of this file).
  bool coverage_stop = false;
  /// A screen cell counts as covered when the splats of the cut nodes chosen so far would cover
  /// it this many times over: their summed area (each at least a pixel, sized at the node box's
  /// farthest point) over the cell's. A node's splats are spread evenly over its box's screen
  /// rectangle, which underestimates them on surfaces: the conservative side. One layer of a
  /// surface at the default splat scale counts about pi; random splats leave e^-layers open.
  double coverage_layers = 8.0;
  /// A node whose reach lies on cells covered this many times over is left out of the cut
  /// (hidden: no point of it would win a pixel); 0 keeps every node. Set well above
  /// coverage_layers, so only what lies behind many layers (the inside of a volume) goes: at 8
  /// the 10^7-point bunny scan loses 0.1 dB against the full render, at 16 and above nothing.
  double coverage_hide_layers = 16.0;
  uint32_t coverage_cell_px = 8;  ///< side of a grid cell, pixels
  /// Splat radius as a multiple of the projected spacing (RenderOptions::splat_scale / 2) and
  /// its cap in pixels: a node is only stopped when its rectangle grown by its own splat radius
  /// lies on covered cells, so its coarser, larger splats stay inside the covered area.
  double splat_radius_per_spacing = 1.0;
  double max_splat_radius_px = 8.0;
  /// Whether the hierarchy page holding a node's children may be read now. Streaming renderers
  /// answer false for pages not yet in memory (and have the loader thread fetch them), so the
  /// traversal never waits on I/O; such a node ends the refinement for this frame. Empty: read.
  std::function<bool(lod::NodeId)> may_load_children;
};

/// One node of the cut, or one refined node above it (Cut::above).
struct CutNode {
  lod::NodeId id = lod::kNoNode;
  double projected_spacing_px = 0.0;  ///< the bound above, for splat sizes
  double distance = 0.0;              ///< from the eye to the box, world units (load priority)
  double spacing = 0.0;               ///< the node's sample spacing, world units
  uint8_t level = 0;
  /// Octree cell at `level`: with it, the node's name whatever order pages loaded in (ids are
  /// given out as pages load), so ties are broken by it.
  glm::u32vec3 cell{0};
  int32_t parent = -1;  ///< index of the parent in Cut::above, -1 for the root
};

struct Cut {
  std::vector<CutNode> nodes;  ///< the cut, nearest first (ties: level, then cell)
  /// Every refined node (an ancestor of cut nodes), parents before children: what a streaming
  /// renderer draws instead of a cut node whose chunk is not resident yet.
  std::vector<CutNode> above;
  uint64_t points = 0;
  size_t visited = 0;         ///< nodes tested
  size_t culled = 0;          ///< nodes outside the frustum
  size_t pages_deferred = 0;  ///< refinements stopped because may_load_children said no
  size_t covered = 0;         ///< refinements stopped by the coverage stop
  size_t hidden = 0;          ///< nodes left out by the coverage stop (coverage_hide_layers)
  size_t over_budget = 0;     ///< refinements left out to stay within the point budget
  uint64_t point_budget = 0;  ///< the budget the cut was held to (0: none)
  /// With the coverage stop: the screen area, pixels, of the grid cells the cut's splats cover
  /// at least once (an estimate of the pixels the model covers); 0 without it.
  double covered_px = 0.0;
};

/// Selects the cut for `view` of `store`, whose local frame maps to the world by `model`
/// (world = model * local). Loads hierarchy pages on demand unless options.may_load_children
/// says otherwise (may throw StoreError); decodes no chunk. Thread-safe with respect to the
/// store. Costs O(visited nodes log visited); with the coverage stop, also the grid cells under
/// each visited node's rectangle (a 1920x1080 view has 32400 cells of 8 px).
Cut selectCut(lod::LodHierarchy& store, const glm::dmat4& model, const ViewSetup& view,
              const CutOptions& options = {});

/// Pixels per store unit at distance 1 along the view axis for this view (vertical).
double pixelsPerUnitAtDistanceOne(const ViewSetup& view);

}  // namespace tessera::render
