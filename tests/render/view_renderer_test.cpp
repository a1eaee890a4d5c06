// The GPU renderer (headless EGL, llvmpipe in CI) against an independent CPU projection of the
// same points, the 2x2 mosaic against one render of the whole wall, and repeatability.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/view_renderer.h>

#include "../support/bunny_store_test.h"
#include "../support/bunny_views.h"
#include "../support/random_cube.h"
#include "../support/temp_dir.h"

namespace tessera::render {
namespace {

const std::string kConfigs = TESSERA_CONFIG_DIR;

class ViewRendererTest : public test::BunnyStoreTest {
 protected:
  static config::Camera camera(const lod::PointStore& s, double distance) {
    return test::frontCamera(s, distance);
  }
};

/// The unit cube from afar: about 140 px across at 640x480, ~50 points per covered pixel of a
/// 10^6-point cube, each leaf's spacing still above 1 px.
config::Camera farCubeCamera() {
  config::Camera cam;
  cam.mutable_eye()->set_x(4.5);
  cam.mutable_eye()->set_y(-4.5);
  cam.mutable_eye()->set_z(3.8);
  cam.mutable_target()->set_x(0.5);
  cam.mutable_target()->set_y(0.5);
  cam.mutable_target()->set_z(0.5);
  cam.mutable_up()->set_z(1);
  return cam;
}

ViewSetup plainView(const config::Camera& cam, uint32_t w, uint32_t h) {
  return test::perspectiveView(cam, w, h);
}

TEST_F(ViewRendererTest, SilhouetteMatchesACpuProjectionOfTheSamePoints) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  const ViewSetup v = plainView(camera(*s, 0.35), 320, 240);
  const glm::dmat4 model = storeModel(*s);
  ViewRenderer r(v.width, v.height);
  ModelInstance inst{s.get(), model};
  Image img = r.renderSettled({&inst, 1}, v, RenderOptions{});
  // CPU: the same cut, projected in double precision, the same splat radius.
  std::vector<uint8_t> cpu(size_t(v.width) * v.height, 0);
  Cut cut = selectCut(*s, model, v);
  for (const CutNode& n : cut.nodes) {
    auto chunk = s->loadChunk(n.id);
    int radius = std::clamp(int(std::ceil(n.projected_spacing_px * 0.5 - 0.5)), 0, 8);
    for (const glm::vec3& p : chunk->positions) {
      glm::dvec4 clip =
          v.projection * v.view * model * glm::dvec4(chunk->offset + glm::dvec3(p), 1.0);
      if (clip.w <= 0) continue;
      glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
      if (ndc.z < -1 || ndc.z > 1) continue;
      int cx = int(std::floor((ndc.x * 0.5 + 0.5) * v.width)),
          cy = int(std::floor((ndc.y * 0.5 + 0.5) * v.height));
      for (int dy = -radius; dy <= radius; ++dy)
        for (int dx = -radius; dx <= radius; ++dx) {
          if (dx * dx + dy * dy > radius * radius + radius) continue;
          int x = cx + dx, y = cy + dy;
          if (x < 0 || y < 0 || x >= int(v.width) || y >= int(v.height)) continue;
          cpu[size_t(v.height - 1 - y) * v.width + size_t(x)] = 1;
        }
    }
  }
  size_t both = 0, either = 0;
  for (size_t i = 0; i < cpu.size(); ++i) {
    bool gpu = img.rgba[4 * i] != 0 || img.rgba[4 * i + 1] != 0 || img.rgba[4 * i + 2] != 0;
    both += gpu && cpu[i];
    either += gpu || cpu[i];
  }
  ASSERT_GT(either, 5000u) << "the bunny should cover a good part of the image";
  double iou = double(both) / double(either);
  EXPECT_GE(iou, 0.98);
  std::printf("silhouette IoU GPU vs CPU: %.5f over %zu pixels\n", iou, either);
}

// Every shading mode: the tiles, each drawn with the guard band its screen passes reach and the
// relative depth range the wall agrees on, show the whole wall's picture outside the bezels.
TEST_F(ViewRendererTest, MosaicEqualsTheWholeWallRenderInEveryShadingMode) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  config::WallConfig wall = sync::loadWallConfig(kConfigs + "/walls/2x2.json");
  config::Camera cam = camera(*s, 0.6);
  ModelInstance inst{s.get(), storeModel(*s)};
  struct Mode {
    const char* name;
    RenderOptions options;
  };
  std::vector<Mode> modes(7);
  modes[0].name = "colour";
  modes[1].name = "eye-dome lighting";
  modes[1].options.edl.strength = 1.0f;
  modes[2].name = "relative depth";
  modes[2].options.relative_depth.enabled = true;
  modes[3].name = "contour lines (view depth)";
  modes[3].options.contours.enabled = true;
  modes[3].options.contours.interval = 0.004;
  modes[4].name = "contour lines (height) over eye-dome lighting";
  modes[4].options.edl.strength = 1.0f;
  modes[4].options.contours.enabled = true;
  modes[4].options.contours.interval = 0.003;
  modes[4].options.contours.height = true;
  modes[4].options.contours.axis = glm::dvec3(0.0, 1.0, 0.0);
  modes[5].name = "ambient occlusion over colour";
  modes[5].options.ao.enabled = true;
  modes[5].options.ao.max_frames = 4;
  modes[6].name = "ambient occlusion (half resolution, metres) with eye-dome lighting";
  modes[6].options.ao.enabled = true;
  modes[6].options.ao.radius = 0.01f;
  modes[6].options.ao.half_resolution = true;
  modes[6].options.ao.max_frames = 3;
  modes[6].options.edl.strength = 1.0f;
  const ViewSetup whole_view = wholeWallView(wall, cam);
  for (Mode& mode : modes) {
    SCOPED_TRACE(mode.name);
    // The tiles' own ranges, then the wall's (what a master sends with the next frame).
    std::vector<glm::vec2> ranges;
    std::vector<Image> tiles;
    for (int round = 0; round < (mode.options.relative_depth.enabled ? 2 : 1); ++round) {
      tiles.clear();
      for (const auto& tile : wall.tiles()) {
        ViewSetup tv = tileView(wall, tile, cam);
        ViewRenderer tr(tv.width, tv.height);
        RenderStats st;
        tiles.push_back(tr.renderSettled({&inst, 1}, tv, mode.options, &st));
        EXPECT_EQ(tr.lastGuardBand() > 0, &mode != &modes[0]);
        if (mode.options.ao.enabled) EXPECT_EQ(st.ao_frames, uint32_t(mode.options.ao.max_frames));
        if (round == 0) ranges.push_back(st.relative_depth_range);
      }
      if (mode.options.relative_depth.enabled) {
        mode.options.relative_depth.agreed_range = wallRange(ranges);
        ASSERT_TRUE(mode.options.relative_depth.agreed_range);
      }
    }
    ViewRenderer whole_r(whole_view.width, whole_view.height);
    Image whole = whole_r.renderSettled({&inst, 1}, whole_view, mode.options);
    size_t differ = 0, compared = 0, covered = 0;
    size_t visible = 0;  // pixels off by more than 2 levels of 255
    int max_step = 0;
    for (size_t t = 0; t < tiles.size(); ++t) {
      const Image& img = tiles[t];
      const glm::ivec2 off = tileOffsetInWhole(wall, wall.tiles(int(t)));
      for (uint32_t y = 0; y < img.height; ++y)
        for (uint32_t x = 0; x < img.width; ++x) {
          const uint8_t* a = &img.rgba[(size_t(y) * img.width + x) * 4];
          const uint8_t* b = &whole.rgba[(size_t(off.y + y) * whole.width + off.x + x) * 4];
          ++compared;
          covered += a[0] != 0 || a[1] != 0 || a[2] != 0;
          differ += std::memcmp(a, b, 4) != 0;
          int d = 0;
          for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(int(a[c]) - int(b[c])));
          max_step = std::max(max_step, d);
          visible += d > 2;
        }
    }
    EXPECT_GT(covered, 100000u);
    // Pixel for pixel, up to float rounding: the tiles' projections and the whole wall's put a
    // point a few ulps apart, which moves a shade by a level here and there, and now and then
    // moves a disc whose centre lies on a pixel edge by a pixel, showing the surface behind on
    // one pixel; the relative depth shows that as a spot of colour around it, ambient
    // occlusion as a shade a few levels off around it (measured: up to 451 pixels differ, up to
    // 90 by more than 2 levels, of 2,073,600).
    EXPECT_LE(double(differ) / double(compared), 5e-4)
        << differ << " of " << compared << " pixels differ";
    EXPECT_LE(visible, compared / 10000) << visible << " pixels differ by more than 2 levels";
    std::printf("%s: mosaic vs whole, %zu of %zu pixels differ, %zu by more than 2 levels, by at "
                "most %d\n",
                mode.name, differ, compared, visible, max_step);
  }
}

