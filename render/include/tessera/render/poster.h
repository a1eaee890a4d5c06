// Posters: one view rendered larger than a frame target holds (frame_target.h: 16384 px a side,
// 2^27 pixels) or than memory allows at once, part by part, and written as a PNG strip by strip.
//
// Each part is a sub-rectangle of the full view's near-plane window with the same off-axis
// frustum: its projection is the full projection scaled and translated in NDC (as withGuardBand()
// widens one for a band), so a part shows exactly the full view's pixels there. Each part is drawn
// with ViewSetup::origin at its top-left in the poster, so passes that seed samples by pixel
// (ambient occlusion) draw what the full view draws, and with the renderer's guard band
// (RenderOptions::guard_band), so screen passes reach across the parts' edges without seams. The
// relative depth's range is agreed over all parts in two rounds, as a wall's tiles agree on one
// (wallRange()). Memory: one row of parts (the poster's width times a part's height, RGBA) and one
// part's frame target at a time, never the whole poster.
#pragma once

#include <cstdint>
#include <cstdio>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <tessera/render/image.h>
#include <tessera/render/tile_frustum.h>
#include <tessera/render/view_renderer.h>

namespace tessera::render {

/// The largest poster side, pixels (PNG allows 2^31 - 1; 65535 keeps a row of parts in memory
/// and readers happy).
constexpr uint32_t kMaxPosterSide = 65535;
/// The largest part side by default.
constexpr uint32_t kDefaultPosterPart = 4096;
/// The largest part side at all: a part and its guard band stay within a frame target (16384 a
/// side, 2^27 pixels).
constexpr uint32_t kMaxPosterPart = 8192;
/// What one rendered pixel of a part costs in memory, bytes: the frame target's four planes, the
/// screen passes' planes (eye-dome lighting, ambient occlusion, analysis), the cropped image and
/// its read-back (llvmpipe keeps GL buffers in host memory). An estimate that bounds the parts'
/// size from the memory allowed.
constexpr uint64_t kPosterBytesPerPartPixel = 64;

/// One part of a poster: its rectangle in the poster (pixels from the top-left) and its view.
struct PosterPart {
  uint32_t x = 0, y = 0, width = 0, height = 0;
  uint32_t column = 0, row = 0;
  ViewSetup view;
};

/// How a poster is cut: `columns` x `rows` parts, the parts of one row the same height, widths
/// and heights differing by at most one pixel.
struct PosterPlan {
  uint32_t width = 0, height = 0;
  uint32_t columns = 0, rows = 0;
  uint32_t part_width = 0, part_height = 0;  ///< the largest part
  /// Bytes in memory at once: one row of parts and one part's render.
  uint64_t peakBytes() const;
};

/// The view of the sub-rectangle [x, x + width) x [y, y + height) (pixels from the top-left) of
/// `full`: the same view matrix and eye, the projection scaled and translated in NDC so its window
/// is that part of `full`'s, origin moved by (x, y). Precondition (TESSERA_CHECK): the rectangle
/// is non-empty and inside `full`.
ViewSetup subView(const ViewSetup& full, uint32_t x, uint32_t y, uint32_t width, uint32_t height);

/// Cuts a `width` x `height` poster into parts of at most `max_part` pixels a side, as few rows as
/// `memory_bytes` allows (peakBytes() within it). Throws RenderError naming the size for a side
/// of 0 or above kMaxPosterSide, and the memory needed when `memory_bytes` holds no row of parts 16
/// pixels tall (or the poster's height, if less). Precondition (TESSERA_CHECK): 16 <= max_part <=
/// kMaxPosterPart.
PosterPlan planPoster(uint32_t width, uint32_t height, uint32_t max_part, uint64_t memory_bytes);

/// The parts of `full` (a view of plan.width x plan.height) for `plan`, row by row, top first.
/// Precondition (TESSERA_CHECK): `full`'s size is the plan's.
std::vector<PosterPart> posterParts(const ViewSetup& full, const PosterPlan& plan);

/// Writes an 8-bit RGBA PNG a few rows at a time (libpng, row by row) to a temporary name beside
/// `path`, renamed to `path` by finish(); destroyed unfinished, it removes the temporary file,
/// so a failed or killed poster never leaves a PNG that opens. One thread.
class PngStripWriter {
 public:
  /// Throws RenderError naming the file when it cannot be created, or for a size of 0 or above
  /// kMaxPosterSide.
  PngStripWriter(const std::string& path, uint32_t width, uint32_t height);
  ~PngStripWriter();
  PngStripWriter(const PngStripWriter&) = delete;
  PngStripWriter& operator=(const PngStripWriter&) = delete;

  /// Appends `rows` rows of width * 4 bytes each (RGBA, top row first). Precondition
  /// (TESSERA_CHECK): rgba holds them and they do not go past the height. Throws RenderError
  /// naming the file when writing fails (disk full).
  void writeRows(std::span<const uint8_t> rgba, uint32_t rows);
  /// Ends the PNG and renames it to its path. Precondition (TESSERA_CHECK): every row written.
  void finish();
  uint32_t rowsWritten() const { return mRows; }

 private:
  std::string mPath, mTemp;
  uint32_t mWidth, mHeight, mRows = 0;
  FILE* mFile = nullptr;
  void* mPng = nullptr;   ///< png_structp
  void* mInfo = nullptr;  ///< png_infop
  bool mDone = false;
};

/// What renderPoster() did.
struct PosterStats {
  size_t parts = 0;       ///< parts rendered for the picture
  size_t renders = 0;     ///< renders in all (twice the parts when the relative depth agreed)
  size_t frames = 0;      ///< frames renderSettled() drew over all renders
  uint32_t max_band = 0;  ///< the widest guard band a part was drawn with
  /// The relative depth range the parts agreed on (wallRange() of their own), when they did.
  std::optional<glm::vec2> agreed_range;
};

/// Renders `full` (plan.width x plan.height) part by part with renderSettled() and hands each
/// finished row of parts to `strip` (RGBA, top row first, the poster's width times the row's
/// height; `y`: its first row in the poster). With the relative depth on and neither a fixed nor an
/// agreed range, each part is rendered once for its own range first and the range wallRange() makes
/// of them is used by every part. The parts share one chunk streamer with `stream_options`.
/// `progress`, when given, is called after each render with (renders done, renders in all).
PosterStats renderPoster(
    std::span<const ModelInstance> models, const ViewSetup& full, const RenderOptions& options,
    const PosterPlan& plan,
    const std::function<void(std::span<const uint8_t> rgba, uint32_t y, uint32_t rows)>& strip,
    const StreamerOptions& stream_options = {}, const Overlay* overlay = nullptr,
    const std::function<void(size_t, size_t)>& progress = {});

/// renderPoster() into one Image (tests, and posters small enough to hold).
Image renderPosterImage(std::span<const ModelInstance> models, const ViewSetup& full,
                        const RenderOptions& options, const PosterPlan& plan,
                        const StreamerOptions& stream_options = {},
                        const Overlay* overlay = nullptr, PosterStats* stats = nullptr);

}  // namespace tessera::render
