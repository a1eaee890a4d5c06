// One view of point stores, end to end: the LOD cut for the view's frustum (lod_selector.h),
// chunks streamed to the GPU by a loader thread (chunk_streamer.h), points rasterised by compute
// shaders (point_rasterizer.h), the image read back. render() never waits on I/O: a cut node
// whose chunk is not resident is drawn by its nearest resident ancestor, so a frame shows
// coarse data at once and refines over the next frames. renderSettled() repeats frames until
// every chunk of the cut is resident, for screenshots, tools and tests: its pixels depend only
// on the inputs, not on the loader's timing. A GL 4.5 context must be current on the calling
// thread for the object's whole life.
#pragma once

#include <memory>
#include <span>

#include <tessera/lod/point_store.h>
#include <tessera/render/chunk_streamer.h>
#include <tessera/render/lod_selector.h>
#include <tessera/render/point_rasterizer.h>
#include <tessera/render/spbr.h>
#include <tessera/render/tile_frustum.h>

namespace tessera::render {

/// How models with opacity below 1 are drawn.
enum class Transparency {
  kStochastic,       ///< SPBR (spbr.h): no sorting, correct in the mean, noise falls with L
  kWeightedAverage,  ///< baseline: opacity-weighted average of every point on a pixel
  kWeightedBlended,  ///< baseline: McGuire and Bavoil's weighted blended OIT (depth weights)
};

struct RenderOptions {
  double lod_pixels = 1.0;
  /// Most points in each model's cut for a view (0: no limit), refined largest projected
  /// spacing first (lod_selector.h; Potree's point budget). Bounds a frame's cost whatever the
  /// model's size, at the price of detail on views that need more.
  uint64_t point_budget = 0;
  /// Stop refining where the model's nearer points already cover the pixels densely
  /// (lod_selector.h): a volume of points draws a few points per pixel, not every leaf; surfaces
  /// are unchanged. Opaque frames only: see-through frames show what lies behind.
  bool coverage_stop = true;
  glm::vec3 background{0.0f};
  glm::u8vec3 default_color{200, 200, 200};  ///< for stores without colour (all must agree)
  float edl_strength = 0.0f;                 ///< eye-dome lighting (0: off, 1: usual)
  int edl_radius = 1;                        ///< EDL neighbour distance, pixels
  /// Splat diameter as a multiple of the node's projected mean sample spacing (the mean nearest-
  /// neighbour distance). At 1 random samples leave 20% of a surface open; 2 closes them and
  /// LiDAR scan lines (tests/render/view_renderer_test.cpp measures it).
  float splat_scale = 2.0f;
  int max_splat_radius = 8;  ///< pixels
  /// See-through rendering, used when a model's opacity is below 1.
  Transparency transparency = Transparency::kStochastic;
  SpbrOptions spbr;
};

/// One frame. `nodes`..`points` describe what was drawn.
struct RenderStats {
  size_t cut_nodes = 0;       ///< the LOD cut for this view
  size_t nodes = 0;           ///< batches drawn: resident cut nodes plus ancestors standing in
  size_t fallback_nodes = 0;  ///< ancestors drawn for cut nodes not resident yet
  size_t missing_nodes = 0;   ///< cut nodes not drawn at their own level this frame
  uint64_t points = 0;
  size_t corrupt_chunks = 0;  ///< cut nodes whose chunk the store refused (drawn by ancestors)
  StreamStats stream;         ///< requested / uploaded / evicted, resident bytes
  double select_ms = 0, upload_ms = 0, depth_ms = 0, color_ms = 0, resolve_ms = 0, readback_ms = 0;
  size_t frames = 1;             ///< frames renderSettled() drew
  uint32_t ensembles = 0;        ///< see-through: ensembles averaged in the image (0: opaque)
  uint32_t ensembles_drawn = 0;  ///< ... of which this frame drew
  uint64_t copies = 0;           ///< see-through: point copies drawn this frame
  double totalMs() const {
    return select_ms + upload_ms + depth_ms + color_ms + resolve_ms + readback_ms;
  }
};

/// A store placed in the world: world = model * local.
struct ModelInstance {
  lod::PointStore* store = nullptr;
  glm::dmat4 model{1.0};
  /// (0, 1]: below 1 the view is drawn see-through with stochastic point-based rendering
  /// (spbr.h; issue 5), every model with its own opacity.
  float opacity = 1.0f;
  /// The colour of every point of a store without colours (0, 0, 0: RenderOptions's
  /// default_color), e.g. to tell fused scans apart.
  glm::u8vec3 color{0, 0, 0};
};

class ViewRenderer {
 public:
  /// Renders `width` x `height` views, streaming through `streamer` (shared between views of
  /// one process, e.g. the tiles of a mosaic) or a streamer of its own with `stream_options`.
  ViewRenderer(uint32_t width, uint32_t height, std::shared_ptr<ChunkStreamer> streamer = nullptr,
               const StreamerOptions& stream_options = {});
  /// One frame of every model (nearest point wins across models) into imageBuffer(), without
  /// reading it back (windows, wall nodes). Never waits on I/O. When a model's opacity is below
  /// 1, the frame is see-through (spbr.h): options.spbr.ensembles ensembles are drawn and
  /// averaged; while the view and the resident data stay the same, later frames add further
  /// ensembles up to options.spbr.progressive_max, and any change starts over. Throws
  /// RenderError when the opacities asked for need more point copies than
  /// options.spbr.max_copies_per_frame, naming the opacities that fit.
  void draw(std::span<const ModelInstance> models, const ViewSetup& view,
            const RenderOptions& options, RenderStats* stats = nullptr);
  /// draw() and read the image back.
  Image render(std::span<const ModelInstance> models, const ViewSetup& view,
               const RenderOptions& options, RenderStats* stats = nullptr);
  /// Frames until the whole cut is resident (or refused as corrupt) and, see-through, every
  /// ensemble up to options.spbr's maximum is averaged; the last one's image.
  /// `stats` holds the last frame's figures with `frames` counting all of them.
  Image renderSettled(std::span<const ModelInstance> models, const ViewSetup& view,
                      const RenderOptions& options, RenderStats* stats = nullptr);

  ChunkStreamer& streamer() { return *mStreamer; }
  /// The GL buffer with the last frame (PointRasterizer::imageBuffer()).
  uint32_t imageBuffer() const { return mRaster.imageBuffer(); }

 private:
  void drawSeeThrough(std::span<const ModelInstance> models, const ViewSetup& view,
                      const RenderOptions& options, std::vector<DrawBatch>& batches,
                      const RasterShading& shading, RenderStats& st);
  void addModel(const ModelInstance& instance, bool see_through, const ViewSetup& view,
                const RenderOptions& options, std::vector<DrawBatch>& batches, RenderStats& stats);
  std::shared_ptr<ChunkStreamer> mStreamer;
  PointRasterizer mRaster;
  uint64_t mSpbrSignature = 0;  ///< what the accumulated ensembles show
  uint32_t mSpbrDone = 0;       ///< ensembles accumulated for it
};

/// The store's local frame in the world: a translation by its origin (world = origin + local).
glm::dmat4 storeModel(const lod::PointStore& store);

}  // namespace tessera::render