// With the multi-view grid, the AO a view shows gathers what the views drawn before saw: the
// same view looks otherwise once another view has added its samples.
TEST_F(ViewRendererTest, TheAoGridGathersTheViewsDrawn) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const config::Camera ca = camera(*s, 0.35);
  config::Camera cb = ca;  // 70 degrees around the vertical through the target
  const double dx = ca.eye().x() - ca.target().x(), dz = ca.eye().z() - ca.target().z();
  const double c = std::cos(glm::radians(70.0)), sn = std::sin(glm::radians(70.0));
  cb.mutable_eye()->set_x(ca.target().x() + c * dx - sn * dz);
  cb.mutable_eye()->set_z(ca.target().z() + sn * dx + c * dz);
  const ViewSetup va = plainView(ca, 256, 192), vb = plainView(cb, 256, 192);
  RenderOptions o;
  o.ao.enabled = true;
  o.ao.max_frames = 2;
  o.ao_grid.enabled = true;
  ViewRenderer r(va.width, va.height);
  const Image first = r.renderSettled({&inst, 1}, va, o);
  r.renderSettled({&inst, 1}, vb, o);
  const Image again = r.renderSettled({&inst, 1}, va, o);
  size_t covered = 0, changed = 0;
  for (size_t i = 0; i < first.rgba.size(); i += 4) {
    covered += first.rgba[i] != 0;
    changed += first.rgba[i] != again.rgba[i];
  }
  EXPECT_GT(covered, 5000u);
  EXPECT_GT(changed, covered / 20) << "the other view's samples shade this one";
  ViewRenderer bare_r(va.width, va.height);
  const Image bare = bare_r.renderSettled({&inst, 1}, va, RenderOptions{});
  double shaded = 0, unshaded = 0;
  for (size_t i = 0; i < first.rgba.size(); i += 4) {
    shaded += first.rgba[i];
    unshaded += bare.rgba[i];
  }
  EXPECT_LT(shaded, 0.99 * unshaded) << "the grid darkens the picture";
}

