#include <tessera/render/ao_grid.h>

#include <cmath>
#include <string>
#include <vector>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/check.h>

#include "gpu_lap.h"
#include "shaders.h"
#include "shared_layout.h"

namespace tessera::render {
namespace {

constexpr int kBindingKeys = 27, kBindingSums = 28, kBindingVisibility = 29;

void dispatch(glm::ivec2 size) {
  glDispatchCompute(GLuint(size.x + 15) / 16, GLuint(size.y + 15) / 16, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT |
                  GL_BUFFER_UPDATE_BARRIER_BIT);
}

}  // namespace

AoGrid::AoGrid()
    : mKeys(size_t(kAoGridSlots) * 4, nullptr), mSums(size_t(kAoGridSlots) * 8, nullptr) {
  const std::string defines =
      "#define TESSERA_AO_GRID_BINDING_KEYS " + std::to_string(kBindingKeys) +
      "\n#define TESSERA_AO_GRID_BINDING_SUMS " + std::to_string(kBindingSums) +
      "\n#define TESSERA_AO_GRID_BINDING_VISIBILITY " + std::to_string(kBindingVisibility) +
      "\n#define TESSERA_AO_GRID_SLOTS " + std::to_string(kAoGridSlots) +
      "u\n#define TESSERA_AO_GRID_SIDE " + std::to_string(kAoGridSide) + "\n";
  for (int stage = 0; stage < 2; ++stage)
    mStages[stage] = GlProgram::compute(
        shaders::kAoGrid, "ao_grid.comp",
        defines + "#define TESSERA_AO_GRID_STAGE " + std::to_string(stage) + "\n");
  mKeys.clear(0);
  mSums.clear(0);
}

void AoGrid::reset(const glm::dvec3& centre, double cell) {
  TESSERA_CHECK(std::isfinite(cell) && cell > 0.0 && std::isfinite(centre.x) &&
                    std::isfinite(centre.y) && std::isfinite(centre.z),
                "render::AoGrid::reset(): the cell must be finite and positive, the centre finite");
  mCentre = centre;
  mCell = cell;
  mKeys.clear(0);
  mSums.clear(0);
}

glm::mat4 AoGrid::gridFromCamera(const glm::dmat4& view) const {
  // grid = (world - centre) / cell + side / 2, world = inverse(view) camera; the translation to
  // the centre in double, so a georeferenced model keeps its precision.
  const glm::dmat4 grid_from_world =
      glm::translate(glm::dmat4(1.0), glm::dvec3(kAoGridSide / 2.0)) *
      glm::scale(glm::dmat4(1.0), glm::dvec3(1.0 / mCell)) *
      glm::translate(glm::dmat4(1.0), -mCentre);
  return glm::mat4(grid_from_world * glm::inverse(view));
}

double AoGrid::add(const FrameTarget& target, const GlBuffer& visibility,
                   const glm::dmat4& projection, const glm::dmat4& view, int stride) {
  TESSERA_CHECK(mCell > 0.0, "render::AoGrid::add(): reset() the grid first");
  TESSERA_CHECK(stride >= 1 && stride <= 8, "render::AoGrid::add(): stride must be 1..8");
  TESSERA_CHECK(visibility.bytes() >= target.pixels() * 4,
                "render::AoGrid::add(): a visibility per pixel of the target");
  GpuLap lap;
  const GlBufferTexture depth(target.depth(), GL_R32UI);
  depth.bind(TESSERA_TEXTURE_DEPTH);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kBindingKeys, mKeys.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kBindingSums, mSums.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kBindingVisibility, visibility.name());
  const GlProgram& p = mStages[0];
  p.use();
  const glm::ivec2 size(int(target.width()), int(target.height()));
  p.set("uSize", size);
  p.set("uStride", stride);
  p.set("uCameraFromClip", glm::mat4(glm::inverse(projection)));
  p.set("uGridFromCamera", gridFromCamera(view));
  p.set("uFar", float(mCell * kAoGridSide));
  dispatch((size + stride - 1) / stride);
  glBindTextureUnit(TESSERA_TEXTURE_DEPTH, 0);
  return lap();
}

double AoGrid::shade(FrameTarget& target, const glm::dmat4& projection, const glm::dmat4& view,
                     float strength) {
  TESSERA_CHECK(mCell > 0.0, "render::AoGrid::shade(): reset() the grid first");
  TESSERA_CHECK(std::isfinite(strength) && strength >= 0.0f,
                "render::AoGrid::shade(): the strength must be finite and >= 0");
  GpuLap lap;
  const GlBufferTexture depth(target.depth(), GL_R32UI);
  depth.bind(TESSERA_TEXTURE_DEPTH);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, target.image().name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kBindingKeys, mKeys.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kBindingSums, mSums.name());
  const GlProgram& p = mStages[1];
  p.use();
  const glm::ivec2 size(int(target.width()), int(target.height()));
  p.set("uSize", size);
  p.set("uCameraFromClip", glm::mat4(glm::inverse(projection)));
  p.set("uGridFromCamera", gridFromCamera(view));
  p.set("uStrength", strength);
  dispatch(size);
  glBindTextureUnit(TESSERA_TEXTURE_DEPTH, 0);
  return lap();
}

uint32_t AoGrid::cells() const {
  std::vector<uint32_t> keys(kAoGridSlots);
  mKeys.read(0, keys.size() * 4, keys.data());
  uint32_t n = 0;
  for (uint32_t k : keys) n += k != 0;
  return n;
}

float AoGrid::at(const glm::dvec3& world) const {
  std::vector<uint32_t> keys(kAoGridSlots);
  std::vector<glm::uvec2> sums(kAoGridSlots);
  mKeys.read(0, keys.size() * 4, keys.data());
  mSums.read(0, sums.size() * 8, sums.data());
  auto pcg = [](uint32_t v) {
    const uint32_t state = v * 747796405u + 2891336453u;
    const uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
  };
  auto lookup = [&](glm::ivec3 c, glm::uvec2& out) {
    if (glm::any(glm::lessThan(c, glm::ivec3(0))) ||
        glm::any(glm::greaterThanEqual(c, glm::ivec3(int(kAoGridSide)))))
      return false;
    const uint32_t key = (uint32_t(c.x) | uint32_t(c.y) << 9 | uint32_t(c.z) << 18) + 1u;
    uint32_t slot = pcg(key) & (kAoGridSlots - 1u);
    for (int i = 0; i < 32; ++i) {
      if (keys[slot] == key) {
        out = sums[slot];
        return out.y != 0;
      }
      if (keys[slot] == 0) return false;
      slot = (slot + 1u) & (kAoGridSlots - 1u);
    }
    return false;
  };
  const glm::dvec3 g = (world - mCentre) / mCell + glm::dvec3(kAoGridSide / 2.0) - 0.5;
  const glm::ivec3 base(glm::floor(g));
  const glm::dvec3 f = g - glm::dvec3(base);
  double sum = 0.0, weight = 0.0;
  for (int corner = 0; corner < 8; ++corner) {
    const glm::ivec3 o(corner & 1, (corner >> 1) & 1, corner >> 2);
    glm::uvec2 s;
    if (!lookup(base + o, s)) continue;
    const glm::dvec3 t = glm::mix(1.0 - f, f, glm::dvec3(o));
    const double tri = t.x * t.y * t.z;
    sum += tri * double(s.x) / double(s.y);
    weight += tri;
  }
  return weight > 0.0 ? float(sum / weight) : -1.0f;
}

}  // namespace tessera::render
