#include <tessera/render/splat_sizes.h>

#include <cmath>
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
  ViewSetup v;
  const glm::dvec3 eye(636590, 849150, 480), target(636590, 849216, 430);
  v.view = glm::lookAt(eye, target, glm::dvec3(0, 0, 1));
  v.projection = glm::perspective(glm::radians(45.0), double(W) / H, 1.0, 10000.0);
  v.width = W;
  v.height = H;
  v.eye_world = eye;
  StreamerOptions so;
  so.point_splat_sizes = own_sizes;
  ViewRenderer r(W, H, std::make_shared<ChunkStreamer>(so));
  RenderOptions o;
  o.max_splat_radius = max_radius;
  o.fill = fill;
  const ModelInstance inst{&store, storeModel(store)};
  r.renderSettled({&inst, 1}, v, o);
  const std::vector<uint32_t> depth = r.target().readDepth();  // raster order: bottom row first
  size_t open = 0;
  for (uint32_t y = 4; y < H * 2 / 5; ++y)
    for (uint32_t x = 4; x + 4 < W; ++x) open += depth[size_t(y) * W + x] == 0xFFFFFFFFu;
  return open;
}

TEST(SplatSizes, AutzenCloseUpHasNoOpenPixelInTheGround) {
  const std::filesystem::path las =
      std::filesystem::path(TESSERA_DATA_DIR) / "lidar/autzen_trim.las";
  if (!std::filesystem::exists(las)) GTEST_SKIP() << "no " << las;
  test::TempDir dir;
  lod::BuildOptions bo;
  bo.quiet = true;
  lod::buildStore({las}, dir.path() / "autzen.tlod", bo);
  auto store = lod::PointStore::open(dir.path() / "autzen.tlod");
  auto ctx = GlContext::createHeadless();
  // Today's default: each point's own splat size, discs up to 32 px.
  EXPECT_EQ(openGroundPixels(*store, true, 32, SurfaceFill::kDiscs), 0u);
  // The node's spacing alone leaves the scan lines' gaps, at any disc size; own sizes within
  // 8 px leave the nearest ground open.
  EXPECT_GT(openGroundPixels(*store, false, 32, SurfaceFill::kDiscs), 640u * 192u / 100u);
  EXPECT_GT(openGroundPixels(*store, true, 8, SurfaceFill::kDiscs), 640u * 192u / 100u);
}

}  // namespace
}  // namespace tessera::render