// Without the guard band a kernel stops at the tile's edge: the seams the band removes are there.
TEST_F(ViewRendererTest, WithoutAGuardBandTheTilesShowSeams) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  config::WallConfig wall = sync::loadWallConfig(kConfigs + "/walls/2x2.json");
  config::Camera cam = camera(*s, 0.6);
  ModelInstance inst{s.get(), storeModel(*s)};
  RenderOptions o;
  o.edl.strength = 1.0f;
  o.guard_band = 0;
  const ViewSetup whole_view = wholeWallView(wall, cam);
  ViewRenderer whole_r(whole_view.width, whole_view.height);
  Image whole = whole_r.renderSettled({&inst, 1}, whole_view, o);
  size_t differ = 0;
  for (const auto& tile : wall.tiles()) {
    ViewSetup tv = tileView(wall, tile, cam);
    ViewRenderer tr(tv.width, tv.height);
    Image img = tr.renderSettled({&inst, 1}, tv, o);
    const glm::ivec2 off = tileOffsetInWhole(wall, tile);
    for (uint32_t y = 0; y < img.height; ++y)
      for (uint32_t x = 0; x < img.width; ++x)
        differ += std::memcmp(&img.rgba[(size_t(y) * img.width + x) * 4],
                              &whole.rgba[(size_t(off.y + y) * whole.width + off.x + x) * 4],
                              4) != 0;
  }
  EXPECT_GT(differ, 200u) << "eye-dome lighting should differ along the tiles' edges";
}

// The pixels of a view drawn with a guard band are those of the same view drawn larger.
TEST_F(ViewRendererTest, AGuardBandKeepsPicksAndPixelsInPlace) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const ViewSetup v = plainView(camera(*s, 0.35), 320, 240);
  RenderOptions plain;
  plain.pick_ids = true;
  RenderOptions banded = plain;
  banded.guard_band = 7;
  ViewRenderer a(v.width, v.height), b(v.width, v.height);
  const Image ia = a.renderSettled({&inst, 1}, v, plain);
  const Image ib = b.renderSettled({&inst, 1}, v, banded);
  EXPECT_EQ(b.lastGuardBand(), 7u);
  EXPECT_EQ(b.target().width(), 334u);
  size_t differ = 0;
  for (size_t i = 0; i < ia.rgba.size(); ++i) differ += ia.rgba[i] != ib.rgba[i];
  EXPECT_LE(differ, ia.rgba.size() / 10000) << differ << " bytes differ";
  for (uint32_t y = 40; y < 200; y += 40)
    for (uint32_t x = 40; x < 280; x += 40) {
      const auto pa = a.pick(x, y), pb = b.pick(x, y);
      ASSERT_EQ(pa.has_value(), pb.has_value()) << x << "," << y;
      if (!pa) continue;
      EXPECT_EQ(pa->node, pb->node);
      EXPECT_EQ(pa->point, pb->point);
      EXPECT_NEAR(glm::length(pa->world - pb->world), 0.0, 1e-6);
    }
  RenderOptions bad;
  bad.guard_band = -5;
  EXPECT_THROW(b.render({&inst, 1}, v, bad), std::exception);
}

