// Screens anywhere in the room: a tile on a plane of its own projects as a hand-derived ray
// through its rectangle does, a CAVE's walls meet at their shared edges, planar walls keep their
// frusta, the room's net places its tiles side by side, and bad planes are refused by field.
#include <gtest/gtest.h>

#include <cmath>

#include <tessera/render/tile_frustum.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/config.h>

namespace tessera::render {
namespace {

const std::string kConfigs = TESSERA_CONFIG_DIR;

/// Pixel coordinates (x right, y down) of a world point in a view, and its clip w.
glm::dvec3 pixelOf(const ViewSetup& v, const glm::dvec3& world) {
  const glm::dvec4 clip = v.projection * v.view * glm::dvec4(world, 1.0);
  const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
  return {(ndc.x * 0.5 + 0.5) * v.width, (0.5 - ndc.y * 0.5) * v.height, clip.w};
}

/// The camera standing at the wall's eye, looking down -z: world = wall frame.
config::Camera cameraAtEye(const config::WallConfig& wall, const glm::dvec3& look = {0, 0, -1}) {
  config::Camera c;
  *c.mutable_eye() = wall.eye();
  c.mutable_target()->set_x(wall.eye().x() + look.x);
  c.mutable_target()->set_y(wall.eye().y() + look.y);
  c.mutable_target()->set_z(wall.eye().z() + look.z);
  c.mutable_up()->set_y(1.0);
  return c;
}

config::WallConfig parse(const std::string& json) {
  return sync::parseWallConfig(json, "room.json");
}

TEST(Room, ATileTurnedNinetyDegreesProjectsAsARayThroughItsRectangle) {
  // One tile on the plane x = -1 (a CAVE's left wall), facing +x, seen from an eye off centre.
  const auto wall = parse(R"({"tiles": [{"name": "side", "width": 2.0, "height": 1.5,
      "pixelWidth": 400, "pixelHeight": 300, "origin": {"x": -1, "y": 0.25, "z": 1.2},
      "right": {"z": -1}, "up": {"y": 1}}], "eye": {"x": 0.4, "y": 0.9, "z": 0.3}})");
  const config::Tile& tile = wall.tiles(0);
  // A camera turned away from the wall frame: the tile's view must not depend on it beyond the
  // placing of the wall frame in the world.
  config::Camera cam;
  cam.mutable_eye()->set_x(5.0);
  cam.mutable_eye()->set_y(-2.0);
  cam.mutable_eye()->set_z(3.0);
  cam.mutable_target()->set_x(4.0);
  cam.mutable_target()->set_y(-2.0);
  cam.mutable_target()->set_z(3.0);
  cam.mutable_up()->set_y(1.0);
  const ViewSetup v = tileView(wall, tile, cam);
  ASSERT_EQ(v.width, 400u);
  ASSERT_EQ(v.height, 300u);
  // World -> wall frame: the camera looks down -x (its target is at -x), so world = R * wall +
  // camera eye - R * wall eye, with R taking the wall frame's -z to the world's -x: x_w = z,
  // z_w = -x (a turn of 90 degrees about y).
  const glm::dvec3 e(0.4, 0.9, 0.3), ce(5.0, -2.0, 3.0);
  auto toWorld = [&](const glm::dvec3& p) {
    const glm::dvec3 d = p - e;
    return ce + glm::dvec3(d.z, d.y, -d.x);
  };
  int inside = 0;
  for (int i = 0; i < 500; ++i) {
    // Points in the room in front of the plane x = -1 and behind it.
    const glm::dvec3 p(-3.0 + 2.8 * std::fmod(i * 0.618, 1.0), 2.0 * std::sin(i * 0.7),
                       1.5 * std::cos(i * 0.3));
    if (p.x > -0.05 && p.x < 0.45) continue;  // too near the eye's plane x = 0.4
    // By hand: the ray from the eye through p meets the plane x = -1 at t; the tile's (u, v)
    // there: u along -z from z = 1.2 over 2 m, v down from y = 1.75 over 1.5 m.
    const double t = (-1.0 - e.x) / (p.x - e.x);
    if (t <= 0) continue;  // behind the eye
    const glm::dvec3 hit = e + (p - e) * t;
    const double u = (1.2 - hit.z) / 2.0, vv = (1.75 - hit.y) / 1.5;
    const glm::dvec3 px = pixelOf(v, toWorld(p));
    ASSERT_GT(px.z, 0.0);
    EXPECT_NEAR(px.x, u * 400.0, 1e-6) << i;
    EXPECT_NEAR(px.y, vv * 300.0, 1e-6) << i;
    if (u >= 0 && u <= 1 && vv >= 0 && vv <= 1) ++inside;
  }
  EXPECT_GT(inside, 50);
}

