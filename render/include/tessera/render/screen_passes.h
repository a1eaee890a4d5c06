// Screen passes: read a frame target's planes, write its image, cost proportional to the pixels
// (not the scene). The resolve turns the geometry passes' depth and colours into the image; eye-
// dome lighting then shades it by depth. Ambient occlusion and the analysis filters join here.
// A GL 4.5 context must be current for each object's whole life.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/render/frame_target.h>
#include <tessera/render/gl_objects.h>

namespace tessera::render {

/// Depth + colours -> image: the nearest colour, `uniform_color` (non-zero: every element has
/// it and no colour was written), or `background` where nothing was drawn. Milliseconds.
/// Cost: one read of depth and colours (texels) and one write per pixel.
class ResolvePass {
 public:
  ResolvePass();
  /// `blended`: colours are the means of the target's colour sums (PointShading::blend).
  double run(FrameTarget& target, const glm::vec3& background, uint32_t uniform_color,
             bool blended = false);

 private:
  GlProgram mPrograms[3];  ///< resolve.comp's MODE: nearest colour, blended, one colour
};

/// FillPass's most pyramid levels (TESSERA_FILL_MAX_LEVELS in shaders/shared_layout.h): radii
/// up to 2^4 = 16 pixels are filled in full (footprints hold radii to 15.9 px in 1/16 px).
constexpr int kFillMaxLevels = 4;

/// The pull-push fill's depth tolerance, in splat radii (FillPass).
constexpr float kFillDepthTolerance = 4.0f;

/// Screen-space surface reconstruction for points drawn as single pixels with their splat
/// footprints (PointShading::fill; R. Marroquim, M. Kraus, P. R. Cavalcanti, "Efficient
/// point-based rendering using image reconstruction", SPBG 2007; shaders/fill.comp): the pull
/// phase builds a pyramid keeping one front-surface sample per 2x2 block, the push phase, coarse
/// to fine, gives each texel and then each pixel the front sample whose disc reaches it. A pixel
/// without a sample, or lying behind that sample by more than kFillDepthTolerance radii (a back
/// surface seen through a hole of the front), takes it; so does its depth, colour (when
/// `colors`) and pick id (when `pick`), so later passes and pick() see the filled surface. Pixels
/// no disc reaches stay empty: silhouettes grow no more than the discs'. Where discs overlap,
/// the surface shows the sample whose disc holds the pixel deepest rather than the nearest in
/// depth. Run after the point pass and before the resolve. Milliseconds.
///
/// The pass works in tiles of 2^kFillMaxLevels pixels: those holding a drawn pixel, grown by the
/// farthest reach of a sample, and those it worked in last time (which it empties). A run is
/// the same as on a fresh pass (FillTest.AFillPassReusedFrameAfterFrameGivesWhatAFreshOneGives).
///
/// Cost: levels = ceil(log2(max_radius)) (1 to kFillMaxLevels). One read of the depth over the
/// whole frame (which tiles hold a drawn pixel; a word a tile read back). Then in the tiles only:
/// one pass over the pixels in 2x2 blocks reading the frame's depth and footprints (2 words a
/// pixel) into packed samples (8 bytes); pull and push passes over each level's texels (a quarter
/// of the pixels and less; 4 and 16 samples and 9 winners read a texel); one pass over the pixels
/// in 2x2 blocks (16 samples and 9 winners read a block, the 9 winners only where no sample
/// reaches); planes written where the fill changes a pixel, then copied into the frame's. At
/// 1920x1080 on llvmpipe 30-45 ms where a model covers a quarter to a third of the view
/// (bench/fill), 70-75 ms over the whole frame. Owns two pyramid textures of 8 bytes a texel (level
/// 0 included: 1.7 times the pixels) and output planes of 4 bytes a pixel, reallocated when the
/// target's size changes.
class FillPass {
 public:
  FillPass();
  /// `projection`: the one the depth was written with (view depth and a pixel's size for the
  /// depth tolerance). `max_radius`: the largest splat radius drawn, pixels (larger radii in
  /// the target are clamped to it, and to 2^kFillMaxLevels). Does nothing for a max_radius
  /// below 1 (or NaN).
  double run(FrameTarget& target, const glm::dmat4& projection, float max_radius, bool colors,
             bool pick);

