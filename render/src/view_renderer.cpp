#include <tessera/render/view_renderer.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <limits>
#include <numbers>
#include <unordered_set>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/check.h>
#include <tessera/core/stopwatch.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/splat_sizes.h>

namespace tessera::render {
namespace {

/// The largest splat radius a frame draws, pixels: the discs' cap; with the pull-push fill,
/// whose cost does not grow with the splats' area, at least the fill's reach (so close views of
/// sparse scans close); 0 for single pixels.
int splatRadiusCap(const RenderOptions& o, SurfaceFill fill) {
  if (fill == SurfaceFill::kNone) return 0;
  if (fill == SurfaceFill::kPullPush && !o.blend_colors)
    return std::max(o.max_splat_radius, 1 << kFillMaxLevels);
  return o.max_splat_radius;
}


uint32_t packRgb(const glm::u8vec3& c) {
  return uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16;
}

uint64_t mix(uint64_t h, uint64_t v) {  // order-dependent hash combination (splitmix64 step)
  h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
  h = (h ^ (h >> 30)) * 0xBF58476D1CE4E5B9ull;
  return h ^ (h >> 27);
}

uint64_t mixBytes(uint64_t h, const void* data, size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; i += 8) {
    uint64_t v = 0;
    std::memcpy(&v, p + i, std::min<size_t>(8, bytes - i));
    h = mix(h, v);
  }
  return h;
}

/// The same for every process that opens the same store: it picks points' ensembles.
uint64_t storeKey(const lod::PointStore& store) {
  const lod::StoreSummary& s = store.summary();
  uint64_t h = mix(mix(mix(0, s.points), s.stored_points), s.nodes);
  return mixBytes(h, &s.origin, sizeof s.origin);
}

}  // namespace

glm::dmat4 storeModel(const lod::PointStore& store) {
  return glm::translate(glm::dmat4(1.0), store.summary().origin);
}

glm::dmat4 storeModel(const lod::MeshStore& store) {
  return glm::translate(glm::dmat4(1.0), store.summary().origin);
}