TEST_F(ViewRendererTest, FarViewAtOnePixelDrawsFewPointsAndLooksLikeFullResolution) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  const ViewSetup v = plainView(camera(*s, 1.2), 320, 240);
  ModelInstance inst{s.get(), storeModel(*s)};
  ViewRenderer r(v.width, v.height);
  RenderOptions lod1;
  lod1.edl.strength = 1.0f;
  RenderOptions full = lod1;
  full.lod_pixels = 1e-6;  // every leaf: the full-resolution reference
  full.coverage_stop = false;
  RenderStats st1, stf;
  Image a = r.renderSettled({&inst, 1}, v, lod1, &st1);
  Image b = r.renderSettled({&inst, 1}, v, full, &stf);
  EXPECT_EQ(stf.points, 362272u);
  EXPECT_LT(double(st1.points), 0.25 * double(stf.points));
  double se = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4) {
    for (int c = 0; c < 3; ++c) {
      double d = double(a.rgba[i + c]) - double(b.rgba[i + c]);
      se += d * d;
    }
  }
  double mse = se / double(a.rgba.size() / 4 * 3);
  double psnr = mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 99.0;
  std::printf("far view at 1 px: %llu of %llu points (%.1f%%), PSNR %.1f dB to full resolution\n",
              (unsigned long long)st1.points, (unsigned long long)stf.points,
              100.0 * st1.points / stf.points, psnr);
  EXPECT_GE(psnr, 37.0);  // measured 48.5 dB with 1.7% of the points (40.2 with classic EDL)
}

TEST_F(ViewRendererTest, ColdAndWarmRendersAreIdentical) {
  const ViewSetup v = [&] {
    auto s = lod::PointStore::open(*sDir / "b.tlod");
    return plainView(camera(*s, 0.3), 256, 192);
  }();
  Image first;
  for (int round = 0; round < 3; ++round) {
    auto s = lod::PointStore::open(*sDir / "b.tlod");  // cold cache each time
    ModelInstance inst{s.get(), storeModel(*s)};
    ViewRenderer r(v.width, v.height);
    Image img = r.renderSettled({&inst, 1}, v, RenderOptions{});
    Image warm = r.renderSettled({&inst, 1}, v, RenderOptions{});
    EXPECT_EQ(img.rgba, warm.rgba);
    if (round == 0) {
      first = img;
    } else {
      EXPECT_EQ(img.rgba, first.rgba);
    }
  }
}

TEST_F(ViewRendererTest, FramesNeverWaitForTheLoaderAndAncestorsStandIn) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const ViewSetup far = plainView(camera(*s, 1.2), 256, 192);
  const ViewSetup near = plainView(camera(*s, 0.25), 256, 192);
  ViewRenderer r(far.width, far.height);
  r.streamer().pauseLoader(true);
  RenderStats st;
  Image empty = r.render({&inst, 1}, far, RenderOptions{}, &st);  // returns with nothing loaded
  EXPECT_EQ(st.points, 0u);
  EXPECT_EQ(st.missing_nodes, st.cut_nodes);
  EXPECT_GE(st.stream.requested, st.cut_nodes);  // the cut (and ancestors), coarse first
  r.streamer().pauseLoader(false);
  r.renderSettled({&inst, 1}, far, RenderOptions{}, &st);
  EXPECT_EQ(st.missing_nodes, 0u);

  // Closer, loader held: the far view's nodes stand in for the finer cut.
  r.streamer().pauseLoader(true);
  Image coarse = r.render({&inst, 1}, near, RenderOptions{}, &st);
  EXPECT_GT(st.missing_nodes, 0u);
  EXPECT_GT(st.fallback_nodes, 0u);
  EXPECT_GT(st.points, 0u);
  r.streamer().pauseLoader(false);
  Image settled = r.renderSettled({&inst, 1}, near, RenderOptions{}, &st);
  EXPECT_EQ(st.missing_nodes, 0u);
  EXPECT_NE(coarse.rgba, settled.rgba);

  // What the renderer went through does not change the settled picture.
  ViewRenderer fresh(near.width, near.height);
  EXPECT_EQ(fresh.renderSettled({&inst, 1}, near, RenderOptions{}).rgba, settled.rgba);
}

