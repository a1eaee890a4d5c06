// The foveal inset (render/inset.h): the context black under it minus the blend band, the band's
// weights monotone and summing to one picture in linear light, the inset's pixels those of a
// direct off-axis render of its rectangle, its place a synced scene property, the wall picture
// seamless, and bad wall files refused by field.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include <tessera/render/inset.h>
#include <tessera/render/stereo.h>
#include <tessera/render/view_renderer.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/config.h>
#include <tessera/sync/scene_graph.h>

#include "../support/bunny_store_test.h"
#include "../support/bunny_views.h"

namespace tessera::render {
namespace {

/// Two 320x180 tiles of 0.48 x 0.27 m (666.7 px/m), a 2 cm bezel, and `inset` (JSON fields).
std::string wallJson(const std::string& inset) {
  return R"({"name": "inset test", "tiles": [
    {"name": "left", "x": 0, "y": 0, "width": 0.48, "height": 0.27, "pixelWidth": 320,
     "pixelHeight": 180},
    {"name": "right", "x": 0.5, "y": 0, "width": 0.48, "height": 0.27, "pixelWidth": 320,
     "pixelHeight": 180}], "eye": {"x": 0.49, "y": 0.135, "z": 1.5}, "insets": [)" +
         inset + "]}";
}

/// An inset at the context's density, aligned with the left tile's pixels: 80x60 pixels from
/// column 40, row 60, a 10-pixel band.
const std::string kAligned =
    R"({"name": "fovea", "x": 0.06, "y": 0.09, "width": 0.12, "height": 0.09,
        "pixelWidth": 80, "pixelHeight": 60, "blendBand": 0.015})";
/// An inset at twice the density over the bezel, 0.24 x 0.135 m, a 1.2 cm band.
const std::string kFine =
    R"({"name": "fovea", "x": 0.37, "y": 0.0675, "width": 0.24, "height": 0.135,
        "pixelWidth": 320, "pixelHeight": 180, "blendBand": 0.012})";

config::WallConfig wall(const std::string& inset) {
  return sync::parseWallConfig(wallJson(inset), "inset.json", "");
}

Image filled(uint32_t w, uint32_t h, uint8_t v) {
  Image img;
  img.width = w;
  img.height = h;
  img.rgba.assign(size_t(w) * h * 4, v);
  for (size_t i = 3; i < img.rgba.size(); i += 4) img.rgba[i] = 255;
  return img;
}

uint8_t red(const Image& img, uint32_t x, uint32_t y) {
  return img.rgba[(size_t(y) * img.width + x) * 4];
}

TEST(InsetWeights, TheContextIsBlackUnderTheInsetMinusTheBand) {
  const config::WallConfig w = wall(kAligned);
  const std::vector<WallSlot> slots = wallSlots(w);
  ASSERT_EQ(slots.size(), 3u);
  Image left = filled(320, 180, 255), right = filled(320, 180, 255);
  applySlotWeights(w, slots[0], {}, left);
  applySlotWeights(w, slots[1], {}, right);
  size_t black = 0, band = 0;
  for (uint32_t y = 0; y < 180; ++y)
    for (uint32_t x = 0; x < 320; ++x) {
      const bool inside = x >= 40 && x < 120 && y >= 60 && y < 120;
      const bool deep = x >= 50 && x < 110 && y >= 70 && y < 110;
      const uint8_t v = red(left, x, y);
      if (deep) {
        EXPECT_EQ(v, 0) << x << "," << y;
        black += v == 0;
      } else if (inside) {
        EXPECT_GT(v, 0) << x << "," << y;
        EXPECT_LT(v, 255) << x << "," << y;
        ++band;
      } else {
        EXPECT_EQ(v, 255) << x << "," << y;
      }
      EXPECT_EQ(red(right, x, y), 255);  // the inset is not over the right tile
    }
  EXPECT_EQ(black, 60u * 40u);
  EXPECT_EQ(band, 80u * 60u - 60u * 40u);
}