TEST(Room, ACavesWallsAndFloorMeetAtTheirSharedEdges) {
  const auto wall = sync::loadWallConfig(kConfigs + "/walls/cave.json");
  ASSERT_EQ(wall.tiles_size(), 4);
  ASSERT_TRUE(isRoom(wall));
  const config::Camera cam = cameraAtEye(wall);
  auto view = [&](const char* name) {
    for (const auto& t : wall.tiles())
      if (t.name() == name) return tileView(wall, t, cam);
    throw std::runtime_error(name);
  };
  const ViewSetup left = view("left"), front = view("front"), right = view("right"),
                  floor = view("floor");
  for (int i = 0; i <= 20; ++i) {
    const double s = i / 20.0;
    // The left wall's right edge is the front wall's left edge (x = -1.5, z = -1.5).
    const glm::dvec3 a(-1.5, 3.0 * s, -1.5);
    EXPECT_NEAR(pixelOf(left, a).x, 512.0, 1e-6);
    EXPECT_NEAR(pixelOf(front, a).x, 0.0, 1e-6);
    EXPECT_NEAR(pixelOf(left, a).y, pixelOf(front, a).y, 1e-6);
    // The front's right edge is the right wall's left edge.
    const glm::dvec3 b(1.5, 3.0 * s, -1.5);
    EXPECT_NEAR(pixelOf(front, b).x, 512.0, 1e-6);
    EXPECT_NEAR(pixelOf(right, b).x, 0.0, 1e-6);
    EXPECT_NEAR(pixelOf(front, b).y, pixelOf(right, b).y, 1e-6);
    // The floor's far edge is the front's bottom edge.
    const glm::dvec3 c(-1.5 + 3.0 * s, 0.0, -1.5);
    EXPECT_NEAR(pixelOf(floor, c).y, 0.0, 1e-6);
    EXPECT_NEAR(pixelOf(front, c).y, 512.0, 1e-6);
    EXPECT_NEAR(pixelOf(floor, c).x, pixelOf(front, c).x, 1e-6);
    // The floor's left edge is the left wall's bottom edge: the left wall runs from the viewer's
    // back (x = 0) to the front wall (x = 512), the floor's left edge from the front wall (y = 0)
    // to the back (y = 512).
    const glm::dvec3 d(-1.5, 0.0, 1.5 - 3.0 * s);
    EXPECT_NEAR(pixelOf(floor, d).x, 0.0, 1e-6);
    EXPECT_NEAR(pixelOf(left, d).y, 512.0, 1e-6);
    EXPECT_NEAR(pixelOf(left, d).x, 512.0 - pixelOf(floor, d).y, 1e-6);
    EXPECT_NEAR(pixelOf(left, d).x, 512.0 * s, 1e-6);
  }
  // A line crossing from the front wall onto the left one stays straight in the wide view from
  // the eye: its pixels in each tile, carried to the walls and seen from the eye, are collinear.
  const ViewSetup eye = eyeView(wall, cam, 800, 800, 150.0);
  const glm::dvec3 p0(-1.5, 0.8, 0.6), p1(0.6, 2.4, -1.5);  // on the left and the front walls
  const glm::dvec3 e0 = pixelOf(eye, p0), e1 = pixelOf(eye, p1);
  for (int i = 1; i < 10; ++i) {
    const glm::dvec3 q = p0 + (p1 - p0) * (i / 10.0);  // through the room, off the walls
    const glm::dvec3 eq = pixelOf(eye, q);
    const double cross = (e1.x - e0.x) * (eq.y - e0.y) - (e1.y - e0.y) * (eq.x - e0.x);
    EXPECT_NEAR(cross / glm::length(glm::dvec2(e1 - e0)), 0.0, 1e-6);
  }
}

