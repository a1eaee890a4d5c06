#include <tessera/render/screen_passes.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <optional>
#include <string>

#include <tessera/core/check.h>

#include "gpu_lap.h"
#include "shaders.h"
#include "shared_layout.h"

namespace tessera::render {
namespace {

static_assert(kEdlMaxFilterRadius == TESSERA_EDL_MAX_FILTER_RADIUS);
static_assert(kFillMaxLevels == TESSERA_FILL_MAX_LEVELS);

void dispatchPixels(uint32_t width, uint32_t height) {
  glDispatchCompute((width + 15) / 16, (height + 15) / 16, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT |
                  GL_PIXEL_BUFFER_BARRIER_BIT);
}

void dispatchPixels(const FrameTarget& target) {
  dispatchPixels(target.width(), target.height());
}

}  // namespace

ResolvePass::ResolvePass() {
  for (int mode = 0; mode < 3; ++mode)
    mPrograms[mode] = GlProgram::compute(shaders::kResolve, "resolve.comp",
                                         "#define MODE " + std::to_string(mode) + "\n");
}

double ResolvePass::run(FrameTarget& target, const glm::vec3& background, uint32_t uniform_color,
                        bool blended) {
  GpuLap lap;
  // resolve.comp's MODE: one colour for the frame, the blended points' means, the nearest's.
  const int mode = uniform_color != 0 ? 2 : blended ? 1 : 0;
  const GlProgram& program = mPrograms[mode];
  program.use();
  const GlBufferTexture depth(target.depth(), GL_R32UI);
  depth.bind(TESSERA_TEXTURE_DEPTH);
  std::optional<GlBufferTexture> colors, sums;
  if (mode == 0) {
    colors.emplace(target.colors(), GL_R32UI);
    colors->bind(TESSERA_TEXTURE_COLORS);
  }
  if (mode == 1) {
    sums.emplace(target.colorSums(), GL_RGBA32UI);
    sums->bind(TESSERA_TEXTURE_COLOR_SUMS);
  }
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, target.image().name());
  program.set("uSize", glm::ivec2(target.width(), target.height()));
  const glm::uvec3 bg = glm::uvec3(glm::clamp(background, 0.0f, 1.0f) * 255.0f + 0.5f);
  program.set("uBackground", bg.r | bg.g << 8 | bg.b << 16 | 0xFF000000u);
  program.set("uUniformColor", uniform_color);
  dispatchPixels(target);
  for (uint32_t unit : {TESSERA_TEXTURE_DEPTH, TESSERA_TEXTURE_COLORS, TESSERA_TEXTURE_COLOR_SUMS})
    glBindTextureUnit(unit, 0);
  return lap();
}

EdlPass::EdlPass() {
  for (int stage = 0; stage < 3; ++stage)
    mStages[stage] = GlProgram::compute(
        shaders::kEdl, "edl.comp", "#define TESSERA_EDL_STAGE " + std::to_string(stage) + "\n");
}

double EdlPass::run(FrameTarget& target, const EdlOptions& options, const glm::dmat4& projection) {
  if (options.strength <= 0.0f) return 0.0;
  TESSERA_CHECK(options.radius >= 1, "render::EdlPass: the neighbour radius must be at least 1");
  TESSERA_CHECK(options.filter_radius >= 0 && options.filter_radius <= kEdlMaxFilterRadius,
                "render::EdlPass: filter_radius must be in [0, kEdlMaxFilterRadius]");
  GpuLap lap;
  const GlBufferTexture depth(target.depth(), GL_R32UI);
  depth.bind(TESSERA_TEXTURE_DEPTH);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, target.image().name());
  const bool robust = options.method != EdlMethod::kClassic;
  if (robust && mFiltered.bytes() != target.pixels() * 4) {
    mFiltered = GlBuffer(target.pixels() * 4, nullptr);
    mFilteredTexels = GlBufferTexture(mFiltered, GL_R32F);
  }
  if (robust) {
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_SCREEN_SCRATCH, mFiltered.name());
    mFilteredTexels.bind(TESSERA_TEXTURE_SCREEN_SCRATCH);
  }
  // One pixel's angle at the view centre (radians): the projection maps tan(angle) to
  // NDC y by projection[1][1], and NDC y spans 2 over the height.
  const double pixel_angle = 2.0 / (projection[1][1] * target.height());
  const int first = robust ? 0 : 2, last = robust ? 1 : 2;
  for (int stage = first; stage <= last; ++stage) {
    const GlProgram& p = mStages[stage];
    p.use();
    p.set("uSize", glm::ivec2(target.width(), target.height()));
    p.set("uEdlStrength", options.strength);
    p.set("uEdlRadius", options.radius);
    p.set("uP22", float(projection[2][2]));
    p.set("uP32", float(projection[3][2]));
    p.set("uFilterRadius", options.filter_radius);
    p.set("uEdgeTau", float(std::log2(1.0 + double(options.edge_slope) * pixel_angle)));
    p.set("uPlaneFit", options.plane_fit ? 1 : 0);
    p.set("uMedian", options.median_reference ? 1 : 0);
    dispatchPixels(target);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
  }
  for (uint32_t unit : {TESSERA_TEXTURE_DEPTH, TESSERA_TEXTURE_SCREEN_SCRATCH})
    glBindTextureUnit(unit, 0);
  return lap();
}

