// The frame pipeline (frame_target.h): pick ids read back name the right model and point, and
// the overlay pass draws on the GPU with depth test against the scene: a line across a bezel
// meets itself on the neighbour tile, what is behind the model is hidden, labels and textured
// quads land where their world positions project.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/config.h>

#include "../support/temp_dir.h"

namespace tessera::render {
namespace {

const std::string kData = TESSERA_DATA_DIR;
const std::string kConfigs = TESSERA_CONFIG_DIR;

class FramePipelineTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new test::TempDir();
    lod::BuildOptions o;
    o.quiet = true;
    lod::buildStore({kData + "/stanford-bunny/scans/bun.conf"}, *sDir / "b.tlod", o);
    sContext = GlContext::createHeadless().release();
  }
  static void TearDownTestSuite() {
    delete sContext;
    delete sDir;
  }
  static test::TempDir* sDir;
  static GlContext* sContext;
};
test::TempDir* FramePipelineTest::sDir = nullptr;
GlContext* FramePipelineTest::sContext = nullptr;

/// A camera `distance` in front of the store's centre (+z), looking at it.
ViewSetup frontView(const lod::PointStore& s, double distance, uint32_t w, uint32_t h,
                    glm::dvec3* centre = nullptr) {
  const auto& sum = s.summary();
  const glm::dvec3 c = sum.origin + 0.5 * (sum.bbox_min + sum.bbox_max);
  if (centre) *centre = c;
  ViewSetup v;
  v.eye_world = c + glm::dvec3(0.0, 0.0, distance);
  v.view = glm::lookAt(v.eye_world, c, glm::dvec3(0, 1, 0));
  v.projection = glm::perspective(glm::radians(40.0), double(w) / h, 0.01, 10.0);
  v.width = w;
  v.height = h;
  return v;
}

const uint8_t* pixel(const Image& img, uint32_t x, uint32_t y) {
  return &img.rgba[(size_t(y) * img.width + x) * 4];
}

bool isRed(const uint8_t* p) {
  return p[0] > 200 && p[1] < 60 && p[2] < 60;
}

/// Where world point p lands in the view's image (x right, y down; pixel centres at +0.5).
glm::dvec3 project(const ViewSetup& v, const glm::dvec3& p) {
  const glm::dvec4 c = v.projection * v.view * glm::dvec4(p, 1.0);
  const glm::dvec3 ndc = glm::dvec3(c) / c.w;
  return {(ndc.x * 0.5 + 0.5) * v.width, (0.5 - ndc.y * 0.5) * v.height, ndc.z * 0.5 + 0.5};
}

TEST_F(FramePipelineTest, PickIdsNameTheModelAndThePointUnderThePixel) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  const ViewSetup v = frontView(*s, 0.5, 320, 240);
  // Two bunnies side by side: model 0 to the left, model 1 to the right.
  const glm::dmat4 base = storeModel(*s);
  ModelInstance m[2] = {{s.get(), glm::translate(glm::dmat4(1.0), {-0.09, 0, 0}) * base},
                        {s.get(), glm::translate(glm::dmat4(1.0), {0.09, 0, 0}) * base}};
  // With discs and with the pull-push fill, whose filled pixels take the depth and pick id of
  // the sample that fills them.
  for (const SurfaceFill fill : {SurfaceFill::kDiscs, SurfaceFill::kPullPush}) {
    SCOPED_TRACE(fill == SurfaceFill::kDiscs ? "discs" : "pull-push");
    ViewRenderer r(v.width, v.height);
    RenderOptions o;
    o.pick_ids = true;
    o.fill = fill;
    const Image img = r.renderSettled(m, v, o);
    size_t hits = 0, checked = 0;
    for (uint32_t y = 0; y < v.height; y += 3) {
      for (uint32_t x = 0; x < v.width; x += 3) {
        const std::optional<PickHit> hit = r.pick(x, y);
        const uint8_t* p = pixel(img, x, y);
        const bool covered = p[0] || p[1] || p[2];
        ASSERT_EQ(hit.has_value(), covered) << "at " << x << "," << y;
        if (!hit) continue;
        ++hits;
        ASSERT_LT(hit->model, 2u);
        EXPECT_EQ(hit->model, x < v.width / 2 ? 0u : 1u) << "at " << x << "," << y;
        if (hits % 7) continue;  // every 7th hit: the point itself, from the store
        ++checked;
        auto chunk = s->loadChunk(hit->node);
        ASSERT_LT(hit->point, chunk->size());
        const glm::dvec3 world =
            glm::dvec3(m[hit->model].model *
                       glm::dvec4(chunk->offset + glm::dvec3(chunk->positions[hit->point]), 1.0));
        const glm::dvec3 at = project(v, world);
        // The point's splat covers the pixel: within the largest splat radius (8) of it.
        EXPECT_LE(std::abs(at.x - (x + 0.5)), 8.5) << "at " << x << "," << y;
        EXPECT_LE(std::abs(at.y - (y + 0.5)), 8.5) << "at " << x << "," << y;
        EXPECT_NEAR(at.z, hit->depth, 1e-5);
        // The unprojected pixel lies on the point's depth plane, a splat away from it.
        EXPECT_LT(glm::length(hit->world - world), 0.01);
      }
    }
    EXPECT_GT(hits, 1000u);
    EXPECT_GT(checked, 100u);
    // A frame without pick ids answers nothing.
    RenderOptions no_pick;
    no_pick.fill = fill;
    r.renderSettled(m, v, no_pick);
    EXPECT_FALSE(r.pick(v.width / 4, v.height / 2).has_value());
  }
}

