// One view of point stores, end to end: the LOD cut for the view's frustum (lod_selector.h),
// chunks streamed to the GPU by a loader thread (chunk_streamer.h), points rasterised by compute
// shaders into the view's frame target (point_pass.h), the screen passes (resolve, eye-dome
// lighting: screen_passes.h) and overlays (overlay_pass.h) on it, the image read back. render()
// never waits on I/O: a cut node whose chunk is not resident is drawn by its nearest resident
// ancestor, so a frame shows coarse data at once and refines over the next frames. renderSettled()
// repeats frames until every chunk of the cut is resident, for screenshots, tools and tests: its
// pixels depend only on the inputs, not on the loader's timing. A GL 4.5 context must be current on
// the calling thread for the object's whole life.
#pragma once

#include <memory>
#include <optional>
#include <span>

#include <tessera/lod/point_store.h>
#include <tessera/render/ao_grid.h>
#include <tessera/render/ao_pass.h>
#include <tessera/render/chunk_streamer.h>
#include <tessera/render/frame_target.h>
#include <tessera/render/lod_selector.h>
#include <tessera/render/mesh_pass.h>
#include <tessera/render/overlay_pass.h>
#include <tessera/render/point_pass.h>
#include <tessera/render/screen_passes.h>
#include <tessera/render/spbr.h>
#include <tessera/render/tile_frustum.h>

