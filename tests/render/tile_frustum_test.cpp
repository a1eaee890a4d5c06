// Off-axis tile frusta: a point on the wall plane lands on the tile pixel it lies on, tiles and
// the whole-wall view agree pixel for pixel across bezels, and a centred eye gives the ordinary
// symmetric perspective.
#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/render/tile_frustum.h>

namespace tessera::render {
namespace {

const std::string kConfigs = TESSERA_CONFIG_DIR;

config::Camera camera() {
  config::Camera c;
  c.mutable_eye()->set_x(0.3);
  c.mutable_eye()->set_y(-0.2);
  c.mutable_eye()->set_z(4.0);
  c.mutable_target()->set_x(0.1);
  c.mutable_up()->set_y(1.0);
  return c;
}

/// Pixel coordinates (x right, y down, pixel centres at +0.5) of a world point in a view.
glm::dvec2 pixelOf(const ViewSetup& v, const glm::dvec3& world) {
  glm::dvec4 clip = v.projection * v.view * glm::dvec4(world, 1.0);
  glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
  return {(ndc.x * 0.5 + 0.5) * v.width, (0.5 - ndc.y * 0.5) * v.height};
}

TEST(TileFrustum, TilesAndWholeWallAgreeAcrossBezels) {
  auto wall = sync::loadWallConfig(kConfigs + "/walls/2x2.json");
  config::Camera cam = camera();
  ViewSetup whole = wholeWallView(wall, cam);
  EXPECT_EQ(whole.width, 960u * 2 + 20);
  EXPECT_EQ(whole.height, 540u * 2 + 20);
  // Points all over the scene, including ones that project near the bezels.
  int checked = 0;
  for (int i = 0; i < 2000; ++i) {
    glm::dvec3 p(std::sin(i * 0.37) * 1.5, std::cos(i * 0.11) * 0.9, std::sin(i * 0.05) * 2.0);
    glm::dvec2 w = pixelOf(whole, p);
    for (const auto& tile : wall.tiles()) {
      ViewSetup tv = tileView(wall, tile, cam);
      glm::dvec2 t = pixelOf(tv, p);
      if (t.x < 0 || t.y < 0 || t.x >= tv.width || t.y >= tv.height) continue;
      glm::ivec2 off = tileOffsetInWhole(wall, tile);
      ASSERT_NEAR(t.x + off.x, w.x, 1e-6) << tile.name();
      ASSERT_NEAR(t.y + off.y, w.y, 1e-6) << tile.name();
      ++checked;
    }
  }
  EXPECT_GT(checked, 500);
}

// A tile, a tile with its guard band and a poster-like part rebuild the view of the picture they
// belong to: every point lands on the same whole-picture pixel as in wholeWallView().
TEST(TileFrustum, WholeViewOfAPartIsThePictureItBelongsTo) {
  auto wall = sync::loadWallConfig(kConfigs + "/walls/2x2.json");
  const config::Camera cam = camera();
  const ViewSetup whole = wholeWallView(wall, cam);
  EXPECT_EQ(whole.whole_size, glm::uvec2(0));
  EXPECT_EQ(wholeView(whole).projection, whole.projection);  // a picture of its own
  for (const auto& tile : wall.tiles()) {
    const ViewSetup tv = tileView(wall, tile, cam);
    EXPECT_EQ(tv.whole_size, glm::uvec2(whole.width, whole.height)) << tile.name();
    for (uint32_t band : {0u, 7u}) {
      const ViewSetup rebuilt = wholeView(withGuardBand(tv, band));
      ASSERT_EQ(rebuilt.width, whole.width);
      ASSERT_EQ(rebuilt.height, whole.height);
      EXPECT_EQ(rebuilt.origin, glm::ivec2(0));
      for (int i = 0; i < 200; ++i) {
        const glm::dvec3 p(std::sin(i * 0.37) * 1.5, std::cos(i * 0.11) * 0.9,
                           std::sin(i * 0.05) * 2.0);
        const glm::dvec2 a = pixelOf(rebuilt, p), b = pixelOf(whole, p);
        ASSERT_NEAR(a.x, b.x, 1e-6) << tile.name() << " band " << band;
        ASSERT_NEAR(a.y, b.y, 1e-6) << tile.name() << " band " << band;
      }
    }
  }
  // A plain view with a guard band belongs to the view without it.
  ViewSetup plain = whole;
  const ViewSetup banded = withGuardBand(plain, 5);
  EXPECT_EQ(banded.whole_size, glm::uvec2(plain.width, plain.height));
  const ViewSetup back = wholeView(banded);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) EXPECT_NEAR(back.projection[c][r], plain.projection[c][r], 1e-12);
  // A room's screens have planes of their own: no whole picture to share.
  auto cave = sync::loadWallConfig(kConfigs + "/walls/cave.json");
  EXPECT_EQ(tileView(cave, cave.tiles(0), cam).whole_size, glm::uvec2(0));
}

TEST(TileFrustum, WallPlanePointsLandOnTheirTilePixel) {
  auto wall = sync::loadWallConfig(kConfigs + "/walls/3x2.json");
  config::Camera cam;
  // Camera at the wall eye, looking straight at the wall: camera space = wall frame - eye.
  const auto& e = wall.eye();
  cam.mutable_eye()->CopyFrom(e);
  cam.mutable_target()->set_x(e.x());
  cam.mutable_target()->set_y(e.y());
  cam.mutable_target()->set_z(0.0);
  cam.mutable_up()->set_y(1.0);
  for (const auto& tile : wall.tiles()) {
    ViewSetup tv = tileView(wall, tile, cam);
    // The centre of pixel (10, 20) of this tile, on the wall plane.
    glm::dvec3 p(tile.x() + 10.5 * tile.width() / tile.pixel_width(),
                 tile.y() + tile.height() - 20.5 * tile.height() / tile.pixel_height(), 0.0);
    glm::dvec2 px = pixelOf(tv, p);
    EXPECT_NEAR(px.x, 10.5, 1e-6);
    EXPECT_NEAR(px.y, 20.5, 1e-6);
  }
}

TEST(TileFrustum, StereoEyesAgreeOnTheWallPlaneAndDisagreeBehindIt) {
  auto wall = sync::loadWallConfig(kConfigs + "/walls/3x2.json");
  const config::Camera cam = camera();
  const glm::dvec3 half_ipd(0.032, 0.0, 0.0);
  // World position of a point given in the wall frame: camera space is the wall frame minus the
  // viewer's eye.
  const glm::dmat4 world_from_camera = glm::inverse(cameraView(cam));
  const auto world = [&](const glm::dvec3& wall_point) {
    const glm::dvec3 e(wall.eye().x(), wall.eye().y(), wall.eye().z());
    return glm::dvec3(world_from_camera * glm::dvec4(wall_point - e, 1.0));
  };
  for (const auto& tile : wall.tiles()) {
    const ViewSetup left = tileView(wall, tile, cam, -half_ipd);
    const ViewSetup right = tileView(wall, tile, cam, half_ipd);
    const ViewSetup mono = tileView(wall, tile, cam);
    EXPECT_EQ(left.eye_offset, -half_ipd);
    EXPECT_NEAR(left.pixels_per_metre.x, tile.pixel_width() / tile.width(), 1e-9);
    // The eyes are 64 mm apart in the world too, on either side of the mono eye.
    EXPECT_NEAR(glm::distance(left.eye_world, right.eye_world), 0.064, 1e-9);
    EXPECT_NEAR(glm::distance(0.5 * (left.eye_world + right.eye_world), mono.eye_world), 0.0, 1e-9);
    const glm::dvec3 on_wall(tile.x() + 0.3 * tile.width(), tile.y() + 0.6 * tile.height(), 0.0);
    const glm::dvec2 l = pixelOf(left, world(on_wall)), r = pixelOf(right, world(on_wall));
    EXPECT_NEAR(l.x, r.x, 1e-6);  // zero parallax at the screen
    EXPECT_NEAR(l.y, r.y, 1e-6);
    EXPECT_NEAR(l.x, pixelOf(mono, world(on_wall)).x, 1e-6);
    // One metre behind the wall: the right eye sees it further right (positive parallax) by
    // ipd * depth / (eye distance + depth) metres on the wall plane.
    const glm::dvec3 behind = on_wall + glm::dvec3(0.0, 0.0, -1.0);
    const double d = wall.eye().z();
    const double expected_px = 0.064 * 1.0 / (d + 1.0) * tile.pixel_width() / tile.width();
    const glm::dvec2 lb = pixelOf(left, world(behind)), rb = pixelOf(right, world(behind));
    EXPECT_NEAR(rb.x - lb.x, expected_px, 1e-6);
    EXPECT_NEAR(rb.y, lb.y, 1e-6);
  }
}

TEST(TileFrustum, CentredEyeIsTheSymmetricPerspective) {
  const double fovy = glm::radians(45.0), aspect = 16.0 / 9.0, near = 0.1, far = 100.0;
  const double h = 2.0 * std::tan(fovy / 2), w = h * aspect;  // window at distance 1
  glm::dmat4 off = offAxisProjection(glm::dvec3(0, 0, 1), -w / 2, w / 2, -h / 2, h / 2, near, far);
  glm::dmat4 sym = glm::perspective(fovy, aspect, near, far);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) EXPECT_NEAR(off[c][r], sym[c][r], 1e-12);
}

TEST(TileFrustum, FrustumCullsBoxesOutsideOnly) {
  glm::dmat4 m = glm::perspective(glm::radians(60.0), 1.0, 0.1, 10.0);
  Frustum f = Frustum::fromMatrix(m);
  EXPECT_TRUE(f.intersects(glm::dvec3(-0.1, -0.1, -2), glm::dvec3(0.1, 0.1, -1)));
  EXPECT_FALSE(f.intersects(glm::dvec3(-0.1, -0.1, 1), glm::dvec3(0.1, 0.1, 2)));      // behind
  EXPECT_FALSE(f.intersects(glm::dvec3(50, -0.1, -2), glm::dvec3(51, 0.1, -1)));       // right
  EXPECT_FALSE(f.intersects(glm::dvec3(-0.1, -0.1, -30), glm::dvec3(0.1, 0.1, -20)));  // beyond far
  EXPECT_TRUE(f.intersects(glm::dvec3(-100, -100, -5), glm::dvec3(100, 100, -4)));     // straddles
}

}  // namespace
}  // namespace tessera::render