TEST(InsetWeights, TheBandIsMonotoneAndContextPlusInsetIsOneInLinearLight) {
  const config::WallConfig w = wall(kAligned);
  const std::vector<WallSlot> slots = wallSlots(w);
  Image context = filled(320, 180, 255), inset = filled(80, 60, 255);
  applySlotWeights(w, slots[0], {}, context);
  applySlotWeights(w, slots[2], {}, inset);
  const InsetRect r = insetRect(w, 0, {});
  double worst = 0.0;
  for (uint32_t j = 0; j < 60; ++j) {
    double last_context = 2.0, last_inset = -1.0;
    for (uint32_t i = 0; i < 40; ++i) {  // from the left edge to the middle
      const double c = linearFromByte(red(context, 40 + i, 60 + j));
      const double n = linearFromByte(red(inset, i, j));
      // Row j's distance to the top or bottom edge caps the weights: monotone along the row.
      EXPECT_LE(c, last_context + 1e-12) << i << "," << j;
      EXPECT_GE(n, last_inset - 1e-12) << i << "," << j;
      last_context = c;
      last_inset = n;
      worst = std::max(worst, std::abs(c + n - 1.0));
      // The weights themselves sum to one exactly.
      const double wx = r.x0 + (i + 0.5) / (80 / 0.12), wy = r.y1 - (j + 0.5) / (60 / 0.09);
      EXPECT_NEAR(contextWeight(w, {}, wx, wy) + insetWeight(r, wx, wy), 1.0, 1e-12);
    }
  }
  // The ramp itself, by hand: in the middle row the left edge is nearest, pixel i's centre is
  // i + 0.5 of the band's 10 pixels inside it.
  for (uint32_t i = 0; i < 12; ++i) {
    const double expected = i < 10 ? 1.0 - (i + 0.5) / 10.0 : 0.0;
    EXPECT_NEAR(linearFromByte(red(context, 40 + i, 90)), expected, 1.1 / 255.0) << i;
    EXPECT_NEAR(linearFromByte(red(inset, i, 30)), 1.0 - expected, 1.1 / 255.0) << i;
  }
  // 8-bit gamma-2.2 values: each weight rounds to the nearest code, at most 1.47/255 together
  // (near white one code is 2.2/255 of light).
  EXPECT_LE(worst, 1.5 / 255.0);
  std::printf("context + inset in linear light: off by at most %.3f / 255\n", worst * 255.0);
}

class InsetRender : public test::BunnyStoreTest {};

TEST_F(InsetRender, OutsideTheBandTheInsetIsADirectRenderOfItsRectangle) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  config::WallConfig w = wall(kFine);
  const config::Camera cam = test::frontCamera(*s, 0.5);
  // The scene moves the inset 5 cm right and 2 cm down from its config's place.
  scene::InsetPlacement placement;
  scene::InsetCentre& c = *placement.add_centres();
  c.set_name("fovea");
  c.set_x(0.54);
  c.set_y(0.115);
  ASSERT_FALSE(insetPlacementProblem(w, c));
  const WallSlot slot = wallSlots(w)[2];
  ASSERT_EQ(slot.tile.name(), "fovea");
  const ViewSetup v = slotView(w, slot, placement, cam);
  ViewRenderer r1(v.width, v.height);
  Image inset = r1.renderSettled({&inst, 1}, v, RenderOptions{});
  applySlotWeights(w, slot, placement, inset);

  // The same rectangle, its view built by hand: Kooima's off-axis frustum from the wall eye.
  const double x0 = 0.54 - 0.12, x1 = 0.54 + 0.12, y0 = 0.115 - 0.0675, y1 = 0.115 + 0.0675;
  ViewSetup d;
  d.view = cameraView(cam);
  d.projection = offAxisProjection(glm::dvec3(0.49, 0.135, 1.5), x0, x1, y0, y1, w.near(), w.far());
  d.width = 320;
  d.height = 180;
  d.eye_world = glm::dvec3(cam.eye().x(), cam.eye().y(), cam.eye().z());
  d.pixels_per_metre = glm::dvec2(320 / 0.24, 180 / 0.135);
  ViewRenderer r2(d.width, d.height);
  const Image direct = r2.renderSettled({&inst, 1}, d, RenderOptions{});

  const int band_x = int(std::ceil(0.012 * 320 / 0.24)),
            band_y = int(std::ceil(0.012 * 180 / 0.135));
  size_t compared = 0, lit = 0, differ = 0;
  for (uint32_t y = uint32_t(band_y); y < 180 - uint32_t(band_y); ++y)
    for (uint32_t x = uint32_t(band_x); x < 320 - uint32_t(band_x); ++x) {
      const size_t k = (size_t(y) * 320 + x) * 4;
      ++compared;
      differ += std::memcmp(&inset.rgba[k], &direct.rgba[k], 4) != 0;
      lit += direct.rgba[k] > 100;
    }
  EXPECT_EQ(differ, 0u) << "of " << compared;
  EXPECT_GT(lit, compared / 4) << "the bunny should fill a good part of the inset";
  // Across the band (the middle row) the inset is the direct render times its weight in linear
  // light, rising from the edge.
  const InsetRect rect = insetRect(w, 0, placement);
  for (uint32_t x = 0; x < uint32_t(band_x) + 2; ++x) {
    const double weight = insetWeight(rect, x0 + (x + 0.5) * 0.24 / 320, 0.115);
    EXPECT_NEAR(linearFromByte(red(inset, x, 90)), weight * linearFromByte(red(direct, x, 90)),
                1.1 / 255.0)
        << x;
  }
  EXPECT_LT(insetWeight(rect, x0 + 0.5 * 0.24 / 320, 0.115), 0.05);
}

