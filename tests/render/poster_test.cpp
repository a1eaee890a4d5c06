// Posters (poster.h) against single renders and against posters cut another way, the strip PNG
// writer against the picture in memory, and stereo eyes (stereo.h) against the analytic disparity
// of points on, in front of and behind the zero-parallax plane.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/cli.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/poster.h>
#include <tessera/render/stereo.h>
#include <tessera/render/view_renderer.h>

#include "../support/bunny_store_test.h"
#include "../support/bunny_views.h"
#include "../support/temp_dir.h"

namespace tessera::render {
namespace {

const std::string kConfigs = TESSERA_CONFIG_DIR;

class PosterTest : public test::BunnyStoreTest {};

using test::frontCamera;
using test::perspectiveView;

/// How two pictures of one size differ: pixels whose bytes differ, and those off by more than 2
/// levels of 255 in a colour channel.
struct Difference {
  size_t pixels = 0, differ = 0, visible = 0, covered = 0;
  int max_step = 0;
};

Difference compare(const Image& a, const Image& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  Difference d;
  if (a.rgba.size() != b.rgba.size()) return d;
  d.pixels = size_t(a.width) * a.height;
  for (size_t i = 0; i < d.pixels; ++i) {
    const uint8_t* p = &a.rgba[4 * i];
    const uint8_t* q = &b.rgba[4 * i];
    d.covered += p[0] != 0 || p[1] != 0 || p[2] != 0;
    d.differ += std::memcmp(p, q, 4) != 0;
    int step = 0;
    for (int c = 0; c < 3; ++c) step = std::max(step, std::abs(int(p[c]) - int(q[c])));
    d.max_step = std::max(d.max_step, step);
    d.visible += step > 2;
  }
  return d;
}

TEST_F(PosterTest, PartsAreSubRectanglesOfTheFullWindowAndCoverThePoster) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  const ViewSetup full = perspectiveView(frontCamera(*s, 0.35), 1000, 700);
  const PosterPlan plan = planPoster(1000, 700, 256, uint64_t(1) << 30);
  EXPECT_EQ(plan.columns, 4u);
  EXPECT_EQ(plan.rows, 3u);
  const std::vector<PosterPart> parts = posterParts(full, plan);
  ASSERT_EQ(parts.size(), 12u);
  std::vector<uint8_t> hits(size_t(1000) * 700, 0);
  for (const PosterPart& p : parts) {
    EXPECT_LE(p.width, 256u);
    EXPECT_LE(p.height, 256u);
    EXPECT_EQ(p.view.origin, glm::ivec2(int(p.x), int(p.y)));
    for (uint32_t y = p.y; y < p.y + p.height; ++y)
      for (uint32_t x = p.x; x < p.x + p.width; ++x) ++hits[size_t(y) * 1000 + x];
    // A world point's pixel in the part is its pixel in the full view, less the part's corner.
    const glm::dvec3 world =
        glm::dvec3(glm::inverse(full.projection * full.view) * glm::dvec4(0.3, -0.2, 0.5, 1.0));
    auto pixel = [&](const ViewSetup& v) {
      const glm::dvec4 c = v.projection * v.view * glm::dvec4(world, 1.0);
      return glm::dvec2((c.x / c.w * 0.5 + 0.5) * v.width, (0.5 - c.y / c.w * 0.5) * v.height);
    };
    const glm::dvec2 in_full = pixel(full), in_part = pixel(p.view);
    EXPECT_NEAR(in_part.x + p.x, in_full.x, 1e-6);
    EXPECT_NEAR(in_part.y + p.y, in_full.y, 1e-6);
  }
  for (uint8_t h : hits) ASSERT_EQ(h, 1);
}

TEST_F(PosterTest, APosterThatFitsOneRenderEqualsThatRender) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const ViewSetup v = perspectiveView(frontCamera(*s, 0.35), 320, 240);
  RenderOptions o;
  o.edl.strength = 1.0f;
  const PosterPlan plan = planPoster(v.width, v.height, kDefaultPosterPart, uint64_t(1) << 30);
  ASSERT_EQ(plan.columns * plan.rows, 1u);
  PosterStats st;
  const Image poster = renderPosterImage({&inst, 1}, v, o, plan, {}, nullptr, &st);
  EXPECT_EQ(st.parts, 1u);
  ViewRenderer r(v.width, v.height);
  const Image single = r.renderSettled({&inst, 1}, v, o);
  const Difference d = compare(poster, single);
  EXPECT_GT(d.covered, 10000u);
  EXPECT_EQ(d.differ, 0u) << d.differ << " of " << d.pixels << " pixels differ";
}