namespace tessera::render {

/// How models with opacity below 1 are drawn.
enum class Transparency {
  kStochastic,       ///< SPBR (spbr.h): no sorting, correct in the mean, noise falls with L
  kWeightedAverage,  ///< baseline: opacity-weighted average of every point on a pixel
  kWeightedBlended,  ///< baseline: McGuire and Bavoil's weighted blended OIT (depth weights)
};

/// How opaque points close surfaces (RenderOptions::fill).
enum class SurfaceFill {
  /// Each point a disc of its splat size: cost grows with the splats' area.
  kDiscs,
  /// Each point one pixel, then the pull-push fill (FillPass; Marroquim et al. 2007) closes
  /// what the discs would have covered: cost grows with the pixels, whatever the splat size.
  kPullPush,
  /// Each point one pixel, nothing filled: surfaces stay open. The cost floor the others are
  /// measured against (bench/fill), and a quick preview.
  kNone,
  /// Whichever of kDiscs and kPullPush costs the frame less (chooseFill()): the pull-push fill
  /// where the discs' summed area is many times the pixels the models cover (a volume of
  /// points seen whole) and every disc lies within the fill's reach; discs otherwise, and always
  /// in a view that is part of a larger picture (a wall's tiles, a poster's parts: the fill's
  /// pyramid follows each part's own pixel grid, so parts would not join seamlessly).
  kAuto,
};

/// What the discs of a frame's cuts would cost, for SurfaceFill::kAuto (ViewRenderer measures
/// it from each model's cut).
struct FillEstimate {
  double disc_px = 0.0;     ///< summed disc area, pixels (each disc at least a pixel)
  double covered_px = 0.0;  ///< pixels the models cover (the coverage grid's estimate)
  double max_radius_px = 0.0;  ///< the largest disc radius, pixels (leaves' own sizes included)
  double points = 0.0;         ///< points drawn
  /// Points whose discs are wider than the pull-push fill reaches (2^kFillMaxLevels pixels).
  double wide_points = 0.0;
};

/// The discs' summed area, in covered pixels, above which SurfaceFill::kAuto fills instead: on
/// llvmpipe a disc pixel costs about 4 ns (10 for discs of a pixel or two) and the fill about
/// 80-125 ns a covered pixel (bench/fill, bench/paraview_peer): they cross at 20 to 30 layers.
constexpr double kAutoFillDiscLayers = 24.0;

/// kAuto's choice: kPullPush when the discs' summed area exceeds kAutoFillDiscLayers times the
/// covered pixels and no disc is wider than the fill reaches (2^kFillMaxLevels pixels), else
/// kDiscs; `fill` itself when it is not kAuto.
SurfaceFill chooseFill(SurfaceFill fill, const FillEstimate& estimate);

struct RenderOptions {
  double lod_pixels = 1.0;
  /// Most points in each model's cut for a view, refined largest projected spacing first
  /// (lod_selector.h; Potree's point budget). Bounds a frame's cost whatever the model's size,
  /// at the price of detail on views that need more. 0: budget_per_covered_pixel sets it.
  uint64_t point_budget = 0;
  /// Without point_budget: each model's budget is this many points per pixel it covers in the
  /// picture the view belongs to (the whole wall for a tile, the whole poster for a part:
  /// wholeView()), counted on the coverage stop's grid (CutOptions::budget_per_covered_px), but
  /// never below budget_floor; 0: no budget. At the default 2 a view draws about as many points
  /// as the pixels it shows, not as many as the model holds (tiled Autzen seen whole: 0.53 M of
  /// 10^7 points, 30x ParaView's frame; a 10^7-point random cube: 1.2 M); the splats, sized
  /// from the projected spacing of the nodes drawn, grow as the budget coarsens the cut, so
  /// surfaces stay closed and the outline is kept (silhouette IoU 0.996 against every leaf),
  /// at the price of fine colour detail on cuts the budget holds (bench/paraview_peer charts
  /// frame time against PSNR). A view that is part of a larger picture draws that picture's
  /// budget-limited cut (CutOptions::refine_only), so a wall's tiles agree at their seams.
  /// Opaque models only, as the coverage stop: a see-through model shows every layer.
  double budget_per_covered_pixel = 2.0;
  /// The pixel budget is at least this many points per model: cuts this small cost little to
  /// draw (about 25 ms for 5x10^5 discs on llvmpipe at 1920x1080), so small models and close
  /// views of registered range scans keep every level their pixels ask for, where a budget by
  /// pixels would coarsen surfaces that lie several layers a pixel (the bunny's ten scans,
  /// 362,272 points, at 0.3 m and 640x480: 38.5 dB with eye-dome lighting against the cut
  /// without a budget; with the floor, the same picture).
  uint64_t budget_floor = 500'000;
  /// Stop refining where the model's nearer points already cover the pixels densely
  /// (lod_selector.h): a volume of points draws its front, not every leaf (about a third of the
  /// points of a 10^7- or 5x10^7-point cube seen whole); surfaces are unchanged. Opaque frames
  /// only: see-through frames show what lies behind.
  bool coverage_stop = true;
  glm::vec3 background{0.0f};
  glm::u8vec3 default_color{200, 200, 200};  ///< for stores without colour (all must agree)
  /// Eye-dome lighting (screen_passes.h): off unless edl.strength is set (1: usual).
  EdlOptions edl{.strength = 0.0f};
  /// Screen-space ambient occlusion (ao_pass.h), opaque frames: multiplies the resolved colour
  /// (and eye-dome lighting's shade) by the ambient light reaching each pixel's surface. While
  /// the view and its data rest, each frame adds its samples to a running mean, up to
  /// ao.max_frames; renderSettled() draws frames until that mean is full.
  AoOptions ao;
  /// With `ao`: its visibility gathered over the frames the view draws into a multi-view grid
  /// (ao_grid.h, Sabbadin et al.'s real-time variant), and the picture shaded from the grid
  /// instead of the frame's own AO. The grid is the view's: it lives as long as the renderer.
  AoGridOptions ao_grid;
  /// Points of stores carrying ambient occlusion (multi-view AO of range scans): their colour
  /// times it, the colour alone, or the AO alone. Changing it reloads those stores' chunks.
  StoredAo stored_ao = StoredAo::kModulate;
  /// Analysis filters (screen_passes.h AnalysisPass), after eye-dome lighting, opaque frames:
  /// relative depth (the fine relief in a colour map) and contour lines over the picture.
  RelativeDepthOptions relative_depth;
  ContourOptions contours;
  /// Pixels drawn around the view for the screen passes' kernels (withGuardBand() in
  /// tile_frustum.h), cropped off before the image is read or shown: a pass then sees past the
  /// view's edge what a larger picture has there, so the tiles of a wall show one picture
  /// without seams. -1: what the passes switched on reach (guardBand()); 0: none (a pass's
  /// kernel then stops at the edge).
  int guard_band = -1;
  /// Splat diameter as a multiple of the node's projected mean sample spacing (the mean nearest-
  /// neighbour distance). At 1 random samples leave 20% of a surface open; 2 closes them and
  /// LiDAR scan lines (tests/render/view_renderer_test.cpp measures it).
  float splat_scale = 2.0f;
  /// Pixels. Discs grow this large only on leaves seen close (a sparse scan close up: Autzen's
  /// scan lines need about 20 px at 640x480), where few points are on screen.
  int max_splat_radius = 32;
  /// See-through rendering, used when a model's opacity is below 1.
  Transparency transparency = Transparency::kStochastic;
  SpbrOptions spbr;
  /// Write pick ids for opaque frames, so pick() names the model and point under a pixel. Costs
  /// one more atomic per covered pixel, and the colour pass when all points have one colour.
  bool pick_ids = false;
  /// Colour points: blend the colours of all points within a splat's depth of the nearest on
  /// each pixel (high-quality splatting, as Potree's) instead of the nearest point's colour:
  /// smooth, alias-free colour for 4 atomics per point and pixel more.
  bool blend_colors = false;
  /// Opaque frames without blend_colors: discs or 1 px points and the pull-push fill (see-
  /// through and blended frames always draw discs). By default the cheaper of the two for the
  /// frame (kAuto): the fill costs 30-75 ms at 1920x1080 on llvmpipe whatever the splats' size,
  /// the discs grow with their area, so a volume of points seen whole fills and a surface draws
  /// discs (bench/fill, bench/paraview_peer).
  SurfaceFill fill = SurfaceFill::kAuto;
  /// Mesh models: geomorphing (mesh_pass.h). A patch morphs from its parent's surface to its
  /// own shape while its parent's error grows on screen from lod_pixels to (1 + this) x
  /// lod_pixels; 0 turns it off (a level change then pops).
  double geomorph_range = 1.0;
  /// Mesh models: each triangle lit by its own facet normal instead of the vertices' normals
  /// interpolated (mesh_pass.h): shows the triangulation, e.g. to judge a scan's resolution.
  bool flat_shading = false;
  /// Selections to tint (screen_passes.h HighlightPass; the scene's SELECTION nodes through
  /// sceneHighlights() in scene_overlay.h), drawn after eye-dome lighting, under the overlay.
  /// A highlight naming a model (Highlight::model_node) makes an opaque frame write pick ids,
  /// so only that model's pixels are tinted.
  std::vector<Highlight> highlights;
};

/// The pixels the screen passes `options` switches on read around a pixel: eye-dome lighting's
/// neighbour distance plus its denoise window and median, ambient occlusion's radius and denoise
/// (AoPass::reach(), a radius in world units taken at `nearest_depth`, the nearest view depth a
/// model can have), the relative depth's blur, the contour lines' 5x5 mean and neighbour; the
/// largest of them (0 when none is on). `view`: the view drawn (its projection and height).
uint32_t screenPassReach(const RenderOptions& options, const ViewSetup& view,
                         double nearest_depth);

/// The relative depth blur's half-width in `view`'s pixels: options.radius, or radius_m at
/// radius_depth through the view's projection when radius_m is positive; 1..kMaxRelativeDepthRadius.
int relativeDepthRadiusPx(const RelativeDepthOptions& options, const ViewSetup& view);

/// The guard band a frame is drawn with: options.guard_band, or screenPassReach() when it is -1.
uint32_t guardBand(const RenderOptions& options, const ViewSetup& view, double nearest_depth);

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
  double fill_ms = 0;            ///< the pull-push fill (SurfaceFill::kPullPush)
  SurfaceFill fill = SurfaceFill::kDiscs;  ///< how this frame closed surfaces (never kAuto)
  FillEstimate fill_estimate;              ///< what kAuto chose by
  uint64_t point_budget = 0;  ///< the models' budgets this frame, summed (0: none)
  double mesh_ms = 0;            ///< the mesh pass (mesh_pass.h)
  uint64_t triangles = 0;        ///< mesh triangles drawn
  size_t mesh_patches = 0;       ///< mesh patches drawn (stand-ins included)
  double screen_ms = 0;          ///< screen passes after the resolve (eye-dome lighting, analysis)
  /// The relative depth's range this frame (RelativeDepthOptions; zero when it is off): what a
  /// tile reports so the wall can agree on one range.
  glm::vec2 relative_depth_range{0.0f};
  /// Ambient occlusion: frames in its running mean (0: off); renderSettled() draws until it
  /// reaches AoOptions::max_frames.
  uint32_t ao_frames = 0;
  double overlay_ms = 0;         ///< the overlay pass
  size_t frames = 1;             ///< frames renderSettled() drew
  uint32_t ensembles = 0;        ///< see-through: ensembles averaged in the image (0: opaque)
  uint32_t ensembles_drawn = 0;  ///< ... of which this frame drew
  uint64_t copies = 0;           ///< see-through: point copies drawn this frame
  double totalMs() const {
    return select_ms + upload_ms + mesh_ms + depth_ms + color_ms + fill_ms + resolve_ms +
           screen_ms + overlay_ms + readback_ms;
  }
};