std::pair<glm::dvec3, glm::dvec3> worldBounds(const ModelInstance& m) {
  const glm::dvec3 lo = m.mesh ? m.mesh->summary().bbox_min : m.store->summary().bbox_min;
  const glm::dvec3 hi = m.mesh ? m.mesh->summary().bbox_max : m.store->summary().bbox_max;
  glm::dvec3 wlo(std::numeric_limits<double>::max()), whi(-std::numeric_limits<double>::max());
  for (int k = 0; k < 8; ++k) {
    const glm::dvec3 c((k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z);
    const glm::dvec3 w = glm::dvec3(m.model * glm::dvec4(c, 1.0));
    wlo = glm::min(wlo, w);
    whi = glm::max(whi, w);
  }
  return {wlo, whi};
}

ViewRenderer::ViewRenderer(uint32_t width, uint32_t height, std::shared_ptr<ChunkStreamer> streamer,
                           const StreamerOptions& stream_options)
    : mStreamer(streamer ? std::move(streamer) : std::make_shared<ChunkStreamer>(stream_options)),
      mWidth(width),
      mHeight(height),
      mTarget(width, height) {}

SurfaceFill chooseFill(SurfaceFill fill, const FillEstimate& e) {
  if (fill != SurfaceFill::kAuto) return fill;
  return e.disc_px > kAutoFillDiscLayers * e.covered_px &&
                 e.max_radius_px <= double(1 << kFillMaxLevels)
             ? SurfaceFill::kPullPush
             : SurfaceFill::kDiscs;
}

uint32_t screenPassReach(const RenderOptions& o, const ViewSetup& view, double nearest_depth) {
  int reach = 0;
  if (o.ao.enabled && o.ao.strength > 0.0f && aoOptionsError(o.ao).empty())
    reach = AoPass::reach(o.ao, view.projection, view.height,
                          float(std::max(nearest_depth, 1e-9)));
  if (o.edl.strength > 0.0f) {
    const bool robust = o.edl.method == EdlMethod::kRobust && o.edl.filter_radius > 0;
    // Robust: the shade reads the denoised plane at the radius, each denoised value a window
    // around a 3x3 median.
    reach = std::max(reach, std::max(o.edl.radius, 1) + (robust ? o.edl.filter_radius +
                                                                     (o.edl.median_reference ? 1 : 0)
                                                               : 0));
  }
  if (o.relative_depth.enabled && o.relative_depth.amount > 0.0f)
    reach = std::max(reach, relativeDepthRadiusPx(o.relative_depth, view));
  if (o.contours.enabled) reach = std::max(reach, 3);  // the 5x5 mean, then the neighbours'
  return uint32_t(reach);
}

int relativeDepthRadiusPx(const RelativeDepthOptions& o, const ViewSetup& view) {
  TESSERA_CHECK(std::isfinite(o.radius_m) && std::isfinite(o.radius_depth) && o.radius_depth > 0.0,
                "render::RelativeDepthOptions: radius_m and radius_depth must be finite, the depth "
                "positive");
  if (!(o.radius_m > 0.0f)) return std::clamp(o.radius, 1, kMaxRelativeDepthRadius);
  const double px = double(o.radius_m) * pixelsPerUnitAtDistanceOne(view) / o.radius_depth;
  return int(std::clamp(std::lround(px), 1l, long(kMaxRelativeDepthRadius)));
}

uint32_t guardBand(const RenderOptions& o, const ViewSetup& view, double nearest_depth) {
  TESSERA_CHECK(o.guard_band >= -1 && o.guard_band <= 4096,
                "render::RenderOptions: guard_band must be -1 (automatic) or 0..4096 pixels");
  return o.guard_band < 0 ? screenPassReach(o, view, nearest_depth) : uint32_t(o.guard_band);
}

Image ViewRenderer::render(std::span<const ModelInstance> models, const ViewSetup& view,
                           const RenderOptions& options, RenderStats* stats,
                           const Overlay* overlay) {
  RenderStats st;
  draw(models, view, options, &st, overlay);
  const auto t0 = std::chrono::steady_clock::now();
  Image img = mGuard > 0 ? readImageBuffer(mCropped, mWidth, mHeight) : mTarget.readImage();
  st.readback_ms = msSince(t0);
  if (stats) *stats = st;
  return img;
}

void ViewRenderer::draw(std::span<const ModelInstance> models, const ViewSetup& requested,
                        const RenderOptions& options, RenderStats* stats, const Overlay* overlay) {
  TESSERA_CHECK(requested.width == mWidth && requested.height == mHeight,
                "render::ViewRenderer: a view's size must be the renderer's");
  // The frame is drawn with its guard band; the view's own pixels are cropped out at the end.
  double nearest = std::numeric_limits<double>::infinity();  // view depth, for AO's reach
  if (options.ao.enabled) {
    for (const ModelInstance& m : models) {
      const auto [lo, hi] = worldBounds(m);
      const glm::dvec3 eye = glm::dvec3(glm::inverse(requested.view)[3]);
      nearest = std::min(nearest, glm::length(glm::clamp(eye, lo, hi) - eye));
    }
    // The nearest a point can be is the near plane: -P[3][2] / (1 - P[2][2]) of a perspective.
    const glm::dmat4& p = requested.projection;
    nearest = std::max(nearest, p[3][2] / (p[2][2] - 1.0));
  }
  const uint32_t band = guardBand(options, requested, nearest);
  const ViewSetup view = withGuardBand(requested, band);
  if (view.width != mTarget.width() || view.height != mTarget.height()) {
    mTarget = FrameTarget(view.width, view.height);
    mSpbrSignature = 0;  // the accumulated ensembles were of the other size
  }
  mGuard = band;
  RenderStats st;
  bool see_through = false, meshes = false;
  for (const ModelInstance& m : models) {
    TESSERA_CHECK((m.store != nullptr) != (m.mesh != nullptr),
                  "render::ViewRenderer: a model is a point store or a mesh store");
    if (m.mesh && m.opacity < 1.0f)
      throw RenderError("render::ViewRenderer: " + m.mesh->path().filename().string() +
                        " is a mesh at opacity " + std::to_string(m.opacity) +
                        ": see-through meshes are not supported yet (draw it opaque)");
    see_through |= m.store && m.opacity < 1.0f;
    meshes |= m.mesh != nullptr;
  }
  if (see_through && meshes)
    throw RenderError(
        "render::ViewRenderer: a see-through frame with mesh models: meshes are drawn only in "
        "opaque frames yet (set every point model's opacity to 1, or hide the meshes)");
  if (options.stored_ao != mStreamer->storedAo()) {
    // Stored AO is coloured in on loading: the stores carrying it load again in the new mode.
    mStreamer->setStoredAo(options.stored_ao);
    for (const ModelInstance& m : models)
      if (m.store && (m.store->summary().attributes & lod::kAmbientOcclusion)) mStreamer->forget(*m.store);
  }
  mStreamer->beginFrame();
  st.upload_ms = mStreamer->stats().upload_ms;
  // A highlight on one model needs the pick ids to tell that model's pixels (HighlightPass).
  bool model_highlights = false;
  for (const Highlight& h : options.highlights) model_highlights |= h.model_node != 0;
  const bool pick = (options.pick_ids || model_highlights) && !see_through;
  std::vector<PickSpan> model_picks;
  mPickRanges.clear();
  mBatchNodes.clear();
  mBatchWorld.clear();
  mMeshWorld.clear();
  std::vector<DrawBatch> batches;
  FillEstimate fill_estimate;
  std::vector<MeshBatch> mesh_batches;
  std::vector<lod::NodeId> mesh_nodes;
  auto nextBase = [&] {
    return mPickRanges.empty() ? 0u : mPickRanges.back().base + mPickRanges.back().count;
  };
  for (size_t i = 0; i < models.size(); ++i) {
    if (pick) model_picks.push_back({models[i].node, nextBase(), 0});
    if (models[i].mesh) {
      const size_t first = mesh_batches.size();
      addMeshModel(models[i], view, options, mesh_batches, mesh_nodes, st);
      for (size_t b = first; pick && b < mesh_batches.size(); ++b) {
        mesh_batches[b].pick_base = nextBase();
        mPickRanges.push_back(
            {nextBase(), mesh_batches[b].index_count / 3, i, mesh_nodes[b], true});
      }
      continue;
    }
    const size_t first = batches.size();
    addModel(models[i], see_through, view, options, batches, fill_estimate, st);
    for (size_t b = first; pick && b < batches.size(); ++b) {
      const uint32_t base = nextBase();
      batches[b].pick_base = base;
      mPickRanges.push_back({base, batches[b].count, i, mBatchNodes[b]});
    }
  }
  // Each model's batches took consecutive pick ids: its span ends where the next one starts.
  for (size_t i = 0; i < model_picks.size(); ++i)
    model_picks[i].count =
        (i + 1 < model_picks.size() ? model_picks[i + 1].first : nextBase()) - model_picks[i].first;
  // The fill: the cheaper for this frame where the view is a picture of its own (a part of a
  // larger one draws discs, so the parts join seamlessly: FillPass's pyramid follows the
  // part's pixel grid); see-through and blended frames draw discs.
  const bool own_picture =
      requested.whole_size == glm::uvec2(0) && requested.pixels_per_metre == glm::dvec2(0.0);
  st.fill = options.fill;
  if (st.fill == SurfaceFill::kAuto)
    st.fill = own_picture && !see_through ? chooseFill(st.fill, fill_estimate) : SurfaceFill::kDiscs;
  st.fill_estimate = fill_estimate;
  for (DrawBatch& b : batches) b.splat_radius = splatRadiusCap(options, st.fill);
  mStreamer->endFrame();
  st.stream = mStreamer->stats();
  mPickUnproject = glm::inverse(view.projection * view.view);

  PointShading shading;
  shading.pick = pick;
  // Points of one colour (stores without colour, all drawn alike) need only the depth pass.
  bool one_color = mesh_batches.empty();  // shaded triangles have colours of their own
  for (const ModelInstance& m : models) {
    if (!m.store) continue;
    const bool shaded = (m.store->summary().attributes & lod::kAmbientOcclusion) != 0 &&
                        options.stored_ao != StoredAo::kOff;
    one_color &= (m.store->summary().attributes & lod::kColor) == 0 && !shaded &&
                 (m.color == glm::u8vec3(0) || m.color == models.front().color);
  }
  if (one_color && !models.empty()) {
    const glm::u8vec3 c =
        models.front().color == glm::u8vec3(0) ? options.default_color : models.front().color;
    shading.uniform_color = packRgb(c) | 0xFF000000u;
  }
  if (see_through && options.transparency != Transparency::kStochastic) {
    mSpbrSignature = 0;
    for (DrawBatch& b : batches) b.disc_k = 0.5f * b.spacing_k;  // the opaque disc
    const PassTimings t =
        mPoints.drawBlended(mTarget, batches, options.background,
                            options.transparency == Transparency::kWeightedBlended);
    st.depth_ms = t.depth_ms;
    st.resolve_ms = t.resolve_ms;
  } else if (see_through) {
    drawSeeThrough(models, view, options, batches, shading, st);
  } else {
    mSpbrSignature = 0;
    shading.blend = options.blend_colors && shading.uniform_color == 0;
    shading.projection = view.projection;
    shading.fill = st.fill == SurfaceFill::kPullPush && !shading.blend;
    mTarget.clearGeometry(pick, shading.blend, shading.fill);
    if (!mesh_batches.empty()) {
      if (!mMeshes) mMeshes = std::make_unique<MeshPass>();
      st.mesh_ms = mMeshes->draw(mTarget, mesh_batches,
                                 MeshShading{.flat = options.flat_shading, .pick = pick});
    }
    const PassTimings t = mPoints.draw(mTarget, batches, shading);
    st.depth_ms = t.depth_ms;
    st.color_ms = t.color_ms;
    if (shading.fill) {
      if (!mFill) mFill = std::make_unique<FillPass>();
      st.fill_ms = mFill->run(mTarget, view.projection, float(splatRadiusCap(options, st.fill)),
                              shading.uniform_color == 0, pick);
    }
    st.resolve_ms = mResolve.run(mTarget, options.background, shading.uniform_color, shading.blend);
    if (options.ao.enabled && options.ao.strength > 0.0f) {
      // The running mean goes on while the view, the options and the data drawn stay the same.
      uint64_t sig = mixBytes(0xA0u, &view.view, sizeof view.view);
      sig = mixBytes(sig, &view.projection, sizeof view.projection);
      const AoOptions& a = options.ao;  // field by field: the struct has padding
      const float numbers[3] = {a.radius, a.radius_px, a.strength};
      sig = mixBytes(sig, numbers, sizeof numbers);
      sig = mix(mix(mix(mix(sig, uint64_t(a.slices)), uint64_t(a.steps)),
                    uint64_t(a.half_resolution) | uint64_t(a.denoise) << 1),
                uint64_t(a.max_frames));
      for (const DrawBatch& b : batches) sig = mix(mix(mix(sig, b.buffer), b.first), b.count);
      for (const MeshBatch& b : mesh_batches)
        sig = mixBytes(mix(mix(sig, b.vertices), b.index_count), &b.morph, sizeof b.morph);
      mAoFrame = sig == mAoSignature ? mAoFrame + 1 : 0;
      mAoSignature = sig;
      if (!mAo) mAo = std::make_unique<AoPass>();
      const bool grid = options.ao_grid.enabled;
      AoOptions ao = options.ao;
      ao.shade = !grid;  // the grid shades the picture instead
      // The pass seeds by raster position (rows from the bottom); the view's origin counts rows
      // from the top of the whole picture. Rows counted up from the whole picture's top edge
      // (negative) are the same for a tile and the whole, whatever the whole's height.
      const glm::ivec2 raster_origin(view.origin.x, -(view.origin.y + int(view.height)));
      st.screen_ms += mAo->run(mTarget, ao, view.projection, mAoFrame, raster_origin);
      if (grid) {
        // Placed once around the models (a 256th of their extent a cell unless given); their
        // samples then gather over every frame the view draws, until the placing changes.
        glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-lo);
        for (const ModelInstance& m : models) {
          const auto [m_lo, m_hi] = worldBounds(m);
          lo = glm::min(lo, m_lo);
          hi = glm::max(hi, m_hi);
        }
        const double extent = std::max(glm::length(hi - lo), 1e-9);
        TESSERA_CHECK(std::isfinite(options.ao_grid.cell) && options.ao_grid.cell >= 0.0,
                      "render::AoGridOptions: the cell must be finite and >= 0");
        const double cell = options.ao_grid.cell > 0.0 ? options.ao_grid.cell : extent / 256.0;
        const glm::dvec3 centre = 0.5 * (lo + hi);
        if (!mAoGrid) mAoGrid = std::make_unique<AoGrid>();
        if (mAoGrid->cell() != cell || mAoGrid->centre() != centre) mAoGrid->reset(centre, cell);
        // A resting view adds its samples while its running mean takes new ones.
        if (mAoFrame < uint32_t(std::max(options.ao.max_frames, 1)))
          st.screen_ms += mAoGrid->add(mTarget, mAo->visibility(), view.projection, view.view,
                                       options.ao_grid.stride);
        st.screen_ms += mAoGrid->shade(mTarget, view.projection, view.view, options.ao.strength);
      }
      st.ao_frames = std::min<uint32_t>(mAoFrame + 1, uint32_t(std::max(options.ao.max_frames, 1)));
    }
    st.screen_ms += mEdl.run(mTarget, options.edl, view.projection);
    if (options.relative_depth.enabled || options.contours.enabled) {
      if (!mAnalysis) mAnalysis = std::make_unique<AnalysisPass>();
      RelativeDepthOptions relative = options.relative_depth;
      if (relative.enabled) relative.radius = relativeDepthRadiusPx(relative, view);
      st.screen_ms += mAnalysis->relativeDepth(mTarget, relative, view.projection,
                                               &st.relative_depth_range, band);
      st.screen_ms += mAnalysis->contours(mTarget, options.contours, view.projection, view.view);
    }
  }
  if (!options.highlights.empty()) {
    if (!mHighlight) mHighlight = std::make_unique<HighlightPass>();
    const auto spans = pick ? std::optional(std::span<const PickSpan>(model_picks)) : std::nullopt;
    for (const Highlight& h : options.highlights) {
      // Visible only: what the lasso's view shows of this frame's batches, drawn again from
      // there (opaque frames: see-through ones tint through the depth).
      const bool visible = h.visible_only && !see_through;
      if (visible) drawLassoDepth(h.clip_from_world, view, batches, mesh_batches);
      st.screen_ms += mHighlight->run(mTarget, std::span(&h, 1), view.projection * view.view, spans,
                                      visible ? mLassoTarget.get() : nullptr);
    }
  }
  if (overlay && !overlay->empty()) {
    if (!mOverlay) mOverlay = std::make_unique<OverlayPass>();
    if (band > 0 && !overlay->rects.empty()) {
      // Rectangles are in the view's pixels: in the target they lie `band` further in.
      Overlay moved = *overlay;
      for (ScreenRect& r : moved.rects) {
        r.min += glm::vec2(float(band));
        r.max += glm::vec2(float(band));
      }
      st.overlay_ms = mOverlay->run(mTarget, view, moved);
    } else {
      st.overlay_ms = mOverlay->run(mTarget, view, *overlay);
    }
  }
  if (band > 0) {
    if (mCropped.bytes() != size_t(mWidth) * mHeight * 4)
      mCropped = GlBuffer(size_t(mWidth) * mHeight * 4, nullptr);
    mTarget.copyImageRegion(band, band, mWidth, mHeight, mCropped);
  }
  if (stats) *stats = st;
}