/// A camera 2 m in front of the z = 0 plane, looking at its origin, y up (the 1x2 wall's bezel
/// tests).
config::Camera twoMetresAhead() {
  config::Camera cam;
  cam.mutable_eye()->set_z(2.0);
  cam.mutable_up()->set_y(1.0);
  cam.mutable_target()->set_z(0.0);
  return cam;
}

// A long label in several scripts across the bezel of the 1x2 wall: each tile draws its part
// where the whole-wall view draws it, glyph pixel for glyph pixel.
TEST_F(FramePipelineTest, ALongLabelCrossesTheBezelSeamlessly) {
  const config::WallConfig wall = sync::loadWallConfig(kConfigs + "/walls/1x2.json");
  const config::Camera cam = twoMetresAhead();
  Overlay overlay;
  OverlayLabel label;
  label.at = {-0.1, 0.0, 0.0};
  label.text = "東京の調査 — crack survey, Ναός, الشقوق 🐇";
  label.height_px = 28.0f;
  label.color = {255, 255, 255, 255};
  label.background = {0, 0, 0, 0};
  overlay.labels.push_back(label);
  const ViewSetup whole_view = wholeWallView(wall, cam);
  ViewRenderer whole_r(whole_view.width, whole_view.height);
  const Image whole = whole_r.render({}, whole_view, RenderOptions{}, nullptr, &overlay);
  auto ink = [](const uint8_t* p) { return p[0] > 128 && p[1] > 128 && p[2] > 128; };
  size_t differ = 0, glyph = 0;
  int tiles_with_ink = 0;
  for (const auto& tile : wall.tiles()) {
    const ViewSetup tv = tileView(wall, tile, cam);
    ViewRenderer tr(tv.width, tv.height);
    const Image img = tr.render({}, tv, RenderOptions{}, nullptr, &overlay);
    const glm::ivec2 off = tileOffsetInWhole(wall, tile);
    size_t here = 0;
    for (uint32_t y = 0; y < img.height; ++y)
      for (uint32_t x = 0; x < img.width; ++x) {
        const bool a = ink(pixel(img, x, y));
        const bool b = ink(pixel(whole, off.x + x, off.y + y));
        here += a;
        differ += a != b;
      }
    glyph += here;
    tiles_with_ink += here > 200;
  }
  EXPECT_EQ(tiles_with_ink, 2) << "the label crosses the bezel";
  EXPECT_GT(glyph, 1500u);
  EXPECT_LE(double(differ) / double(glyph), 0.02) << differ << " of " << glyph;
}