AnalysisPass::AnalysisPass() {
  for (int stage = 0; stage < 6; ++stage)
    mStages[stage] = GlProgram::compute(shaders::kAnalysis, "analysis.comp",
                                        "#define TESSERA_ANALYSIS_STAGE " +
                                            std::to_string(stage) + "\n");
}

void AnalysisPass::ensurePlanes(const FrameTarget& target) {
  if (mPlane.bytes() == target.pixels() * 4) return;
  mSums = GlBuffer(target.pixels() * 8, nullptr);
  mPlane = GlBuffer(target.pixels() * 4, nullptr);
  mSumTexels = GlBufferTexture(mSums, GL_RG32F);
  mPlaneTexels = GlBufferTexture(mPlane, GL_R32F);
}

const GlProgram& AnalysisPass::useStage(int stage, const FrameTarget& target,
                                        const glm::dmat4& projection) const {
  const GlProgram& p = mStages[stage];
  p.use();
  p.set("uSize", glm::ivec2(target.width(), target.height()));
  p.set("uP22", float(projection[2][2]));
  p.set("uP32", float(projection[3][2]));
  return p;
}

double AnalysisPass::relativeDepth(FrameTarget& target, const RelativeDepthOptions& o,
                                   const glm::dmat4& projection, glm::vec2* range_out,
                                   uint32_t band) {
  if (!o.enabled || !(o.amount > 0.0f)) return 0.0;
  TESSERA_CHECK(o.radius >= 1 && o.radius <= kMaxRelativeDepthRadius,
                "render::AnalysisPass: the relative depth's radius must be in [1, 256] pixels");
  for (const auto& r : {o.range, o.agreed_range})
    TESSERA_CHECK(!r || (std::isfinite(r->x) && std::isfinite(r->y) && r->x < r->y),
                  "render::AnalysisPass: a relative depth range must be finite and increasing");
  GpuLap lap;
  ensurePlanes(target);
  constexpr size_t kRangeBytes = 8 + 4 * size_t(TESSERA_ANALYSIS_BINS);
  if (!mRange) mRange = GlBuffer(kRangeBytes, nullptr, GL_DYNAMIC_STORAGE_BIT);
  std::vector<uint32_t> counts(2 + TESSERA_ANALYSIS_BINS, 0);
  counts[0] = 0xFFFFFFFFu;  // the extremes start beyond every value
  glNamedBufferSubData(mRange.name(), 0, kRangeBytes, counts.data());
  const GlBufferTexture depth(target.depth(), GL_R32UI);
  depth.bind(TESSERA_TEXTURE_DEPTH);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, target.image().name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_SCREEN_SCRATCH, mSums.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_ANALYSIS_PLANE, mPlane.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_ANALYSIS_RANGE, mRange.name());
  // The blur's taps, every `step` pixels from -(radius / step) step (shaders/analysis.comp).
  const int step = std::max(1, o.radius / 6), first = -(o.radius / step) * step;
  const double sigma = std::max(o.radius / 3.0, 0.5);
  std::vector<float> weights;
  for (int k = first; k <= o.radius; k += step)
    weights.push_back(float(std::exp(-double(k) * k / (2.0 * sigma * sigma))));
  TESSERA_CHECK(weights.size() <= size_t(TESSERA_ANALYSIS_MAX_TAPS),
                "render::AnalysisPass: too many taps for the blur");
  auto run = [&](int stage, const glm::vec2& range) {
    (stage == 1 ? mSumTexels : mPlaneTexels).bind(TESSERA_TEXTURE_SCREEN_SCRATCH);
    const GlProgram& p = useStage(stage, target, projection);
    p.set("uRadius", o.radius);
    if (stage <= 1) p.set("uWeights", std::span<const float>(weights));
    p.set("uAmount", std::clamp(o.amount, 0.0f, 1.0f));
    p.set("uFixedRange", 1);
    p.set("uRangeLo", range.x);
    p.set("uRangeHi", range.y);
    const auto b = int(std::min(band, std::min(target.width(), target.height()) / 2));
    p.set("uInner", glm::ivec4(b, b, int(target.width()) - b, int(target.height()) - b));
    dispatchPixels(target);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
  };
  run(0, {});
  run(1, {});
  glm::vec2 range(0.0f);
  if (o.range) {
    range = *o.range;
  } else {
    // The 1st to 99th percentile of this frame's differences (analysis.comp, stage 4).
    run(4, {});
    mRange.read(0, kRangeBytes, counts.data());
    auto value = [](uint32_t u) {
      return std::bit_cast<float>((u & 0x80000000u) ? u & 0x7FFFFFFFu : ~u);
    };
    if (counts[0] <= counts[1]) {
      const float lo = value(counts[0]), hi = value(counts[1]);
      uint64_t total = 0;
      for (size_t i = 2; i < counts.size(); ++i) total += counts[i];
      const uint64_t low_cut = total / 100, high_cut = total - total / 100;
      uint64_t seen = 0;
      size_t first = 0, last = TESSERA_ANALYSIS_BINS - 1;
      bool found_first = false;
      for (size_t b = 0; b < TESSERA_ANALYSIS_BINS; ++b) {
        seen += counts[2 + b];
        if (!found_first && seen > low_cut) {
          first = b;
          found_first = true;
        }
        if (seen >= high_cut) {
          last = b;
          break;
        }
      }
      const float width = (hi - lo) / float(TESSERA_ANALYSIS_BINS);
      range = glm::vec2(lo + width * float(first), lo + width * float(last + 1));
    }
  }
  if (range_out) *range_out = range;
  if (!o.range && o.agreed_range) range = *o.agreed_range;
  if (range.y > range.x) run(2, range);
  for (uint32_t unit : {TESSERA_TEXTURE_DEPTH, TESSERA_TEXTURE_SCREEN_SCRATCH})
    glBindTextureUnit(unit, 0);
  return lap();
}