/// A store placed in the world: world = model * local. Either a point store (`store`) or a mesh
/// store (`mesh`, lod/mesh_store.h: drawn by the mesh pass, opaque only).
struct ModelInstance {
  lod::PointStore* store = nullptr;
  glm::dmat4 model{1.0};
  /// (0, 1]: below 1 the view is drawn see-through with stochastic point-based rendering
  /// (spbr.h), every model with its own opacity.
  float opacity = 1.0f;
  /// The colour of every point (or triangle) of a store without colours (0, 0, 0:
  /// RenderOptions's default_color), e.g. to tell fused scans apart.
  glm::u8vec3 color{0, 0, 0};
  /// A mesh store instead of `store` (last, so positional initialisers of point models stay).
  lod::MeshStore* mesh = nullptr;
  /// What cuts the model, world frame (clip_planes.h; the scene's CLIP nodes through
  /// SceneDrawList): each batch tests its points or fragments against these planes, moved to
  /// its own frame in double. Empty: nothing cut.
  ClipPlanes clip{};
  /// The MODEL node drawn (SceneDrawList), 0: none. A Highlight naming it (model_node) tints
  /// only this model's pixels.
  uint32_t node = 0;
  /// The store drawn, whichever kind it is.
  lod::LodHierarchy* hierarchy() const {
    return mesh ? static_cast<lod::LodHierarchy*>(mesh) : store;
  }
};