TEST_F(FramePipelineTest, OverlayLineAcrossTheBezelMeetsOnTheNextTile) {
  const config::WallConfig wall = sync::loadWallConfig(kConfigs + "/walls/1x2.json");
  const config::Camera cam = twoMetresAhead();
  // A diagonal line through the middle of the wall, in the scene (z = 0 plane, 2 m ahead).
  Overlay overlay;
  overlay.lines.push_back({{-0.7, -0.2, 0.0}, {0.7, 0.15, 0.0}, {255, 0, 0, 255}, 3.0f});
  const ViewSetup whole_view = wholeWallView(wall, cam);
  ViewRenderer whole_r(whole_view.width, whole_view.height);
  const Image whole = whole_r.render({}, whole_view, RenderOptions{}, nullptr, &overlay);
  // The line's centre row in each column of an image (the mean row of its red pixels).
  auto centre = [](const Image& img, uint32_t x) {
    double sum = 0, n = 0;
    for (uint32_t y = 0; y < img.height; ++y)
      if (isRed(pixel(img, x, y))) sum += y, ++n;
    return n > 0 ? sum / n : -1.0;
  };
  size_t differ = 0, red = 0;
  std::vector<double> edge_rows;  // in the whole wall's rows: left tile's last, right's first
  for (const auto& tile : wall.tiles()) {
    const ViewSetup tv = tileView(wall, tile, cam);
    ViewRenderer tr(tv.width, tv.height);
    const Image img = tr.render({}, tv, RenderOptions{}, nullptr, &overlay);
    const glm::ivec2 off = tileOffsetInWhole(wall, tile);
    for (uint32_t y = 0; y < img.height; ++y)
      for (uint32_t x = 0; x < img.width; ++x) {
        const bool a = isRed(pixel(img, x, y));
        const bool b = isRed(pixel(whole, off.x + x, off.y + y));
        red += a;
        differ += a != b;
      }
    const uint32_t x = tile.name() == "left" ? img.width - 1 : 0;
    const double row = centre(img, x);
    ASSERT_GE(row, 0.0) << "the line reaches the bezel on tile " << tile.name();
    edge_rows.push_back(row + off.y);
  }
  EXPECT_GT(red, 3000u);
  // Tiles show the line where the whole wall shows it, pixel for pixel up to edge rounding.
  EXPECT_LE(double(differ) / double(red), 0.02) << differ << " of " << red;
  // Across the bezel (20 px of 1 cm pixels between the two columns) the line continues
  // straight: the row it reaches at the right tile is the left tile's plus the slope's share.
  const double slope = (centre(whole, whole.width * 3 / 4) - centre(whole, whole.width / 4)) /
                       double(whole.width / 2);
  const glm::ivec2 right = tileOffsetInWhole(wall, wall.tiles(1));
  const double gap = double(right.x) - double(wall.tiles(0).pixel_width() - 1);
  EXPECT_NEAR(edge_rows[1], edge_rows[0] + slope * gap, 0.75);
}

TEST_F(FramePipelineTest, OverlayIsHiddenBehindTheModelAndDrawnInFrontOfIt) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  glm::dvec3 c;
  const ViewSetup v = frontView(*s, 0.4, 320, 240, &c);
  ModelInstance inst{s.get(), storeModel(*s)};
  ViewRenderer r(v.width, v.height);
  const Image plain = r.renderSettled({&inst, 1}, v, RenderOptions{});
  Overlay overlay;
  // Behind the bunny (10 cm further than its centre), and in front of it (10 cm nearer).
  overlay.lines.push_back(
      {c + glm::dvec3(-0.2, 0.01, -0.1), c + glm::dvec3(0.2, 0.01, -0.1), {255, 0, 0, 255}, 3.0f});
  overlay.lines.push_back(
      {c + glm::dvec3(-0.2, -0.02, 0.1), c + glm::dvec3(0.2, -0.02, 0.1), {0, 0, 255, 255}, 3.0f});
  const Image img = r.render({&inst, 1}, v, RenderOptions{}, nullptr, &overlay);
  size_t red_over_model = 0, red_over_background = 0, blue_over_model = 0;
  for (uint32_t y = 0; y < v.height; ++y)
    for (uint32_t x = 0; x < v.width; ++x) {
      const uint8_t* p = pixel(img, x, y);
      const uint8_t* q = pixel(plain, x, y);
      const bool model = q[0] || q[1] || q[2];
      const bool red = isRed(p), blue = p[2] > 200 && p[0] < 60 && p[1] < 60;
      (model ? red_over_model : red_over_background) += red;
      blue_over_model += blue && model;
    }
  EXPECT_GT(red_over_background, 200u) << "the far line shows beside the bunny";
  EXPECT_EQ(red_over_model, 0u) << "the bunny hides the far line";
  EXPECT_GT(blue_over_model, 100u) << "the near line shows over the bunny";
  // Pixels away from the lines are the scene's.
  EXPECT_EQ(std::memcmp(pixel(img, 0, 0), pixel(plain, 0, 0), 4), 0);
}

