// Screen-space ambient occlusion: a screen pass that darkens each covered pixel of the resolved
// image by the share of ambient light reaching its surface point, computed from the frame's depth
// alone (points and meshes alike), GTAO-style: J. Jimenez, X. Wu, A. Pesce, A. Jarabo,
// "Practical Realtime Strategies for Accurate Indirect Occlusion", SIGGRAPH 2016 course /
// Activision tech report ATVI-TR-16-01 (GTAO).
//
// Per pixel, the view-space point P is unprojected from its depth through the full projection
// (off-axis tile frusta included) and the surface normal N is reconstructed from the depth (per
// axis the one-sided difference towards the side whose two neighbours continue the pixel's depth
// in a straight line: J. Turanszki, "Improved normal reconstruction from depth", 2021; a pixel
// beside a crease or a silhouette takes its own face's slope). Each slice is a direction phi in
// the screen; the plane through the view vector V and phi cuts the hemisphere into a half
// circle. Marching the depth from the pixel both ways along phi finds the two horizon angles h1,
// h2: the highest tap within the radius, its elevation above the slice's tangent line measured
// against the normal (sin e = (Q - P).N / (|Q - P| |Np|), the same as the angle from V for a
// tap in the slice's plane; a tap rounded to a pixel centre lies a little off it, where only
// this measure keeps a plane's own taps at elevation 0), scaled down by a falloff with its
// distance so the radius has no hard edge. N projected into the slice plane (length |Np|, angle
// n from V) gives the slice's cosine-weighted visibility in closed form (the paper's equation 10):
//   a(h1, h2) = |Np| / 4 (-cos(2 h1 - n) + cos n + 2 h1 sin n - cos(2 h2 - n) + cos n + 2 h2 sin n).
// The pass divides the slices' sum of a(h1, h2) by their sum of the unoccluded value
// (h = n -/+ pi/2): a ratio estimator that tends to the paper's mean over slices as the slices
// grow, and is exactly 1 on any plane for any number of slices (the paper's mean scatters
// between 0.5 and 1.4 per slice on a plane tilted 60 degrees).
//
// Noise and determinism: slice directions come from a table of kAoDirections directions over
// half a turn; a pixel's directions and its step offsets are a PCG hash (M. O'Neill 2014, as in
// Jarzynski and Olano, "Hash Functions for GPU Rendering", JCGT 2020) of its position in the
// whole picture (`origin` + its pixel) rotated per frame by the golden ratio (an R1 sequence),
// so frames 0, 1, 2, ... of a resting camera cover the circle evenly and every process drawing
// the same frame number draws the same picture, a wall tile the same pixels as the whole wall.
// Taps lie at 1 + s^2 (r - 1) pixels along phi, s = (k + jitter) / steps (more taps near the
// pixel, as the paper's), rounded to a pixel centre.
//
// Then the visibility is averaged over frames while the camera rests (a running mean), blurred
// over 5x5 pixels where the depth says they are one surface (a bilateral filter, so a depth step
// keeps its sides apart), and optionally computed at half resolution and brought to full
// resolution with weights from the depth (a joint bilateral upsample: J. Kopf, M. Cohen,
// D. Lischinski, M. Uyttendaele, "Joint Bilateral Upsampling", SIGGRAPH 2007). The image's
// colour is multiplied by visibility^strength; empty pixels are left as they are, so the pass
// composes with colour and eye-dome lighting in either order.
//
// A GL 4.5 context must be current for the pass's whole life. Not thread-safe: one GL thread.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/render/frame_target.h>
#include <tessera/render/gl_buffer.h>
#include <tessera/render/gl_objects.h>