TEST_F(InsetRender, TheWallPictureIsOnePictureAcrossTheSeam) {
  // The context and the inset rendered, weighted and composited: at the context's density the
  // wall under the inset is the render of the whole wall there, up to the filters' rounding.
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const config::WallConfig w = wall(kFine);
  const config::Camera cam = test::frontCamera(*s, 0.5);
  std::vector<Image> pictures;
  for (const WallSlot& slot : wallSlots(w)) {
    const ViewSetup v = slotView(w, slot, {}, cam);
    ViewRenderer r(v.width, v.height);
    pictures.push_back(r.renderSettled({&inst, 1}, v, RenderOptions{}));
    applySlotWeights(w, slot, {}, pictures.back());
  }
  const Image wall_picture = assembleInsetWall(w, pictures, {});
  const ViewSetup whole = wholeWallView(w, cam);
  ASSERT_EQ(wall_picture.width, whole.width);
  ASSERT_EQ(wall_picture.height, whole.height);
  ViewRenderer rw(whole.width, whole.height);
  const Image reference = rw.renderSettled({&inst, 1}, whole, RenderOptions{});
  // Compare the inset's rectangle (bezel included: the inset covers it) on the bunny's body.
  const InsetRect r = insetRect(w, 0, {});
  const double ppm = 320 / 0.48;
  double sum = 0;
  size_t n = 0;
  for (int y = int((0.27 - r.y1) * ppm) + 2; y < int((0.27 - r.y0) * ppm) - 2; ++y)
    for (int x = int(r.x0 * ppm) + 2; x < int(r.x1 * ppm) - 2; ++x) {
      const uint8_t a = red(wall_picture, uint32_t(x), uint32_t(y));
      const uint8_t b = red(reference, uint32_t(x), uint32_t(y));
      if (b < 100) continue;  // the bunny's lit surface, where point sampling noise is least
      sum += std::abs(int(a) - int(b));
      ++n;
    }
  ASSERT_GT(n, 2000u);
  // The inset's pixels are averaged 2x2 down: the surface's brightness, not its exact pixels.
  EXPECT_LT(sum / n, 12.0) << "mean level difference under the inset";
  std::printf("wall picture vs whole-wall render under the inset: mean %.2f levels over %zu px\n",
              sum / n, n);
  // The inset's picture at its own density (insetDetail) is the inset where it is fully shown.
  const Image detail = insetDetail(w, pictures, {}, 0, 0);
  EXPECT_EQ(detail.width, 320u);
  EXPECT_EQ(red(detail, 160, 90), red(pictures[2], 160, 90));
  // The bezel's grey is gone under the inset, kept outside it.
  EXPECT_EQ(red(wall_picture, 325, 5), kBezelGrey);
  EXPECT_NE(red(wall_picture, 325, 90), kBezelGrey);
}