// Opaque lines are written straight into the image (overlay_lines.comp) unless a textured quad
// must stay under them; then they are quads of the raster pass. Both ways give the same
// pixels: lines of every direction and width, through the bunny (partly hidden), off the
// view's edges, crossing each other (the later on top).
TEST_F(FramePipelineTest, DirectLinesDrawTheRasterPathsPixels) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  glm::dvec3 c;
  const ViewSetup v = frontView(*s, 0.4, 320, 240, &c);
  ModelInstance inst{s.get(), storeModel(*s)};
  ViewRenderer r(v.width, v.height);
  (void)r.renderSettled({&inst, 1}, v, RenderOptions{});
  Overlay direct;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.25, 0.25);
  for (int i = 0; i < 60; ++i) {
    const glm::u8vec4 colour(uint8_t(rng() % 256), uint8_t(rng() % 256), uint8_t(rng() % 256), 255);
    direct.lines.push_back({c + glm::dvec3(u(rng), u(rng), u(rng)),
                            c + glm::dvec3(u(rng), u(rng), u(rng)), colour,
                            float(1.0 + (i % 7) * 0.5)});
  }
  // Off the view's left and right edges, and along a row and a column exactly.
  direct.lines.push_back(
      {c + glm::dvec3(-3, 0.02, 0), c + glm::dvec3(3, 0.05, 0), {0, 255, 0, 255}, 2.0f});
  direct.lines.push_back(
      {c + glm::dvec3(-0.1, 0.0, 0.1), c + glm::dvec3(0.1, 0.0, 0.1), {255, 0, 0, 255}, 3.0f});
  direct.lines.push_back(
      {c + glm::dvec3(0.0, -0.1, 0.1), c + glm::dvec3(0.0, 0.1, 0.1), {0, 0, 255, 255}, 3.0f});
  // One end just in front of the eye (millions of pixels off the view): left to the raster.
  direct.lines.push_back(
      {c, c + (v.eye_world - c) * 0.9999999 + glm::dvec3(1e-9, 0, 0), {255, 255, 0, 255}, 2.0f});
  Overlay raster = direct;
  // A quad behind the eye (never drawn) makes every line a quad of the raster pass.
  raster.quads.push_back({{v.eye_world + glm::dvec3(0, 0, 1), v.eye_world + glm::dvec3(1, 0, 1),
                           v.eye_world + glm::dvec3(1, 1, 1), v.eye_world + glm::dvec3(0, 1, 1)},
                          nullptr,
                          {0, 0, 0, 0}});
  const Image a = r.render({&inst, 1}, v, RenderOptions{}, nullptr, &direct);
  const Image b = r.render({&inst, 1}, v, RenderOptions{}, nullptr, &raster);
  const Image plain = r.render({&inst, 1}, v, RenderOptions{});
  size_t lines = 0, differ = 0;
  for (uint32_t y = 0; y < v.height; ++y)
    for (uint32_t x = 0; x < v.width; ++x) {
      const bool in_a = std::memcmp(pixel(a, x, y), pixel(plain, x, y), 3) != 0;
      const bool in_b = std::memcmp(pixel(b, x, y), pixel(plain, x, y), 3) != 0;
      lines += in_a || in_b;
      differ += std::memcmp(pixel(a, x, y), pixel(b, x, y), 4) != 0;
    }
  EXPECT_GT(lines, 3000u);
  // Both follow the rasteriser's tie rule (axis-aligned lines on pixel edges: the 3 px lines
  // through the view's centre); float rounding moves a few pixels (11 of 17,664 here).
  EXPECT_LE(double(differ), 0.002 * double(lines)) << differ << " of " << lines << " line pixels";
}

