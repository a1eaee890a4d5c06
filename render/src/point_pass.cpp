#include <tessera/render/point_pass.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/core/check.h>

#include "clip_uniforms.h"
#include "gpu_lap.h"
#include "shaders.h"
#include "shared_layout.h"

namespace tessera::render {
namespace {

/// Dispatches `count` points in slices of at most 65535 work groups of 128 (GL's guaranteed
/// minimum, llvmpipe's limit); `setSlice(first, n)` sets each slice's uniforms and bindings.
template <typename F>
void dispatchSlices(uint32_t count, F&& setSlice) {
  constexpr uint32_t kMaxPoints = 65535u * 128u;
  for (uint32_t done = 0; done < count; done += kMaxPoints) {
    const uint32_t n = std::min(kMaxPoints, count - done);
    setSlice(done, n);
    glDispatchCompute((n + 127) / 128, 1, 1);
  }
}

/// A shader variant's define line (PointPass::raster(), spbr()).
std::string define(const char* name, int value) {
  return "#define " + std::string(name) + " " + std::to_string(value) + "\n";
}

void bind(uint32_t binding, const GlBuffer& b) {
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, b.name());
}

}  // namespace

uint32_t packColor(const glm::vec3& c) {
  const glm::uvec3 u = glm::uvec3(glm::clamp(c, 0.0f, 1.0f) * 255.0f + 0.5f);
  return u.r | u.g << 8 | u.b << 16 | 0xFF000000u;
}

PointPass::PointPass() : mNone(16, nullptr) {
  raster({.clipping = true});  // compiles now: a shader error shows at construction
}

void PointPass::setPoints(std::span<const GpuPoint> points) {
  // The raster reads points as a buffer texture: Mesa allows 2^27 texels.
  TESSERA_CHECK(points.size() <= (size_t(1) << 27),
                "render::PointPass::setPoints: " + std::to_string(points.size()) +
                    " points (at most 2^27 in one buffer)");
  std::vector<GpuPoint> rgb(points.begin(), points.end());
  for (GpuPoint& p : rgb) p.rgba &= 0xFFFFFFu;
  mPoints = GlBuffer(rgb.size() * sizeof(GpuPoint), rgb.empty() ? nullptr : rgb.data());
}

void PointPass::fit(const FrameTarget& target) {
  if (mPlane == target.pixels()) return;
  mPlane = target.pixels();
  for (GlBuffer* b : {&mLayerDepth, &mLayerColors, &mAccum, &mOitSums}) *b = GlBuffer();
  mLayers = 0;
}

const GlProgram& PointPass::raster(const RasterVariant& v) {
  const int index = v.pass | v.one_pixel << 1 | v.clipping << 2 | v.blend << 3 | v.pick << 4 |
                    v.fill << 5;
  GlProgram& p = mRaster[index];
  if (!p) {
    const std::string defines = define("PASS", v.pass) + define("ONE_PIXEL", v.one_pixel) +
                                define("BLEND", v.blend) + define("WRITE_PICK", v.pick) +
                                define("FILL", v.fill) + clippingDefine(v.clipping);
    p = GlProgram::compute(shaders::kPointRaster, "point_raster.comp", defines);
  }
  return p;
}

const GlProgram& PointPass::spbr(const SpbrVariant& v) {
  const int index = v.pass | v.cells << 1 | v.in_cell << 2 | v.jitter << 3 | v.slant_off << 4 |
                    v.ratios << 5 | v.one_layer << 6 | v.clipping << 7;
  GlProgram& p = mSpbr[index];
  if (!p) {
    const std::string defines =
        define("PASS", v.pass) + define("HAS_CELLS", v.cells) + define("IN_CELL", v.in_cell) +
        define("JITTER", v.jitter) + define("SLANT_OFF", v.slant_off) +
        define("HAS_RATIOS", v.ratios) + define("ONE_LAYER", v.one_layer) +
        clippingDefine(v.clipping);
    p = GlProgram::compute(shaders::kSpbrRaster, "spbr_raster.comp", defines);
  }
  return p;
}

