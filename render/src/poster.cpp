#include <tessera/render/poster.h>

#include <png.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <memory>
#include <random>

#include <tessera/core/check.h>
#include <tessera/core/file_checks.h>
#include <tessera/render/gl_context.h>

namespace tessera::render {

namespace {

uint32_t ceilDiv(uint64_t a, uint64_t b) {
  return uint32_t((a + b - 1) / b);
}

/// Part `i` of `n` equal spans over `total` pixels: its start (the first total % n spans are one
/// pixel longer).
uint32_t spanStart(uint32_t total, uint32_t n, uint32_t i) {
  const uint32_t base = total / n, extra = total % n;
  return i * base + std::min(i, extra);
}

void checkPosterSide(uint32_t side, const char* which, const std::string& where) {
  if (side == 0 || side > kMaxPosterSide)
    throw RenderError(where + ": poster " + which + " " + std::to_string(side) +
                      " pixels is outside 1.." + std::to_string(kMaxPosterSide));
}

}  // namespace

uint64_t PosterPlan::peakBytes() const {
  return uint64_t(width) * part_height * 4 +
         uint64_t(part_width) * part_height * kPosterBytesPerPartPixel;
}

ViewSetup subView(const ViewSetup& full, uint32_t x, uint32_t y, uint32_t width, uint32_t height) {
  TESSERA_CHECK(width > 0 && height > 0 && uint64_t(x) + width <= full.width &&
                    uint64_t(y) + height <= full.height,
                "render::subView(): the part lies inside the view");
  ViewSetup v = full;
  v.width = width;
  v.height = height;
  // The part's window in the full view's NDC: x from -1 + 2 x / W, y (up) from 1 - 2 (y + h) / H.
  const double W = full.width, H = full.height;
  const double x0 = -1.0 + 2.0 * x / W, x1 = -1.0 + 2.0 * (double(x) + width) / W;
  const double y1 = 1.0 - 2.0 * y / H, y0 = 1.0 - 2.0 * (double(y) + height) / H;
  // NDC' = (NDC - centre) * scale, in clip space: x' = s x - s c w.
  glm::dmat4 m(1.0);
  m[0][0] = 2.0 / (x1 - x0);
  m[1][1] = 2.0 / (y1 - y0);
  m[3][0] = -(x0 + x1) / (x1 - x0);
  m[3][1] = -(y0 + y1) / (y1 - y0);
  v.projection = m * full.projection;
  v.origin = full.origin + glm::ivec2(int(x), int(y));
  if (full.whole_size == glm::uvec2(0)) v.whole_size = {full.width, full.height};
  return v;
}

PosterPlan planPoster(uint32_t width, uint32_t height, uint32_t max_part, uint64_t memory_bytes) {
  TESSERA_CHECK(max_part >= 16 && max_part <= kMaxPosterPart,
                "render::planPoster(): parts of 16..kMaxPosterPart pixels a side");
  checkPosterSide(width, "width", "render::planPoster()");
  checkPosterSide(height, "height", "render::planPoster()");
  PosterPlan p;
  p.width = width;
  p.height = height;
  p.columns = ceilDiv(width, max_part);
  p.part_width = ceilDiv(width, p.columns);
  // The tallest part the memory allows beside a row of parts that tall.
  const uint64_t per_row = uint64_t(width) * 4 + uint64_t(p.part_width) * kPosterBytesPerPartPixel;
  const uint64_t fit = memory_bytes / per_row;
  if (fit < std::min<uint64_t>(16, height))
    throw RenderError("render::planPoster(): a " + std::to_string(width) + "x" +
                      std::to_string(height) + " poster needs at least " +
                      std::to_string(ceilDiv(per_row * 16, 1 << 20)) +
                      " MiB for rows of parts 16 pixels tall (" +
                      std::to_string(memory_bytes >> 20) + " MiB allowed)");
  const uint32_t tallest = uint32_t(std::min<uint64_t>({fit, max_part, height}));
  p.rows = ceilDiv(height, tallest);
  p.part_height = ceilDiv(height, p.rows);
  return p;
}

std::vector<PosterPart> posterParts(const ViewSetup& full, const PosterPlan& plan) {
  TESSERA_CHECK(full.width == plan.width && full.height == plan.height,
                "render::posterParts(): the view is the plan's size");
  std::vector<PosterPart> parts;
  parts.reserve(size_t(plan.columns) * plan.rows);
  for (uint32_t r = 0; r < plan.rows; ++r) {
    const uint32_t y = spanStart(plan.height, plan.rows, r),
                   h = spanStart(plan.height, plan.rows, r + 1) - y;
    for (uint32_t c = 0; c < plan.columns; ++c) {
      const uint32_t x = spanStart(plan.width, plan.columns, c),
                     w = spanStart(plan.width, plan.columns, c + 1) - x;
      parts.push_back({x, y, w, h, c, r, subView(full, x, y, w, h)});
    }
  }
  return parts;
}

PngStripWriter::PngStripWriter(const std::string& path, uint32_t width, uint32_t height)
    : mPath(path), mWidth(width), mHeight(height) {
  checkPosterSide(width, "width", "render::PngStripWriter: " + path);
  checkPosterSide(height, "height", "render::PngStripWriter: " + path);
  const std::filesystem::path p(path);
  mTemp = (p.parent_path() /
           ("." + p.filename().string() + ".part-" + std::to_string(std::random_device{}())))
              .string();
  mFile = std::fopen(mTemp.c_str(), "wb");
  if (!mFile)
    throw RenderError("render::PngStripWriter: cannot create " + path + ": " +
                      whyNotWritable(path, errno));
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  mPng = png;
  mInfo = info;
  if (!png || !info) throw RenderError("render::PngStripWriter: " + path + ": out of memory");
  if (setjmp(png_jmpbuf(png)))
    throw RenderError("render::PngStripWriter: writing " + path + " failed (disk full?)");
  png_init_io(png, mFile);
  png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGBA, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
}

PngStripWriter::~PngStripWriter() {
  png_structp png = static_cast<png_structp>(mPng);
  png_infop info = static_cast<png_infop>(mInfo);
  if (png) png_destroy_write_struct(&png, &info);
  if (mFile) std::fclose(mFile);
  if (!mDone) {
    std::error_code ec;
    std::filesystem::remove(mTemp, ec);
  }
}

void PngStripWriter::writeRows(std::span<const uint8_t> rgba, uint32_t rows) {
  TESSERA_CHECK(
      !mDone && uint64_t(mRows) + rows <= mHeight && rgba.size() >= size_t(rows) * mWidth * 4,
      "render::PngStripWriter::writeRows(): rows within the picture, all given");
  png_structp png = static_cast<png_structp>(mPng);
  if (setjmp(png_jmpbuf(png)))
    throw RenderError("render::PngStripWriter: writing " + mPath + " failed (disk full?)");
  for (uint32_t r = 0; r < rows; ++r)
    png_write_row(png, const_cast<png_bytep>(rgba.data() + size_t(r) * mWidth * 4));
  mRows += rows;
}

void PngStripWriter::finish() {
  TESSERA_CHECK(!mDone && mRows == mHeight, "render::PngStripWriter::finish(): every row written");
  png_structp png = static_cast<png_structp>(mPng);
  png_infop info = static_cast<png_infop>(mInfo);
  if (setjmp(png_jmpbuf(png)))
    throw RenderError("render::PngStripWriter: writing " + mPath + " failed (disk full?)");
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  mPng = mInfo = nullptr;
  const int closed = std::fclose(mFile);
  mFile = nullptr;
  if (closed != 0)
    throw RenderError("render::PngStripWriter: closing " + mPath +
                      " failed: " + std::strerror(errno));
  std::error_code ec;
  std::filesystem::rename(mTemp, mPath, ec);
  if (ec) throw RenderError("render::PngStripWriter: " + mPath + ": " + ec.message());
  mDone = true;
}

PosterStats renderPoster(
    std::span<const ModelInstance> models, const ViewSetup& full, const RenderOptions& options,
    const PosterPlan& plan,
    const std::function<void(std::span<const uint8_t>, uint32_t, uint32_t)>& strip,
    const StreamerOptions& stream_options, const Overlay* overlay,
    const std::function<void(size_t, size_t)>& progress) {
  const std::vector<PosterPart> parts = posterParts(full, plan);
  auto streamer = std::make_shared<ChunkStreamer>(stream_options);
  PosterStats stats;
  stats.parts = parts.size();
  RenderOptions o = options;
  const bool agree =
      o.relative_depth.enabled && !o.relative_depth.range && !o.relative_depth.agreed_range;
  const size_t total = parts.size() * (agree ? 2 : 1);
  auto renderPart = [&](const PosterPart& part, const RenderOptions& part_options,
                        RenderStats& st) {
    ViewRenderer r(part.width, part.height, streamer);
    Image img = r.renderSettled(models, part.view, part_options, &st, overlay);
    stats.max_band = std::max(stats.max_band, r.lastGuardBand());
    stats.frames += st.frames;
    ++stats.renders;
    if (progress) progress(stats.renders, total);
    return img;
  };
  if (agree) {
    // Each part's own range first, then the pictures with the range they agree on.
    std::vector<glm::vec2> ranges;
    for (const PosterPart& part : parts) {
      RenderStats st;
      renderPart(part, o, st);
      ranges.push_back(st.relative_depth_range);
    }
    o.relative_depth.agreed_range = wallRange(ranges);
    stats.agreed_range = o.relative_depth.agreed_range;
  }
  std::vector<uint8_t> row_pixels;
  for (uint32_t r = 0; r < plan.rows; ++r) {
    const PosterPart& first = parts[size_t(r) * plan.columns];
    row_pixels.assign(size_t(plan.width) * first.height * 4, 0);
    for (uint32_t c = 0; c < plan.columns; ++c) {
      const PosterPart& part = parts[size_t(r) * plan.columns + c];
      RenderStats st;
      const Image img = renderPart(part, o, st);
      for (uint32_t y = 0; y < part.height; ++y)
        std::memcpy(&row_pixels[(size_t(y) * plan.width + part.x) * 4],
                    &img.rgba[size_t(y) * part.width * 4], size_t(part.width) * 4);
    }
    strip(row_pixels, first.y, first.height);
  }
  return stats;
}

Image renderPosterImage(std::span<const ModelInstance> models, const ViewSetup& full,
                        const RenderOptions& options, const PosterPlan& plan,
                        const StreamerOptions& stream_options, const Overlay* overlay,
                        PosterStats* stats) {
  Image out;
  out.width = plan.width;
  out.height = plan.height;
  out.rgba.resize(size_t(plan.width) * plan.height * 4);
  const PosterStats st = renderPoster(
      models, full, options, plan,
      [&](std::span<const uint8_t> rgba, uint32_t y, uint32_t rows) {
        std::memcpy(&out.rgba[size_t(y) * plan.width * 4], rgba.data(),
                    size_t(rows) * plan.width * 4);
      },
      stream_options, overlay);
  if (stats) *stats = st;
  return out;
}

}  // namespace tessera::render
