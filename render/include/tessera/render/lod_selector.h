// View-dependent LOD: the cut of a point store's hierarchy that one view (a tile, an eye)
// needs (Bettio et al. 2009, section 4.1). Nodes outside the frustum are culled; a node is
// refined while its projected sample spacing exceeds the pixel threshold, measured as the
// apparent size of a sphere as wide as the spacing at the node box's point nearest the eye
// (a consistent upper bound). Nodes are self-contained, so a cut is drawn from its nodes only.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/lod/point_store.h>
#include <tessera/render/tile_frustum.h>

namespace tessera::render {

struct CutOptions {
  double pixel_threshold = 1.0;  ///< refine while projected spacing > this many pixels
  size_t max_nodes = 1 << 20;    ///< stop refining beyond this many nodes (a safety bound)
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
  int32_t parent = -1;  ///< index of the parent in Cut::above, -1 for the root
};

struct Cut {
  std::vector<CutNode> nodes;  ///< the cut, nearest first
  /// Every refined node (an ancestor of cut nodes), parents before children: what a streaming
  /// renderer draws instead of a cut node whose chunk is not resident yet.
  std::vector<CutNode> above;
  uint64_t points = 0;
  size_t visited = 0;         ///< nodes tested
  size_t culled = 0;          ///< nodes outside the frustum
  size_t pages_deferred = 0;  ///< refinements stopped because may_load_children said no
};

/// Selects the cut for `view` of `store`, whose local frame maps to the world by `model`
/// (world = model * local). Loads hierarchy pages on demand unless options.may_load_children
/// says otherwise (may throw StoreError); decodes no chunk. Thread-safe with respect to the
/// store.
Cut selectCut(lod::LodHierarchy& store, const glm::dmat4& model, const ViewSetup& view,
              const CutOptions& options = {});

/// Pixels per store unit at distance 1 along the view axis for this view (vertical).
double pixelsPerUnitAtDistanceOne(const ViewSetup& view);

}  // namespace tessera::render