PassTimings PointPass::draw(FrameTarget& target, std::span<const DrawBatch> batches,
                            const PointShading& shading) {
  PassTimings timings;
  GpuLap lap;
  bind(TESSERA_BINDING_DEPTH, target.depth());
  bind(TESSERA_BINDING_COLORS, target.colors());
  bind(TESSERA_BINDING_PICK, target.pick());
  const bool blend = shading.blend && shading.uniform_color == 0;
  if (blend) bind(TESSERA_BINDING_COLOR_SUMS, target.colorSums());
  if (shading.fill) bind(TESSERA_BINDING_SPLAT_FOOTPRINTS, target.splatFootprints());
  // Texel views of the depth and footprints for the reads before the atomics
  // (point_raster.comp).
  const GlBufferTexture depth_texels(target.depth(), GL_R32UI);
  depth_texels.bind(TESSERA_TEXTURE_DEPTH);
  std::optional<GlBufferTexture> footprint_texels;
  if (shading.fill) {
    footprint_texels.emplace(target.splatFootprints(), GL_RG32UI);
    footprint_texels->bind(TESSERA_TEXTURE_FOOTPRINTS);
  }
  const int passes = shading.uniform_color != 0 && !shading.pick ? 1 : 2;
  for (int pass = 0; pass < passes; ++pass) {
    const GlProgram* in_use = nullptr;
    for (const DrawBatch& b : batches) {
      if (b.count == 0) continue;
      // Every splat one pixel: the variant without disc code (not for the fill, whose points
      // leave their footprints).
      const bool one_pixel = !shading.fill && (b.splat_radius == 0 || std::isnan(b.spacing_k) ||
                                               (b.spacing_k > 0.0f && b.max_disc_px <= 0.5f));
      // Batches without clip planes: the variant without plane code (shared_layout.h).
      const GlProgram& program = raster({.pass = pass,
                                         .one_pixel = one_pixel,
                                         .clipping = b.clip.count > 0,
                                         .blend = pass == 1 && blend,
                                         .pick = pass == 1 && shading.pick,
                                         .fill = shading.fill});
      if (&program != in_use) {
        in_use = &program;
        program.use();
        program.set("uP22", float(shading.projection[2][2]));
        program.set("uP32", float(shading.projection[3][2]));
        program.set("uSize", glm::ivec2(target.width(), target.height()));
        program.set("uWriteColor", shading.uniform_color == 0 ? 1 : 0);
      }
      // The points as a buffer texture (point_raster.comp reads them with texelFetch), alive
      // until the dispatches are issued.
      const GlBufferTexture texels(b.buffer ? b.buffer : mPoints.name(), GL_RGBA32UI);
      texels.bind(TESSERA_TEXTURE_POINTS);
      // A spacing that is not a number (bad input upstream) draws single pixels.
      const bool no_spacing = std::isnan(b.spacing_k);
      program.set("uSpacingK", no_spacing ? 0.0f : b.spacing_k);
      program.set("uOwnScaleCap", std::max(1.0f, b.own_scale_cap));
      program.set("uColorOverride", b.color_override);
      program.set("uClip", b.clip_from_local);
      program.set("uRadius", no_spacing ? 0 : b.splat_radius);
      program.set("uBlendDepth", b.blend_depth);
      setClipUniforms(program, b.clip);
      dispatchSlices(b.count, [&](uint32_t done, uint32_t count) {
        program.set("uFirst", b.first + done);
        program.set("uCount", count);
        program.set("uPickBase", b.pick_base + done);
      });
    }
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
    (pass == 0 ? timings.depth_ms : timings.color_ms) = lap();
  }
  for (uint32_t unit : {TESSERA_TEXTURE_POINTS, TESSERA_TEXTURE_DEPTH, TESSERA_TEXTURE_FOOTPRINTS})
    glBindTextureUnit(unit, 0);
  return timings;
}

void PointPass::beginEnsembles(FrameTarget& target) {
  if (!mAccumulate) {
    spbr({.cells = true, .in_cell = true});  // the default's: a shader error shows at once
    mAccumulate = GlProgram::compute(shaders::kSpbrAccumulate, "spbr_accumulate.comp");
  }
  fit(target);
  if (!mAccum) mAccum = GlBuffer(mPlane * 12, nullptr);
  mAccum.clear(0);
  target.clearGeometry(true);
}

