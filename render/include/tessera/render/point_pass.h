// The point pass: the geometry pass that turns point batches into a frame target's depth,
// colours and pick ids with compute shaders (shaders/point_raster.comp): nearest point wins,
// deterministic whatever the thread order, round splats of a given radius. Its see-through modes
// draw stochastic ensembles (Tanaka et al. 2016; spbr.h) or the blended baselines and resolve
// them into the target's image themselves. A GL 4.5 context must be current on the calling
// thread for the object's whole life.
//
// Cost (llvmpipe, 1920x1080): opaque, two scatters over the points (depth, then colour and pick
// ids among the nearest) at ~100 M points/s for 1 px splats; see-through, the same per ensemble
// layer plus one accumulation over the pixels per group of layers.
#pragma once

#include <cstdint>
#include <limits>
#include <span>

#include <glm/glm.hpp>

#include <tessera/render/clip_planes.h>
#include <tessera/render/frame_target.h>
#include <tessera/render/gl_objects.h>
#include <tessera/render/spbr.h>

namespace tessera::render {

/// One point as the GPU holds it: position relative to its batch's frame, colour packed in the
/// low three bytes (r lowest); the top byte is not alpha but the point's splat scale
/// (splat_sizes.h pointSplatScale(): 0 draws the node's disc). 16 bytes.
struct GpuPoint {
  glm::vec3 position;
  uint32_t rgba;
};
static_assert(sizeof(GpuPoint) == 16);  // TESSERA_POINT_BYTES, shaders/shared_layout.h

/// A range of GpuPoints drawn with one transform and splat size.
struct DrawBatch {
  uint32_t buffer = 0;  ///< GL buffer holding the points; 0: the one setPoints() filled
  uint32_t first = 0;   ///< index of the first point in that buffer
  uint32_t count = 0;
  glm::mat4 clip_from_local{1.0f};
  /// Splats: with spacing_k > 0, a point at view depth w covers spacing_k / w pixels (the
  /// node's sample spacing projected), radius capped at splat_radius; with spacing_k = 0 every
  /// splat has radius splat_radius (0: one pixel).
  float spacing_k = 0.0f;
  int splat_radius = 0;
  /// With spacing_k > 0: a bound on the batch's disc radii, pixels (from its box's nearest view
  /// depth); at most 0.5 draws every point as one pixel with the variant that has no disc code.
  float max_disc_px = std::numeric_limits<float>::infinity();
  /// The largest of the points' own splat scales (the top byte, splat_sizes.h) drawn: 1 draws
  /// every point with the node's disc. The view decides per node and view, so a chunk measured
  /// for an earlier, closer view draws as one that never was (pixels do not depend on what was
  /// seen before).
  float own_scale_cap = 1.0f;
  uint32_t color_override = 0;  ///< non-zero: 0x1000000 | rgb for every point (r low byte)
  /// With PointShading::pick: point i of the batch writes pick id pick_base + i where it is the
  /// nearest (the view keeps which batch owns which range).
  uint32_t pick_base = 0;
  /// With PointShading::blend: points whose view depth is within this of the nearest's (world
  /// units: about a splat's diameter) blend their colours on the pixel.
  float blend_depth = 0.0f;
  /// Clip planes in the batch's frame (clip_planes.h, the scene's CLIP nodes): points they cut
  /// away are not drawn, in every mode (opaque, ensembles, blended baselines).
  GpuClipPlanes clip{};

  // See-through (drawEnsembles() only; spbr.h):
  float spbr_k = 0.0f;          ///< copies per point over all ensembles (eq. 4), <= total ensembles
  float disc_k = 0.0f;          ///< cross-section disc radius in pixels at view depth 1
  uint32_t seed = 0;            ///< stable key of the node: picks each point's ensembles
  uint32_t normals = 0;         ///< GL buffer of 10:10:10 normals (slant shading off), or 0
  glm::vec3 eye_local{0.0f};    ///< the eye in the batch's frame
  uint32_t density_ratios = 0;  ///< GL buffer of per-point density ratios (k scale), or 0
  uint32_t cells = 0;           ///< GL buffer of surface cells (chunk_streamer.h GpuChunk), or 0
  float jitter_k = 0.0f;        ///< kGaussian: copies' offset standard deviation, px at depth 1
  SpbrCopies copies = SpbrCopies::kAtPoint;  ///< where copies go (with `cells`: kInCell)
  float cell_unit = 0.0f;       ///< store units of the cells' axes (the chunk's spacing)
  float cell_spread = 0.0f;     ///< kInCell: share of the cell copies spread over (spbr.h)
  float ensemble_shift = 0.0f;  ///< kInCell: pixels whole ensembles shift over (x cell_spread)
  float point_alpha = 0.0f;     ///< blended baselines (drawBlended()): each point's opacity
};

struct PointShading {
  /// Non-zero (rgba, r in the low byte): every point has this colour, so only the depth pass
  /// runs (points without colour need no colour pass) unless pick ids are asked for.
  uint32_t uniform_color = 0;
  /// Write pick ids (DrawBatch::pick_base + index) for the nearest points: one more atomic per
  /// covered pixel of the colour pass.
  bool pick = false;
  /// Blend the colours of the points near the nearest (DrawBatch::blend_depth) into the target's
  /// colour sums instead of keeping the nearest point's: smooth, alias-free colour (Potree's
  /// high-quality splatting). Costs 4 atomics per blended point and pixel. `projection` is the
  /// view's (for view depth from window depth).
  bool blend = false;
  glm::dmat4 projection{1.0};
  /// For the pull-push fill (FillPass; Marroquim et al. 2007): every point on screen is one
  /// pixel, and the depth pass also keeps per pixel the footprint of the nearest point's disc
  /// (the target's splatFootprints(); a read more for each point as near as the nearest so far
  /// in its top depth bits, an atomic when its print is larger). Points off screen still draw
  /// their discs, so what reaches into the view from outside is as before.
  bool fill = false;
};

/// Milliseconds per step of the last call, measured on the CPU with the GL work finished after
/// each step (llvmpipe runs it on the CPU; on a GPU this also includes the stall).
struct PassTimings {
  double depth_ms = 0, color_ms = 0, resolve_ms = 0;
};

class PointPass {
 public:
  PointPass();