TEST_F(FramePipelineTest, LabelsQuadsAndScreenRectsLandWhereTheyShould) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  glm::dvec3 c;
  const ViewSetup v = frontView(*s, 0.4, 320, 240, &c);
  ViewRenderer r(v.width, v.height);
  // A 2x2 texture (red, green / blue, white) on a quad facing the camera around the centre.
  GlTexture tex(2, 2, 0x8058 /* GL_RGBA8 */);
  const uint32_t texels[4] = {0xFF0000FFu, 0xFF00FF00u, 0xFFFF0000u, 0xFFFFFFFFu};
  tex.upload(texels);
  Overlay overlay;
  OverlayQuad q;
  const double h = 0.05;
  q.corners = {c + glm::dvec3(-h, h, 0), c + glm::dvec3(h, h, 0), c + glm::dvec3(h, -h, 0),
               c + glm::dvec3(-h, -h, 0)};
  q.texture = &tex;
  overlay.quads.push_back(q);
  overlay.rects.push_back({{10, 200}, {60, 230}, {255, 255, 0, 255}, nullptr});
  OverlayLabel label;
  label.at = c + glm::dvec3(-0.1, 0.07, 0);
  label.text = "Tessera label";
  label.color = {255, 255, 255, 255};
  label.background = {0, 0, 0, 0};
  overlay.labels.push_back(label);
  const Image img = r.render({}, v, RenderOptions{}, nullptr, &overlay);
  const glm::dvec3 tl = project(v, q.corners[0]), br = project(v, q.corners[2]);
  auto at = [&](double fx, double fy) {
    return pixel(img, uint32_t(tl.x + fx * (br.x - tl.x)), uint32_t(tl.y + fy * (br.y - tl.y)));
  };
  // Quadrants sampled near their centres (linear filtering blends only near the middle).
  EXPECT_TRUE(isRed(at(0.1, 0.1)));
  const uint8_t* green = at(0.9, 0.1);
  EXPECT_TRUE(green[1] > 200 && green[0] < 60);
  const uint8_t* blue = at(0.1, 0.9);
  EXPECT_TRUE(blue[2] > 200 && blue[0] < 60);
  const uint8_t* rect = pixel(img, 30, 215);
  EXPECT_TRUE(rect[0] > 200 && rect[1] > 200 && rect[2] < 60);
  // The label: white glyph pixels inside the box measure() gives, none just beyond it.
  const glm::dvec3 a = project(v, label.at);
  const glm::vec2 box = OverlayPass().measure(label);
  EXPECT_GT(box.x, 5.0f * label.height_px) << "13 glyphs are wider than 5 heights";
  size_t white = 0, beyond = 0;
  const int x0 = int(a.x + label.offset_px.x), y0 = int(a.y + label.offset_px.y);
  for (int y = y0 - 4; y < y0 + int(box.y) + 4; ++y)
    for (int x = x0 - 4; x < x0 + int(box.x) + 40; ++x) {
      if (x < 0 || y < 0 || x >= int(v.width) || y >= int(v.height)) continue;
      const uint8_t* p = pixel(img, uint32_t(x), uint32_t(y));
      const bool w = p[0] > 128 && p[1] > 128 && p[2] > 128;
      const bool inside = x >= x0 && y >= y0 && x < x0 + int(box.x) && y < y0 + int(box.y);
      (inside ? white : beyond) += w;
    }
  EXPECT_GT(white, 150u) << "glyphs drawn";
  EXPECT_EQ(beyond, 0u) << "nothing outside the label's box";
}

}  // namespace
}  // namespace tessera::render

