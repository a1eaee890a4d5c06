// Sets a geometry pass's clip uniforms (shaders/shared_layout.h tesseraClipped()) from a batch's
// planes (render/clip_planes.h). The program must be in use or not: glProgramUniform.
#pragma once

#include <tessera/render/clip_planes.h>
#include <tessera/render/gl_objects.h>

#include <string>

namespace tessera::render {

/// The define that compiles a geometry program with (batches with clip planes) or without the
/// plane test (shared_layout.h: TESSERA_CLIPPING).
inline std::string clippingDefine(bool clipping) {
  return std::string("#define TESSERA_CLIPPING ") + (clipping ? "1" : "0") + "\n";
}

inline void setClipUniforms(const GlProgram& program, const GpuClipPlanes& clip) {
  program.set("uClipCount", clip.count);
  if (clip.count == 0) return;
  program.set("uClipPlanes", std::span<const glm::vec4>(clip.planes.data(), clip.count));
  program.set("uClipGroups", std::span<const uint32_t>(clip.groups.data(), clip.count));
  program.set("uClipInvert", clip.invert);
}

}  // namespace tessera::render