 private:
  /// Empties every texel of the pyramid and forgets the tiles listed.
  void clearPyramid();
  /// shaders/fill.comp's stage 0-4 (mark tiles, pull, push a level, the pixels, write back),
  /// compiled on first use; stages 3 and 4 per copy of colours and pick ids.
  const GlProgram& stage(int stage, bool colors, bool pick);

  GlProgram mStages[5 * 4];
  /// The pyramid: samples of levels 0 .. kFillMaxLevels (mip l), the push's winners of levels
  /// 1 .. kFillMaxLevels (mip l - 1); sized up to whole tiles (2^kFillMaxLevels pixels) so every
  /// level's mip holds its texels. Outside the tiles listed last, every texel is empty.
  GlTexture mSamples, mWinners;
  GlBuffer mDepth, mColors, mPick;
  GlBuffer mMarks, mTiles;  ///< per tile: holds a drawn pixel; the tiles listed (y << 16 | x)
  GlBufferTexture mTileTexels;
  std::vector<uint8_t> mListedBefore;  ///< per tile: listed by the last run
  size_t mPixels = 0;                  ///< target size the planes are for
  uint32_t mWidth = 0;
  int mLevels = 0;  ///< the levels the pyramid was last built with
};

/// EdlOptions::filter_radius's largest value (TESSERA_EDL_MAX_FILTER_RADIUS in
/// shaders/shared_layout.h).
constexpr int kEdlMaxFilterRadius = 4;

enum class EdlMethod {
  /// Today's (Potree's) form: raw depths, the sum over the 8 neighbours divided by 8. Speckles
  /// on scans with range noise; kept as the baseline (bench/edl.cpp).
  kClassic,
  /// The same shade from a denoised depth: a plane fitted to each pixel's window of log depths,
  /// same-surface pixels only; the obscurance normalised by the neighbours with a point.
  kRobust,
};

struct EdlOptions {
  float strength = 1.0f;  ///< 0: off
  int radius = 2;         ///< neighbour distance, pixels (kRobust: the strength is divided by it)
  EdlMethod method = EdlMethod::kRobust;
  // kRobust only:
  /// The fitted window is (2 r + 1)^2 pixels (0: raw depth), r <= kEdlMaxFilterRadius.
  int filter_radius = 2;
  /// The steepest surface slope (tan of the angle between its normal and the view ray) that the
  /// fit still takes as one surface across a window; steeper or a depth step: an edge.
  float edge_slope = 4.0f;
  bool plane_fit = true;  ///< false: the mean of the window's same-surface pixels
  /// Same surface as the 3x3 median of depths (true) or as the pixel itself (false: a lone
  /// sample of a layer behind keeps its depth and shades dark).
  bool median_reference = true;

  /// The classic method: kClassic at radius 1.
  static EdlOptions classic() {
    EdlOptions o;
    o.radius = 1;
    o.method = EdlMethod::kClassic;
    return o;
  }
};

/// Eye-dome lighting (Boucheny 2009): multiplies each covered pixel of the image by a shade from
/// the log-depth differences to its 8 neighbours at `radius`. `projection` is the one the depth
/// was written with (for linear depth and the pixel angle). Milliseconds.
/// Cost: kClassic one pass over the pixels, 9 depth reads and logarithms a pixel; kRobust two
/// passes, a 3x3 median and a plane fit over (2 filter_radius + 1)^2 depth reads a pixel, then 9
/// reads of the denoised plane (a float plane of its own, 4 bytes a pixel, reallocated when the
/// target's size changes). Reads go through buffer textures; each stage is its own program. On
/// llvmpipe at 1920x1080 the robust pass costs 55 ms with the defaults.
class EdlPass {
 public:
  EdlPass();
  double run(FrameTarget& target, const EdlOptions& options, const glm::dmat4& projection);