void ViewRenderer::drawLassoDepth(const glm::dmat4& lasso_clip_from_world, const ViewSetup& view,
                                  std::span<const DrawBatch> batches,
                                  std::span<const MeshBatch> meshes) {
  if (!mLassoTarget) mLassoTarget = std::make_unique<FrameTarget>(kLassoDepthSize, kLassoDepthSize);
  FrameTarget& t = *mLassoTarget;
  t.clearGeometry(false);
  const glm::dmat4& m = lasso_clip_from_world;
  // Splats keep their size on the surface: pixels per unit at distance one are half the plane's
  // height times the projection's [1][1], the length of clip row 1's rotation part.
  const double lasso_k =
      0.5 * double(kLassoDepthSize) * glm::length(glm::dvec3(m[0][1], m[1][1], m[2][1]));
  const float scale = float(lasso_k / pixelsPerUnitAtDistanceOne(view));
  if (!meshes.empty()) {
    std::vector<MeshBatch> moved(meshes.begin(), meshes.end());
    for (size_t i = 0; i < moved.size(); ++i)
      moved[i].clip_from_local = glm::mat4(m * mMeshWorld[i]);
    mMeshes->draw(t, moved, MeshShading{});
  }
  std::vector<DrawBatch> moved(batches.begin(), batches.end());
  for (size_t i = 0; i < moved.size(); ++i) {
    moved[i].clip_from_local = glm::mat4(m * mBatchWorld[i]);
    moved[i].spacing_k *= scale;
    moved[i].max_disc_px *= scale;
  }
  PointShading depth_only;
  depth_only.uniform_color = 0xFFFFFFFFu;
  mPoints.draw(t, moved, depth_only);
}

