#include <tessera/render/ao_pass.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include <tessera/core/check.h>

#include "gpu_lap.h"
#include "shaders.h"
#include "shared_layout.h"

namespace tessera::render {
namespace {

// ao.comp's own bindings, given to it as #defines (shared_layout.h holds the frame's planes):
// storage buffers and the texture unit of the plane stages 1 and 2 read.
constexpr int kBindingMean = 24, kBindingDenoised = 25, kBindingVisibility = 26;
constexpr int kTexturePlane = 13;

/// Half a turn's directions, two to a vec4, in double then rounded (the tests' reference reads
/// the same floats).
std::vector<glm::vec4> directionTable() {
  std::vector<glm::vec4> t(kAoDirections / 2);
  for (int i = 0; i < kAoDirections; ++i) {
    const double a = std::numbers::pi * double(i) / kAoDirections;
    const glm::vec2 d(float(std::cos(a)), float(std::sin(a)));
    if (i % 2 == 0)
      t[i / 2].x = d.x, t[i / 2].y = d.y;
    else
      t[i / 2].z = d.x, t[i / 2].w = d.y;
  }
  return t;
}

bool finite(float v) { return std::isfinite(v); }

/// The options that change the running mean's samples (not strength or denoise).
bool sameSamples(const AoOptions& a, const AoOptions& b) {
  return a.radius == b.radius && a.radius_px == b.radius_px && a.slices == b.slices &&
         a.steps == b.steps && a.half_resolution == b.half_resolution;
}

void dispatch(glm::ivec2 size) {
  glDispatchCompute(GLuint(size.x + 15) / 16, GLuint(size.y + 15) / 16, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT |
                  GL_BUFFER_UPDATE_BARRIER_BIT);
}

}  // namespace

std::string aoOptionsError(const AoOptions& o) {
  if (!finite(o.radius)) return "the radius must be finite";
  if (!finite(o.radius_px)) return "radius_px must be finite";
  if (o.radius <= 0.0f && !(o.radius_px > 0.0f))
    return "radius_px must be positive when no world radius is given";
  if (o.slices < 1 || o.slices > kAoMaxSlices) return "slices must be in [1, 64]";
  if (o.steps < 1 || o.steps > kAoMaxSteps) return "steps must be in [1, 32]";
  if (!finite(o.strength) || o.strength < 0.0f) return "strength must be finite and >= 0";
  if (o.max_frames < 1) return "max_frames must be at least 1";
  return {};
}

AoPass::AoPass() {
  const std::string bindings =
      "#define TESSERA_AO_BINDING_MEAN " + std::to_string(kBindingMean) +
      "\n#define TESSERA_AO_BINDING_DENOISED " + std::to_string(kBindingDenoised) +
      "\n#define TESSERA_AO_BINDING_VISIBILITY " + std::to_string(kBindingVisibility) +
      "\n#define TESSERA_AO_TEXTURE_PLANE " + std::to_string(kTexturePlane) +
      "\n#define TESSERA_AO_MAX_RADIUS_PX " + std::to_string(kAoMaxRadiusPx) +
      "\n#define TESSERA_AO_FALLOFF " + std::to_string(kAoFalloff) +
      "\n#define TESSERA_AO_DENOISE_RADIUS " + std::to_string(kAoDenoiseRadius) + "\n";
  for (int stage = 0; stage < 3; ++stage)
    for (int half = 0; half < 2; ++half)
      mStages[stage * 2 + half] = GlProgram::compute(
          shaders::kAo, "ao.comp",
          bindings + "#define TESSERA_AO_STAGE " + std::to_string(stage) +
              "\n#define TESSERA_AO_HALF " + std::to_string(half) + "\n");
  const std::vector<glm::vec4> table = directionTable();
  for (const GlProgram& p : mStages) p.set("uDirections", std::span<const glm::vec4>(table));
}

double AoPass::run(FrameTarget& target, const AoOptions& o, const glm::dmat4& projection,
                   uint32_t frame, glm::ivec2 origin) {
  if (!o.enabled) return 0.0;
  const std::string error = aoOptionsError(o);
  TESSERA_CHECK(error.empty(), "render::AoPass::run(): " + error);
  TESSERA_CHECK(projection[2][3] == -1.0 && projection[3][3] == 0.0,
                "render::AoPass::run(): the projection must be a perspective one");
  if (o.strength <= 0.0f) return 0.0;
  GpuLap lap;
  const glm::ivec2 size(int(target.width()), int(target.height()));
  // Half resolution: the computed pixels are those even both ways in the whole picture.
  const glm::ivec2 parity = o.half_resolution ? (origin & 1) : glm::ivec2(0);
  const glm::ivec2 grid = o.half_resolution ? (size - parity + 1) / 2 : size;
  const bool resized = grid != mGrid || mPixels != target.pixels();
  if (resized) {
    const size_t cells = size_t(grid.x) * size_t(grid.y);
    mMean = GlBuffer(cells * 4, nullptr);
    mDenoised = GlBuffer(cells * 4, nullptr);
    mVisibility = GlBuffer(target.pixels() * 4, nullptr);
    mMeanTexels = GlBufferTexture(mMean, GL_R32F);
    mDenoisedTexels = GlBufferTexture(mDenoised, GL_R32F);
    mGrid = grid;
    mPixels = target.pixels();
  }
  // The running mean: start over on frame 0, and whenever it would mix other samples; the same
  // frame again keeps it (the same picture).
  const bool same = !resized && mMeanFrames > 0 && sameSamples(o, mMeanOptions) &&
                    origin == mMeanOrigin && projection == mMeanProjection;
  float blend = 0.0f;  // 0: the mean stays
  if (frame == 0 || !same || (frame != mLastFrame && frame != mLastFrame + 1)) {
    blend = 1.0f;
    mMeanFrames = 1;
  } else if (frame == mLastFrame + 1 && mMeanFrames < o.max_frames) {
    ++mMeanFrames;
    blend = 1.0f / float(mMeanFrames);
  }
  mMeanOptions = o;
  mMeanOrigin = origin;
  mMeanProjection = projection;
  mLastFrame = frame;

  const GlBufferTexture depth(target.depth(), GL_R32UI);
  depth.bind(TESSERA_TEXTURE_DEPTH);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, target.image().name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kBindingMean, mMean.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kBindingDenoised, mDenoised.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kBindingVisibility, mVisibility.name());
  // Same surface: the depth may change by a slope of 4 (76 degrees from facing the eye) times a
  // pixel's angle per pixel apart, as eye-dome lighting's edge test.
  const double pixel_scale = projection[1][1] * double(size.y) / 2.0;
  const float edge_tau = float(4.0 / pixel_scale);
  const int half = o.half_resolution ? 1 : 0;
  auto use = [&](int stage) -> const GlProgram& {
    const GlProgram& p = mStages[stage * 2 + half];
    p.use();
    p.set("uSize", size);
    p.set("uGrid", grid);
    p.set("uParity", parity);
    p.set("uOrigin", origin);
    p.set("uNdcScale", glm::vec2(float(2.0 / size.x), float(2.0 / size.y)));
    p.set("uProjection", glm::vec4(float(projection[0][0]), float(projection[1][1]),
                                   float(projection[2][0]), float(projection[2][1])));
    p.set("uP22", float(projection[2][2]));
    p.set("uP32", float(projection[3][2]));
    p.set("uPixelScale", float(pixel_scale));
    p.set("uEdgeTau", edge_tau);
    return p;
  };
  if (blend > 0.0f) {
    const GlProgram& p = use(0);
    p.set("uRadius", o.radius);
    p.set("uRadiusPx", o.radius_px);
    p.set("uSlices", o.slices);
    p.set("uSteps", o.steps);
    // The frame's rotation within a slice's share of the table and its step shift: the R1
    // sequence (golden ratio) and the R2 sequence's second constant, in double.
    const double turn = double(frame) * 0.6180339887498949;
    const double shift = double(frame) * 0.7548776662466927;
    p.set("uFrameDirection",
          uint32_t((turn - std::floor(turn)) * double(kAoDirections / o.slices)));
    p.set("uFrameJitter", uint32_t((shift - std::floor(shift)) * 65536.0));
    p.set("uBlend", blend);
    dispatch(grid);
  }
  if (o.denoise) {
    mMeanTexels.bind(kTexturePlane);
    use(1);
    dispatch(grid);
  }
  (o.denoise ? mDenoisedTexels : mMeanTexels).bind(kTexturePlane);
  use(2).set("uStrength", o.shade ? o.strength : 0.0f);  // x^0: the image as it is
  dispatch(size);
  for (uint32_t unit : {uint32_t(TESSERA_TEXTURE_DEPTH), uint32_t(kTexturePlane)})
    glBindTextureUnit(unit, 0);
  return lap();
}

std::vector<float> AoPass::readVisibility() const {
  std::vector<float> out(mPixels);
  if (mPixels) mVisibility.read(0, mPixels * 4, out.data());
  return out;
}

int AoPass::reach(const AoOptions& o, const glm::dmat4& projection, uint32_t height,
                  float nearest_depth_hint) {
  if (!o.enabled) return 0;
  const double pixel_scale = projection[1][1] * double(height) / 2.0;
  double r = o.radius > 0.0f ? double(o.radius) * pixel_scale / double(nearest_depth_hint)
                             : double(o.radius_px);
  if (!(r >= 1.0)) r = r > 0.0 ? 1.0 : double(kAoMaxRadiusPx);  // NaN: the largest
  r = std::min(r, double(kAoMaxRadiusPx));
  // The taps reach r + 0.5 (rounded to a pixel), the normal one pixel more; the denoise and the
  // upsample reach further at half resolution (2 target pixels a computed one, plus the grid's
  // offset).
  const int scale = o.half_resolution ? 2 : 1;
  const int denoise = o.denoise ? kAoDenoiseRadius * scale : 0;
  return int(std::ceil(r + 0.5)) + 1 + denoise + (o.half_resolution ? 3 : 0);
}

}  // namespace tessera::render