std::optional<glm::vec2> wallRange(std::span<const glm::vec2> part_ranges) {
  std::optional<glm::vec2> wall;
  for (const glm::vec2& r : part_ranges) {
    if (!std::isfinite(r.x) || !std::isfinite(r.y) || !(r.x < r.y)) continue;
    wall = wall ? glm::vec2(std::min(wall->x, r.x), std::max(wall->y, r.y)) : r;
  }
  return wall;
}

double AnalysisPass::contours(FrameTarget& target, const ContourOptions& o,
                              const glm::dmat4& projection, const glm::dmat4& view) {
  if (!o.enabled) return 0.0;
  TESSERA_CHECK(std::isfinite(o.interval) && o.interval > 0.0 && std::isfinite(o.phase),
                "render::AnalysisPass: the contour interval must be finite and positive");
  const double axis_length = glm::length(o.axis);
  TESSERA_CHECK(!o.height || (std::isfinite(axis_length) && axis_length > 0.0),
                "render::AnalysisPass: the contour height axis must be a finite non-zero vector");
  GpuLap lap;
  // Height along the world axis a: h(p) = a . p_world = a . eye + (R a) . p_view, R the view's
  // rotation. The eye's part is the same for every pixel: only its fraction of an interval
  // matters to where the lines fall, so it joins the phase and floats keep their precision
  // however far the model lies from the world's origin.
  const glm::dvec3 a = o.height ? o.axis / axis_length : glm::dvec3(0.0);
  const glm::dvec3 eye = glm::dvec3(glm::inverse(view)[3]);
  const glm::dvec3 axis_view = glm::dmat3(view) * a;
  double phase = o.phase / o.interval;
  if (o.height) phase -= glm::dot(a, eye) / o.interval;  // h = a.eye + ..., levels of h - phase
  phase = -phase;
  phase -= std::floor(phase);
  ensurePlanes(target);
  const GlBufferTexture depth(target.depth(), GL_R32UI);
  depth.bind(TESSERA_TEXTURE_DEPTH);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, target.image().name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_ANALYSIS_PLANE, mPlane.name());
  mPlaneTexels.bind(TESSERA_TEXTURE_SCREEN_SCRATCH);
  for (int stage : {3, 5}) {  // the surface's value per pixel, then the lines
    const GlProgram& p = useStage(stage, target, projection);
    p.set("uViewFromClip", glm::mat4(glm::inverse(projection)));
    p.set("uHeight", o.height ? 1 : 0);
    p.set("uAxis", glm::vec3(axis_view));
    p.set("uInvInterval", float(1.0 / o.interval));
    p.set("uPhase", float(phase));
    p.set("uEdge", o.edge);
    p.set("uLineColor", o.color);
    dispatchPixels(target);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
  }
  for (uint32_t unit : {TESSERA_TEXTURE_DEPTH, TESSERA_TEXTURE_SCREEN_SCRATCH})
    glBindTextureUnit(unit, 0);
  return lap();
}