std::vector<uint32_t> ViewRenderer::readDepth() const {
  std::vector<uint32_t> all = mTarget.readDepth();
  if (mGuard == 0) return all;
  std::vector<uint32_t> own(size_t(mWidth) * mHeight);
  for (uint32_t y = 0; y < mHeight; ++y)
    std::copy_n(all.begin() + ptrdiff_t(size_t(y + mGuard) * mTarget.width() + mGuard), mWidth,
                own.begin() + ptrdiff_t(size_t(y) * mWidth));
  return own;
}

std::optional<PickHit> ViewRenderer::pick(uint32_t x, uint32_t y) const {
  if (x >= mWidth || y >= mHeight || mPickRanges.empty()) return std::nullopt;
  x += mGuard;  // the frame's target holds the guard band around the view
  y += mGuard;
  const uint32_t id = mTarget.readAt(mTarget.pick(), x, y);
  if (id == kNoPick) return std::nullopt;
  // The range holding id: the last whose base is at most id.
  auto it = std::upper_bound(mPickRanges.begin(), mPickRanges.end(), id,
                             [](uint32_t v, const PickRange& r) { return v < r.base; });
  if (it == mPickRanges.begin()) return std::nullopt;
  const PickRange& r = *std::prev(it);
  if (id - r.base >= r.count) return std::nullopt;
  PickHit hit;
  hit.model = r.model;
  hit.node = r.node;
  hit.point = id - r.base;
  hit.triangle = r.triangles;
  const uint32_t d = mTarget.readAt(mTarget.depth(), x, y);
  float depth = 1.0f;
  std::memcpy(&depth, &d, 4);
  hit.depth = depth;
  const glm::dvec4 ndc((x + 0.5) / mTarget.width() * 2.0 - 1.0,
                       1.0 - (y + 0.5) / mTarget.height() * 2.0, 2.0 * depth - 1.0, 1.0);
  const glm::dvec4 w = mPickUnproject * ndc;
  hit.world = glm::dvec3(w) / w.w;
  return hit;
}

