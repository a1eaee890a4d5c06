#include <tessera/render/image.h>

#include <png.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>

#include <tessera/core/check.h>
#include <tessera/core/file_checks.h>
#include <tessera/render/gl_context.h>

namespace tessera::render {

double edgeWidth(const Image& img, uint32_t edge) {
  std::vector<double> col(img.width, 0.0);
  for (uint32_t y = 0; y < img.height; ++y)
    for (uint32_t x = 0; x < img.width; ++x)
      col[x] += img.rgba[(size_t(y) * img.width + x) * 4] / double(img.height);
  auto mean = [&](uint32_t x0, uint32_t x1) {
    double s = 0;
    for (uint32_t x = x0; x < x1; ++x) s += col[x];
    return s / double(std::max(1u, x1 - x0));
  };
  const double hi = mean(edge / 4, 3 * edge / 4);
  const double lo = mean(edge + (img.width - edge) / 4, edge + 3 * (img.width - edge) / 4);
  // Where the profile falls through `level`, scanning from the plateau.
  auto crossing = [&](double level) {
    for (uint32_t x = edge / 2; x + 1 < img.width; ++x)
      if (col[x] >= level && col[x + 1] < level)
        return x + (col[x] - level) / (col[x] - col[x + 1]);
    return double(img.width);
  };
  return crossing(lo + 0.1 * (hi - lo)) - crossing(lo + 0.9 * (hi - lo));
}

void writePng(const std::string& path, const Image& image) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f)
    throw RenderError("render::writePng(): cannot create " + path + ": " +
                      whyNotWritable(path, errno));
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    std::fclose(f);
    throw RenderError("render::writePng(): writing " + path + " failed (disk full?)");
  }
  png_init_io(png, f);
  png_set_IHDR(png, info, image.width, image.height, 8, PNG_COLOR_TYPE_RGBA, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (uint32_t y = 0; y < image.height; ++y) {
    png_write_row(png, const_cast<png_bytep>(image.rgba.data() + size_t(y) * image.width * 4));
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  if (std::fclose(f) != 0) throw RenderError("render::writePng(): closing " + path + " failed");
}

Image resizeImage(const Image& image, uint32_t width, uint32_t height) {
  TESSERA_CHECK(width > 0 && height > 0 && image.width > 0 && image.height > 0 &&
                    image.rgba.size() == size_t(image.width) * image.height * 4,
                "render::resizeImage(): sizes > 0 and width * height RGBA pixels");
  // Along one axis: for new pixel i, the old pixels [first, last] it covers and their shares.
  struct Span {
    uint32_t first = 0;
    std::vector<double> share;
  };
  auto spans = [](uint32_t from, uint32_t to) {
    std::vector<Span> out(to);
    const double scale = double(from) / to;
    for (uint32_t i = 0; i < to; ++i) {
      const double lo = i * scale, hi = (i + 1) * scale;
      out[i].first = uint32_t(lo);
      for (uint32_t k = out[i].first; k < from && k < hi; ++k)
        out[i].share.push_back((std::min(hi, k + 1.0) - std::max(lo, double(k))) / scale);
    }
    return out;
  };
  const std::vector<Span> xs = spans(image.width, width), ys = spans(image.height, height);
  Image out;
  out.width = width;
  out.height = height;
  out.rgba.resize(size_t(width) * height * 4);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x) {
      double sum[4] = {0, 0, 0, 0};
      for (size_t j = 0; j < ys[y].share.size(); ++j)
        for (size_t i = 0; i < xs[x].share.size(); ++i) {
          const double w = ys[y].share[j] * xs[x].share[i];
          const uint8_t* p =
              &image.rgba[(size_t(ys[y].first + j) * image.width + xs[x].first + i) * 4];
          for (int c = 0; c < 4; ++c) sum[c] += w * p[c];
        }
      uint8_t* q = &out.rgba[(size_t(y) * width + x) * 4];
      for (int c = 0; c < 4; ++c) q[c] = uint8_t(std::clamp(std::lround(sum[c]), 0l, 255l));
    }
  return out;
}

Image readPng(const std::string& path) {
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.c_str()))
    throw RenderError("render::readPng(): " + path + ": " + png.message);
  png.format = PNG_FORMAT_RGBA;
  if (png.width == 0 || png.height == 0 || png.width > 65536 || png.height > 65536) {
    png_image_free(&png);
    throw RenderError("render::readPng(): " + path + ": " + std::to_string(png.width) + "x" +
                      std::to_string(png.height) + " pixels (1..65536 each way)");
  }
  Image img;
  img.width = png.width;
  img.height = png.height;
  img.rgba.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, img.rgba.data(), 0, nullptr)) {
    const std::string why = png.message;
    png_image_free(&png);
    throw RenderError("render::readPng(): " + path + ": " + why);
  }
  return img;
}

PictureLikeness comparePictures(const Image& a, const Image& b, uint32_t block) {
  TESSERA_CHECK(a.width == b.width && a.height == b.height && block >= 1 &&
                    a.rgba.size() == size_t(a.width) * a.height * 4 &&
                    b.rgba.size() == a.rgba.size(),
                "render::comparePictures(): pictures of one size and a block of at least 1");
  auto covered = [](const uint8_t* p) { return p[0] > 16 || p[1] > 16 || p[2] > 16; };
  const uint32_t bw = (a.width + block - 1) / block, bh = (a.height + block - 1) / block;
  std::vector<uint8_t> blocks(size_t(bw) * bh, 0);  // bit 0: a covers, bit 1: b covers
  uint64_t both = 0, either = 0, difference = 0;
  for (uint32_t y = 0; y < a.height; ++y)
    for (uint32_t x = 0; x < a.width; ++x) {
      const size_t i = (size_t(y) * a.width + x) * 4;
      const bool pa = covered(&a.rgba[i]), pb = covered(&b.rgba[i]);
      both += pa && pb;
      either += pa || pb;
      blocks[size_t(y / block) * bw + x / block] |= uint8_t(pa) | uint8_t(pb) << 1;
      if (pa || pb)
        for (size_t c = 0; c < 3; ++c)
          difference += uint64_t(std::abs(int(a.rgba[i + c]) - b.rgba[i + c]));
    }
  uint64_t blocks_both = 0, blocks_either = 0;
  for (const uint8_t m : blocks) blocks_both += m == 3, blocks_either += m != 0;
  PictureLikeness l;
  if (either > 0) {
    l.pixel_iou = double(both) / double(either);
    l.mean_difference = double(difference) / double(3 * either);
  }
  if (blocks_either > 0) l.silhouette_iou = double(blocks_both) / double(blocks_either);
  return l;
}

}  // namespace tessera::render