/// What a pixel shows, from the last frame's pick ids (RenderOptions::pick_ids).
struct PickHit {
  size_t model = 0;                 ///< index into the models drawn
  lod::NodeId node = lod::kNoNode;  ///< the LOD node whose chunk (or patch) holds the element
  /// The point's index in that chunk (PointStore::readChunk order), or for a mesh model the
  /// triangle's index in its patch (MeshStore::readPatch order).
  uint32_t point = 0;
  bool triangle = false;  ///< the element is a mesh triangle
  double depth = 1.0;     ///< window depth in [0, 1]
  glm::dvec3 world{0.0};  ///< the pixel centre unprojected at that depth
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
  /// `overlay`, when given, is drawn on top (overlay_pass.h).
  /// Mesh models (ModelInstance::mesh) are drawn by the mesh pass first, opaque, their cut
  /// chosen by projected geometric error; a frame that is see-through or whose mesh models have
  /// an opacity below 1 throws RenderError (see-through meshes are not there yet).
  void draw(std::span<const ModelInstance> models, const ViewSetup& view,
            const RenderOptions& options, RenderStats* stats = nullptr,
            const Overlay* overlay = nullptr);
  /// draw() and read the image back.
  Image render(std::span<const ModelInstance> models, const ViewSetup& view,
               const RenderOptions& options, RenderStats* stats = nullptr,
               const Overlay* overlay = nullptr);
  /// Frames until the whole cut is resident (or refused as corrupt) and, see-through, every
  /// ensemble up to options.spbr's maximum is averaged, and with ambient occlusion its running
  /// mean holds options.ao.max_frames frames; the last one's image.
  /// `stats` holds the last frame's figures with `frames` counting all of them. `overlay`, when
  /// given, is drawn on every frame's image, so the settled one shows it (screenshots).
  Image renderSettled(std::span<const ModelInstance> models, const ViewSetup& view,
                      const RenderOptions& options, RenderStats* stats = nullptr,
                      const Overlay* overlay = nullptr);

  /// What pixel (x right, y down from the top-left) of the last frame shows: the model, node and
  /// point, its depth and world position. Empty where the pixel shows background, or when the
  /// frame was see-through or drawn without RenderOptions::pick_ids. Reads two values back.
  std::optional<PickHit> pick(uint32_t x, uint32_t y) const;

  ChunkStreamer& streamer() { return *mStreamer; }
  /// The view's frame target: the last frame's depth, colours, pick ids and image, with the
  /// guard band the frame was drawn with (lastGuardBand() pixels on every side).
  const FrameTarget& target() const { return mTarget; }
  uint32_t lastGuardBand() const { return mGuard; }
  /// The last frame's depth plane over the view's own pixels (without the guard band), raster
  /// order (row 0 at the bottom), as FrameTarget::readDepth(). Reads the plane back.
  std::vector<uint32_t> readDepth() const;
  /// The GL buffer with the last frame's image, the view's own pixels (top row first).
  uint32_t imageBuffer() const { return mGuard > 0 ? mCropped.name() : mTarget.image().name(); }