Image ViewRenderer::renderSettled(std::span<const ModelInstance> models, const ViewSetup& view,
                                  const RenderOptions& options, RenderStats* stats,
                                  const Overlay* overlay) {
  RenderStats st;
  Image img;
  // Each round either finds the cut complete or makes the loader fetch at least one missing
  // chunk or page, so this ends; the bound only guards against a bug.
  const uint32_t ensembles = std::max(options.spbr.ensembles, options.spbr.progressive_max);
  for (size_t frame = 1; frame <= 100000; ++frame) {
    img = render(models, view, options, &st, overlay);
    st.frames = frame;
    if (st.stream.requested == 0 && st.stream.pages_requested == 0) {
      const bool more_ao = st.ao_frames > 0 && st.ao_frames < uint32_t(options.ao.max_frames);
      if ((st.ensembles == 0 || st.ensembles >= ensembles) && !more_ao) break;
      continue;  // a resting view: more see-through ensembles or ambient occlusion samples
    }
    mStreamer->waitForLoader();
  }
  if (stats) *stats = st;
  return img;
}

void ViewRenderer::drawSeeThrough(std::span<const ModelInstance> models, const ViewSetup& view,
                                  const RenderOptions& options, std::vector<DrawBatch>& batches,
                                  const PointShading& shading, RenderStats& st) {
  const SpbrOptions& o = options.spbr;
  TESSERA_CHECK(o.ensembles >= 1, "render::ViewRenderer: see-through needs at least 1 ensemble");
  const uint32_t total = std::max(o.ensembles, o.progressive_max);
  // What the accumulated ensembles show: the view, the options and every batch.
  uint64_t sig = mixBytes(0x5B9Bu, &view.view, sizeof view.view);
  sig = mixBytes(sig, &view.projection, sizeof view.projection);
  sig =
      mix(mix(mix(sig, total), o.slant_shading), packRgb(glm::u8vec3(options.background * 255.0f)));
  for (const DrawBatch& b : batches) {
    sig = mix(mix(mix(sig, b.buffer), b.count), b.seed);
    sig = mixBytes(sig, &b.spbr_k, sizeof b.spbr_k);
    sig = mixBytes(sig, &b.disc_k, sizeof b.disc_k);
    sig = mixBytes(mix(mix(sig, b.cells), uint32_t(b.copies)), &b.jitter_k, sizeof b.jitter_k);
    sig = mixBytes(sig, &b.cell_spread, sizeof b.cell_spread);
    sig = mixBytes(sig, &b.ensemble_shift, sizeof b.ensemble_shift);
    sig = mixBytes(sig, &b.clip, sizeof b.clip);
  }
  if (sig != mSpbrSignature) {
    mSpbrSignature = sig;
    mSpbrDone = 0;
    mPoints.beginEnsembles(mTarget);
  }
  const uint32_t n = std::min(o.ensembles, total - std::min(total, mSpbrDone));
  // Point copies this frame: each point has k copies over the L ensembles (spbr_k is capped).
  double copies = 0.0;
  for (const DrawBatch& b : batches) copies += double(b.count) * double(b.spbr_k) * n / total;
  if (copies > double(o.max_copies_per_frame)) {
    // Copies grow as -ln(1 - alpha): the opacities that fit scale that by budget / copies.
    const double f = double(o.max_copies_per_frame) / copies;
    std::string fits;
    for (const ModelInstance& m : models) {
      if (m.opacity >= 1.0f || !m.store) continue;
      char line[512];
      std::snprintf(line, sizeof line, "%s%s at opacity %.3g fits at %.3g",
                    fits.empty() ? "" : "; ", m.store->path().filename().c_str(), m.opacity,
                    1.0 - std::pow(1.0 - double(m.opacity), f));
      fits += line;
    }
    char msg[1024];
    std::snprintf(msg, sizeof msg,
                  "render::ViewRenderer: see-through at these opacities needs %.3g point copies "
                  "per frame, beyond the budget of %.3g (SpbrOptions::max_copies_per_frame): %s; "
                  "or draw fewer ensembles per frame",
                  copies, double(o.max_copies_per_frame), fits.c_str());
    throw RenderError(msg);
  }
  if (n > 0) {
    const size_t layer_bytes = size_t(view.width) * view.height * 8;
    const auto layers = uint32_t(std::max<size_t>(1, o.buffer_bytes / layer_bytes));
    const PassTimings t =
        mPoints.drawEnsembles(mTarget, batches, mSpbrDone, n, total, layers, options.background,
                              shading, !o.slant_shading, o.single_layer_baseline);
    mSpbrDone += n;
    st.depth_ms = t.depth_ms;
    st.color_ms = t.color_ms;
    st.resolve_ms = t.resolve_ms;
    st.copies = uint64_t(copies);
  }
  st.resolve_ms += mPoints.resolveEnsembles(mTarget, mSpbrDone);
  st.ensembles = mSpbrDone;
  st.ensembles_drawn = n;
}

