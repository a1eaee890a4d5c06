// Photos as points (Tanaka et al. 2016, section 4.5): placement on the rectangle, displacement
// by the height map, 1/cos(phi) proliferation, and refusal of bad files.
#include <gtest/gtest.h>

#include <png.h>

#include <cmath>
#include <fstream>

#include <tessera/core/check.h>
#include <tessera/lod/photo_points.h>
#include <tessera/lod/point_reader.h>

#include "../support/temp_dir.h"

namespace tessera::lod {
namespace {

void writeGreyPng(const std::filesystem::path& path, uint32_t w, uint32_t h,
                  const std::vector<uint8_t>& pixels, png_uint_32 format) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = w;
  image.height = h;
  image.format = format;
  ASSERT_TRUE(png_image_write_to_file(&image, path.c_str(), 0, pixels.data(), 0, nullptr))
      << image.message;
}

TEST(PhotoPoints, PixelsLieOnTheRectangleWithTheirColours) {
  test::TempDir dir;
  const uint32_t W = 40, H = 20;
  std::vector<uint8_t> rgb(W * H * 3);
  for (uint32_t y = 0; y < H; ++y)
    for (uint32_t x = 0; x < W; ++x) {
      rgb[(y * W + x) * 3] = uint8_t(x * 6);
      rgb[(y * W + x) * 3 + 1] = uint8_t(y * 12);
      rgb[(y * W + x) * 3 + 2] = 255;
    }
  writeGreyPng(dir / "photo.png", W, H, rgb, PNG_FORMAT_RGB);
  PhotoOptions o;
  o.image = dir / "photo.png";
  o.corner = {10.0, 20.0, 5.0};
  o.u = {2.0, 0.0, 0.0};
  o.v = {0.0, 0.0, 1.0};  // standing upright, facing -y
  glm::dvec3 origin;
  PhotoReport r;
  const PointBatch b = photoPoints(o, origin, &r);
  ASSERT_EQ(b.size(), size_t(W) * H);  // flat: one point a pixel
  EXPECT_EQ(origin, o.corner);
  // Top-left pixel: x = half a pixel in, z = half a pixel below the top edge.
  EXPECT_NEAR(b.positions[0].x, 2.0 * 0.5 / W, 1e-12);
  EXPECT_NEAR(b.positions[0].z, 1.0 - 0.5 / H, 1e-12);
  EXPECT_NEAR(b.positions[0].y, 0.0, 1e-12);
  // Colours survive the PNG round trip within a level.
  const size_t i = 7 * W + 13;
  EXPECT_NEAR(b.colors[i].r, 13 * 6, 1);
  EXPECT_NEAR(b.colors[i].g, 7 * 12, 1);
  EXPECT_EQ(b.colors[i].b, 255);
}

TEST(PhotoPoints, ARampHeightMapTiltsAndProliferatesByOneOverCosPhi) {
  test::TempDir dir;
  const uint32_t W = 200, H = 100;
  writeGreyPng(dir / "photo.png", W, H, std::vector<uint8_t>(W * H, 128), PNG_FORMAT_GRAY);
  std::vector<uint8_t> ramp(W * H);
  for (uint32_t y = 0; y < H; ++y)
    for (uint32_t x = 0; x < W; ++x) ramp[y * W + x] = uint8_t(std::lround(255.0 * x / (W - 1)));
  writeGreyPng(dir / "height.png", W, H, ramp, PNG_FORMAT_GRAY);
  PhotoOptions o;
  o.image = dir / "photo.png";
  o.height = dir / "height.png";
  o.height_scale = 1.5;  // rises 1.5 m across 2 m: slope 0.75, 1/cos(phi) = 1.25
  o.u = {2.0, 0.0, 0.0};
  o.v = {0.0, 1.0, 0.0};
  glm::dvec3 origin;
  PhotoReport r;
  const PointBatch b = photoPoints(o, origin, &r);
  const double expected = double(W) * H * 1.25;
  EXPECT_NEAR(double(b.size()), expected, 0.02 * expected);
  // Displaced along the normal (+z) by the height: z grows with x at the slope.
  for (size_t i = 0; i < b.size(); i += 997)
    EXPECT_NEAR(b.positions[i].z, 0.75 * b.positions[i].x, 0.02);
}

TEST(PhotoPoints, BadFilesAreRefusedByName) {
  test::TempDir dir;
  std::ofstream(dir / "not.png") << "this is not a PNG";
  PhotoOptions o;
  o.image = dir / "not.png";
  glm::dvec3 origin;
  try {
    photoPoints(o, origin);
    FAIL() << "expected ReadError";
  } catch (const ReadError& e) {
    EXPECT_NE(std::string(e.what()).find("not.png"), std::string::npos) << e.what();
  }
  o.image = dir / "missing.png";
  EXPECT_THROW(photoPoints(o, origin), ReadError);
  o.v = o.u;  // degenerate rectangle
  EXPECT_THROW(photoPoints(o, origin), PreconditionError);
}

}  // namespace
}  // namespace tessera::lod