 private:
  GlProgram mStages[3];             ///< shaders/edl.comp's stages: robust 0 and 1, classic 2
  GlBuffer mFiltered;               ///< kRobust: denoised log2 depth per pixel
  GlBufferTexture mFilteredTexels;  ///< mFiltered as stage 1 reads it
};

/// The relative depth filter (Borgeat et al., "Visualizing and analyzing large and detailed 3D
/// datasets", section 4; shaders/analysis.comp): the linear view depth minus its Gaussian blur
/// keeps the fine relief (tool marks, erosion, faint carving) and drops the global shape, shown
/// through a perceptual colour map (viridis, dark for hollows, yellow for ridges).
struct RelativeDepthOptions {
  bool enabled = false;
  int radius = 24;      ///< the blur's half-width, pixels (sigma = radius / 3); 1..kMaxRelativeDepthRadius
  /// Positive: the half-width in units (metres) on the model instead, at view depth
  /// `radius_depth` (the camera's distance to what it looks at), turned into pixels for each
  /// view (ViewRenderer; clamped to 1..kMaxRelativeDepthRadius), so the same relief is kept
  /// whatever the zoom. Finite.
  float radius_m = 0.0f;
  double radius_depth = 1.0;  ///< view depth (units) radius_m is taken at; finite, > 0
  float amount = 1.0f;  ///< 1: the colour map replaces the picture; less: mixed into it
  /// The depth difference (view units) mapped to the colour map's ends, fixed (a scene
  /// setting); unset: agreed_range, else this frame's own 1st to 99th percentile.
  std::optional<glm::vec2> range;
  /// The range the whole picture agreed on (a wall: wallRange() of every tile's own range, sent
  /// by the master), used when `range` is unset; the frame's own range is still measured, so a
  /// tile keeps reporting it.
  std::optional<glm::vec2> agreed_range;
};

/// One range for a picture made of parts (the tiles of a wall) from each part's own relative
/// depth range: from the lowest low to the highest high, parts with an empty range (hi <= lo,
/// or not finite: nothing drawn) left out; unset when no part has one.
std::optional<glm::vec2> wallRange(std::span<const glm::vec2> part_ranges);
constexpr int kMaxRelativeDepthRadius = 256;

/// Contour lines (the same paper, section 4): one pixel wide wherever a level is crossed, even on
/// flat ground, of the view depth or of the height along a world axis (a LiDAR scan's vertical).
struct ContourOptions {
  bool enabled = false;
  double interval = 1.0;  ///< units (metres) between two lines; finite, > 0
  double phase = 0.0;     ///< units: lines at phase + k * interval
  /// Height along `axis` (world, need not be unit length) instead of the view depth.
  bool height = false;
  glm::dvec3 axis{0.0, 0.0, 1.0};
  glm::vec4 color{0.05f, 0.05f, 0.05f, 0.85f};  ///< rgb 0..1 and opacity over the picture
  /// Neighbours whose view depths differ by more than this fraction lie on another surface: no
  /// line along a depth step.
  float edge = 0.05f;
};

/// Relative depth and contour lines on the resolved image (run after eye-dome lighting, before
/// highlights and the overlay). Milliseconds. Opaque frames: they read the depth plane.
/// Cost: relative depth, 2 (2 radius / stride + 1) reads a pixel in two separable passes (taps
/// every max(1, radius / 6) pixels: 13 to 23 a pass for any radius; the extremes of every other
/// pixel each way), one histogram pass over those pixels (16 KiB read back) and one
/// colour-map pass (a plane of 8 bytes a pixel and
/// one of 4, reallocated when the target's size changes); contour lines, 25 depth reads a pixel
/// (the surface's mean value over 5x5) and 5 more (the lines).
class AnalysisPass {
 public:
  AnalysisPass();
  /// `range_out`: the frame's own range (or the fixed one, when options.range is set), for a
  /// wall to agree on. `band`: the target's guard band, pixels; the frame's own range is that of
  /// the pixels inside it.
  double relativeDepth(FrameTarget& target, const RelativeDepthOptions& options,
                       const glm::dmat4& projection, glm::vec2* range_out = nullptr,
                       uint32_t band = 0);
  /// `view`: world to view (the height's axis and its offset from the eye).
  double contours(FrameTarget& target, const ContourOptions& options,
                  const glm::dmat4& projection, const glm::dmat4& view);