void ViewRenderer::addModel(const ModelInstance& instance, bool see_through, const ViewSetup& view,
                            const RenderOptions& options, std::vector<DrawBatch>& batches,
                            FillEstimate& estimate, RenderStats& stats) {
  lod::PointStore& store = *instance.store;
  const glm::dmat4& model = instance.model;
  auto t0 = std::chrono::steady_clock::now();
  CutOptions co;
  co.pixel_threshold = options.lod_pixels * (see_through ? options.spbr.lod_scale : 1.0);
  co.point_budget = options.point_budget;
  co.coverage_stop = options.coverage_stop && !see_through;
  co.splat_radius_per_spacing = 0.5 * options.splat_scale;  // the splat diameter of addBatch
  co.max_splat_radius_px = options.max_splat_radius;
  // Hierarchy pages not in memory are read by the loader; refinement waits a frame for them.
  co.may_load_children = [&](lod::NodeId id) {
    mStreamer->requestChildren(store, id);
    return false;
  };
  TESSERA_CHECK(std::isfinite(options.budget_per_covered_pixel) &&
                    options.budget_per_covered_pixel >= 0.0,
                "render::RenderOptions: budget_per_covered_pixel must be finite and >= 0");
  co.point_budget = options.point_budget;
  // The pixel budget counts the pixels an opaque model covers: a see-through model shows every
  // layer, and its opacity comes from its points' density at each level (spbr.h).
  co.budget_per_covered_px = see_through ? 0.0 : options.budget_per_covered_pixel;
  co.budget_floor = options.budget_floor;
  uint64_t budget = 0;
  std::unordered_set<lod::NodeId> whole_refined;
  if ((co.point_budget > 0 || co.budget_per_covered_px > 0.0) &&
      view.whole_size != glm::uvec2(0)) {
    // A part of a larger picture (a wall's tile, a poster's part, a view with its guard band)
    // draws the whole picture's cut: it refines only what that cut refined, which every part
    // computes alike, instead of holding a budget of its own that would end at other nodes.
    const Cut whole = selectCut(store, model, wholeView(view), co);
    budget = whole.point_budget;
    co.point_budget = 0;
    co.budget_per_covered_px = 0.0;
    if (whole.over_budget > 0) {
      for (const CutNode& n : whole.above) whole_refined.insert(n.id);
      co.refine_only = &whole_refined;
    }
  }
  const Cut cut = selectCut(store, model, view, co);
  stats.point_budget += budget > 0 ? budget : cut.point_budget;
  stats.cut_nodes += cut.nodes.size();
  estimate.covered_px += cut.covered_px > 0.0 ? cut.covered_px : double(view.width) * view.height;

  const glm::dmat4 clip_from_world = view.projection * view.view;
  const double k = pixelsPerUnitAtDistanceOne(view);
  const double unit = std::cbrt(std::abs(glm::determinant(glm::dmat3(model))));
  const uint32_t total = std::max(options.spbr.ensembles, options.spbr.progressive_max);
  const uint64_t key = storeKey(store);
  // See-through batches need the chunks' density (and ratios, normals, cells): only their
  // chunks are measured on loading.
  const ChunkUse use = see_through ? ChunkUse::kSeeThrough : ChunkUse::kOpaque;
  // Opaque leaves whose discs are a pixel across or more (at their nearest) show their
  // sampling's gaps (scan lines; range-scan rows a few mean spacings apart): the loader
  // measures each of their points' own splat size (splat_sizes.h). Discs of 0.5 to 2 px radius
  // draw those sizes up to 1.5x (the gaps between range-scan rows at a wall tile's scale:
  // SplatSizes.RangeScansOnAWallTileHaveNoOpenPixel; the full 4x there cost a fifth more frame
  // time for the same open pixels, as llvmpipe runs each group of points to its largest disc),
  // larger discs (close-ups, LiDAR ground under the eye) up to kMaxPointSplatScale.
  constexpr double kOwnSizesFromRadiusPx = 0.5, kFullOwnSizesFromRadiusPx = 2.0;
  constexpr float kSmallDiscOwnScaleCap = 1.5f;
  // (A node around the eye has no bound: distance and projected spacing 0.)
  auto discPx = [&](const CutNode& n) {
    return n.distance == 0.0 ? std::numeric_limits<double>::infinity()
                             : 0.5 * options.splat_scale * n.projected_spacing_px;
  };
  auto close = [&](const CutNode& n) {
    return !see_through && discPx(n) >= kOwnSizesFromRadiusPx && store.node(n.id).leaf();
  };
  auto addBatch = [&](const CutNode& n, const GpuChunk& chunk) {
    DrawBatch b;
    b.buffer = chunk.buffer.name();
    b.count = chunk.count;
    // Double precision down to the node, float within it: georeferenced data stays exact.
    const glm::dmat4 world_from_local = model * glm::translate(glm::dmat4(1.0), chunk.offset);
    b.clip_from_local = glm::mat4(clip_from_world * world_from_local);
    b.clip = gpuClipPlanes(instance.clip, world_from_local);
    b.spacing_k = float(n.spacing * k * options.splat_scale);
    b.splat_radius = options.max_splat_radius;  // the frame's fill sets it (draw())
    // The discs' bound: the node's nearest view depth (at a corner of its box), a leaf's
    // largest point scale.
    const lod::NodeInfo info = store.node(n.id);
    const glm::dmat4 view_from_local = view.view * world_from_local;
    double nearest_w = std::numeric_limits<double>::infinity();
    for (int c = 0; c < 8; ++c) {
      const glm::dvec3 corner((c & 1 ? info.box_max : info.box_min).x,
                              (c & 2 ? info.box_max : info.box_min).y,
                              (c & 4 ? info.box_max : info.box_min).z);
      nearest_w =
          std::min(nearest_w, -(view_from_local * glm::dvec4(corner - chunk.offset, 1.0)).z);
    }
    // Own sizes only where this view would measure them: a chunk measured for a closer view
    // draws as one that never was.
    if (chunk.splat_sized && close(n))
      b.own_scale_cap =
          discPx(n) >= kFullOwnSizesFromRadiusPx ? kMaxPointSplatScale : kSmallDiscOwnScaleCap;
    if (nearest_w > 0) b.max_disc_px = float(0.5 * b.spacing_k * b.own_scale_cap / nearest_w);
    // What the discs cost (SurfaceFill::kAuto): their area at the node's nearest, and the
    // widest, own sizes included.
    const double disc_r = std::min(discPx(n), double(options.max_splat_radius));
    const double own = std::min(double(b.own_scale_cap), double(chunk.max_splat_scale));
    estimate.disc_px += double(chunk.count) * std::max(std::numbers::pi * disc_r * disc_r, 1.0);
    const double widest = std::min(disc_r * own, double(options.max_splat_radius));
    estimate.max_radius_px = std::max(estimate.max_radius_px, widest);
    estimate.points += chunk.count;
    if (widest > double(1 << kFillMaxLevels)) estimate.wide_points += chunk.count;
    b.blend_depth = float(n.spacing * unit * options.splat_scale);
    if (instance.color != glm::u8vec3(0) && (store.summary().attributes & lod::kColor) == 0)
      b.color_override = 0x1000000u | packRgb(instance.color);
    if (see_through) {
      // Each node its own k and cross-section, from its own density and spacing (spbr.h), so
      // the opacity holds at every LOD level; opaque models sit in every ensemble.
      const SpbrOptions& so = options.spbr;
      // Independent ensembles (max_k <= 1: one copy at most) keep their points where they are.
      const bool moved =
          so.copies != SpbrCopies::kAtPoint && so.max_k > 1.0 && instance.opacity < 1.0f;
      const double density = chunk.density / (unit * unit);
      const bool gaussian = moved && so.copies == SpbrCopies::kGaussian && so.copy_jitter > 0.0;
      // Copies in cells only where the node's discs do not cover its cells (spbr.h).
      const double spread = moved && so.copies == SpbrCopies::kInCell && chunk.cells.name() != 0
                                ? spbrCellSpread(density, n.spacing)
                                : 0.0;
      if ((gaussian && so.cell_weights) || spread > 0.0) b.cells = chunk.cells.name();
      double alpha = instance.opacity;
      if (b.cells && alpha < 1.0) alpha = spbrCoverAlpha(alpha, so.copies, spread);
      // Moved copies fill at most max_share of the ensembles (in cells, as far as they spread).
      const double share = gaussian ? so.max_share : 1.0 + (so.max_share - 1.0) * spread;
      const SpbrNodeParams p =
          spbrNodeParams(alpha, density, n.spacing, total,
                         gaussian || spread > 0.0 ? std::min(so.max_k, share * total) : so.max_k);
      b.spbr_k = float(p.k);
      b.jitter_k = gaussian ? float(so.copy_jitter * n.spacing * k) : 0.0f;
      b.copies = spread > 0.0 ? SpbrCopies::kInCell
                 : gaussian   ? SpbrCopies::kGaussian
                              : SpbrCopies::kAtPoint;
      b.cell_spread = float(spread);
      b.ensemble_shift = float(so.ensemble_shift * spbrShiftScale(total));
      b.cell_unit = float(chunk.spacing);
      b.disc_k = float(std::sqrt(p.cross_section / std::numbers::pi) * k);
      if (instance.opacity >= 1.0f) b.disc_k = 0.5f * b.spacing_k;
      b.seed = uint32_t(mix(key, n.id));
      b.normals = chunk.normals.name();
      b.density_ratios = chunk.density_ratios.name();
      b.eye_local = glm::vec3(glm::inverse(world_from_local) * glm::dvec4(view.eye_world, 1.0));
      // The blended baselines: every point once as the opaque disc, with the opacity that m
      // stacked discs (density x disc area) turn into the model's.
      const double r = 0.5 * options.splat_scale * n.spacing;
      const double m = std::max(1.0, chunk.density / (unit * unit) * std::numbers::pi * r * r);
      b.point_alpha = instance.opacity >= 1.0f
                          ? 1.0f
                          : float(1.0 - std::pow(1.0 - double(instance.opacity), 1.0 / m));
    }
    batches.push_back(b);
    mBatchNodes.push_back(n.id);
    mBatchWorld.push_back(world_from_local);
    stats.points += chunk.count;
    ++stats.nodes;
  };
  std::vector<bool> drawn_above(cut.above.size(), false);
  for (const CutNode& n : cut.nodes) {  // nearest first
    if (const GpuChunk* chunk = mStreamer->find(store, n.id, use)) {
      addBatch(n, *chunk);
      if (close(n) && !chunk->splat_sized)
        mStreamer->request(store, n.id, n.level, n.distance, use, true);
      continue;
    }
    ++stats.missing_nodes;
    if (mStreamer->failed(store, n.id)) {
      ++stats.corrupt_chunks;
    } else {
      mStreamer->request(store, n.id, n.level, n.distance, use, close(n));
    }
    // The nearest resident ancestor stands in; ancestors on the way are fetched too, coarse
    // first, so a new view fills in from coarse to fine.
    for (int32_t p = n.parent; p >= 0; p = cut.above[size_t(p)].parent) {
      const CutNode& a = cut.above[size_t(p)];
      if (drawn_above[size_t(p)]) break;
      if (const GpuChunk* chunk = mStreamer->find(store, a.id, use)) {
        addBatch(a, *chunk);
        drawn_above[size_t(p)] = true;
        ++stats.fallback_nodes;
        break;
      }
      if (!mStreamer->failed(store, a.id))
        mStreamer->request(store, a.id, a.level, a.distance, use);
    }
  }
  stats.select_ms += msSince(t0);
}

