#include <tessera/render/splat_sizes.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/store_builder.h>
#include <tessera/render/chunk_streamer.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/view_renderer.h>

#include "../support/temp_dir.h"

namespace tessera::render {
namespace {

/// Scan lines on a tilted plane: `along` apart on each line, lines `across` apart.
std::vector<glm::vec3> scanLines(int lines, int per_line, float along, float across) {
  const glm::vec3 n = glm::normalize(glm::vec3(0.1f, 0.2f, 1.0f));
  const glm::vec3 a = glm::normalize(glm::cross(n, glm::vec3(1, 0, 0))), b = glm::cross(n, a);
  std::vector<glm::vec3> pts;
  for (int l = 0; l < lines; ++l)
    for (int i = 0; i < per_line; ++i) pts.push_back(float(i) * along * a + float(l) * across * b);
  return pts;
}

/// A perspective view from `eye` to `target`.
ViewSetup perspective(glm::dvec3 eye, glm::dvec3 target, glm::dvec3 up, double fovy_deg,
                      uint32_t width, uint32_t height, double near, double far) {
  ViewSetup v;
  v.view = glm::lookAt(eye, target, up);
  v.projection = glm::perspective(glm::radians(fovy_deg), double(width) / height, near, far);
  v.width = width;
  v.height = height;
  v.eye_world = eye;
  return v;
}

/// A store built from `source` under ../shared/data into `dir`; null when the data is missing.
std::unique_ptr<lod::PointStore> dataStore(const char* source, const test::TempDir& dir) {
  const std::filesystem::path input = std::filesystem::path(TESSERA_DATA_DIR) / source;
  if (!std::filesystem::exists(input)) return nullptr;
  lod::BuildOptions bo;
  bo.quiet = true;
  lod::buildStore({input}, dir.path() / "data.tlod", bo);
  return lod::PointStore::open(dir.path() / "data.tlod");
}

TEST(SplatSizes, ScanLinesGetTheDiscThatClosesTheirGaps) {
  // Lines 4 apart, points 1 apart on them: a cell is the 1 x 4 rectangle around its point, so
  // the disc that closes the surface has the rectangle's half-diagonal, sqrt(0.5^2 + 2^2)
  // (and the margin for slanted views).
  const std::vector<glm::vec3> pts = scanLines(30, 120, 1.0f, 4.0f);
  const double spacing = 1.5;
  const std::vector<uint8_t> codes = splatScales(pts, spacing);
  ASSERT_EQ(codes.size(), pts.size());
  const double expected = kCellMargin * std::hypot(0.5, 2.0) / spacing;
  size_t inner = 0, right = 0;
  for (int l = 2; l < 28; ++l)
    for (int i = 4; i < 116; ++i) {
      const uint32_t rgba = uint32_t(codes[size_t(l) * 120 + i]) << 24;
      ++inner;
      right += std::abs(pointSplatScale(rgba) - expected) < 1.0 / 64.0;
    }
  EXPECT_EQ(right, inner) << "expected scale " << expected;
}

/// Open pixels in the ground of the Autzen close-up (640x480, looking down the scan
/// lines): the bottom 40% of the picture is ground only, 4 px from the edges. `own_sizes`,
/// `max_radius`: StreamerOptions::point_splat_sizes, RenderOptions::max_splat_radius.
size_t openGroundPixels(lod::PointStore& store, bool own_sizes, int max_radius, SurfaceFill fill) {
  const uint32_t W = 640, H = 480;
  const ViewSetup v = perspective({636590, 849150, 480}, {636590, 849216, 430}, {0, 0, 1}, 45.0,
                                  W, H, 1.0, 10000.0);
  StreamerOptions so;
  so.point_splat_sizes = own_sizes;
  ViewRenderer r(W, H, std::make_shared<ChunkStreamer>(so));
  RenderOptions o;
  o.max_splat_radius = max_radius;
  o.fill = fill;
  const ModelInstance inst{&store, storeModel(store)};
  r.renderSettled({&inst, 1}, v, o);
  const std::vector<uint32_t> depth = r.readDepth();  // raster order: bottom row first
  size_t open = 0;
  for (uint32_t y = 4; y < H * 2 / 5; ++y)
    for (uint32_t x = 4; x + 4 < W; ++x) open += depth[size_t(y) * W + x] == 0xFFFFFFFFu;
  return open;
}

TEST(SplatSizes, AutzenCloseUpHasNoOpenPixelInTheGround) {
  test::TempDir dir;
  auto store = dataStore("lidar/autzen_trim.las", dir);
  if (!store) GTEST_SKIP() << "no lidar/autzen_trim.las in " << TESSERA_DATA_DIR;
  auto ctx = GlContext::createHeadless();
  // Today's default: each point's own splat size, discs up to 32 px.
  EXPECT_EQ(openGroundPixels(*store, true, 32, SurfaceFill::kDiscs), 0u);
  // The node's spacing alone leaves the scan lines' gaps, at any disc size; own sizes within
  // 8 px leave the nearest ground open.
  EXPECT_GT(openGroundPixels(*store, false, 32, SurfaceFill::kDiscs), 640u * 192u / 100u);
  EXPECT_GT(openGroundPixels(*store, true, 8, SurfaceFill::kDiscs), 640u * 192u / 100u);
}

/// Open pixels inside the bunny's range scans (bun.conf, ten registered scans) seen as the
/// sites' benchmark wall tile sees them (640x360, 10.3 degrees: leaves' discs about a pixel
/// across): empty pixels with at least 16 of their 5x5 neighbours covered.
std::pair<size_t, size_t> openBunnyPixels(lod::PointStore& store, bool own_sizes) {
  const uint32_t W = 640, H = 360;
  const ViewSetup v =
      perspective({-0.027, 0.12, 0.6}, {-0.027, 0.1, 0.0}, {0, 1, 0}, 10.3, W, H, 0.01, 10.0);
  StreamerOptions so;
  so.point_splat_sizes = own_sizes;
  ViewRenderer r(W, H, std::make_shared<ChunkStreamer>(so));
  RenderOptions o;
  o.lod_pixels = 2.0;
  const ModelInstance inst{&store, storeModel(store)};
  r.renderSettled({&inst, 1}, v, o);
  const std::vector<uint32_t> depth = r.readDepth();
  auto empty = [&](uint32_t x, uint32_t y) { return depth[size_t(y) * W + x] == 0xFFFFFFFFu; };
  size_t open = 0, covered = 0;
  for (uint32_t y = 2; y + 2 < H; ++y)
    for (uint32_t x = 2; x + 2 < W; ++x) {
      if (!empty(x, y)) {
        ++covered;
        continue;
      }
      int around = 0;
      for (uint32_t dy = 0; dy < 5; ++dy)
        for (uint32_t dx = 0; dx < 5; ++dx) around += !empty(x + dx - 2, y + dy - 2);
      open += around >= 16;
    }
  return {open, covered};
}

TEST(SplatSizes, RangeScansOnAWallTileHaveNoOpenPixel) {
  test::TempDir dir;
  auto store = dataStore("stanford-bunny/scans/bun.conf", dir);
  if (!store) GTEST_SKIP() << "no stanford-bunny/scans/bun.conf in " << TESSERA_DATA_DIR;
  auto ctx = GlContext::createHeadless();
  const auto [open, covered] = openBunnyPixels(*store, true);
  ASSERT_GT(covered, 640u * 360u / 2u);  // the bunny fills the tile
  EXPECT_LE(open, covered / 10000) << open << " open of " << covered;
  // The node's spacing alone leaves the rows' gaps open (968 pixels when own sizes were
  // measured only for discs of 2 px radius).
  EXPECT_GT(openBunnyPixels(*store, false).first, covered / 1000);
}

}  // namespace
}  // namespace tessera::render
