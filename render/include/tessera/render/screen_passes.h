// Screen passes: read a frame target's planes, write its image, cost proportional to the pixels
// (not the scene). The resolve turns the geometry passes' depth and colours into the image; eye-
// dome lighting then shades it by depth. Ambient occlusion and the analysis filters join here.
// A GL 4.5 context must be current for each object's whole life.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

#include <tessera/render/frame_target.h>
#include <tessera/render/gl_objects.h>

namespace tessera::render {

/// Depth + colours -> image: the nearest colour, `uniform_color` (non-zero: every element has
/// it and no colour was written), or `background` where nothing was drawn. Milliseconds.
/// Cost: one read of depth and colours and one write per pixel.
class ResolvePass {
 public:
  ResolvePass();
  /// `blended`: colours are the means of the target's colour sums (PointShading::blend).
  double run(FrameTarget& target, const glm::vec3& background, uint32_t uniform_color,
             bool blended = false);

 private:
  GlProgram mProgram;
};

struct EdlOptions {
  float strength = 1.0f;  ///< 0: off
  int radius = 1;         ///< neighbour distance, pixels
};

/// Eye-dome lighting (Boucheny 2009): multiplies each covered pixel of the image by a shade from
/// the log-depth differences to its 8 neighbours at `radius`. `projection` is the one the depth
/// was written with (for linear depth). Milliseconds. Cost: 9 depth reads a pixel.
class EdlPass {
 public:
  EdlPass();
  double run(FrameTarget& target, const EdlOptions& options, const glm::dmat4& projection);

 private:
  GlProgram mProgram;
};

}  // namespace tessera::render