TEST_F(ViewRendererTest, GpuCacheEvictsLeastRecentlyUsedChunksUnderItsBudget) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const config::Camera base = camera(*s, 0.12);
  std::vector<ViewSetup> views;
  for (double dx : {-0.06, 0.0, 0.06}) {
    config::Camera c = base;
    c.mutable_eye()->set_x(c.eye().x() + dx);
    c.mutable_target()->set_x(c.target().x() + dx);
    views.push_back(plainView(c, 200, 150));
  }
  StreamerOptions so;
  so.budget_bytes = 1u << 20;  // about 65,000 points: less than one close view needs
  ViewRenderer r(200, 150, nullptr, so);
  RenderStats st;
  uint64_t evicted = 0;
  for (const ViewSetup& v : views) {
    Image img = r.renderSettled({&inst, 1}, v, RenderOptions{}, &st);
    evicted += st.stream.evicted;
    // Over budget only by what this very view draws, which is never evicted under it.
    EXPECT_LE(st.stream.resident_bytes,
              so.budget_bytes + st.points * sizeof(GpuPoint) + 16 * st.nodes);
    ViewRenderer fresh(200, 150);
    EXPECT_EQ(fresh.renderSettled({&inst, 1}, v, RenderOptions{}).rgba, img.rgba);
  }
  EXPECT_GT(evicted, 0u);
  // Back to the first view: its chunks were evicted and come back.
  r.renderSettled({&inst, 1}, views[0], RenderOptions{}, &st);
  EXPECT_GT(st.frames, 1u);
}

// Splats against geometry with a known outline: a unit square of uniformly random points, seen
// at a slant (random samples: the hardest case for splats sized from the mean nearest-neighbour
// distance). Inside the projected square no pixel may stay empty (closed surface); outside it no
// splat may reach further than its own radius allows (no fat blobs), at every LOD threshold.
TEST_F(ViewRendererTest, SplatsCloseSurfacesAtEveryLevelWithoutFatBlobs) {
  lod::PointBatch plane;
  plane.reset(0);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 400000; ++i) plane.positions.push_back({u(rng), u(rng), 0.0});
  lod::writePly(*sDir / "plane.ply", plane, glm::dvec3(0.0));
  lod::BuildOptions o;
  o.quiet = true;
  lod::buildStore({*sDir / "plane.ply"}, *sDir / "plane.tlod", o);
  auto s = lod::PointStore::open(*sDir / "plane.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  config::Camera cam;
  cam.mutable_eye()->set_x(0.5);
  cam.mutable_eye()->set_y(-0.5);
  cam.mutable_eye()->set_z(0.9);
  cam.mutable_target()->set_x(0.5);
  cam.mutable_target()->set_y(0.45);
  cam.mutable_up()->set_z(1);
  const ViewSetup v = plainView(cam, 320, 240);
  // The square's corners in pixels (x right, y down, as the image rows run).
  const glm::dmat4 clip = v.projection * v.view;
  std::vector<glm::dvec2> quad;
  for (glm::dvec2 c : {glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(1, 1), glm::dvec2(0, 1)}) {
    glm::dvec4 p = clip * glm::dvec4(c, 0.0, 1.0);
    quad.push_back({(p.x / p.w * 0.5 + 0.5) * v.width, (0.5 - p.y / p.w * 0.5) * v.height});
  }
  auto insideBy = [&](double x, double y) {  // signed distance to the outline, > 0 inside
    double d = 1e9;
    for (size_t i = 0; i < 4; ++i) {
      glm::dvec2 a = quad[i], b = quad[(i + 1) % 4], e = glm::normalize(b - a);
      d = std::min(d, -(e.x * (y - a.y) - e.y * (x - a.x)));
    }
    return d;
  };
  if (insideBy(160, 120) < 0)  // winding: make the inside positive
    std::reverse(quad.begin(), quad.end());
  // Both ways of closing surfaces: discs, and 1 px points with the pull-push fill, which must
  // close the surface as well as the discs and reach no further.
  std::map<std::pair<double, float>, double> disc_holes;
  for (const SurfaceFill fill : {SurfaceFill::kDiscs, SurfaceFill::kPullPush}) {
    for (double lod_px : {1.0, 2.0, 4.0}) {
      for (float scale : {1.0f, 1.5f, 2.0f}) {
        RenderOptions opt;
        opt.lod_pixels = lod_px;
        opt.splat_scale = scale;
        opt.fill = fill;
        const char* fill_name = fill == SurfaceFill::kDiscs ? "discs" : "pull-push";
        ViewRenderer r(v.width, v.height);
        RenderStats st;
        Image img = r.renderSettled({&inst, 1}, v, opt, &st);
        size_t inside = 0, holes = 0, blobs = 0;
        for (uint32_t y = 0; y < v.height; ++y)
          for (uint32_t x = 0; x < v.width; ++x) {
            const bool covered = img.rgba[(size_t(y) * v.width + x) * 4] != 0;
            const double d = insideBy(x + 0.5, y + 0.5);
            if (d >= 2.0) {
              ++inside;
              holes += !covered;
            } else if (d < -(0.5 * scale * lod_px + 1.5)) {
              blobs += covered;
            }
          }
        ASSERT_GT(inside, 20000u);
        const double hole_fraction = double(holes) / double(inside);
        std::printf(
            "%s, lod %.0f px, splat scale %.1f: %llu points, %.3f%% holes, %zu pixels past the "
            "outline\n",
            fill_name, lod_px, scale, (unsigned long long)st.points, 100.0 * hole_fraction, blobs);
        EXPECT_EQ(blobs, 0u) << fill_name << " lod " << lod_px << " scale " << scale;
        if (scale == 2.0f) {
          // Single-pixel splats over random samples leave a few pixels open at 1 px. Coarser
          // levels sample their children's samples (one per grid cell, the one nearest its
          // centre among those), which places them less evenly than a pick among every point
          // below: measured 0.09% open at 2 px and 0.94% at 4 px (docs/limits.md).
          EXPECT_LT(hole_fraction, lod_px == 1.0 ? 0.005 : lod_px == 2.0 ? 0.0015 : 0.015)
              << fill_name << " lod " << lod_px;
        } else if (scale == 1.0f && lod_px > 1.0) {
          EXPECT_GT(hole_fraction, 0.05) << "the mean spacing alone cannot close random samples";
        }
        if (fill == SurfaceFill::kDiscs) {
          disc_holes[{lod_px, scale}] = hole_fraction;
        } else {
          // At least as closed as the discs, to 0.02% of the inside (measured: as closed or
          // more at every level and scale).
          EXPECT_LE(hole_fraction, (disc_holes[{lod_px, scale}] + 0.0002))
            << "lod " << lod_px << " scale " << scale;
        }
      }
    }
  }
}