 private:
  /// The planes sized to the target (reallocated when its size changes).
  void ensurePlanes(const FrameTarget& target);
  /// Stage `stage`'s program in use with the target's size and the depth's projection set.
  const GlProgram& useStage(int stage, const FrameTarget& target,
                            const glm::dmat4& projection) const;

  GlProgram mStages[6];  ///< shaders/analysis.comp's stages
  GlBuffer mSums, mPlane, mRange;
  GlBufferTexture mSumTexels, mPlaneTexels;
};

/// The side of a highlight mask, bits: 1024 x 1024 over the lasso view's NDC square (128 KiB),
/// so a lasso drawn on a 1920-pixel view is followed to about 2 of its pixels.
constexpr uint32_t kHighlightMaskSize = 1024;

/// A region to tint (a selection): what the lasso drawn in view `clip_from_world`
/// enclosed (`mask`: rasterizeLasso()), the whole depth through, on one model.
struct Highlight {
  glm::dmat4 clip_from_world{1.0};
  std::shared_ptr<const std::vector<uint32_t>> mask;
  glm::u8vec4 tint{255, 190, 0, 120};  ///< rgb and how much of it (alpha / 255) over the pixel
  /// The MODEL node selected on (ModelInstance::node): only pixels whose pick id is one of that
  /// model's elements are tinted (other models inside the lasso's volume are not). 0: any
  /// surface. See-through frames have no pick ids: there any surface is tinted.
  uint32_t model_node = 0;
  /// The lasso took only what its view showed (SelectionPayload::visible_only): a pixel is
  /// tinted only where its surface point is not hidden from the lasso's view. The view renderer
  /// draws the frame's batches once more from the lasso's view into a depth plane
  /// (kLassoDepthSize^2 over its NDC square) and the pass compares eye depths, as the lasso did
  /// (within 1%). Approximate where the lasso's view saw occluders this view's cut does not hold
  /// (outside this view's frustum) and at the depth plane's resolution. Opaque frames only.
  bool visible_only = false;
};

/// The side of the depth plane a visible-only highlight is tested against, pixels over the
/// lasso view's NDC square (4 MiB of planes).
constexpr uint32_t kLassoDepthSize = 512;

/// The pick ids one model's elements wrote in a frame, [first, first + count), and its node.
struct PickSpan {
  uint32_t node = 0;
  uint32_t first = 0, count = 0;
};

/// The lasso `ndc` (the lasso view's normalised device coordinates, x right, y up; at least 3
/// finite vertices, else an empty mask) as kHighlightMaskSize^2 bits, row-major from NDC y = -1,
/// by the even-odd rule at each cell's centre (annotate/lasso_selection.h's rule). Cost: one
/// pass over the rows, O(rows x edges + cells / 32).
std::vector<uint32_t> rasterizeLasso(std::span<const glm::dvec2> ndc);

/// Tints the pixels whose surface point (this view's pixel centre at its depth) projects inside
/// a highlight's lasso. Run after the resolve and eye-dome lighting, before the overlay.
/// `clip_from_world`: the view the depth was written with. `models`: the frame's pick ids per
/// model, when the target holds pick ids: a highlight naming a model then tints only pixels of
/// that model's span (and nothing when the model was not drawn); without them (see-through
/// frames) any surface in the lasso is tinted. `lasso_depth`: for visible-only highlights, the
/// depth the lasso's view shows (a target whose depth plane was drawn with each highlight's
/// clip_from_world; the caller draws it, so run() then takes one highlight); null: through the
/// depth. Milliseconds.
/// Cost per highlight: one pass over the pixels reading the depth, the pick id and the mask (a
/// 128 KiB upload when the mask changed), like one eye-dome lighting stage.
class HighlightPass {
 public:
  HighlightPass();
  double run(FrameTarget& target, std::span<const Highlight> highlights,
             const glm::dmat4& clip_from_world,
             std::optional<std::span<const PickSpan>> models = std::nullopt,
             const FrameTarget* lasso_depth = nullptr);

 private:
  GlProgram mProgram;
  GlBuffer mMask;
  const std::vector<uint32_t>* mUploaded = nullptr;    ///< the mask in mMask (by identity)
  std::shared_ptr<const std::vector<uint32_t>> mKeep;  ///< keeps that identity valid
};

}  // namespace tessera::render