  /// Replaces the pass's own point buffer (batches with buffer 0 read it). The points' top bytes
  /// are dropped (callers pack colours with alpha there): each draws its node's disc.
  void setPoints(std::span<const GpuPoint> points);
  /// Opaque points into `target`'s depth, colours (and pick ids): depth pass, then colour pass.
  /// Does not clear the target (FrameTarget::clearGeometry()), so several geometry passes can
  /// share one frame.
  PassTimings draw(FrameTarget& target, std::span<const DrawBatch> batches,
                   const PointShading& shading);

  /// See-through rendering (Tanaka et al. 2016): clears the per-pixel sums of ensemble images
  /// and the target's depth (which then keeps the nearest copy over every ensemble drawn).
  void beginEnsembles(FrameTarget& target);
  /// Draws ensembles [first, first + count) of `total` with each batch's spbr_k, disc_k and seed,
  /// `max_layers` at a time (each layer holds a depth and a colour image: 8 bytes a pixel), and
  /// adds their images (background where empty) to the sums. With `slant_off`, cross-sections
  /// take cos(theta) / cos(phi) from each batch's normals buffer (spbr_raster.comp).
  /// `one_layer` draws every ensemble into a single layer instead (the same adjusted points in
  /// one opaque pass: the speed baseline of bench/spbr).
  PassTimings drawEnsembles(FrameTarget& target, std::span<const DrawBatch> batches, uint32_t first,
                            uint32_t count, uint32_t total, uint32_t max_layers,
                            const glm::vec3& background, const PointShading& shading,
                            bool slant_off, bool one_layer = false);
  /// Writes the mean of the `accumulated` ensembles summed since beginEnsembles() as the
  /// target's image. Milliseconds.
  double resolveEnsembles(FrameTarget& target, uint32_t accumulated);
  /// Order-independent blending baselines for see-through points (shaders/oit_accumulate.comp):
  /// `weighted_blended` false is the weighted average, true McGuire and Bavoil's weighted
  /// blended OIT. Each batch draws its points once as discs of disc_k with point_alpha, and the
  /// result is the target's image.
  PassTimings drawBlended(FrameTarget& target, std::span<const DrawBatch> batches,
                          const glm::vec3& background, bool weighted_blended);

 private:
  /// (Re)allocates the per-pixel buffers of the see-through modes for `target`.
  void fit(const FrameTarget& target);
  /// The point_raster.comp variant for a pass, compiled on first use.
  /// shaders/point_raster.comp compiled for one combination (on first use).
  struct RasterVariant {
    int pass = 0;
    bool one_pixel = false, clipping = false, blend = false, pick = false, fill = false;
  };
  const GlProgram& raster(const RasterVariant& v);
  /// spbr_raster.comp's variants (its defines), compiled on first use.
  struct SpbrVariant {
    int pass = 0;
    bool cells = false, in_cell = false, jitter = false, slant_off = false, ratios = false,
         one_layer = false, clipping = false;
  };
  const GlProgram& spbr(const SpbrVariant& v);
  GlProgram mRaster[64];                       ///< by the variant's bits
  GlProgram mSpbr[256];                        ///< by the variant's bits
  GlProgram mAccumulate, mOit[2], mOitResolve;  ///< [clip planes]
  GlBuffer mPoints;
  size_t mPlane = 0;  ///< pixels the buffers below are sized for
  GlBuffer mLayerDepth, mLayerColors, mAccum, mOitSums, mNone;
  uint32_t mLayers = 0;  ///< layers allocated
};

/// Packs a colour in [0, 1] as opaque RGBA8 (r in the low byte).
uint32_t packColor(const glm::vec3& c);

}  // namespace tessera::render
