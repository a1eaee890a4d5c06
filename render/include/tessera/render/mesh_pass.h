// The mesh pass ("Render pipeline"): the geometry pass for triangle patches
// (lod/mesh_store.h). GL rasterises the batches with its own depth test into the pass's
// framebuffer (depth, packed colour, pick id), then a compute step writes the frame target's
// depth, colours and pick ids where a triangle is nearest (shaders/mesh_merge.comp). Run it
// after FrameTarget::clearGeometry() and before the point pass: points then depth-test against
// the triangles, so points and meshes hide each other correctly in one picture, and the screen
// passes (eye-dome lighting) and the overlay pass see both.
//
// Shading: a two-sided headlight on per-vertex normals (smooth) or screen-derivative facet
// normals (flat), times per-vertex colour or the model's colour.
//
// Geomorphing: each vertex carries the nearest point of its parent patch's surface; a batch
// draws its vertices at mix(target, position, morph), morph rising from 0 when the patch
// replaces its parent to 1 as the parent's error grows on screen (ViewRenderer), so a change of
// level never pops. Border vertices are locked, hence their own targets: no crack while
// morphing.
//
// Cost (llvmpipe): GL's triangle rate for the batches, plus one pass over the pixels for the
// merge (about 2 ms at 1920x1080 on this machine; bench/mesh_lod measures both against a bare
// glDrawElements). A GL 4.5 context must be current on the calling thread for the object's
// whole life.
#pragma once

#include <cstdint>
#include <memory>
#include <span>

#include <glm/glm.hpp>

#include <tessera/render/clip_planes.h>
#include <tessera/render/frame_target.h>

namespace tessera::render {

/// One vertex as the GPU holds it, 36 bytes: position relative to the patch's frame (float),
/// normal as 10:10:10:2 snorm (w unused), rgba (r low byte), and the geomorphing target
/// (lod::MeshStore::morphTargets(): the nearest point of the parent's surface, same frame, and
/// the parent's normal there).
struct GpuMeshVertex {
  glm::vec3 position;
  uint32_t normal;
  uint32_t rgba;
  glm::vec3 morph;
  uint32_t morph_normal;
};
static_assert(sizeof(GpuMeshVertex) == 36);

/// Packs a unit normal as GL_INT_2_10_10_10_REV (x lowest).
uint32_t packNormal1010102(const glm::vec3& n);

/// A patch drawn with one transform.
struct MeshBatch {
  uint32_t vertices = 0;  ///< GL buffer of GpuMeshVertex
  uint32_t indices = 0;   ///< GL buffer of uint32 indices, 3 a triangle
  uint32_t index_count = 0;
  glm::mat4 clip_from_local{1.0f};
  glm::vec3 eye_local{0.0f};    ///< the eye in the patch's frame (headlight)
  uint32_t color_override = 0;  ///< non-zero: 0x1000000 | rgb for every triangle
  uint32_t pick_base = 0;       ///< triangle t writes pick id pick_base + t (with `pick`)
  /// Geomorphing: vertices at mix(morph target, position, morph). 1: the patch's own shape; 0:
  /// on its parent's surface (what it looks like the moment it replaces its parent).
  float morph = 1.0f;
  /// Clip planes in the patch's frame (clip_planes.h): fragments they cut away are discarded
  /// (no depth, colour or pick id), so what lies behind shows.
  GpuClipPlanes clip{};
};

struct MeshShading {
  bool flat = false;  ///< facet normals instead of the vertices'
  bool pick = false;  ///< write pick ids
};

class MeshPass {
 public:
  MeshPass();
  ~MeshPass();
  MeshPass(const MeshPass&) = delete;
  MeshPass& operator=(const MeshPass&) = delete;

  /// Draws `batches` into `target` (see the top of this file). Returns milliseconds, the GL
  /// work finished. Nothing to draw: returns 0 and touches nothing.
  double draw(FrameTarget& target, std::span<const MeshBatch> batches, const MeshShading& shading);
  /// The same triangles with GL only into the pass's framebuffer, no shading and no merge: the
  /// floor the pass is measured against (bench/mesh_lod). Milliseconds.
  double drawBare(const FrameTarget& target, std::span<const MeshBatch> batches);

 private:
  struct Impl;
  std::unique_ptr<Impl> mImpl;
};

}  // namespace tessera::render