namespace tessera::render {

/// Slice directions in the table the pass draws from (over half a turn; a slice looks both ways).
constexpr int kAoDirections = 256;
/// AoOptions::slices and ::steps' largest values.
constexpr int kAoMaxSlices = 64;
constexpr int kAoMaxSteps = 32;
/// The largest screen radius, pixels (a near surface with a world radius is clamped to it).
constexpr float kAoMaxRadiusPx = 128.0f;
/// The denoise's half-width in pixels of the resolution the visibility is computed at.
constexpr int kAoDenoiseRadius = 2;
/// The falloff: a tap at distance d from the pixel's point counts fully up to
/// (1 - kAoFalloff) radius, then linearly less, nothing at the radius.
constexpr float kAoFalloff = 0.25f;

struct AoOptions {
  bool enabled = false;
  /// View-space radius (the model's units, metres on a metric model); 0 or less: `radius_px`
  /// is used instead. Finite.
  float radius = 0.0f;
  /// Used when radius <= 0: the radius in pixels at any depth. Finite, > 0. Either radius is
  /// clamped to kAoMaxRadiusPx pixels on screen.
  float radius_px = 32.0f;
  /// Directions per pixel per frame, each a slice of two opposite horizons; 1..kAoMaxSlices.
  int slices = 2;
  /// Depth taps per horizon side; 1..kAoMaxSteps.
  int steps = 6;
  /// 0: off; the visibility is raised to this power. Finite, >= 0.
  float strength = 1.0f;
  /// Computes the visibility on every other pixel each way (a quarter of the work) and brings it
  /// to full resolution with weights from the depth. On by default: at 1920x1080 on llvmpipe the
  /// full-resolution pass costs 2.7 eye-dome lighting passes, half resolution about one, for a
  /// mean error against a ray-traced reference 0.0005 larger (bench/ao).
  bool half_resolution = true;
  /// A depth-aware (bilateral) 5x5 blur of the visibility plane.
  bool denoise = true;
  /// Frames averaged while the camera rests (1: none); frames beyond it keep the mean and cost
  /// only the denoise and the image's shading. >= 1.
  int max_frames = 16;
  /// false: the visibility plane only (visibility(), for the multi-view grid of ao_grid.h), the
  /// image left as it is.
  bool shade = true;
};

/// Why `options` cannot be run ("" when they can): NaN or infinite numbers, slices or steps out
/// of range, a non-positive pixel radius when no world radius is given, max_frames below 1. For
/// callers checking outside input (scene files) before they reach run(), which throws.
std::string aoOptionsError(const AoOptions& options);

/// The pass (see the top of this file). Owns float planes of 4 bytes a pixel (the visibility,
/// and at the resolution computed the running mean and the denoised mean), reallocated when the
/// target's size changes.
/// Cost per pixel computed (a quarter of the pixels at half resolution): 5 depth reads for the
/// normal, 2 x slices x steps depth reads and unprojections, 4 arc cosines a slice; the denoise
/// 25 reads of depth and visibility; the image pass 1 (full) or 4 (half resolution) reads.
class AoPass {
 public:
  AoPass();

  /// Multiplies each covered pixel of target.image() by its visibility^strength (the ambient
  /// light reaching it, 0..1). `projection`: the perspective projection the depth was written
  /// with (any frustum, off-axis included). `frame`: 0 starts the accumulation over (pass 0
  /// whenever the view or the data changed), then 1, 2, ... while the camera rests; frame k <
  /// max_frames takes weight 1 / (k + 1) in the running mean; later frames keep the mean. A frame
  /// that does not follow this pass's previous run (k != previous + 1), other options or another
  /// target size start over as frame 0 would, with this frame's samples. `origin`: this target's
  /// pixel (0, 0) in a larger picture it is part of (a wall tile with its guard band in the
  /// whole wall): samples are seeded by that position and `frame`, never by time, so tiles draw
  /// what the whole picture draws (pixels farther than reach() from the target's border).
  /// Returns milliseconds (pass_timing.h), 0 when disabled or strength is 0 (then nothing is
  /// touched).
  /// Precondition (TESSERA_CHECK): aoOptionsError(options) is empty; `projection` is a
  /// perspective one ([2][3] = -1, [3][3] = 0).
  double run(FrameTarget& target, const AoOptions& options, const glm::dmat4& projection,
             uint32_t frame, glm::ivec2 origin = glm::ivec2(0));

  /// The last run's visibility per pixel (before the strength), raster order (row 0 at the
  /// bottom), -1 where nothing was drawn. Empty before the first run. Waits for the GL work.
  std::vector<float> readVisibility() const;
  /// The same on the GPU: a float per pixel of the last run's target.
  const GlBuffer& visibility() const { return mVisibility; }

  /// The pixels a tile needs around it (its guard band) so that its pixels equal the whole
  /// picture's: the largest screen radius of these options (a world radius at
  /// `nearest_depth_hint`, the nearest view depth expected, positive), plus the denoise's
  /// half-width, plus the half-resolution grid's and upsample's reach. `height`: the picture's
  /// height in pixels the projection maps to. At least 1 for enabled options.
  static int reach(const AoOptions& options, const glm::dmat4& projection, uint32_t height,
                   float nearest_depth_hint);

 private:
  /// shaders/ao.comp's stages (visibility and mean, denoise, shade), each at full and half
  /// resolution: [stage * 2 + half].
  GlProgram mStages[6];
  GlBuffer mMean, mDenoised, mVisibility;
  GlBufferTexture mMeanTexels, mDenoisedTexels;
  glm::ivec2 mGrid{0};  ///< size of the computed planes (half resolution: about half each way)
  size_t mPixels = 0;   ///< the target's pixels mVisibility holds
  /// The accumulation: options, origin and target size of the mean, frames in it, last frame.
  AoOptions mMeanOptions;
  glm::ivec2 mMeanOrigin{0};
  glm::dmat4 mMeanProjection{0.0};
  int mMeanFrames = 0;
  uint32_t mLastFrame = 0;
};

}  // namespace tessera::render
