// The lazy snapping tool (thesis chapter 4): strokes drawn over a view become a
// SELECTION node, as the lasso's do (select_tool.h), on point and mesh stores alike.
//
//   1. Gather: the leaves of the model's hierarchy whose boxes meet the view frustum (point
//      chunks, or mesh patches welded along their borders), as SurfaceSamples in the store's
//      local frame (lazy_snapping.h). At most SnapToolOptions::max_samples: a view showing more
//      is refused with a message saying to zoom in (the cut needs the leaves: a coarser LOD cut
//      would select samples that are not elements, and mapping them back would be a guess).
//   2. Pick: the visible samples under each stroke (pickStroke(), visibleSamples()).
//   3. Cut: LazySnapping::cut() (or robustLassoSeeds() then the cut for the robust lasso).
//   4. Map back: selected point samples are their chunks' points; a triangle of a leaf patch is
//      selected when its three vertices are (selectedTriangles()'s rule). The result is the exact
//      elements as annotate::Selection bytes, as the lasso gives.
//   5. Mask: the region the view saw selected, for every view's tint (SelectionPayload.mask, in
//      the stroke view, visible_only): each sample in front splatted into a depth buffer of mask
//      cells with its footprint (the sample spacing in cells), the nearest sample deciding a
//      cell; then a closing (dilate, erode by SnapToolOptions::close_cells) that fills the gaps
//      between splats but never grows into a cell an unselected sample is nearest in. So the tint
//      is a solid region, and visible unselected surface is never tinted.
//
// Window-free and GL-free: the master's selection worker (selection_worker.h) calls it with a
// view and pixels, for the console and the sites. Thread-safe over the stores (their reads are).
#pragma once

#include <cstdint>
#include <span>

#include <glm/glm.hpp>

#include <tessera/annotate/lazy_snapping.h>
#include <tessera/interact/select_tool.h>

namespace tessera::interact {

struct SnapToolOptions {
  /// Most surface samples gathered from the view (point samples, or mesh vertices; mesh leaves
  /// are counted as half their triangles before they are read). More: SnappingError.
  uint64_t max_samples = 1'000'000;
  double stroke_radius_px = 4.0;  ///< samples within this of a stroke are its seeds
  uint32_t neighbours = 8;        ///< k of the point samples' k-NN graph
  annotate::SnapOptions snap;               ///< the cut's weights and over-segmentation
  /// Largest mask side, cells (the highlight samples it to 1024^2): the view's pixels, scaled
  /// down to fit.
  uint32_t max_mask_side = 1024;
  uint32_t close_cells = 2;  ///< radius of the mask's closing (Chebyshev), cells
};

/// Where the time went (milliseconds) and how big the problem was.
struct SnapToolStats {
  uint64_t leaves = 0, samples = 0;
  uint32_t graph_nodes = 0;
  uint32_t mask_width = 0, mask_height = 0;
  double gather_ms = 0, cut_ms = 0, map_ms = 0, mask_ms = 0;
};

/// A lasso-like selection (payload with the elements and the region mask instead of a lasso,
/// count, corrupt leaves skipped) and its stats. payload is empty when nothing was selected.
struct SnapSelection : LassoSelection {
  SnapToolStats stats;
};

/// Lazy snapping on `instance` (the MODEL node `model_node`) seen in `view`: `foreground` and
/// `background` are strokes in the view's pixels (x right, y down from the top-left, as the
/// lasso's; polylines of at least one point each). Throws SnappingError (message starting
/// "snapSelection():") when a stroke covers no visible sample of the model, the view shows more
/// than max_samples, or the strokes are not finite. Cost: gathering reads every leaf in the
/// frustum (and for points builds their k-NN graph and normals, most of the time); on the
/// bunny's mesh store (7e4 triangles) 0.13 s in all, on its scans (3.6e5 points) 2.3 s, one
/// thread (bench/lazy_snapping).
SnapSelection snapSelection(const render::ModelInstance& instance, uint32_t model_node,
                            const render::ViewSetup& view, std::span<const glm::dvec2> foreground,
                            std::span<const glm::dvec2> background,
                            const SnapToolOptions& options = {});

/// The robust lasso (thesis 4.3.1): one heavy stroke `heavy` (closed, at least 3 points, the
/// view's pixels as above) `width_px` wide along the region's border; seeds in bands of that
/// width inside and outside, then the cut. Throws SnappingError as snapSelection().
SnapSelection robustLassoSelection(const render::ModelInstance& instance, uint32_t model_node,
                                   const render::ViewSetup& view, std::span<const glm::dvec2> heavy,
                                   double width_px, const SnapToolOptions& options = {});

/// The region mask of a selection (step 5 above) as mask cells, exposed for tests and benches:
/// `cells` width x height, row 0 at the bottom (NDC y = -1), 1 where set. `selected` per
/// sample; `spacing` the samples' spacing (units of the positions); `eye_from_local` and
/// `projection` the view, `viewport` its pixels.
struct SnapMask {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> cells;
};
SnapMask selectionMask(const annotate::SurfaceSamples& samples, std::span<const uint8_t> selected,
                       double spacing, const annotate::ScreenView& view, const SnapToolOptions& options);

}  // namespace tessera::interact
