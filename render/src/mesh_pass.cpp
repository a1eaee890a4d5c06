#include <tessera/render/mesh_pass.h>

#include <algorithm>
#include <string>
#include <cmath>

#include <tessera/render/gl_context.h>
#include <tessera/render/gl_objects.h>

#include "clip_uniforms.h"
#include "gpu_lap.h"
#include "shaders.h"
#include "shared_layout.h"

namespace tessera::render {

uint32_t packNormal1010102(const glm::vec3& n) {
  auto q = [](float v) {
    const float c = std::isfinite(v) ? std::clamp(v, -1.0f, 1.0f) : 0.0f;
    return uint32_t(int32_t(std::lround(c * 511.0f))) & 0x3FFu;
  };
  return q(n.x) | q(n.y) << 10 | q(n.z) << 20;
}

namespace {

/// The variant of the mesh pass's program: flat or smooth shading, with or without the clip
/// plane test (shared_layout.h: TESSERA_CLIPPING 0 for batches without planes, which llvmpipe
/// would otherwise pay for on every fragment).
GlProgram shadeProgram(bool flat, bool clipping) {
  const std::string defines =
      std::string(flat ? "#define MESH_FLAT 1\n" : "") + clippingDefine(clipping);
  return GlProgram::graphics(shaders::kMeshVert, shaders::kMeshFrag,
                             flat ? "mesh pass (flat)" : "mesh pass", defines);
}

}  // namespace

struct MeshPass::Impl {
  GlProgram shade[2][2] = {{shadeProgram(false, false), shadeProgram(false, true)},
                           {shadeProgram(true, false), shadeProgram(true, true)}};  ///< [flat][clip]
  GlProgram bare = GlProgram::graphics(shaders::kMeshVert, shaders::kMeshBareFrag, "mesh pass (bare)");
  GlProgram merge = GlProgram::compute(shaders::kMeshMerge, "mesh merge");
  uint32_t vao = 0, fbo = 0;
  uint32_t depth = 0, color = 0, pick = 0;  // textures
  uint32_t width = 0, height = 0;

  Impl() {
    glCreateVertexArrays(1, &vao);
    glEnableVertexArrayAttrib(vao, 0);
    glEnableVertexArrayAttrib(vao, 1);
    glEnableVertexArrayAttrib(vao, 2);
    glEnableVertexArrayAttrib(vao, 3);
    glEnableVertexArrayAttrib(vao, 4);
    glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribFormat(vao, 1, 4, GL_INT_2_10_10_10_REV, GL_TRUE, 12);
    glVertexArrayAttribFormat(vao, 2, 4, GL_UNSIGNED_BYTE, GL_TRUE, 16);
    glVertexArrayAttribFormat(vao, 3, 3, GL_FLOAT, GL_FALSE, 20);
    glVertexArrayAttribFormat(vao, 4, 4, GL_INT_2_10_10_10_REV, GL_TRUE, 32);
    for (uint32_t a = 0; a < 5; ++a) glVertexArrayAttribBinding(vao, a, 0);
  }
  ~Impl() {
    release();
    glDeleteVertexArrays(1, &vao);
  }
  void release() {
    if (fbo) glDeleteFramebuffers(1, &fbo);
    const uint32_t textures[3] = {depth, color, pick};
    glDeleteTextures(3, textures);
    fbo = depth = color = pick = 0;
  }

