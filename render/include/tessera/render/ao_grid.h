// Multi-view ambient occlusion while the view moves: the real-time variant of Sabbadin, Palma,
// Cignoni and Scopigno, "Multi-View Ambient Occlusion for Enhancing Visualization of Raw
// Scanning Data" (2016), section 6, with the frames a user's navigation draws standing in for
// the depth camera's stream. Each frame's screen-space AO (ao_pass.h, computed without shading
// the image) is scattered into a sparse voxel grid over the world: each sampled pixel adds
// w * visibility and w to the cell holding its surface point, w = w_d w_n (equations 10 and 11:
// nearer views and views facing the surface count more; no border weight, which the grid's
// integration replaces, as the paper's section 6 leaves it out). The picture is then shaded by
// the grid's mean at each pixel's surface point, interpolated between the cells around it, so
// what earlier views saw (an occluder now outside the frame, a hollow seen head-on before and
// grazing now) darkens the present one, and the noise of a single frame averages out.
//
// The grid: 512^3 cells of `cell` world units around a centre (the paper's 512^3 grid), a cell
// kept only once a sample lands in it, in a GPU hash table (open addressing, 2^21 slots of a
// 27-bit cell key, sums in 20.12 fixed point, so the order samples arrive in changes nothing and
// two runs of the same frames give the same grid). A GL 4.5 context must be current for the
// object's whole life.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

#include <tessera/render/frame_target.h>
#include <tessera/render/gl_buffer.h>
#include <tessera/render/gl_objects.h>

namespace tessera::render {

/// Cells a side of the grid, and the hash table's slots.
constexpr uint32_t kAoGridSide = 512;
constexpr uint32_t kAoGridSlots = 1u << 21;

struct AoGridOptions {
  bool enabled = false;
  /// A cell's side in world units (metres); 0: a 256th of the models' largest extent (the
  /// grid then spans twice the models). Finite, >= 0.
  double cell = 0.0;
  /// Every `stride`-th pixel each way adds a sample (1..8).
  int stride = 2;
};

class AoGrid {
 public:
  AoGrid();
  /// Empties the grid and places it: cells of `cell` units, the grid centred on `centre`
  /// (world). Precondition: cell finite and positive.
  void reset(const glm::dvec3& centre, double cell);
  glm::dvec3 centre() const { return mCentre; }
  double cell() const { return mCell; }

  /// Adds the frame's visibility (`visibility`: a float per pixel of `target`, raster order, -1
  /// where nothing was drawn; AoPass::visibility()) at the surface points of every stride-th
  /// pixel each way (the target's depth unprojected through `projection` and `view`, world to
  /// camera). Milliseconds.
  /// Cost: one invocation per sampled pixel, 3 depth reads (the normal), up to 32 probes of the
  /// table and two atomic adds.
  double add(const FrameTarget& target, const GlBuffer& visibility, const glm::dmat4& projection,
             const glm::dmat4& view, int stride);
  /// Multiplies each covered pixel of target.image() by the grid's visibility at its surface
  /// point (trilinear over the 8 cells around it that hold samples; a pixel with none is left
  /// as it is) raised to `strength`. Milliseconds. Cost: 8 lookups of up to 32 probes a pixel.
  double shade(FrameTarget& target, const glm::dmat4& projection, const glm::dmat4& view,
               float strength);

  /// Cells holding samples, and the grid's visibility at a world point as shade() takes it
  /// (-1: no cell around it holds a sample). Read the table back: for tests.
  uint32_t cells() const;
  float at(const glm::dvec3& world) const;

 private:
  /// World to grid coordinates (cells, the grid's corner at 0) from camera space, for the
  /// shaders in float: the translation to the centre is taken in double first.
  glm::mat4 gridFromCamera(const glm::dmat4& view) const;

  GlProgram mStages[2];  ///< shaders/ao_grid.comp: 0 add, 1 shade
  GlBuffer mKeys, mSums;  ///< per slot: cell key + 1 (0: empty); w v and w in 20.12
  glm::dvec3 mCentre{0.0};
  double mCell = 0.0;
};

}  // namespace tessera::render