namespace tessera::render {
namespace {

TEST_F(FramePipelineTest, BlendedColoursAverageWhereNearestColoursAlias) {
  // A plane of points coloured black or white at random, seen face on: keeping the nearest
  // point's colour gives each pixel one sample (binary noise; every point of a plane facing the
  // eye has the same depth, and ties must not go to the darker colour); blending the points
  // within a splat's depth of the nearest averages the several on each pixel.
  lod::PointBatch plane;
  plane.reset(lod::kColor);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 300000; ++i) {
    plane.positions.push_back({u(rng), u(rng), 0.0});
    const uint8_t g = rng() % 2 ? 255 : 0;
    plane.colors.push_back({g, g, g, 255});
  }
  lod::writePly(*sDir / "bw.ply", plane, glm::dvec3(0.0));
  lod::BuildOptions o;
  o.quiet = true;
  lod::buildStore({*sDir / "bw.ply"}, *sDir / "bw.tlod", o);
  auto s = lod::PointStore::open(*sDir / "bw.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  glm::dvec3 c;
  const ViewSetup v = frontView(*s, 1.2, 320, 240, &c);
  auto stats = [&](const Image& img, double& mean, double& sd) {
    double sum = 0, sum2 = 0, n = 0;
    for (uint32_t y = 80; y < 160; ++y)  // the middle of the plane
      for (uint32_t x = 120; x < 200; ++x) {
        const double g = pixel(img, x, y)[0];
        sum += g, sum2 += g * g, ++n;
      }
    mean = sum / n;
    sd = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
  };
  ViewRenderer r(v.width, v.height);
  RenderOptions nearest;
  // About 4 points a pixel, splats 3 pixels across: a pixel sees about 12 points.
  nearest.splat_scale = 8.0f;
  const Image a = r.renderSettled({&inst, 1}, v, nearest);
  RenderOptions blended = nearest;
  blended.blend_colors = true;
  const Image b = r.renderSettled({&inst, 1}, v, blended);
  double mean_a, sd_a, mean_b, sd_b;
  stats(a, mean_a, sd_a);
  stats(b, mean_b, sd_b);
  std::printf("nearest: mean %.1f sd %.1f; blended: mean %.1f sd %.1f\n", mean_a, sd_a, mean_b,
              sd_b);
  EXPECT_NEAR(mean_a, 127.5, 0.05 * 255) << "ties go to either colour alike";
  EXPECT_GT(sd_a, 0.9 * 127.5) << "nearest colours are binary";
  EXPECT_NEAR(mean_b, 127.5, 0.05 * 255) << "blended: the plane's mean grey";
  EXPECT_LT(sd_b, 0.5 * 127.5) << "blending averages several points a pixel";
  // Blending changes colours, not coverage: the depth planes are the same.
  const std::vector<uint32_t> depth_b = r.readDepth();
  r.renderSettled({&inst, 1}, v, nearest);
  EXPECT_TRUE(depth_b == r.readDepth());
}

// A store carrying ambient occlusion (multi-view AO of scans): the points' colours times their
// visibility, their colours, or the visibility alone, switched on one renderer (the chunks load
// again in each mode).
TEST_F(FramePipelineTest, StoredAmbientOcclusionShadesThePointsInEachMode) {
  lod::PointBatch plane;
  plane.reset(lod::kColor);
  std::vector<uint8_t> ao;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 100000; ++i) {
    const double x = u(rng);
    plane.positions.push_back({x, u(rng), 0.0});
    plane.colors.push_back({200, 100, 50, 255});
    ao.push_back(x < 0.5 ? 255 : 102);  // open on the left, visibility 0.4 on the right
  }
  lod::writePly(*sDir / "ao.ply", plane, glm::dvec3(0.0));
  lod::BuildOptions o;
  o.quiet = true;
  o.ambient_occlusion = ao;
  lod::buildStore({*sDir / "ao.ply"}, *sDir / "ao.tlod", o);
  auto s = lod::PointStore::open(*sDir / "ao.tlod");
  ASSERT_TRUE(s->summary().attributes & lod::kAmbientOcclusion);
  ModelInstance inst{s.get(), storeModel(*s)};
  const ViewSetup v = frontView(*s, 1.2, 320, 240);
  ViewRenderer r(v.width, v.height);
  auto at = [&](const Image& img, uint32_t x) { return glm::ivec3(pixel(img, x, 120)[0],
                                                                  pixel(img, x, 120)[1],
                                                                  pixel(img, x, 120)[2]); };
  const uint32_t left = 110, right = 210;  // the plane's left and right halves
  RenderOptions opt;
  for (StoredAo mode : {StoredAo::kModulate, StoredAo::kOff, StoredAo::kAlone, StoredAo::kModulate}) {
    opt.stored_ao = mode;
    const Image img = r.renderSettled({&inst, 1}, v, opt);
    const glm::ivec3 l = at(img, left), rt = at(img, right);
    SCOPED_TRACE(int(mode));
    if (mode == StoredAo::kModulate) {
      EXPECT_EQ(l, glm::ivec3(200, 100, 50));
      EXPECT_EQ(rt, glm::ivec3(80, 40, 20));
    } else if (mode == StoredAo::kOff) {
      EXPECT_EQ(l, glm::ivec3(200, 100, 50));
      EXPECT_EQ(rt, glm::ivec3(200, 100, 50));
    } else {
      EXPECT_EQ(l, glm::ivec3(255));
      EXPECT_EQ(rt, glm::ivec3(102));
    }
  }
}

}  // namespace
}  // namespace tessera::render