 private:
  void drawSeeThrough(std::span<const ModelInstance> models, const ViewSetup& view,
                      const RenderOptions& options, std::vector<DrawBatch>& batches,
                      const PointShading& shading, RenderStats& st);
  /// Adds the model's batches for this view, their nodes to mBatchNodes.
  /// Adds what its discs would cost to `estimate` (SurfaceFill::kAuto).
  void addModel(const ModelInstance& instance, bool see_through, const ViewSetup& view,
                const RenderOptions& options, std::vector<DrawBatch>& batches,
                FillEstimate& estimate, RenderStats& stats);
  /// Adds a mesh model's patches for this view: the cut by projected error, a missing patch's
  /// nearest resident ancestor standing in for every cut node below it.
  void addMeshModel(const ModelInstance& instance, const ViewSetup& view,
                    const RenderOptions& options, std::vector<MeshBatch>& batches,
                    std::vector<lod::NodeId>& nodes, RenderStats& stats);
  /// The depth the lasso view `lasso_clip_from_world` shows of this frame's batches, into
  /// mLassoTarget (visible-only highlights, screen_passes.h): the same batches through that
  /// view, splats scaled to its kLassoDepthSize^2 plane, depth only.
  void drawLassoDepth(const glm::dmat4& lasso_clip_from_world, const ViewSetup& view,
                      std::span<const DrawBatch> batches, std::span<const MeshBatch> meshes);
  /// A range of pick ids: the points of one batch, or the triangles of one patch.
  struct PickRange {
    uint32_t base = 0, count = 0;
    size_t model = 0;
    lod::NodeId node = lod::kNoNode;
    bool triangles = false;
  };
  std::shared_ptr<ChunkStreamer> mStreamer;
  uint32_t mWidth, mHeight;  ///< the views' size
  FrameTarget mTarget;       ///< the views' size plus the last frame's guard band
  uint32_t mGuard = 0;       ///< the last frame's guard band, pixels
  GlBuffer mCropped;         ///< mGuard > 0: the image without the band (mWidth x mHeight)
  PointPass mPoints;
  std::unique_ptr<MeshPass> mMeshes;      ///< made on first use
  ResolvePass mResolve;
  EdlPass mEdl;
  std::unique_ptr<FillPass> mFill;        ///< made on first use
  std::unique_ptr<OverlayPass> mOverlay;  ///< made on first use (builds a font atlas)
  std::unique_ptr<HighlightPass> mHighlight;  ///< made on first use
  std::unique_ptr<AnalysisPass> mAnalysis;    ///< made on first use
  std::unique_ptr<AoPass> mAo;                ///< made on first use
  std::unique_ptr<AoGrid> mAoGrid;            ///< made on first use
  uint64_t mAoSignature = 0;                  ///< what the AO's running mean is of
  uint32_t mAoFrame = 0;                      ///< the last frame's number in that mean
  std::vector<PickRange> mPickRanges;     ///< the last frame's, by base
  std::vector<lod::NodeId> mBatchNodes;   ///< this frame's batches' nodes
  std::vector<glm::dmat4> mBatchWorld;    ///< this frame's point batches' world_from_local
  std::vector<glm::dmat4> mMeshWorld;     ///< ... and mesh batches'
  std::unique_ptr<FrameTarget> mLassoTarget;  ///< visible-only highlights: made on first use
  glm::dmat4 mPickUnproject{1.0};         ///< world from NDC, the last frame's
  uint64_t mSpbrSignature = 0;            ///< what the accumulated ensembles show
  uint32_t mSpbrDone = 0;                 ///< ensembles accumulated for it
};

/// The store's local frame in the world: a translation by its origin (world = origin + local).
glm::dmat4 storeModel(const lod::PointStore& store);
glm::dmat4 storeModel(const lod::MeshStore& store);
/// A model's box in the world: its store's local box (either kind) through `model`, corner by
/// corner. Min > max when the store is empty.
std::pair<glm::dvec3, glm::dvec3> worldBounds(const ModelInstance& m);

}  // namespace tessera::render