// A 4x4 poster and a 2x2 poster of the same view: the parts' edges differ (a 2x2 edge is inside
// a 4x4 part and the 4x4 parts have edges the 2x2 have not), so a seam in either shows.
TEST_F(PosterTest, FourByFourPartsEqualTwoByTwoPartsWithScreenPasses) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const ViewSetup v = perspectiveView(frontCamera(*s, 0.3), 400, 400);
  struct Mode {
    const char* name;
    RenderOptions options;
  };
  std::vector<Mode> modes(3);
  modes[0].name = "eye-dome lighting";
  modes[0].options.edl.strength = 1.0f;
  modes[1].name = "ambient occlusion";
  modes[1].options.ao.enabled = true;
  modes[1].options.ao.max_frames = 3;
  modes[2].name = "relative depth";
  modes[2].options.relative_depth.enabled = true;
  for (const Mode& mode : modes) {
    SCOPED_TRACE(mode.name);
    const PosterPlan four = planPoster(v.width, v.height, 100, uint64_t(1) << 30);
    const PosterPlan two = planPoster(v.width, v.height, 200, uint64_t(1) << 30);
    ASSERT_EQ(four.columns, 4u);
    ASSERT_EQ(four.rows, 4u);
    ASSERT_EQ(two.columns, 2u);
    ASSERT_EQ(two.rows, 2u);
    PosterStats st4, st2;
    const Image a = renderPosterImage({&inst, 1}, v, mode.options, four, {}, nullptr, &st4);
    RenderOptions same = mode.options;
    if (st4.agreed_range) {
      // The parts' ranges are their own 1st to 99th percentiles, so the range they agree on
      // depends on the cut: the 2x2 poster and the single render get the 4x4 poster's.
      EXPECT_EQ(st4.renders, 32u) << "each part's range, then the pictures";
      same.relative_depth.agreed_range = st4.agreed_range;
    } else {
      EXPECT_EQ(st4.renders, 16u);
    }
    const Image b = renderPosterImage({&inst, 1}, v, same, two, {}, nullptr, &st2);
    EXPECT_GT(st4.max_band, 0u) << "the screen passes draw a guard band";
    const Difference d = compare(a, b);
    EXPECT_GT(d.covered, 40000u);
    // Up to float rounding, as the wall mosaic against the whole wall
    // (view_renderer_test.cpp): the parts' projections put a point a few ulps apart, which moves
    // a shade by a level here and there.
    EXPECT_LE(double(d.differ) / double(d.pixels), 2e-4)
        << d.differ << " of " << d.pixels << " pixels differ";
    EXPECT_LE(d.visible, d.pixels / 10000) << d.visible << " pixels differ by more than 2 levels";
    std::printf(
        "%s: 4x4 vs 2x2 parts, %zu of %zu pixels differ, %zu by more than 2 levels, by at "
        "most %d\n",
        mode.name, d.differ, d.pixels, d.visible, d.max_step);
    // Against one render of the whole view (measured with ambient occlusion: 40 of 160,000
    // pixels differ, each by one level).
    ViewRenderer r(v.width, v.height);
    const Difference one = compare(a, r.renderSettled({&inst, 1}, v, same));
    EXPECT_LE(double(one.differ) / double(one.pixels), 5e-4)
        << one.differ << " of " << one.pixels << " pixels differ from one render";
    EXPECT_LE(one.visible, one.pixels / 10000)
        << one.visible << " pixels differ from one render by more than 2 levels";
    std::printf("%s: 4x4 parts vs one render, %zu pixels differ, %zu by more than 2 levels\n",
                mode.name, one.differ, one.visible);
  }
}