namespace tessera::render {
namespace {

TEST_F(FramePipelineTest, NonFiniteOverlayPrimitivesAreSkipped) {
  // Sketches and labels will come from remote sites: NaN or infinite positions and sizes must
  // draw nothing (not garbage across the image), and the rest of the overlay still draws.
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  glm::dvec3 c;
  const ViewSetup v = frontView(*s, 0.4, 160, 120, &c);
  ViewRenderer r(v.width, v.height);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  Overlay bad;
  bad.lines.push_back({{nan, 0, 0}, c, {255, 0, 0, 255}, 3.0f});
  bad.lines.push_back(
      {c, c + glm::dvec3(0.1, 0, 0), {255, 0, 0, 255}, std::numeric_limits<float>::infinity()});
  bad.points.push_back({{inf, 0, 0}, {255, 0, 0, 255}, 8.0f});
  bad.points.push_back({c, {255, 0, 0, 255}, std::numeric_limits<float>::quiet_NaN()});
  OverlayLabel label;
  label.at = {0, nan, 0};
  label.text = "x";
  bad.labels.push_back(label);
  OverlayQuad quad;
  quad.corners = {c, c + glm::dvec3(inf, 0, 0), c, c};
  bad.quads.push_back(quad);
  bad.rects.push_back({{0, 0}, {float(nan), 10}, {255, 0, 0, 255}, nullptr});
  const Image plain = r.render({}, v, RenderOptions{});
  const Image drawn = r.render({}, v, RenderOptions{}, nullptr, &bad);
  EXPECT_TRUE(drawn.rgba == plain.rgba) << "nothing drawn";
  bad.points.push_back({c, {255, 0, 0, 255}, 8.0f});  // one good dot among the bad
  const Image one = r.render({}, v, RenderOptions{}, nullptr, &bad);
  size_t red = 0;
  for (size_t i = 0; i < one.rgba.size(); i += 4) red += isRed(&one.rgba[i]);
  EXPECT_GT(red, 20u);
  EXPECT_LT(red, 80u);
}

}  // namespace
// A label is shown or hidden whole by its anchor (tested on the GPU, overlay.vert): anchored
// behind the bunny it is gone, even where its box lies over the background; anchored in front
// of it, it is drawn whole over the bunny. Two lines make a box two lines high.
TEST_F(FramePipelineTest, ALabelIsHiddenWholeByItsAnchorAndTakesLineBreaks) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  glm::dvec3 c;
  const ViewSetup v = frontView(*s, 0.4, 320, 240, &c);
  ViewRenderer r(v.width, v.height);
  const ModelInstance inst{s.get(), storeModel(*s)};
  (void)r.renderSettled({&inst, 1}, v, RenderOptions{});  // every chunk resident
  auto labelled = [&](glm::dvec3 at, const std::string& text) {
    Overlay overlay;
    OverlayLabel label;
    label.at = at;
    label.text = text;
    label.color = {255, 255, 255, 255};
    label.background = {255, 0, 255, 255};  // magenta: no bunny or background pixel is
    overlay.labels.push_back(label);
    const Image img = r.render({&inst, 1}, v, RenderOptions{}, nullptr, &overlay);
    size_t magenta = 0;
    for (uint32_t y = 0; y < v.height; ++y)
      for (uint32_t x = 0; x < v.width; ++x) {
        const uint8_t* p = pixel(img, x, y);
        magenta += p[0] > 200 && p[1] < 60 && p[2] > 200;
      }
    return magenta;
  };
  const double depth = glm::length(c - glm::dvec3(glm::inverse(v.view)[3]));
  const glm::dvec3 toward = glm::normalize(glm::dvec3(glm::inverse(v.view)[3]) - c);
  const size_t behind = labelled(c - 0.3 * depth * toward, "behind");
  const size_t front = labelled(c + 0.3 * depth * toward, "in front");
  const size_t two = labelled(c + 0.3 * depth * toward, "in front\nin front");
  EXPECT_EQ(behind, 0u) << "a label anchored behind the bunny is hidden whole";
  EXPECT_GT(front, 200u) << "a label anchored in front is drawn";
  const glm::vec2 one_box = OverlayPass().measure({c, "in front"});
  const glm::vec2 two_box = OverlayPass().measure({c, "in front\nin front"});
  EXPECT_EQ(one_box.x, two_box.x);
  EXPECT_NEAR(two_box.y - one_box.y, 1.2 * 20.0, 1e-3) << "one more line, 1.2 heights";
  EXPECT_GT(double(two), 1.5 * double(front)) << "the second line's box drawn too";
}