/// Covered pixels (any channel set) in both images over those in either.
double silhouetteIou(const Image& a, const Image& b) {
  size_t both = 0, either = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4) {
    const bool pa = a.rgba[i] != 0 || a.rgba[i + 1] != 0 || a.rgba[i + 2] != 0;
    const bool pb = b.rgba[i] != 0 || b.rgba[i + 1] != 0 || b.rgba[i + 2] != 0;
    both += pa && pb;
    either += pa || pb;
  }
  return either ? double(both) / double(either) : 1.0;
}

double psnr(const Image& a, const Image& b) {
  double se = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4) {
    for (int c = 0; c < 3; ++c) {
      const double d = double(a.rgba[i + c]) - double(b.rgba[i + c]);
      se += d * d;
    }
  }
  const double mse = se / double(a.rgba.size() / 4 * 3);
  return mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 99.0;
}

// A volume of points (the ParaView comparison's scene, smaller): the coverage stop (on by
// default) and a point budget draw a fraction of the points with the silhouette of every leaf.
TEST_F(ViewRendererTest, CoverageStopAndBudgetKeepTheSilhouetteOfAVolume) {
  test::TempDir dir;
  auto s = lod::PointStore::open(test::randomCubeStore(dir.path(), 1'000'000, 500));
  ModelInstance inst{s.get(), storeModel(*s)};
  const config::Camera cam = farCubeCamera();
  const ViewSetup v = plainView(cam, 640, 480);
  RenderOptions full;
  full.lod_pixels = 1e-6;
  full.coverage_stop = false;
  full.budget_per_covered_pixel = 0.0;
  // The coverage stop alone and with an explicit budget, discs (the defaults' budget and fill
  // are the next test's).
  RenderOptions coverage;
  coverage.budget_per_covered_pixel = 0.0;
  coverage.fill = SurfaceFill::kDiscs;
  RenderOptions budget = coverage;
  budget.point_budget = 300000;  // the root alone holds 110,583
  ViewRenderer r(v.width, v.height);
  RenderStats sf, sd, sb;
  const Image ref = r.renderSettled({&inst, 1}, v, full, &sf);
  const Image def = r.renderSettled({&inst, 1}, v, coverage, &sd);
  const Image bud = r.renderSettled({&inst, 1}, v, budget, &sb);
  EXPECT_EQ(sf.points, 1'000'000u);
  const double iou_default = silhouetteIou(ref, def), iou_budget = silhouetteIou(ref, bud);
  std::printf(
      "cube: every leaf %llu points; default %llu (IoU %.4f); budget 3x10^5: %llu (IoU "
      "%.4f)\n",
      (unsigned long long)sf.points, (unsigned long long)sd.points, iou_default,
      (unsigned long long)sb.points, iou_budget);
  EXPECT_LT(double(sd.points), 0.5 * double(sf.points));  // measured 0.46
  EXPECT_GE(iou_default, 0.99);
  EXPECT_LE(sb.points, 300000u);
  EXPECT_GT(sb.points, 150000u);
  EXPECT_GE(iou_budget, 0.99);
}