TEST(Room, APlanarWallKeepsItsFrustaAndAWallWithIdentityPlanesMatchesIt) {
  const auto wall = sync::loadWallConfig(kConfigs + "/walls/2x2.json");
  ASSERT_FALSE(isRoom(wall));
  auto explicitPlanes = wall;
  for (auto& t : *explicitPlanes.mutable_tiles()) {
    t.mutable_origin()->set_x(t.x());
    t.mutable_origin()->set_y(t.y());
    t.mutable_right()->set_x(1.0);
    t.mutable_up()->set_y(1.0);
  }
  config::Camera cam = cameraAtEye(wall);
  cam.mutable_eye()->set_x(0.3);
  for (int i = 0; i < wall.tiles_size(); ++i) {
    const ViewSetup a = tileView(wall, wall.tiles(i), cam),
                    b = tileView(explicitPlanes, explicitPlanes.tiles(i), cam);
    const glm::dmat4 ma = a.projection * a.view, mb = b.projection * b.view;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) EXPECT_NEAR(ma[c][r], mb[c][r], 1e-12);
  }
}

TEST(Room, TheNetPlacesTilesSideBySideInTheOrderOfTheConfig) {
  const auto wall = sync::loadWallConfig(kConfigs + "/walls/cave.json");
  EXPECT_EQ(roomNetSize(wall), glm::uvec2(4 * 512 + 3 * kRoomNetGap, 512));
  std::vector<Image> tiles;
  for (int i = 0; i < wall.tiles_size(); ++i) {
    Image img;
    img.width = img.height = 512;
    img.rgba.assign(512 * 512 * 4, uint8_t(50 * (i + 1)));
    tiles.push_back(std::move(img));
    EXPECT_EQ(tileOffsetInWhole(wall, wall.tiles(i)), glm::ivec2(i * (512 + kRoomNetGap), 0));
  }
  const Image net = assembleWallMosaic(wall, tiles);
  ASSERT_EQ(net.width, 4u * 512 + 3 * kRoomNetGap);
  for (int i = 0; i < 4; ++i) {
    const size_t x = size_t(i * (512 + kRoomNetGap) + 100);
    EXPECT_EQ(net.rgba[(300 * net.width + x) * 4], 50 * (i + 1));
  }
  EXPECT_EQ(net.rgba[(300 * net.width + 512 + 4) * 4], kBezelGrey);
  const auto angled = sync::loadWallConfig(kConfigs + "/walls/angled.json");
  EXPECT_TRUE(isRoom(angled));
  // The wings meet the centre panel at its edges.
  const TilePlane l = tilePlane(angled.tiles(0)), c = tilePlane(angled.tiles(1)),
                  r = tilePlane(angled.tiles(2));
  EXPECT_LT(glm::length(l.at(1, 1) - c.at(0, 1)), 1e-8);
  EXPECT_LT(glm::length(c.at(1, 1) - r.at(0, 1)), 1e-8);
}

void expectRefused(const std::string& json, const std::string& field) {
  try {
    parse(json);
    ADD_FAILURE() << "accepted: " << json;
  } catch (const sync::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("room.json: " + field), std::string::npos) << e.what();
  }
}

TEST(Room, BadPlanesAreRefusedByField) {
  const std::string head =
      R"({"eye": {"z": 2}, "tiles": [{"name": "a", "width": 1, "height": 1, "pixelWidth": 8,
          "pixelHeight": 8, )";
  expectRefused(head + R"("right": {"x": 1}, "up": {"x": 1}}]})", "tiles[0].up: right and up must be orthogonal");
  expectRefused(head + R"("right": {"x": 0}}]})", "tiles[0].right: is zero");
  expectRefused(head + R"("right": {"x": "NaN"}}]})", "tiles[0].right: needs finite");
  expectRefused(head + R"("origin": {"x": "Infinity"}}]})", "tiles[0].origin: needs finite");
  expectRefused(head + R"("origin": {"z": 3}}]})", "eye: the viewer's eye must be in front of tiles[0]");
  expectRefused(head + R"("gamma": -1}]})", "tiles[0].gamma");
  expectRefused(head + R"("gamma": "NaN"}]})", "tiles[0].gamma");
  // Nearly orthogonal is fine.
  EXPECT_NO_THROW(parse(head + R"("right": {"x": 1, "y": 0.00001}, "up": {"y": 1}}]})"));
}

}  // namespace
}  // namespace tessera::render
