// Points into pixels with compute shaders (shaders/point_raster.comp): nearest point wins,
// deterministic whatever the thread order, round splats of a given radius. A GL 4.5 context must
// be current on the calling thread for the object's whole life.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace tessera::render {

/// One point as the GPU holds it: position relative to its batch's frame, colour packed RGBA
/// (r in the low byte). 16 bytes.
struct GpuPoint {
  glm::vec3 position;
  uint32_t rgba;
};
static_assert(sizeof(GpuPoint) == 16);  // TESSERA_POINT_BYTES, shaders/shared_layout.h

/// A range of GpuPoints drawn with one transform and splat size.
struct DrawBatch {
  uint32_t buffer = 0;  ///< GL buffer holding the points; 0: the one setPoints() filled
  uint32_t first = 0;   ///< index of the first point in that buffer
  uint32_t count = 0;
  glm::mat4 clip_from_local{1.0f};
  /// Splats: with spacing_k > 0, a point at view depth w covers spacing_k / w pixels (the
  /// node's sample spacing projected), radius capped at splat_radius; with spacing_k = 0 every
  /// splat has radius splat_radius (0: one pixel).
  float spacing_k = 0.0f;
  int splat_radius = 0;
  uint32_t color_override = 0;  ///< non-zero: 0x1000000 | rgb for every point (r low byte)

  // See-through (renderEnsembles() only; spbr.h):
  float spbr_k = 0.0f;          ///< copies per point over all ensembles (eq. 4), <= total ensembles
  float disc_k = 0.0f;          ///< cross-section disc radius in pixels at view depth 1
  uint32_t seed = 0;            ///< stable key of the node: picks each point's ensembles
  uint32_t normals = 0;         ///< GL buffer of 10:10:10 normals (slant shading off), or 0
  glm::vec3 eye_local{0.0f};    ///< the eye in the batch's frame
  uint32_t density_ratios = 0;  ///< GL buffer of per-point density ratios (k scale), or 0
  uint32_t cells = 0;           ///< GL buffer of surface cells (chunk_streamer.h GpuChunk), or 0
  float jitter_k = 0.0f;        ///< copies' offset standard deviation, pixels at view depth 1
  float point_alpha = 0.0f;     ///< blended baselines (renderBlended()): each point's opacity
};

struct Image {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgba;  ///< width * height * 4, top row first
};

/// Eye-dome lighting in the resolve pass: strength (0: off), neighbour distance in pixels, and
/// the projection whose depth the batches wrote (for linear depth).
struct RasterShading {
  /// Non-zero (rgba, r in the low byte): every point has this colour, so only the depth pass
  /// runs (points without colour need no id pass).
  uint32_t uniform_color = 0;
  float edl_strength = 0.0f;
  int edl_radius = 1;
  glm::dmat4 projection{1.0};
};

/// Milliseconds per pass of the last render(), measured on the CPU with the GL work finished
/// after each pass (llvmpipe runs it on the CPU; on a GPU this also includes the stall).
struct RasterTimings {
  double depth_ms = 0, color_ms = 0, resolve_ms = 0;
};

class PointRasterizer {
 public:
  PointRasterizer(uint32_t width, uint32_t height);
  ~PointRasterizer();
  PointRasterizer(const PointRasterizer&) = delete;
  PointRasterizer& operator=(const PointRasterizer&) = delete;

  /// Replaces the rasterizer's own point buffer (batches with buffer 0 read it).
  void setPoints(std::span<const GpuPoint> points);
  /// Clears, rasterises every batch (depth pass, then colour pass), resolves colours.
  RasterTimings render(std::span<const DrawBatch> batches, const glm::vec3& background,
                       const RasterShading& shading = RasterShading());
  /// See-through rendering (Tanaka et al. 2016): clears the per-pixel sums of ensemble images.
  void beginEnsembles();
  /// Draws ensembles [first, first + count) of `total` with each batch's spbr_k, disc_k and seed,
  /// `max_layers` at a time (each layer holds a depth and a colour image: 8 bytes a pixel), and
  /// adds their images (background where empty) to the sums. With `slant_off`, cross-sections
  /// shrink by cos(theta) from each batch's normals buffer.
  /// `one_layer` draws every ensemble into a single layer instead (the same adjusted points in
  /// one opaque pass: the speed baseline of bench/spbr).
  RasterTimings drawEnsembles(std::span<const DrawBatch> batches, uint32_t first, uint32_t count,
                              uint32_t total, uint32_t max_layers, const glm::vec3& background,
                              const RasterShading& shading, bool slant_off, bool one_layer = false);
  /// Writes the mean of the `accumulated` ensembles summed since beginEnsembles() as the image.
  double resolveEnsembles(uint32_t accumulated);
  /// Order-independent blending baselines for see-through points (shaders/oit_accumulate.comp):
  /// `weighted_blended` false is the weighted average, true McGuire and Bavoil's weighted
  /// blended OIT. Each batch draws its points once as discs of disc_k with point_alpha.
  RasterTimings renderBlended(std::span<const DrawBatch> batches, const glm::vec3& background,
                              bool weighted_blended);
  /// The last render, read back.
  Image read() const;
  /// The GL buffer holding the last render: width x height RGBA8, top row first.
  uint32_t imageBuffer() const { return mImage; }
  uint32_t width() const { return mWidth; }
  uint32_t height() const { return mHeight; }

 private:
  uint32_t mWidth, mHeight;
  uint32_t mRasterProgram = 0, mResolveProgram = 0;
  uint32_t mPoints = 0, mDepth = 0, mColors = 0, mImage = 0;
  uint32_t mSpbrProgram = 0, mAccumulateProgram = 0;
  uint32_t mLayerDepth = 0, mLayerColors = 0, mAccum = 0, mNoNormals = 0;
  uint32_t mLayers = 0;  ///< layers allocated
  uint32_t mOitProgram = 0, mOitResolveProgram = 0, mOitSums = 0;
};

/// The 10-90% width, in pixels, of a vertical edge near `column` between a plateau on its left
/// and background on its right (the red channel's column means, linearly interpolated; plateau
/// and background levels from the middle halves of either side). O(width x height).
double edgeWidth(const Image& image, uint32_t column);

/// Writes an 8-bit RGBA PNG. Throws RenderError naming the file on failure.
void writePng(const std::string& path, const Image& image);
/// Reads an 8-bit RGB or RGBA PNG (any libpng can expand: palette, grey, 16-bit are converted)
/// into RGBA, top row first. Throws RenderError naming the file on anything unreadable.
Image readPng(const std::string& path);

}  // namespace tessera::render