// The comparison above sees seams: without a guard band eye-dome lighting stops at each part's
// edge and the 4x4 poster differs from the 2x2 one along the edges.
TEST_F(PosterTest, WithoutAGuardBandThePartsShowSeams) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const ViewSetup v = perspectiveView(frontCamera(*s, 0.3), 400, 400);
  RenderOptions o;
  o.edl.strength = 1.0f;
  o.guard_band = 0;
  const Image a =
      renderPosterImage({&inst, 1}, v, o, planPoster(v.width, v.height, 100, uint64_t(1) << 30));
  const Image b =
      renderPosterImage({&inst, 1}, v, o, planPoster(v.width, v.height, 200, uint64_t(1) << 30));
  const Difference d = compare(a, b);
  EXPECT_GT(d.differ, 100u) << "eye-dome lighting should differ along the parts' edges";
}

TEST(PosterPngTest, AStripWrittenPngReadsBackEqualToThePicture) {
  test::TempDir dir;
  Image img;
  img.width = 301;
  img.height = 203;
  img.rgba.resize(size_t(img.width) * img.height * 4);
  std::mt19937 rng(7);
  for (auto& b : img.rgba) b = uint8_t(rng());
  const std::string path = (dir.path() / "strips.png").string();
  {
    PngStripWriter w(path, img.width, img.height);
    // Strips of uneven heights, as the rows of parts of a poster are.
    uint32_t y = 0;
    for (uint32_t rows : {1u, 50u, 51u, 0u, 101u}) {
      w.writeRows({&img.rgba[size_t(y) * img.width * 4], size_t(rows) * img.width * 4}, rows);
      y += rows;
      EXPECT_FALSE(std::filesystem::exists(path)) << "the PNG appears only when finished";
    }
    ASSERT_EQ(w.rowsWritten(), img.height);
    w.finish();
  }
  const Image back = readPng(path);
  ASSERT_EQ(back.width, img.width);
  ASSERT_EQ(back.height, img.height);
  EXPECT_TRUE(back.rgba == img.rgba);
  // An unfinished writer leaves nothing behind.
  const std::string partial = (dir.path() / "partial.png").string();
  {
    PngStripWriter w(partial, 64, 64);
    w.writeRows({img.rgba.data(), 64 * 4 * 10}, 10);
  }
  EXPECT_FALSE(std::filesystem::exists(partial));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);
  EXPECT_THROW(PngStripWriter((dir.path() / "no-such-folder" / "x.png").string(), 8, 8),
               RenderError);
}