TEST_F(InsetRender, TheGpuPassWeighsAsTheCpuReference) {
  // What nodes and tessera-render --mosaic run (InsetPass) against applySlotWeights(): the
  // context tiles and the inset (with a border), each pixel within one level, most equal.
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const config::WallConfig w = wall(
      R"({"name": "fovea", "x": 0.37, "y": 0.0675, "width": 0.24, "height": 0.135,
          "pixelWidth": 320, "pixelHeight": 180, "blendBand": 0.02, "border": 3})");
  const config::Camera cam = test::frontCamera(*s, 0.5);
  scene::InsetPlacement placement;
  scene::InsetCentre& c = *placement.add_centres();
  c.set_name("fovea");
  c.set_x(0.45);
  c.set_y(0.15);
  InsetPass pass;
  for (const WallSlot& slot : wallSlots(w)) {
    SCOPED_TRACE(slot.tile.name());
    const ViewSetup v = slotView(w, slot, placement, cam);
    ViewRenderer r(v.width, v.height);
    Image cpu = r.renderSettled({&inst, 1}, v, RenderOptions{});
    pass.run(r.imageBuffer(), w, slot, placement);
    const Image gpu = pass.read();
    const Image unweighted = cpu;
    applySlotWeights(w, slot, placement, cpu);
    ASSERT_EQ(gpu.rgba.size(), cpu.rgba.size());
    size_t differ = 0, changed = 0;
    int worst = 0;
    for (size_t i = 0; i < cpu.rgba.size(); ++i) {
      const int d = std::abs(int(gpu.rgba[i]) - int(cpu.rgba[i]));
      worst = std::max(worst, d);
      differ += d != 0;
      changed += cpu.rgba[i] != unweighted.rgba[i];
    }
    EXPECT_LE(worst, 1);
    EXPECT_LT(differ, cpu.rgba.size() / 100);
    EXPECT_GT(changed, 1000u) << "the inset covers part of every slot here";
    std::printf("%s: GPU weights against the CPU's: %zu of %zu bytes one level apart\n",
                slot.tile.name().c_str(), differ, cpu.rgba.size());
  }
}

TEST_F(InsetRender, ASwitchedOffInsetLeavesTheContextWholeAndItsPictureBlack) {
  // settings.inset's `hidden` (the console's switch, a script's setInset): on the GPU as on the
  // CPU, the tiles keep every byte and the inset's own picture is black, its border too.
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const config::WallConfig w = wall(
      R"({"name": "fovea", "x": 0.37, "y": 0.0675, "width": 0.24, "height": 0.135,
          "pixelWidth": 320, "pixelHeight": 180, "blendBand": 0.02, "border": 3})");
  const config::Camera cam = test::frontCamera(*s, 0.5);
  scene::InsetPlacement placement;
  scene::InsetCentre& c = *placement.add_centres();
  c.set_name("fovea");
  c.set_x(0.45);
  c.set_y(0.15);
  c.set_hidden(true);
  EXPECT_FALSE(insetRect(w, 0, placement).shown);
  InsetPass pass;
  for (const WallSlot& slot : wallSlots(w)) {
    SCOPED_TRACE(slot.tile.name());
    const ViewSetup v = slotView(w, slot, placement, cam);
    ViewRenderer r(v.width, v.height);
    const Image drawn = r.renderSettled({&inst, 1}, v, RenderOptions{});
    Image cpu = drawn;
    applySlotWeights(w, slot, placement, cpu);
    pass.run(r.imageBuffer(), w, slot, placement);
    const Image gpu = pass.read();
    EXPECT_TRUE(gpu.rgba == cpu.rgba) << "the GPU pass and the CPU reference differ";
    size_t lit = 0, black = 0;
    for (size_t i = 0; i < cpu.rgba.size(); i += 4) {
      lit += drawn.rgba[i] > 100;
      black += cpu.rgba[i] == 0 && cpu.rgba[i + 1] == 0 && cpu.rgba[i + 2] == 0;
    }
    EXPECT_GT(lit, 1000u) << "the bunny is in every slot here";
    if (slot.inset < 0) {
      EXPECT_TRUE(cpu.rgba == drawn.rgba) << "a tile keeps every byte";
    } else {
      EXPECT_EQ(black, cpu.rgba.size() / 4) << "the inset is black";
    }
  }
  // The wall's picture is the tiles' mosaic alone.
  std::vector<Image> pictures;
  for (const WallSlot& slot : wallSlots(w)) {
    Image img;
    img.width = slot.tile.pixel_width();
    img.height = slot.tile.pixel_height();
    img.rgba.assign(size_t(img.width) * img.height * 4, 200);
    applySlotWeights(w, slot, placement, img);
    pictures.push_back(img);
  }
  const std::vector<Image> tiles(pictures.begin(), pictures.begin() + w.tiles_size());
  EXPECT_TRUE(assembleInsetWall(w, pictures, placement).rgba ==
              assembleWallMosaic(w, tiles).rgba);
}