// A point budget is the whole wall's: each tile draws the whole wall's budget-limited cut (the
// spacing threshold it sets), so the mosaic is the whole wall's picture; tiles holding budgets of
// their own would end their cuts at other levels and disagree.
TEST_F(ViewRendererTest, MosaicEqualsTheWholeWallRenderUnderAPointBudget) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  const config::WallConfig wall = sync::loadWallConfig(kConfigs + "/walls/2x2.json");
  const config::Camera cam = camera(*s, 0.6);
  ModelInstance inst{s.get(), storeModel(*s)};
  const ViewSetup whole_view = wholeWallView(wall, cam);
  ViewRenderer whole_r(whole_view.width, whole_view.height);
  RenderOptions o;
  o.budget_per_covered_pixel = 0.0;
  RenderStats st;
  whole_r.renderSettled({&inst, 1}, whole_view, o, &st);
  const uint64_t free_points = st.points;
  o.point_budget = free_points / 3;
  const Image whole = whole_r.renderSettled({&inst, 1}, whole_view, o, &st);
  EXPECT_LE(st.points, o.point_budget);
  EXPECT_GT(st.points, o.point_budget / 4);
  EXPECT_EQ(st.fill, SurfaceFill::kDiscs);  // a wall's pictures draw discs
  auto mosaicDiffers = [&](bool shared) {
    size_t differ = 0, compared = 0;
    for (const auto& tile : wall.tiles()) {
      ViewSetup tv = tileView(wall, tile, cam);
      if (!shared) tv.whole_size = glm::uvec2(0);  // each tile its own budget
      ViewRenderer tr(tv.width, tv.height);
      RenderStats ts;
      const Image img = tr.renderSettled({&inst, 1}, tv, o, &ts);
      EXPECT_EQ(ts.point_budget, o.point_budget);
      const glm::ivec2 off = tileOffsetInWhole(wall, tile);
      for (uint32_t y = 0; y < img.height; ++y)
        for (uint32_t x = 0; x < img.width; ++x) {
          ++compared;
          differ += std::memcmp(&img.rgba[(size_t(y) * img.width + x) * 4],
                                &whole.rgba[(size_t(off.y + y) * whole.width + off.x + x) * 4],
                                4) != 0;
        }
    }
    return double(differ) / double(compared);
  };
  const double shared = mosaicDiffers(true), own = mosaicDiffers(false);
  std::printf("budget %llu of %llu points: mosaic vs whole, %.5f%% of pixels differ; with a "
              "budget per tile %.3f%%\n",
              (unsigned long long)o.point_budget, (unsigned long long)free_points, 100 * shared,
              100 * own);
  EXPECT_LE(shared, 5e-4);  // float rounding between the projections, as without a budget
  EXPECT_GT(own, 10 * shared + 1e-3) << "budgets of their own end the tiles' cuts elsewhere";
}