// Labels make room for each other: three at one anchor (two notes and a measurement at one
// spot) are all drawn whole, none over another, and the first keeps the place it asked for.
TEST_F(FramePipelineTest, LabelsAtOneSpotDoNotCoverEachOther) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  glm::dvec3 c;
  const ViewSetup v = frontView(*s, 0.4, 320, 240, &c);
  ViewRenderer r(v.width, v.height);
  const ModelInstance inst{s.get(), storeModel(*s)};
  (void)r.renderSettled({&inst, 1}, v, RenderOptions{});
  const glm::dvec3 toward = glm::normalize(glm::dvec3(glm::inverse(v.view)[3]) - c);
  const glm::dvec3 at = c + 0.05 * toward;  // in front of the bunny: never hidden
  const std::array<glm::u8vec4, 3> colors = {
      glm::u8vec4{255, 0, 255, 255}, glm::u8vec4{0, 255, 255, 255}, glm::u8vec4{255, 255, 0, 255}};
  Overlay overlay;
  for (const glm::u8vec4& color : colors) {
    OverlayLabel label;
    label.at = at;
    label.text = "crack A";
    label.color = {0, 0, 0, 0};  // no glyphs: the boxes alone
    label.background = color;
    overlay.labels.push_back(label);
  }
  const glm::vec2 box = OverlayPass().measure(overlay.labels[0]);
  const Image img = r.render({&inst, 1}, v, RenderOptions{}, nullptr, &overlay);
  std::array<size_t, 3> seen{};
  glm::dvec2 first_lo(1e9), first_hi(-1e9);
  for (uint32_t y = 0; y < v.height; ++y)
    for (uint32_t x = 0; x < v.width; ++x) {
      const uint8_t* p = pixel(img, x, y);
      for (size_t k = 0; k < colors.size(); ++k)
        if (std::abs(p[0] - colors[k].r) < 8 && std::abs(p[1] - colors[k].g) < 8 &&
            std::abs(p[2] - colors[k].b) < 8) {
          ++seen[k];
          if (k == 0) {
            first_lo = glm::min(first_lo, glm::dvec2(x, y));
            first_hi = glm::max(first_hi, glm::dvec2(x, y));
          }
        }
    }
  const double area = double(box.x) * double(box.y);
  for (size_t k = 0; k < colors.size(); ++k) {
    SCOPED_TRACE("label " + std::to_string(k));
    EXPECT_GT(double(seen[k]), 0.9 * area) << "drawn whole";
    EXPECT_LT(double(seen[k]), 1.1 * area) << "one box";
  }
  // The first as asked: its box's top-left corner at the offset from the anchor.
  const glm::dvec4 clip = v.projection * v.view * glm::dvec4(at, 1.0);
  const glm::dvec2 px((clip.x / clip.w * 0.5 + 0.5) * v.width,
                      (0.5 - clip.y / clip.w * 0.5) * v.height);
  const OverlayLabel defaults;
  EXPECT_NEAR(first_lo.x, px.x + defaults.offset_px.x, 1.5);
  EXPECT_NEAR(first_lo.y, px.y + defaults.offset_px.y, 1.5);
  EXPECT_NEAR(first_hi.x - first_lo.x + 1.0, box.x, 1.5);
}

}  // namespace tessera::render

namespace tessera::render {
namespace {

// Timing a pass waits for the GL at every pass, so the passes time themselves only when asked
// (pass_timing.h); the picture is the same either way.
TEST_F(FramePipelineTest, PassesAreTimedOnlyWhenAsked) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  const ViewSetup v = frontView(*s, 0.5, 160, 120);
  ModelInstance m[1] = {{s.get(), storeModel(*s)}};
  RenderOptions o;
  o.fill = SurfaceFill::kPullPush;
  o.edl.strength = 1.0f;
  ViewRenderer r(v.width, v.height);
  ASSERT_FALSE(timingPasses());  // the default
  RenderStats off, on;
  const Image quiet = r.renderSettled(m, v, o, &off);
  EXPECT_EQ(off.depth_ms + off.color_ms + off.resolve_ms + off.fill_ms + off.screen_ms, 0.0);
  timePasses(true);
  const Image timed = r.renderSettled(m, v, o, &on);
  timePasses(false);
  EXPECT_GT(on.depth_ms + on.resolve_ms + on.fill_ms + on.screen_ms, 0.0);
  EXPECT_EQ(quiet.rgba, timed.rgba);
  EXPECT_GT(off.points, 0u);
}

}  // namespace
}  // namespace tessera::render