FillPass::FillPass() = default;

const GlProgram& FillPass::stage(int stage, bool colors, bool pick) {
  // Stages 0-2 write no colours or pick ids: one program each.
  const int index = stage * 4 + (stage >= 3 ? int(colors) | int(pick) << 1 : 0);
  GlProgram& p = mStages[index];
  if (!p) {
    const std::string source = "#define TESSERA_FILL_STAGE " + std::to_string(stage) +
                               "\n#define WRITE_COLOR " + std::to_string(int(colors)) +
                               "\n#define WRITE_PICK " + std::to_string(int(pick)) + "\n" +
                               shaders::kFill;
    p = GlProgram::compute(source.c_str(), "fill.comp");
  }
  return p;
}

void FillPass::clearPyramid() {
  const uint32_t empty[2] = {0u, 0xFFFFFFFFu};
  for (int l = 0; l <= kFillMaxLevels; ++l)
    glClearTexImage(mSamples.name(), l, GL_RG_INTEGER, GL_UNSIGNED_INT, empty);
  for (int l = 0; l < kFillMaxLevels; ++l)
    glClearTexImage(mWinners.name(), l, GL_RG_INTEGER, GL_UNSIGNED_INT, empty);
  mListedBefore.clear();
}

double FillPass::run(FrameTarget& target, const glm::dmat4& projection, float max_radius,
                     bool colors, bool pick) {
  if (!(max_radius >= 1.0f)) return 0.0;
  GpuLap lap;
  // Levels whose winners reach max_radius: 2^levels pixels (at least 1: the pixels read level
  // 1's winners).
  int levels = 1;
  while (levels < kFillMaxLevels && float(1 << levels) < max_radius) ++levels;
  max_radius = std::min(max_radius, float(1 << levels));
  const uint32_t w = target.width(), h = target.height();
  constexpr uint32_t kTile = TESSERA_FILL_TILE;
  static_assert(kTile == 1u << kFillMaxLevels, "a tile holds one texel of the coarsest level");
  const uint32_t tiles_x = (w + kTile - 1) / kTile, tiles_y = (h + kTile - 1) / kTile;
  if (mPixels != target.pixels() || mWidth != w) {
    mPixels = target.pixels();
    mWidth = w;
    const uint32_t aw = tiles_x * kTile, ah = tiles_y * kTile;
    for (GlBuffer* b : {&mDepth, &mColors, &mPick}) *b = GlBuffer();
    mSamples = GlTexture();
    mWinners = GlTexture();
    mSamples = GlTexture(aw, ah, GL_RG32UI, kFillMaxLevels + 1);
    mWinners = GlTexture(aw / 2, ah / 2, GL_RG32UI, kFillMaxLevels);
    mDepth = GlBuffer(mPixels * 4, nullptr);
    mMarks = GlBuffer(size_t(tiles_x) * tiles_y * 4, nullptr);
    mTiles = GlBuffer(size_t(tiles_x) * tiles_y * 4, nullptr, GL_DYNAMIC_STORAGE_BIT);
    mTileTexels = GlBufferTexture(mTiles, GL_R32UI);
    clearPyramid();
  }
  if (levels != mLevels) {
    clearPyramid();
    mLevels = levels;
  }
  if (colors && !mColors) mColors = GlBuffer(mPixels * 4, nullptr);
  if (pick && !mPick) mPick = GlBuffer(mPixels * 4, nullptr);
  // The frame's planes as buffer textures (fill.comp reads them with texelFetch).
  const GlBufferTexture depth(target.depth(), GL_R32UI), colors_in(target.colors(), GL_R32UI),
      pick_in(target.pick(), GL_R32UI), footprints(target.splatFootprints(), GL_RG32UI);
  depth.bind(TESSERA_TEXTURE_DEPTH);
  colors_in.bind(TESSERA_TEXTURE_COLORS);
  pick_in.bind(TESSERA_TEXTURE_PICK);
  footprints.bind(TESSERA_TEXTURE_FOOTPRINTS);
  auto common = [&](const GlProgram& p) {
    p.use();
    p.set("uSize", glm::ivec2(w, h));
    p.set("uLevels", levels);
    p.set("uMaxRadius", max_radius);
    p.set("uTolerance", kFillDepthTolerance);
    p.set("uPixelK", float(2.0 / (projection[1][1] * h)));
    p.set("uP22", float(projection[2][2]));
    p.set("uP32", float(projection[3][2]));
  };

  // Stage 0: which tiles hold a drawn pixel.
  mMarks.clear(0u);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_FILL_TILE_MARKS, mMarks.name());
  common(stage(0, colors, pick));
  glDispatchCompute(tiles_x, tiles_y, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  std::vector<uint32_t> marks(size_t(tiles_x) * tiles_y);
  mMarks.read(0, marks.size() * 4, marks.data());
  // Grown by the farthest reach of a sample (its radius, at most max_radius, plus the slack of
  // a level-`levels` texel, its half diagonal): no winner of any level lies further.
  const int grow = int((max_radius + 0.70711f * float(1 << levels)) / float(kTile)) + 1;
  std::vector<uint8_t> listed(marks.size(), 0);
  for (uint32_t ty = 0; ty < tiles_y; ++ty)
    for (uint32_t tx = 0; tx < tiles_x; ++tx) {
      if (!marks[size_t(ty) * tiles_x + tx]) continue;
      const uint32_t x0 = uint32_t(std::max(0, int(tx) - grow)),
                     x1 = std::min(tiles_x - 1, tx + uint32_t(grow)),
                     y0 = uint32_t(std::max(0, int(ty) - grow)),
                     y1 = std::min(tiles_y - 1, ty + uint32_t(grow));
      for (uint32_t y = y0; y <= y1; ++y)
        std::fill(listed.begin() + (size_t(y) * tiles_x + x0),
                  listed.begin() + (size_t(y) * tiles_x + x1 + 1), uint8_t(1));
    }
  // Last frame's tiles too: this frame empties those no sample reaches any more.
  std::vector<uint32_t> list;
  for (size_t i = 0; i < listed.size(); ++i)
    if (listed[i] || (i < mListedBefore.size() && mListedBefore[i]))
      list.push_back(uint32_t(i / tiles_x) << 16 | uint32_t(i % tiles_x));
  mListedBefore = std::move(listed);
  if (list.empty()) {
    for (uint32_t unit : {TESSERA_TEXTURE_DEPTH, TESSERA_TEXTURE_COLORS, TESSERA_TEXTURE_PICK,
                          TESSERA_TEXTURE_FOOTPRINTS})
      glBindTextureUnit(unit, 0);
    return lap();
  }
  glNamedBufferSubData(mTiles.name(), 0, GLsizeiptr(list.size() * 4), list.data());
  mTileTexels.bind(TESSERA_TEXTURE_FILL_TILES);

  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_FILL_DEPTH, mDepth.name());
  // Unused output planes are bound to the depth output (never written: WRITE_COLOR and
  // WRITE_PICK are 0 in the programs for them).
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_FILL_COLORS,
                   colors ? mColors.name() : mDepth.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_FILL_PICK,
                   pick ? mPick.name() : mDepth.name());
  glBindTextureUnit(TESSERA_TEXTURE_FILL_SAMPLES, mSamples.name());
  glBindTextureUnit(TESSERA_TEXTURE_FILL_WINNERS, mWinners.name());
  // A stage over the listed tiles: 4^shift invocations a tile, 64 a group, in rows of at most
  // 32768 groups (GL guarantees 65535 a dimension).
  auto overTiles = [&](int shift) {
    const uint64_t groups = (uint64_t(list.size()) << (2 * shift)) / 64 +
                            ((uint64_t(list.size()) << (2 * shift)) % 64 != 0);
    const uint32_t gx = uint32_t(std::min<uint64_t>(groups, 32768)),
                   gy = uint32_t((groups + gx - 1) / gx);
    return std::pair<uint32_t, uint32_t>(gx, gy);
  };
  auto level = [&](int stage, int l, int shift) {
    const GlProgram& p = this->stage(stage, colors, pick);
    common(p);
    p.set("uLevel", l);
    p.set("uTileCount", int(list.size()));
    p.set("uTileShift", shift);
    // Stage 1 writes the samples of level l (and at level 1 those of level 0), stage 2 the
    // winners of level l; stage 3 the output planes, stage 4 the frame's.
    if (stage == 1)
      glBindImageTexture(TESSERA_IMAGE_FILL_OUT, mSamples.name(), l, GL_FALSE, 0, GL_WRITE_ONLY,
                         GL_RG32UI);
    if (stage == 2)
      glBindImageTexture(TESSERA_IMAGE_FILL_OUT, mWinners.name(), l - 1, GL_FALSE, 0, GL_WRITE_ONLY,
                         GL_RG32UI);
    glBindImageTexture(TESSERA_IMAGE_FILL_LEVEL0, mSamples.name(), 0, GL_FALSE, 0, GL_WRITE_ONLY,
                       GL_RG32UI);
    const auto [gx, gy] = overTiles(shift);
    glDispatchCompute(gx, gy, 1);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT |
                    GL_SHADER_STORAGE_BARRIER_BIT);
  };
  // Shift: a tile is 2^(kFillMaxLevels - l) texels of level l a side.
  for (int l = 1; l < std::max(levels, 2); ++l) level(1, l, kFillMaxLevels - l);  // pack, pull
  for (int l = levels; l >= 1; --l) level(2, l, kFillMaxLevels - l);  // push, coarse to fine
  level(3, 1, kFillMaxLevels - 1);  // push the pixels, a 2x2 block an invocation
  // Stage 4: the pass's planes back into the frame's, in the listed tiles.
  const GlBufferTexture depth_out(mDepth, GL_R32UI),
      colors_out(colors ? mColors : mDepth, GL_R32UI), pick_out(pick ? mPick : mDepth, GL_R32UI);
  depth_out.bind(TESSERA_TEXTURE_DEPTH);
  colors_out.bind(TESSERA_TEXTURE_COLORS);
  pick_out.bind(TESSERA_TEXTURE_PICK);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_DEPTH, target.depth().name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_COLORS, target.colors().name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_PICK,
                   pick ? target.pick().name() : target.depth().name());
  level(4, 0, kFillMaxLevels);
  for (uint32_t unit : {TESSERA_TEXTURE_FILL_SAMPLES, TESSERA_TEXTURE_FILL_WINNERS,
                        TESSERA_TEXTURE_DEPTH, TESSERA_TEXTURE_COLORS, TESSERA_TEXTURE_PICK,
                        TESSERA_TEXTURE_FOOTPRINTS, TESSERA_TEXTURE_FILL_TILES})
    glBindTextureUnit(unit, 0);
  for (uint32_t unit : {TESSERA_IMAGE_FILL_OUT, TESSERA_IMAGE_FILL_LEVEL0})
    glBindImageTexture(unit, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RG32UI);
  return lap();
}