// The defaults' budget of two points a covered pixel, splats sized from the cut drawn (so a
// coarser cut still closes the surface), and the default fill, the one the frame is cheaper
// with: a volume of points seen whole fills, a surface draws discs. The budget's floor keeps
// every level of cuts smaller than it: the bunny's ten scans seen close draw as without it.
TEST_F(ViewRendererTest, APixelBudgetHoldsTheCutAndTheFillFollowsTheFrame) {
  test::TempDir dir;
  auto cube = lod::PointStore::open(test::randomCubeStore(dir.path(), 1'000'000, 500));
  auto bunny = lod::PointStore::open(*sDir / "b.tlod");
  const config::Camera cam = farCubeCamera();
  const ViewSetup v = plainView(cam, 640, 480);
  ModelInstance c{cube.get(), storeModel(*cube)};
  ViewRenderer r(v.width, v.height);
  RenderOptions full;
  full.lod_pixels = 1e-6;
  full.coverage_stop = false;
  full.budget_per_covered_pixel = 0.0;
  full.fill = SurfaceFill::kDiscs;
  RenderStats sf, sd;
  const Image ref = r.renderSettled({&c, 1}, v, full, &sf);
  const RenderOptions defaults;
  EXPECT_EQ(defaults.budget_per_covered_pixel, 2.0);
  RenderOptions pixel_budget;  // the defaults without the floor, which this small view is below
  pixel_budget.budget_floor = 0;
  const Image def = r.renderSettled({&c, 1}, v, pixel_budget, &sd);
  EXPECT_EQ(sf.points, 1'000'000u);
  EXPECT_GT(sd.point_budget, 0u);
  EXPECT_LE(sd.point_budget, 2u * 640u * 480u);  // two points a covered pixel at most
  // Within the budget, or the root when the budget holds fewer points (a cut is never coarser).
  const uint64_t root = cube->node(cube->root()).points;
  EXPECT_TRUE(sd.points <= sd.point_budget || sd.points == root) << sd.points;
  EXPECT_LT(sd.points, sf.points / 5);
  EXPECT_EQ(sd.fill, SurfaceFill::kPullPush) << "discs " << sd.fill_estimate.disc_px
                                              << " px over " << sd.fill_estimate.covered_px;
  const double iou = silhouetteIou(ref, def);
  std::printf("cube, 2 points a covered pixel: %llu points (budget %llu), fill %s, IoU %.4f\n",
              (unsigned long long)sd.points, (unsigned long long)sd.point_budget,
              sd.fill == SurfaceFill::kPullPush ? "pull-push" : "discs", iou);
  // This store's root (110,583 points) already holds more than two points a pixel of this
  // 640x480 view, so the root is drawn, filled: measured 0.985 (bench/paraview_peer measures
  // 0.99 and above at 1920x1080 on 10^7 and 5x10^7 points).
  EXPECT_GE(iou, 0.98);
  // With the floor (the defaults), the cube's cut is held to the floor, not to its pixels.
  RenderStats sfl;
  r.renderSettled({&c, 1}, v, defaults, &sfl);
  EXPECT_EQ(sfl.point_budget, defaults.budget_floor);
  EXPECT_LE(sfl.points, defaults.budget_floor);
  EXPECT_GT(sfl.points, sd.points);
  // The bunny's surface, near: discs, no pixel of its inside left open. Its 362,272 points are
  // below the floor, so the defaults draw every level the pixels ask for, as without a budget;
  // two points a pixel without the floor coarsen it.
  const ViewSetup near = plainView(camera(*bunny, 0.3), 640, 480);
  ModelInstance b{bunny.get(), storeModel(*bunny)};
  RenderStats sb, sn, sp;
  const Image near_defaults = r.renderSettled({&b, 1}, near, defaults, &sb);
  EXPECT_EQ(sb.fill, SurfaceFill::kDiscs) << "discs " << sb.fill_estimate.disc_px << " px over "
                                          << sb.fill_estimate.covered_px;
  RenderOptions no_budget;
  no_budget.budget_per_covered_pixel = 0.0;
  const Image near_free = r.renderSettled({&b, 1}, near, no_budget, &sn);
  EXPECT_EQ(sb.points, sn.points);
  EXPECT_EQ(near_defaults.rgba, near_free.rgba);
  r.renderSettled({&b, 1}, near, pixel_budget, &sp);
  EXPECT_LT(sp.points, sn.points);
  // chooseFill() by its numbers: many layers of discs fill, few or wide discs do not.
  EXPECT_EQ(chooseFill(SurfaceFill::kAuto, {.disc_px = 1e8, .covered_px = 1e5, .max_radius_px = 8}),
            SurfaceFill::kPullPush);
  EXPECT_EQ(chooseFill(SurfaceFill::kAuto, {.disc_px = 1e6, .covered_px = 1e5, .max_radius_px = 8}),
            SurfaceFill::kDiscs);
  EXPECT_EQ(chooseFill(SurfaceFill::kAuto, {.disc_px = 1e8, .covered_px = 1e5, .max_radius_px = 20}),
            SurfaceFill::kDiscs);
  EXPECT_EQ(chooseFill(SurfaceFill::kNone, {.disc_px = 1e8, .covered_px = 1e5, .max_radius_px = 8}),
            SurfaceFill::kNone);
}

// Surfaces: the coverage stop (the default) leaves their accuracy against the full-resolution
// render as it was without it, near and far.
TEST_F(ViewRendererTest, CoverageStopLeavesSurfacesAsAccurate) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  for (double distance : {0.3, 1.2}) {
    const ViewSetup v = plainView(camera(*s, distance), 320, 240);
    ViewRenderer r(v.width, v.height);
    RenderOptions on;
    on.edl.strength = 1.0f;
    RenderOptions off = on;
    off.coverage_stop = false;
    RenderOptions full = off;
    full.lod_pixels = 1e-6;
    RenderStats st_on, st_off;
    const Image ref = r.renderSettled({&inst, 1}, v, full);
    const Image a = r.renderSettled({&inst, 1}, v, on, &st_on);
    const Image b = r.renderSettled({&inst, 1}, v, off, &st_off);
    const double p_on = psnr(a, ref), p_off = psnr(b, ref);
    std::printf(
        "bunny at %.1f m: coverage stop %llu points, %.2f dB; without %llu points, %.2f "
        "dB\n",
        distance, (unsigned long long)st_on.points, p_on, (unsigned long long)st_off.points, p_off);
    EXPECT_GE(p_on, p_off - 0.1) << "distance " << distance;
    EXPECT_GE(silhouetteIou(a, ref), silhouetteIou(b, ref) - 1e-3);
  }
}

}  // namespace
}  // namespace tessera::render