  /// The framebuffer at the target's size (made again when it changes).
  void ensure(uint32_t w, uint32_t h) {
    if (fbo && w == width && h == height) return;
    release();
    width = w;
    height = h;
    auto texture = [&](uint32_t format) {
      uint32_t t = 0;
      glCreateTextures(GL_TEXTURE_2D, 1, &t);
      glTextureStorage2D(t, 1, format, GLsizei(w), GLsizei(h));
      glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
      glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
      return t;
    };
    depth = texture(GL_DEPTH_COMPONENT32F);
    color = texture(GL_R32UI);
    pick = texture(GL_R32UI);
    glCreateFramebuffers(1, &fbo);
    glNamedFramebufferTexture(fbo, GL_DEPTH_ATTACHMENT, depth, 0);
    glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT0, color, 0);
    glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT1, pick, 0);
    const GLenum buffers[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glNamedFramebufferDrawBuffers(fbo, 2, buffers);
    if (glCheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw RenderError("render::MeshPass: the framebuffer is incomplete at " + std::to_string(w) +
                        "x" + std::to_string(h));
  }

  /// Clears and binds the framebuffer, draws every batch with `program(batch)`.
  template <class ProgramOf>
  void rasterise(const ProgramOf& programOf, std::span<const MeshBatch> batches) {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, GLsizei(width), GLsizei(height));
    const float far = 1.0f;
    const uint32_t none = 0xFFFFFFFFu;
    glClearNamedFramebufferfv(fbo, GL_DEPTH, 0, &far);
    glClearNamedFramebufferuiv(fbo, GL_COLOR, 0, &none);
    glClearNamedFramebufferuiv(fbo, GL_COLOR, 1, &none);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDepthMask(GL_TRUE);
    glDisable(GL_CULL_FACE);  // scans are open surfaces, seen from both sides
    glDisable(GL_BLEND);
    glBindVertexArray(vao);
    const GlProgram* in_use = nullptr;
    for (const MeshBatch& b : batches) {
      if (b.index_count == 0) continue;
      const GlProgram& program = programOf(b);
      if (&program != in_use) {
        program.use();
        in_use = &program;
      }
      program.set("uClipFromLocal", b.clip_from_local);
      program.set("uEyeLocal", b.eye_local);
      program.set("uColorOverride", b.color_override);
      program.set("uPickBase", b.pick_base);
      program.set("uMorph", std::clamp(b.morph, 0.0f, 1.0f));
      setClipUniforms(program, b.clip);
      glVertexArrayVertexBuffer(vao, 0, b.vertices, 0, sizeof(GpuMeshVertex));
      glVertexArrayElementBuffer(vao, b.indices);
      glDrawElements(GL_TRIANGLES, GLsizei(b.index_count), GL_UNSIGNED_INT, nullptr);
    }
    glBindVertexArray(0);
    glDisable(GL_DEPTH_TEST);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
  }
};

MeshPass::MeshPass() : mImpl(std::make_unique<Impl>()) {}
MeshPass::~MeshPass() = default;

double MeshPass::draw(FrameTarget& target, std::span<const MeshBatch> batches,
                      const MeshShading& shading) {
  if (batches.empty()) return 0.0;
  GpuLap lap;
  Impl& s = *mImpl;
  s.ensure(target.width(), target.height());
  s.rasterise([&](const MeshBatch& b) -> const GlProgram& {
    return s.shade[shading.flat][b.clip.count > 0];
  }, batches);
  glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT);
  s.merge.use();
  s.merge.set("uSize", glm::ivec2(int(target.width()), int(target.height())));
  s.merge.set("uWritePick", shading.pick ? 1 : 0);
  glBindTextureUnit(0, s.depth);
  glBindTextureUnit(1, s.color);
  glBindTextureUnit(2, s.pick);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_DEPTH, target.depth().name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_COLORS, target.colors().name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_PICK, target.pick().name());
  glDispatchCompute((target.width() + 7) / 8, (target.height() + 7) / 8, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  for (uint32_t u = 0; u < 3; ++u) glBindTextureUnit(u, 0);
  return lap();
}

double MeshPass::drawBare(const FrameTarget& target, std::span<const MeshBatch> batches) {
  GpuLap lap;
  Impl& s = *mImpl;
  s.ensure(target.width(), target.height());
  s.rasterise([&](const MeshBatch&) -> const GlProgram& { return s.bare; }, batches);
  return lap();
}

}  // namespace tessera::render