TEST(PosterPlanTest, BadSizesAreRefusedWithAClearMessage) {
  for (const char* text : {"0x100", "100x0", "nanx100", "100xnan", "infx10", "70000x100",
                           "100x65536", "-5x10", "100", "4096x4096x2", "1e3x10"}) {
    SCOPED_TRACE(text);
    try {
      cli::parseSize(text, "--poster", kMaxPosterSide);
      ADD_FAILURE() << "accepted";
    } catch (const cli::UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("--poster"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("65535"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(cli::parseSize("65535x16384", "--poster", kMaxPosterSide).width, 65535u);
  for (auto [w, h] : {std::pair{0u, 10u}, {10u, 0u}, {65536u, 10u}, {10u, 100000u}}) {
    try {
      planPoster(w, h, kDefaultPosterPart, uint64_t(1) << 30);
      ADD_FAILURE() << w << "x" << h << " accepted";
    } catch (const RenderError& e) {
      EXPECT_NE(std::string(e.what()).find("outside 1..65535"), std::string::npos) << e.what();
    }
  }
  // Too little memory for a row of parts: the message says how much is needed.
  try {
    planPoster(65535, 65535, kDefaultPosterPart, 1 << 20);
    ADD_FAILURE() << "accepted";
  } catch (const RenderError& e) {
    EXPECT_NE(std::string(e.what()).find("needs at least"), std::string::npos) << e.what();
  }
  // Larger than a frame target: rows of parts within the memory allowed.
  const PosterPlan big = planPoster(65535, 40000, kDefaultPosterPart, uint64_t(1024) << 20);
  EXPECT_EQ(big.columns, 16u);
  EXPECT_LE(big.part_width, kDefaultPosterPart);
  EXPECT_LE(big.peakBytes(), uint64_t(1024) << 20);
  EXPECT_GE(uint64_t(big.part_height) * big.rows, 40000u);
}

// --- Stereo -------------------------------------------------------------------------------

TEST(StereoTest, LayoutsPutTheEyesWhereTheySay) {
  Image l, r;
  l.width = r.width = 3;
  l.height = r.height = 2;
  l.rgba.assign(24, 0);
  r.rgba.assign(24, 0);
  for (size_t i = 0; i < 6; ++i) {
    l.rgba[4 * i] = 10, l.rgba[4 * i + 1] = 11, l.rgba[4 * i + 2] = 12, l.rgba[4 * i + 3] = 255;
    r.rgba[4 * i] = 20, r.rgba[4 * i + 1] = 21, r.rgba[4 * i + 2] = 22, r.rgba[4 * i + 3] = 255;
  }
  const Image sbs = composeStereo(l, r, StereoLayout::kSideBySide);
  ASSERT_EQ(sbs.width, 6u);
  ASSERT_EQ(sbs.height, 2u);
  EXPECT_EQ(sbs.rgba[(1 * 6 + 2) * 4], 10);
  EXPECT_EQ(sbs.rgba[(1 * 6 + 3) * 4], 20);
  const Image tb = composeStereo(l, r, StereoLayout::kTopBottom);
  ASSERT_EQ(tb.width, 3u);
  ASSERT_EQ(tb.height, 4u);
  EXPECT_EQ(tb.rgba[(1 * 3 + 2) * 4], 10);
  EXPECT_EQ(tb.rgba[(2 * 3 + 0) * 4], 20);
  const Image ana = composeStereo(l, r, StereoLayout::kAnaglyph);
  EXPECT_EQ(ana.rgba[0], 10);
  EXPECT_EQ(ana.rgba[1], 21);
  EXPECT_EQ(ana.rgba[2], 22);
  EXPECT_EQ(stereoPairPath("out/view.png", false), "out/view-left.png");
  EXPECT_EQ(stereoPairPath("view.png", true), "view-right.png");
  EXPECT_EQ(parseStereoLayout("tb", "--stereo"), StereoLayout::kTopBottom);
  EXPECT_THROW(parseStereoLayout("side", "--stereo"), RenderError);
}

// On a wall the eye's view through the wall plane is tileView()'s with that eye offset.
TEST(StereoTest, AWallTilesEyeViewIsTheTileViewWithThatEyeOffset) {
  const config::WallConfig wall = sync::loadWallConfig(kConfigs + "/walls/2x2.json");
  config::Camera cam;
  cam.mutable_eye()->set_z(3);
  cam.mutable_up()->set_y(1);
  const glm::dvec3 offset(0.0325, 0.0, 0.0);
  for (const auto& tile : wall.tiles()) {
    const ViewSetup mono = tileView(wall, tile, cam);
    const ViewSetup eye = stereoEyeView(mono, offset, wall.eye().z());
    const ViewSetup ref = tileView(wall, tile, cam, offset);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) {
        EXPECT_NEAR(eye.projection[c][r], ref.projection[c][r], 1e-9) << c << "," << r;
        EXPECT_NEAR(eye.view[c][r], ref.view[c][r], 1e-9) << c << "," << r;
      }
    EXPECT_NEAR(glm::length(eye.eye_world - ref.eye_world), 0.0, 1e-12);
    EXPECT_EQ(eye.origin, ref.origin);
  }
}

// Three square patches of points parallel to the screen: on the zero-parallax plane (2 m), in
// front of it (1 m) and behind it (4 m). Each patch's centroid moves between the eyes by the
// analytic disparity s (1 - D / Z) on the screen, in pixels: a patch parallel to the screen
// projects affinely, so its points' centroid moves exactly so.
TEST(StereoTest, DisparityOnInFrontOfAndBehindTheScreenMatchesTheAnalyticValue) {
  test::TempDir dir;
  struct Patch {
    glm::dvec3 centre;  // world; the camera looks down -z from z = 2
    double side;
  };
  const Patch patches[3] = {{{0.0, 0.0, 0.0}, 0.08},     // Z = 2: on the screen
                            {{-0.3, 0.05, 1.0}, 0.05},   // Z = 1: in front
                            {{0.5, -0.1, -2.0}, 0.16}};  // Z = 4: behind
  // 16 x 16 isolated points a patch, 1.6 to 3.3 pixels apart, drawn one pixel each (no splats,
  // no fill): their sub-pixel positions spread over the pixel, so the centroid of the lit pixels
  // follows the points' to a small fraction of a pixel.
  lod::PointBatch b;
  b.reset(0);
  for (const Patch& p : patches)
    for (int i = 0; i < 16; ++i)
      for (int j = 0; j < 16; ++j)
        b.positions.push_back(
            p.centre + glm::dvec3((i + 0.5) / 16.0 - 0.5, (j + 0.5) / 16.0 - 0.5, 0.0) * p.side);
  lod::writePly(dir.path() / "patches.ply", b, glm::dvec3(0.0));
  lod::BuildOptions bo;
  bo.quiet = true;
  lod::buildStore({dir.path() / "patches.ply"}, dir.path() / "patches.tlod", bo);
  auto store = lod::PointStore::open(dir.path() / "patches.tlod");
  ModelInstance inst{store.get(), storeModel(*store)};
  auto ctx = GlContext::createHeadless();
  config::Camera cam;
  cam.mutable_eye()->set_z(2);
  cam.mutable_up()->set_y(1);
  const uint32_t w = 640, h = 480;
  const double D = 2.0, s = 0.065, fovy = 40.0;
  const ViewSetup mono = perspectiveView(cam, w, h, fovy);
  const double px_per_m = h / (2.0 * D * std::tan(glm::radians(fovy) / 2.0));
  RenderOptions o;
  o.lod_pixels = 0.25;
  o.fill = SurfaceFill::kNone;
  ViewRenderer r(w, h);
  const Image left = r.renderSettled({&inst, 1}, stereoEyeView(mono, {-s / 2, 0, 0}, D), o);
  const Image right = r.renderSettled({&inst, 1}, stereoEyeView(mono, {s / 2, 0, 0}, D), o);
  for (const Patch& p : patches) {
    const double Z = 2.0 - p.centre.z;
    SCOPED_TRACE("patch at " + std::to_string(Z) + " m");
    // The mono centre on screen; a window around it wide enough for either eye's patch.
    const glm::dvec2 centre(w / 2.0 + p.centre.x * D / Z * px_per_m,
                            h / 2.0 - p.centre.y * D / Z * px_per_m);
    const int half = int(std::ceil(p.side * D / Z * px_per_m / 2 + s * px_per_m + 4));
    auto centroid = [&](const Image& img) {
      double sx = 0, sy = 0, n = 0;
      for (int y = int(centre.y) - half; y <= int(centre.y) + half; ++y)
        for (int x = int(centre.x) - half; x <= int(centre.x) + half; ++x) {
          const uint8_t* px = &img.rgba[(size_t(y) * w + size_t(x)) * 4];
          if (px[0] == 0 && px[1] == 0 && px[2] == 0) continue;
          sx += x + 0.5, sy += y + 0.5, n += 1;
        }
      EXPECT_GT(n, 200.0);
      return glm::dvec2(sx / n, sy / n);
    };
    const glm::dvec2 cl = centroid(left), cr = centroid(right);
    const double expected = s * (1.0 - D / Z) * px_per_m;
    std::printf("Z = %.0f m: disparity %.3f px, analytic %.3f px; vertical %.3f px\n", Z,
                cr.x - cl.x, expected, cr.y - cl.y);
    EXPECT_NEAR(cr.x - cl.x, expected, 0.1);
    EXPECT_NEAR(cr.y - cl.y, 0.0, 0.1);
  }
  // The analytic values differ enough to tell the planes apart.
  EXPECT_GT(s * (D / 1.0 - 1.0) * px_per_m, 5.0);
}

}  // namespace
}  // namespace tessera::render
