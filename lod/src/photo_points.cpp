#include <tessera/lod/photo_points.h>

#include <png.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <tessera/core/check.h>
#include <tessera/core/file_checks.h>
#include <tessera/lod/point_reader.h>

namespace tessera::lod {
namespace {

struct Picture {
  uint32_t width = 0, height = 0;
  std::vector<uint16_t> data;  ///< `channels` values per pixel, top row first, 0..65535
  int channels = 0;
};

Picture readPng(const std::filesystem::path& path, png_uint_32 format, int channels,
                uint64_t max_pixels, const char* what) {
  if (const auto why = notRegularFile(path))  // a FIFO would block libpng's fopen()
    throw ReadError(std::string("lod::photoPoints(): ") + what + " " + path.string() + ": " + *why);
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) {
    throw ReadError(std::string("lod::photoPoints(): ") + what + " " + path.string() + ": " +
                    image.message);
  }
  if (uint64_t(image.width) * image.height > max_pixels) {
    png_image_free(&image);
    throw ReadError(std::string("lod::photoPoints(): ") + what + " " + path.string() + " has " +
                    std::to_string(uint64_t(image.width) * image.height) +
                    " pixels, more than the limit of " + std::to_string(max_pixels));
  }
  if (format == PNG_FORMAT_GRAY && (image.format & PNG_FORMAT_FLAG_LINEAR)) {
    // 16-bit file: read its values as they are (libpng treats 16-bit data as linear).
    format = PNG_FORMAT_LINEAR_Y;
  }
  image.format = format;
  Picture p;
  p.width = image.width;
  p.height = image.height;
  p.channels = channels;
  const size_t values = size_t(image.width) * image.height * size_t(channels);
  const bool wide = (format & PNG_FORMAT_FLAG_LINEAR) != 0;
  std::vector<uint8_t> narrow(wide ? 0 : values);
  p.data.resize(values);
  if (!png_image_finish_read(
          &image, nullptr,
          wide ? static_cast<void*>(p.data.data()) : static_cast<void*>(narrow.data()), 0,
          nullptr)) {
    const std::string msg = image.message;
    png_image_free(&image);
    throw ReadError(std::string("lod::photoPoints(): ") + what + " " + path.string() + ": " + msg);
  }
  // 8-bit values as they are in the file (no gamma decoding: heights are data), widened.
  for (size_t i = 0; i < narrow.size(); ++i) p.data[i] = uint16_t(narrow[i] * 257u);
  return p;
}

}  // namespace

PointBatch photoPoints(const PhotoOptions& o, glm::dvec3& origin, PhotoReport* report) {
  const glm::dvec3 normal_raw = glm::cross(o.u, o.v);
  TESSERA_CHECK(glm::length(normal_raw) > 0.0,
                "lod::photoPoints(): the rectangle's u and v must span a plane");
  const glm::dvec3 normal = glm::normalize(normal_raw);
  // 8-bit sRGB colours, whatever the file holds (libpng converts).
  const Picture photo = readPng(o.image, PNG_FORMAT_RGB, 3, o.max_pixels, "image");
  Picture heights;
  if (!o.height.empty()) {
    heights = readPng(o.height, PNG_FORMAT_GRAY, 1, o.max_pixels, "height map");
  }
  const uint32_t W = photo.width, H = photo.height;
  // Heights at the photo's pixels (bilinear in the height map), metres.
  std::vector<float> h(size_t(W) * H, 0.0f);
  if (!heights.data.empty()) {
    for (uint32_t y = 0; y < H; ++y)
      for (uint32_t x = 0; x < W; ++x) {
        const double fx =
            std::clamp((x + 0.5) / W * heights.width - 0.5, 0.0, double(heights.width - 1));
        const double fy =
            std::clamp((y + 0.5) / H * heights.height - 0.5, 0.0, double(heights.height - 1));
        const uint32_t x0 = uint32_t(fx), y0 = uint32_t(fy);
        const uint32_t x1 = std::min(x0 + 1, heights.width - 1);
        const uint32_t y1 = std::min(y0 + 1, heights.height - 1);
        const double ax = fx - x0, ay = fy - y0;
        auto at = [&](uint32_t xx, uint32_t yy) {
          return double(heights.data[size_t(yy) * heights.width + xx]) / 65535.0;
        };
        const double v = (at(x0, y0) * (1 - ax) + at(x1, y0) * ax) * (1 - ay) +
                         (at(x0, y1) * (1 - ax) + at(x1, y1) * ax) * ay;
        h[size_t(y) * W + x] = float(v * o.height_scale);
      }
  }
  auto to8 = [](uint16_t wide) { return uint8_t(wide / 257u); };
  const double du = glm::length(o.u) / W, dv = glm::length(o.v) / H;  // metres per pixel
  PointBatch out;
  out.reset(kColor);
  out.positions.reserve(size_t(W) * H);
  uint64_t state = o.seed * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull;
  auto uniform = [&] {  // splitmix64 -> [0, 1)
    uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return double((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
  };
  double max_copies = 1.0;
  for (uint32_t y = 0; y < H; ++y) {
    for (uint32_t x = 0; x < W; ++x) {
      // Steps 3-5: the normal from central differences of the height map, cos(phi) against the
      // rectangle's normal, 1/cos(phi) copies with the fractional one drawn at random.
      const size_t i = size_t(y) * W + x;
      const double gx = (h[y * W + std::min(x + 1, W - 1)] - h[y * W + (x ? x - 1 : 0)]) /
                        (du * double(std::min(x + 1, W - 1) - (x ? x - 1 : 0)));
      const double gy =
          (h[size_t(y ? y - 1 : 0) * W + x] - h[size_t(std::min(y + 1, H - 1)) * W + x]) /
          (dv * double(std::min(y + 1, H - 1) - (y ? y - 1 : 0)));
      const double inv_cos = std::sqrt(1.0 + (std::isfinite(gx) ? gx * gx : 0.0) +
                                       (std::isfinite(gy) ? gy * gy : 0.0));
      max_copies = std::max(max_copies, inv_cos);
      const double whole = std::floor(inv_cos);
      const int copies = int(whole) + (uniform() < inv_cos - whole ? 1 : 0);
      // Row 0 is the top of the picture: v runs upwards.
      const glm::dvec3 p =
          (x + 0.5) / W * o.u + (1.0 - (y + 0.5) / H) * o.v + double(h[i]) * normal;
      const glm::u8vec4 c(to8(photo.data[i * 3]), to8(photo.data[i * 3 + 1]),
                          to8(photo.data[i * 3 + 2]), 255);
      for (int k = 0; k < copies; ++k) {
        out.positions.push_back(p);
        out.colors.push_back(c);
      }
    }
  }
  origin = o.corner;
  if (report) {
    report->width = W;
    report->height = H;
    report->points = out.size();
    report->max_copies = max_copies;
  }
  return out;
}

}  // namespace tessera::lod
