// The frame target of one view ("The frame"): the per-pixel planes every pass of the
// view shares. Geometry passes (points now, meshes next) write depth, colour and pick ids; screen
// passes read them and write the image (resolve, eye-dome lighting); the overlay pass draws on
// the image with depth test against the scene. Owned by the view (ViewRenderer), one per view
// size; GL buffers, so a GL 4.5 context must be current for the target's whole life.
//
// Row order: depth, colours and pick ids are in raster order (row 0 at the bottom, as the
// projection maps y up); the image is top row first (PNG, window upload, wall mosaic).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <tessera/render/gl_buffer.h>
#include <tessera/render/image.h>

namespace tessera::render {

/// The depth plane's empty value (no point on the pixel).
constexpr uint32_t kEmptyDepth = 0xFFFFFFFFu;
/// The most pixels a frame target holds (2^27: Mesa's largest buffer texture).
constexpr size_t kMaxFramePixels = size_t(1) << 27;
/// The pick plane's empty value.
constexpr uint32_t kNoPick = 0xFFFFFFFFu;

/// A GL buffer of width x height RGBA8 pixels (top row first) read back as an Image.
Image readImageBuffer(const GlBuffer& plane, uint32_t width, uint32_t height);

class FrameTarget {
 public:
  /// Four planes of 4 bytes a pixel. Throws RenderError for a zero or absurd size.
  FrameTarget(uint32_t width, uint32_t height);

  uint32_t width() const { return mWidth; }
  uint32_t height() const { return mHeight; }
  size_t pixels() const { return size_t(mWidth) * mHeight; }

  /// Window depth in [0, 1] as float bits (they order like the floats, so atomicMin keeps the
  /// nearest), kEmptyDepth where nothing was drawn. Raster order.
  const GlBuffer& depth() const { return mDepth; }
  /// The nearest element's rgb (r in the low byte), 0xFFFFFFFF where none. Raster order.
  const GlBuffer& colors() const { return mColors; }
  /// The nearest element's frame-wide pick index (the view maps it to model, chunk, element),
  /// kNoPick where none or when the frame did not ask for pick ids. Raster order.
  const GlBuffer& pick() const { return mPick; }
  /// RGBA8, top row first: what a window shows and a screenshot saves.
  const GlBuffer& image() const { return mImage; }
  /// Blended colours (PointShading::blend): per pixel the weighted r, g, b sums and the weight
  /// (16 bytes), made on first use. Raster order.
  const GlBuffer& colorSums();
  /// Splat footprints for the pull-push fill (PointShading::fill, FillPass): per pixel two words,
  /// the disc the pixel's nearest point would have had (radius and position in the pixel,
  /// packed as shaders/point_raster.comp describes; 0 where no point was drawn as one pixel) and
  /// non-zero when other points in its depth group (2-3%) fell on the pixel too. Made on first use
  /// (8 bytes a pixel). Raster order.
  const GlBuffer& splatFootprints();

  /// Starts a frame's geometry: depth and colours empty; pick ids empty when `pick`; colour
  /// sums zero when `blend`; splat footprints zero when `footprints`.
  void clearGeometry(bool pick, bool blend = false, bool footprints = false);

  Image readImage() const;
  /// The image's `width` x `height` pixels from (x, y) (from the top-left) into `out` (at least
  /// width * height * 4 bytes), top row first: a picture's inner part without its guard band.
  /// Cost: one GPU copy per row.
  void copyImageRegion(uint32_t x, uint32_t y, uint32_t width, uint32_t height,
                       const GlBuffer& out) const;
  /// One plane read back, raster order.
  std::vector<uint32_t> readDepth() const;
  std::vector<uint32_t> readPick() const;
  /// One pixel of a raster-order plane at image coordinates (x right, y down from the top).
  uint32_t readAt(const GlBuffer& plane, uint32_t x, uint32_t y) const;

 private:
  uint32_t mWidth, mHeight;
  GlBuffer mDepth, mColors, mPick, mImage, mColorSums, mSplatFootprints;
};

}  // namespace tessera::render