std::vector<uint32_t> rasterizeLasso(std::span<const glm::dvec2> ndc) {
  constexpr uint32_t n = kHighlightMaskSize;
  std::vector<uint32_t> bits(size_t(n) * n / 32, 0u);
  if (ndc.size() < 3) return bits;
  for (const glm::dvec2& v : ndc)
    if (!std::isfinite(v.x) || !std::isfinite(v.y)) return bits;
  std::vector<double> xs;
  for (uint32_t row = 0; row < n; ++row) {
    const double y = -1.0 + (row + 0.5) * 2.0 / n;
    xs.clear();
    for (size_t i = 0; i < ndc.size(); ++i) {
      const glm::dvec2 a = ndc[i], b = ndc[(i + 1) % ndc.size()];
      if ((a.y > y) != (b.y > y)) xs.push_back(a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y));
    }
    std::sort(xs.begin(), xs.end());
    // Even-odd: the cells whose centre lies between crossings 0-1, 2-3, ...
    for (size_t k = 0; k + 1 < xs.size(); k += 2) {
      const double c0 = (xs[k] + 1.0) * 0.5 * n - 0.5, c1 = (xs[k + 1] + 1.0) * 0.5 * n - 0.5;
      const int64_t first = std::max<int64_t>(0, int64_t(std::ceil(c0)));
      const int64_t last = std::min<int64_t>(int64_t(n) - 1, int64_t(std::ceil(c1)) - 1);
      for (int64_t col = first; col <= last; ++col) {
        const size_t bit = size_t(row) * n + size_t(col);
        bits[bit >> 5] |= 1u << (bit & 31u);
      }
    }
  }
  return bits;
}