TEST(InsetStereo, EachEyeIsTheMonoViewSeenFromThatEye) {
  const config::WallConfig w = wall(
      R"({"name": "fovea", "x": 0.37, "y": 0.0675, "width": 0.24, "height": 0.135,
          "pixelWidth": 320, "pixelHeight": 180, "stereo": true, "eyeSeparation": 0.07})");
  const std::vector<WallSlot> slots = wallSlots(w);
  ASSERT_EQ(slots.size(), 4u);
  EXPECT_EQ(slots[2].tile.name(), "fovea/left");
  EXPECT_EQ(slots[3].tile.name(), "fovea/right");
  config::Camera cam;
  cam.mutable_eye()->set_z(1.0);
  cam.mutable_up()->set_y(1.0);
  WallSlot mono = slots[2];
  mono.eye = 0;
  const ViewSetup m = slotView(w, mono, {}, cam);
  for (int e : {2, 3}) {
    const ViewSetup v = slotView(w, slots[size_t(e)], {}, cam);
    EXPECT_DOUBLE_EQ(v.eye_offset.x, e == 2 ? -0.035 : 0.035);
    const ViewSetup ref = stereoEyeView(m, v.eye_offset, w.eye().z());
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        EXPECT_NEAR(v.projection[i][j], ref.projection[i][j], 1e-9);
        EXPECT_NEAR(v.view[i][j], ref.view[i][j], 1e-9);
      }
  }
}

TEST(InsetPlacement, TheCentreIsASyncedSettingCheckedAgainstTheWall) {
  const config::WallConfig w = wall(kFine);
  sync::SceneGraph master;
  (void)master.takeFrame(0, 0);
  sync::SceneGraph node;
  node.apply(master.snapshot());
  master.setInsetCentre("fovea", 0.3, 0.2);
  node.apply(master.takeFrame(1, 0));
  const InsetRect r = insetRect(w, 0, node.settings().inset());
  EXPECT_DOUBLE_EQ(r.x0, 0.3 - 0.12);
  EXPECT_DOUBLE_EQ(r.y1, 0.2 + 0.0675);
  // Outside the wall, an inset the wall lacks, NaN: each said.
  scene::InsetCentre c;
  c.set_name("fovea");
  c.set_x(0.9);
  c.set_y(0.1);
  ASSERT_TRUE(insetPlacementProblem(w, c));
  EXPECT_NE(insetPlacementProblem(w, c)->find("outside the wall's extent"), std::string::npos);
  c.set_name("retina");
  EXPECT_NE(insetPlacementProblem(w, c)->find("no inset 'retina'"), std::string::npos);
  c.set_name("fovea");
  c.set_x(std::numeric_limits<double>::quiet_NaN());
  EXPECT_NE(insetPlacementProblem(w, c)->find("finite"), std::string::npos);
  // A frame placing an inset at NaN is refused by the replica, which stays as it was.
  scene::Frame bad;
  bad.set_number(2);
  bad.set_version(node.version() + 1);
  scene::InsetCentre& n = *bad.mutable_settings()->mutable_inset()->add_centres();
  n.set_name("fovea");
  n.set_x(std::numeric_limits<double>::infinity());
  EXPECT_THROW(node.apply(bad), sync::SyncError);
  EXPECT_DOUBLE_EQ(node.settings().inset().centres(0).x(), 0.3);
  // A node never draws outside the wall: a centre too far is clamped to the extent.
  scene::InsetPlacement far;
  *far.add_centres() = c;
  far.mutable_centres(0)->set_x(5.0);
  EXPECT_DOUBLE_EQ(insetRect(w, 0, far).x1, 0.98);
}

void expectRefused(const std::string& inset, const std::string& field, const std::string& what) {
  try {
    (void)wall(inset);
    ADD_FAILURE() << "accepted " << inset;
  } catch (const sync::ConfigError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("inset.json: " + field + ": "), std::string::npos) << m;
    EXPECT_NE(m.find(what), std::string::npos) << m;
  }
}