PassTimings PointPass::drawEnsembles(FrameTarget& target, std::span<const DrawBatch> batches,
                                     uint32_t first, uint32_t count, uint32_t total,
                                     uint32_t max_layers, const glm::vec3& background,
                                     const PointShading& shading, bool slant_off, bool one_layer) {
  PassTimings timings;
  GpuLap lap;
  const size_t plane = mPlane;
  const uint32_t layers = one_layer ? count : std::max<uint32_t>(1, std::min(max_layers, count));
  const uint32_t allocated = one_layer ? 1 : layers;
  if (allocated > mLayers) {
    mLayerDepth = GlBuffer();  // the old layers go before the new ones come
    mLayerColors = GlBuffer();
    mLayerDepth = GlBuffer(plane * allocated * 4, nullptr);
    mLayerColors = GlBuffer(plane * allocated * 4, nullptr);
    mLayers = allocated;
  }
  const int passes = shading.uniform_color != 0 ? 1 : 2;
  const glm::ivec2 size(target.width(), target.height());
  // Each batch's points and their normals, density ratios and cells as texels, made once for
  // every group and pass of the frame. Normals are read only with slant shading off, where a
  // batch without them reads zeros from a small spare buffer (as the storage buffers before);
  // ratios and cells only by the variants of batches that have them.
  struct Inputs {
    GlBufferTexture points, normals, ratios, cells;
  };
  std::vector<Inputs> inputs(batches.size());
  for (size_t i = 0; i < batches.size(); ++i) {
    const DrawBatch& b = batches[i];
    if (b.count == 0 || b.spbr_k <= 0.0f) continue;
    inputs[i].points = GlBufferTexture(b.buffer ? b.buffer : mPoints.name(), GL_RGBA32UI);
    if (slant_off)
      inputs[i].normals = GlBufferTexture(b.normals ? b.normals : mNone.name(), GL_R32UI);
    if (b.density_ratios) inputs[i].ratios = GlBufferTexture(b.density_ratios, GL_R32F);
    if (b.cells) inputs[i].cells = GlBufferTexture(b.cells, GL_RGBA32UI);
  }
  for (uint32_t group = first; group < first + count; group += layers) {
    const uint32_t n = std::min(layers, first + count - group);
    const uint32_t cleared = one_layer ? 1 : n;
    const GLuint all_ones = 0xFFFFFFFFu;
    glClearNamedBufferSubData(mLayerDepth.name(), GL_R32UI, 0, GLsizeiptr(plane * cleared * 4),
                              GL_RED_INTEGER, GL_UNSIGNED_INT, &all_ones);
    if (passes == 2) {
      glClearNamedBufferSubData(mLayerColors.name(), GL_R32UI, 0, GLsizeiptr(plane * cleared * 4),
                                GL_RED_INTEGER, GL_UNSIGNED_INT, &all_ones);
    }
    bind(TESSERA_BINDING_DEPTH, mLayerDepth);
    bind(TESSERA_BINDING_COLORS, mLayerColors);
    // The colour pass reads the depth its layers kept as texels (spbr_raster.comp).
    const GlBufferTexture layer_depth(mLayerDepth, GL_R32UI);
    layer_depth.bind(TESSERA_TEXTURE_DEPTH);
    for (int pass = 0; pass < passes; ++pass) {
      for (size_t i = 0; i < batches.size(); ++i) {
        const DrawBatch& b = batches[i];
        if (b.count == 0 || b.spbr_k <= 0.0f) continue;
        const bool in_cell = b.cells && b.copies == SpbrCopies::kInCell;
        const GlProgram& spbr_b = spbr({.pass = pass,
                                        .cells = b.cells != 0,
                                        .in_cell = in_cell,
                                        .jitter = !in_cell && b.jitter_k > 0.0f,
                                        .slant_off = slant_off,
                                        .ratios = b.density_ratios != 0,
                                        .one_layer = one_layer,
                                        .clipping = b.clip.count > 0});
        spbr_b.use();
        spbr_b.set("uSize", size);
        spbr_b.set("uTotal", total);
        spbr_b.set("uMaxRadius", 16);
        spbr_b.set("uGroupFirst", group);
        spbr_b.set("uGroupCount", n);
        const Inputs& in = inputs[i];
        in.points.bind(TESSERA_TEXTURE_POINTS);
        if (in.normals.name()) in.normals.bind(TESSERA_TEXTURE_SPBR_NORMALS);
        if (in.ratios.name()) in.ratios.bind(TESSERA_TEXTURE_SPBR_RATIOS);
        if (in.cells.name()) in.cells.bind(TESSERA_TEXTURE_SPBR_CELLS);
        spbr_b.set("uJitterK", b.jitter_k);
        spbr_b.set("uCellUnit", b.cell_unit);
        spbr_b.set("uCellSpread", b.cell_spread);
        spbr_b.set("uEnsembleShift", b.ensemble_shift);
        spbr_b.set("uCopyCap", total);
        spbr_b.set("uClip", b.clip_from_local);
        spbr_b.set("uDiscK", b.disc_k);
        spbr_b.set("uK", b.spbr_k);
        spbr_b.set("uSeed", b.seed);
        spbr_b.set("uEyeLocal", b.eye_local);
        spbr_b.set("uColorOverride", b.color_override);
        setClipUniforms(spbr_b, b.clip);
        dispatchSlices(b.count, [&](uint32_t done, uint32_t c) {
          // Point indices (and so ensembles) stay per batch and per slice: the texels are read
          // from `first`; later slices of a huge batch change the seed so their points stay
          // independent.
          spbr_b.set("uFirst", b.first + done);
          spbr_b.set("uCount", c);
          if (done) spbr_b.set("uSeed", b.seed ^ (done * 0x9E3779B9u));
        });
      }
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
      (pass == 0 ? timings.depth_ms : timings.color_ms) += lap();
    }
    mAccumulate.use();
    bind(TESSERA_BINDING_DEPTH, mLayerDepth);
    bind(TESSERA_BINDING_COLORS, mLayerColors);
    bind(TESSERA_BINDING_ACCUM, mAccum);
    bind(TESSERA_BINDING_TARGET_DEPTH, target.depth());
    mAccumulate.set("uSize", size);
    mAccumulate.set("uLayers", cleared);
    mAccumulate.set("uBackground", packColor(background));
    mAccumulate.set("uUniformColor", shading.uniform_color);
    mAccumulate.set("uMode", 0);
    glDispatchCompute((target.width() + 15) / 16, (target.height() + 15) / 16, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    timings.resolve_ms += lap();
  }
  for (uint32_t unit : {TESSERA_TEXTURE_POINTS, TESSERA_TEXTURE_DEPTH, TESSERA_TEXTURE_SPBR_NORMALS,
                        TESSERA_TEXTURE_SPBR_RATIOS, TESSERA_TEXTURE_SPBR_CELLS})
    glBindTextureUnit(unit, 0);
  return timings;
}

double PointPass::resolveEnsembles(FrameTarget& target, uint32_t accumulated) {
  GpuLap lap;
  mAccumulate.use();
  bind(TESSERA_BINDING_IMAGE, target.image());
  bind(TESSERA_BINDING_ACCUM, mAccum);
  mAccumulate.set("uSize", glm::ivec2(target.width(), target.height()));
  mAccumulate.set("uMode", 1);
  mAccumulate.set("uAccumulated", accumulated);
  glDispatchCompute((target.width() + 15) / 16, (target.height() + 15) / 16, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
  return lap();
}

PassTimings PointPass::drawBlended(FrameTarget& target, std::span<const DrawBatch> batches,
                                   const glm::vec3& background, bool weighted_blended) {
  PassTimings timings;
  GpuLap lap;
  if (!mOit[0]) {
    for (int clipping : {0, 1})
      mOit[clipping] = GlProgram::compute(shaders::kOitAccumulate, "oit_accumulate.comp",
                                          clippingDefine(clipping));
    mOitResolve = GlProgram::compute(shaders::kOitResolve, "oit_resolve.comp");
  }
  fit(target);
  if (!mOitSums) mOitSums = GlBuffer(mPlane * 20, nullptr);
  const float zero = 0.0f;
  glClearNamedBufferData(mOitSums.name(), GL_R32F, GL_RED, GL_FLOAT, &zero);
  const glm::ivec2 size(target.width(), target.height());
  bind(TESSERA_BINDING_ACCUM, mOitSums);
  for (const GlProgram& oit : mOit) {
    oit.set("uSize", size);
    oit.set("uMode", weighted_blended ? 1 : 0);
    oit.set("uMaxRadius", 16);
  }
  const GlProgram* in_use = nullptr;
  for (const DrawBatch& b : batches) {
    if (b.count == 0 || b.point_alpha <= 0.0f) continue;
    const GlProgram& oit = mOit[b.clip.count > 0];
    if (&oit != in_use) {
      oit.use();
      in_use = &oit;
    }
    const GLuint points = b.buffer ? b.buffer : mPoints.name();
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_POINTS, points);
    oit.set("uClip", b.clip_from_local);
    oit.set("uDiscK", b.disc_k);
    oit.set("uAlpha", b.point_alpha);
    oit.set("uColorOverride", b.color_override);
    setClipUniforms(oit, b.clip);
    dispatchSlices(b.count, [&](uint32_t done, uint32_t c) {
      if (done) {
        glBindBufferRange(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_POINTS, points,
                          GLintptr(b.first + done) * 16, GLsizeiptr(c) * 16);
      }
      oit.set("uCount", c);
    });
  }
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  timings.depth_ms = lap();
  mOitResolve.use();
  bind(TESSERA_BINDING_IMAGE, target.image());
  bind(TESSERA_BINDING_ACCUM, mOitSums);
  mOitResolve.set("uSize", size);
  mOitResolve.set("uBackground", glm::clamp(background, 0.0f, 1.0f) * 255.0f);
  glDispatchCompute((target.width() + 15) / 16, (target.height() + 15) / 16, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
  timings.resolve_ms = lap();
  return timings;
}

}  // namespace tessera::render