HighlightPass::HighlightPass()
    : mProgram(GlProgram::compute(shaders::kHighlight, "highlight.comp")),
      mMask(size_t(kHighlightMaskSize) * kHighlightMaskSize / 8, nullptr, GL_DYNAMIC_STORAGE_BIT) {}

double HighlightPass::run(FrameTarget& target, std::span<const Highlight> highlights,
                          const glm::dmat4& clip_from_world,
                          std::optional<std::span<const PickSpan>> models,
                          const FrameTarget* lasso_depth) {
  if (highlights.empty()) return 0.0;
  GpuLap lap;
  mProgram.use();
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_DEPTH, target.depth().name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, target.image().name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_SCREEN_SCRATCH, mMask.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_PICK, target.pick().name());
  mProgram.set("uSize", glm::ivec2(target.width(), target.height()));
  mProgram.set("uMaskSize", kHighlightMaskSize);
  const glm::dmat4 world_from_clip = glm::inverse(clip_from_world);
  for (const Highlight& h : highlights) {
    if (!h.mask || h.mask->size() * 32 != size_t(kHighlightMaskSize) * kHighlightMaskSize) continue;
    // Only the selected model's pixels: its span of pick ids (none drawn: nothing to tint).
    const PickSpan* span = nullptr;
    if (h.model_node != 0 && models) {
      for (const PickSpan& m : *models)
        if (m.node == h.model_node) span = &m;
      if (!span) continue;
    }
    mProgram.set("uPickFirst", span ? span->first : 0u);
    mProgram.set("uPickCount", span ? span->count : 0xFFFFFFFFu);
    if (mUploaded != h.mask.get()) {
      glNamedBufferSubData(mMask.name(), 0, GLsizeiptr(h.mask->size() * 4), h.mask->data());
      mUploaded = h.mask.get();
      mKeep = h.mask;
    }
    mProgram.set("uLassoFromNdc", glm::mat4(h.clip_from_world * world_from_clip));
    // Visible only: the lasso view's eye depth from its window depth, w = P32 / (ndc z + P22),
    // with P22 and P32 read off clip_from_world's rows (projection times a rigid view: row 3 is
    // minus the view's z row, row 2 = -P22 row 3 + P32 (0, 0, 0, 1)).
    const glm::dmat4& m = h.clip_from_world;
    const glm::dvec4 row2(m[0][2], m[1][2], m[2][2], m[3][2]),
        row3(m[0][3], m[1][3], m[2][3], m[3][3]);
    const double r3 = glm::dot(glm::dvec3(row3), glm::dvec3(row3));
    const bool visible = h.visible_only && lasso_depth && r3 > 0.0;
    const double p22 = visible ? -glm::dot(glm::dvec3(row2), glm::dvec3(row3)) / r3 : 0.0;
    mProgram.set("uVisibleOnly", visible ? 1 : 0);
    mProgram.set("uLassoP22", float(p22));
    mProgram.set("uLassoP32", float(row2.w + p22 * row3.w));
    mProgram.set("uWorldW", glm::vec4(world_from_clip[0][3], world_from_clip[1][3],
                                      world_from_clip[2][3], world_from_clip[3][3]));
    if (visible) {
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_TARGET_DEPTH,
                       lasso_depth->depth().name());
      mProgram.set("uLassoSize", glm::ivec2(int(lasso_depth->width()), int(lasso_depth->height())));
    }
    mProgram.set("uTint", glm::vec4(h.tint) / 255.0f);
    dispatchPixels(target);
  }
  return lap();
}

}  // namespace tessera::render