void ViewRenderer::addMeshModel(const ModelInstance& instance, const ViewSetup& view,
                                const RenderOptions& options, std::vector<MeshBatch>& batches,
                                std::vector<lod::NodeId>& nodes, RenderStats& stats) {
  lod::MeshStore& store = *instance.mesh;
  const auto t0 = std::chrono::steady_clock::now();
  CutOptions co;
  co.pixel_threshold = options.lod_pixels;  // a patch's error, projected, in pixels
  const Cut cut = selectCut(store, instance.model, view, co);
  stats.cut_nodes += cut.nodes.size();
  // A cut node not resident is drawn by its nearest resident ancestor, which then stands in for
  // every cut node below it: one level per place on the surface, so no two levels overlap, and
  // any cut of the tree is crack-free (locked borders, mesh_store.h).
  std::vector<const GpuChunk*> chunk_of(cut.nodes.size(), nullptr);
  std::vector<const GpuChunk*> stand_in(cut.above.size(), nullptr);
  for (size_t i = 0; i < cut.nodes.size(); ++i) {
    const CutNode& n = cut.nodes[i];
    if ((chunk_of[i] = mStreamer->find(store, n.id))) continue;
    ++stats.missing_nodes;
    if (mStreamer->failed(store, n.id)) {
      ++stats.corrupt_chunks;
    } else {
      mStreamer->request(store, n.id, n.level, n.distance);
    }
    for (int32_t p = n.parent; p >= 0; p = cut.above[size_t(p)].parent) {
      const CutNode& a = cut.above[size_t(p)];
      if (stand_in[size_t(p)]) break;
      if ((stand_in[size_t(p)] = mStreamer->find(store, a.id))) break;
      if (!mStreamer->failed(store, a.id)) mStreamer->request(store, a.id, a.level, a.distance);
    }
  }
  auto under_stand_in = [&](int32_t p) {
    for (; p >= 0; p = cut.above[size_t(p)].parent)
      if (stand_in[size_t(p)]) return true;
    return false;
  };
  const glm::dmat4 clip_from_world = view.projection * view.view;
  // Geomorphing: 0 the moment a patch replaces its parent (the parent's error just above the
  // threshold on screen), 1 once the parent's error is (1 + range) x the threshold.
  auto morph = [&](const CutNode& n) {
    if (n.parent < 0 || !(options.geomorph_range > 0.0)) return 1.0f;
    const double parent_px = cut.above[size_t(n.parent)].projected_spacing_px;
    const double t = (parent_px / co.pixel_threshold - 1.0) / options.geomorph_range;
    return float(std::clamp(std::isfinite(t) ? t : 1.0, 0.0, 1.0));
  };
  auto add = [&](const CutNode& n, const GpuChunk& chunk) {
    MeshBatch b;
    b.morph = morph(n);
    b.vertices = chunk.buffer.name();
    b.indices = chunk.indices.name();
    b.index_count = chunk.index_count;
    const glm::dmat4 world_from_local =
        instance.model * glm::translate(glm::dmat4(1.0), chunk.offset);
    b.clip_from_local = glm::mat4(clip_from_world * world_from_local);
    b.clip = gpuClipPlanes(instance.clip, world_from_local);
    b.eye_local = glm::vec3(glm::inverse(world_from_local) * glm::dvec4(view.eye_world, 1.0));
    if (instance.color != glm::u8vec3(0) && !store.summary().colors)
      b.color_override = 0x1000000u | packRgb(instance.color);
    batches.push_back(b);
    nodes.push_back(n.id);
    mMeshWorld.push_back(world_from_local);
    stats.triangles += chunk.index_count / 3;
    ++stats.mesh_patches;
    ++stats.nodes;
  };
  for (size_t i = 0; i < cut.nodes.size(); ++i)
    if (chunk_of[i] && !under_stand_in(cut.nodes[i].parent)) add(cut.nodes[i], *chunk_of[i]);
  for (size_t p = 0; p < cut.above.size(); ++p) {
    if (stand_in[p] && !under_stand_in(cut.above[p].parent)) {
      add(cut.above[p], *stand_in[p]);
      ++stats.fallback_nodes;
    }
  }
  stats.select_ms += msSince(t0);
}

}  // namespace tessera::render