TEST(InsetConfig, BadInsetsAreRefusedByField) {
  const std::string ok = R"("x": 0.1, "y": 0.05, "width": 0.2, "height": 0.1,
      "pixelWidth": 400, "pixelHeight": 200)";
  const config::WallConfig w = wall(R"({"name": "f", )" + ok + "}");
  EXPECT_NEAR(w.insets(0).eye_separation(), 0.065, 1e-12);
  EXPECT_NEAR(w.insets(0).blend_band(), 0.01, 1e-12);
  expectRefused(R"({"name": "left", )" + ok + "}", "insets[0].name", "already names a tile");
  expectRefused(R"({"name": "a/b", )" + ok + "}", "insets[0].name", "'/'");
  expectRefused(R"({)" + ok + "}", "insets[0].name", "needs a name");
  expectRefused(R"({"name": "f", )" + ok + R"(}, {"name": "f", )" + ok + "}", "insets[1].name",
                "already names");
  expectRefused(R"({"name": "f", "x": 0.1, "y": 0.05, "width": -0.2, "height": 0.1,
      "pixelWidth": 400, "pixelHeight": 200})",
                "insets[0]", "finite and positive");
  expectRefused(R"({"name": "f", "x": "NaN", "y": 0.05, "width": 0.2, "height": 0.1,
      "pixelWidth": 400, "pixelHeight": 200})",
                "insets[0]", "finite");
  expectRefused(R"({"name": "f", "x": 0.1, "y": 0.05, "width": "Infinity", "height": 0.1,
      "pixelWidth": 400, "pixelHeight": 200})",
                "insets[0]", "finite and positive");
  expectRefused(R"({"name": "f", "x": 0.9, "y": 0.05, "width": 0.2, "height": 0.1,
      "pixelWidth": 400, "pixelHeight": 200})",
                "insets[0]", "inside the wall's extent");
  expectRefused(R"({"name": "f", "x": 0.1, "y": 0.05, "width": 0.2, "height": 0.1,
      "pixelWidth": 0, "pixelHeight": 200})",
                "insets[0]", "1..16384");
  expectRefused(R"({"name": "f", "x": 0.1, "y": 0.05, "width": 0.2, "height": 0.1,
      "pixelWidth": 20000, "pixelHeight": 200})",
                "insets[0]", "1..16384");
  expectRefused(R"({"name": "f", "blendBand": 0.06, )" + ok + "}", "insets[0].blendBand",
                "must be in [0, 0.05");
  expectRefused(R"({"name": "f", "blendBand": "NaN", )" + ok + "}", "insets[0].blendBand",
                "must be in");
  expectRefused(R"({"name": "f", "eyeSeparation": 0, "stereo": true, )" + ok + "}",
                "insets[0].eyeSeparation", "(0, 1]");
  expectRefused(R"({"name": "f", "border": 100, )" + ok + "}", "insets[0].border", "under half");
  // A scene file's inset centres must be finite.
  try {
    (void)sync::parseSceneFile(R"({"camera": {"eye": {"z": 1}, "target": {}, "up": {"y": 1}},
        "settings": {"inset": {"centres": [{"name": "f", "x": "NaN", "y": 0}]}}})",
                               "scene.json", "");
    ADD_FAILURE() << "a NaN inset centre";
  } catch (const sync::ConfigError& e) {
    EXPECT_NE(
        std::string(e.what()).find("scene.json: scene: settings.inset.centres[0] ('f'): x and y "
                                   "must be finite"),
        std::string::npos)
        << e.what();
  }
  // Projector files: the inset's slots would need their own blend and warp.
  try {
    (void)sync::parseWallConfig(R"({"tiles": [{"name": "p", "width": 1, "height": 1,
        "pixelWidth": 8, "pixelHeight": 8, "blend": "auto"}], "eye": {"z": 2}, "insets": [
        {"name": "f", "x": 0.1, "y": 0.1, "width": 0.2, "height": 0.2, "pixelWidth": 8,
         "pixelHeight": 8}]})",
                                "p.json", "");
    ADD_FAILURE() << "an inset on a projector wall";
  } catch (const sync::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("p.json: insets: foveal insets need a wall without "
                                         "projector files"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace tessera::render
