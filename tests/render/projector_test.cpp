// Projectors: over an overlap the blended projectors give the light one would, an identity warp
// changes nothing, a keystone warp carries points where its grid says, overlapping warped and
// blended projectors recompose the screen, an MPCDI file written here reads back, and bad
// files are refused by name and field.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <zip.h>

#include <tessera/render/gl_context.h>
#include <tessera/render/projector_pass.h>
#include <tessera/render/tile_frustum.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/config.h>

#include "../../fuzz/pfm_fuzz.h"
#include "../support/wavy_warp.h"

namespace tessera::render {
namespace {

namespace fs = std::filesystem;
using test::wavyWarp;

class ProjectorTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { sContext = GlContext::createHeadless().release(); }
  static void TearDownTestSuite() {
    delete sContext;
    sContext = nullptr;
  }
  void SetUp() override {
    mDir = fs::temp_directory_path() /
           ("tessera-projector-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(mDir);
  }
  void TearDown() override { fs::remove_all(mDir); }

  /// The pass on the GPU: `picture` in, the projector's picture out.
  static Image project(const ProjectorMap& map, const Image& picture) {
    GlBuffer in(picture.rgba.size(), picture.rgba.data());
    ProjectorPass pass(map);
    pass.run(in.name());
    return pass.read();
  }

  static GlContext* sContext;
  fs::path mDir;
};
GlContext* ProjectorTest::sContext = nullptr;

/// A smooth picture of the screen: colour as a function of the point on the wall plane.
glm::dvec3 screenColour(const glm::dvec2& p) {
  return {0.5 + 0.45 * std::sin(p.x * 3.1 + 0.4), 0.5 + 0.45 * std::cos(p.y * 4.3 + p.x),
          0.5 + 0.4 * std::sin(p.x * 2.0 + p.y * 5.0)};
}

/// What a tile's render shows of screenColour(): its pixel centres on the wall plane.
Image renderTile(const config::Tile& t) {
  Image img;
  img.width = t.pixel_width();
  img.height = t.pixel_height();
  img.rgba.resize(size_t(img.width) * img.height * 4);
  for (uint32_t y = 0; y < img.height; ++y)
    for (uint32_t x = 0; x < img.width; ++x) {
      const glm::dvec2 p(t.x() + (x + 0.5) * t.width() / img.width,
                         t.y() + t.height() - (y + 0.5) * t.height() / img.height);
      const glm::dvec3 c = screenColour(p);
      uint8_t* px = &img.rgba[(size_t(y) * img.width + x) * 4];
      for (int k = 0; k < 3; ++k) px[k] = uint8_t(std::lround(c[k] * 255));
      px[3] = 255;
    }
  return img;
}

/// Two projectors of 1.2 x 0.6 m at 100 pixels a metre overlapping by 0.4 m.
config::WallConfig overlappingPair(const std::string& extra = "") {
  return sync::parseWallConfig(
      R"({"eye": {"x": 1, "y": 0.3, "z": 2}, "tiles": [
        {"name": "a", "x": 0, "y": 0, "width": 1.2, "height": 0.6, "pixelWidth": 120,
         "pixelHeight": 60, "blend": "auto")" + extra + R"(},
        {"name": "b", "x": 0.8, "y": 0, "width": 1.2, "height": 0.6, "pixelWidth": 120,
         "pixelHeight": 60, "blend": "auto")" + extra + R"(}]})",
      "pair.json");
}

TEST_F(ProjectorTest, OverAnOverlapTheBlendedProjectorsSumToOneProjectorsLight) {
  const config::WallConfig wall = overlappingPair();
  const std::vector<ProjectorMap> maps = loadProjectorMaps(wall);
  ASSERT_EQ(maps[0].blend.size(), 120u * 60);
  const Image a = renderTile(wall.tiles(0)), b = renderTile(wall.tiles(1));
  const Image pa = project(maps[0], a), pb = project(maps[1], b);
  // The GPU pass is the CPU reference's.
  const Image ref = applyProjector(maps[0], a);
  for (size_t i = 0; i < ref.rgba.size(); ++i)
    ASSERT_NEAR(pa.rgba[i], ref.rgba[i], 1) << i;
  const double g = 2.2;
  double worst_linear = 0, worst_display = 0;
  int overlap = 0;
  for (uint32_t y = 0; y < 60; ++y) {
    for (uint32_t x = 0; x < 120; ++x) {
      const size_t ia = (size_t(y) * 120 + x) * 4;
      if (x < 80) {  // a alone: unchanged
        for (int k = 0; k < 3; ++k) ASSERT_EQ(pa.rgba[ia + k], a.rgba[ia + k]);
        continue;
      }
      ++overlap;
      const size_t ib = (size_t(y) * 120 + x - 80) * 4;  // the same point in b
      for (int k = 0; k < 3; ++k) {
        ASSERT_EQ(a.rgba[ia + k], b.rgba[ib + k]);
        const double one = std::pow(a.rgba[ia + k] / 255.0, g);
        const double sum = std::pow(pa.rgba[ia + k] / 255.0, g) + std::pow(pb.rgba[ib + k] / 255.0, g);
        worst_linear = std::max(worst_linear, std::abs(sum - one));
        worst_display = std::max(worst_display, std::abs(std::pow(sum, 1 / g) - std::pow(one, 1 / g)));
      }
    }
  }
  EXPECT_EQ(overlap, 40 * 60);
  std::printf("blend: over the overlap the sum of two projectors differs from one by at most "
              "%.3f/255 in linear light, %.3f/255 as display values\n",
              worst_linear * 255, worst_display * 255);
  // The weights sum to 1 at every point of the overlap.
  for (uint32_t y = 0; y < 60; ++y)
    for (uint32_t x = 80; x < 120; ++x)
      ASSERT_NEAR(maps[0].blend[y * 120 + x] + maps[1].blend[y * 120 + x - 80], 1.0, 1e-6);
  // What reaches the screen is 8-bit: each projector's value is rounded by up to half a level,
  // which costs up to gamma / 2 levels of light at full brightness (0.75 at the weight 0.5).
  // As display values (the summed light in the projectors' gamma) the sum is within 1/255.
  EXPECT_LE(worst_display, 1.0 / 255);
  EXPECT_LE(worst_linear, 1.5 / 255);
  // The ramps: a's weight falls from 1 to 0 across the overlap, b's rises.
  EXPECT_NEAR(maps[0].blend[30 * 120 + 79], 1.0, 0.03);
  EXPECT_NEAR(maps[0].blend[30 * 120 + 100], 0.5, 0.05);
  EXPECT_EQ(maps[0].blend[30 * 120 + 119], 0.0f);  // the edge pixel is dark
}

TEST_F(ProjectorTest, AnIdentityWarpChangesNothing) {
  ProjectorMap map;
  map.width = 97;
  map.height = 61;
  map.grid_width = 5;
  map.grid_height = 4;
  for (uint32_t j = 0; j < 4; ++j)
    for (uint32_t i = 0; i < 5; ++i) map.warp.push_back(glm::vec2(i / 4.0f, j / 3.0f));
  Image picture;
  picture.width = 97;
  picture.height = 61;
  for (size_t i = 0; i < size_t(97) * 61; ++i) {
    const uint32_t h = uint32_t(i * 2654435761u);
    picture.rgba.insert(picture.rgba.end(),
                        {uint8_t(h >> 8), uint8_t(h >> 16), uint8_t(h >> 24), 255});
  }
  EXPECT_EQ(project(map, picture).rgba, picture.rgba);
  ProjectorMap none;
  none.width = 97;
  none.height = 61;
  EXPECT_EQ(project(none, picture).rgba, picture.rgba);
  // A blend of 1 everywhere changes nothing either.
  map.blend.assign(size_t(97) * 61, 1.0f);
  EXPECT_EQ(project(map, picture).rgba, picture.rgba);
}

TEST_F(ProjectorTest, AKeystoneWarpCarriesPointsWhereItsGridSays) {
  // The projector's top edge lands narrower than its bottom edge (a projector tilted up).
  ProjectorMap map;
  map.width = map.height = 256;
  map.grid_width = map.grid_height = 2;
  map.warp = {{0.15f, 0.05f}, {0.85f, 0.05f}, {-0.1f, 1.0f}, {1.1f, 1.0f}};
  // The picture's red is its column, green its row: what a projector pixel shows says where it
  // landed.
  Image picture;
  picture.width = picture.height = 256;
  for (uint32_t y = 0; y < 256; ++y)
    for (uint32_t x = 0; x < 256; ++x)
      picture.rgba.insert(picture.rgba.end(), {uint8_t(x), uint8_t(y), 0, 255});
  const Image out = project(map, picture);
  int checked = 0;
  for (uint32_t y = 3; y < 256; y += 7) {
    for (uint32_t x = 1; x < 256; x += 5) {
      const glm::dvec2 st((x + 0.5) / 256, (y + 0.5) / 256);
      // By hand: bilinear between the four corners.
      const glm::dvec2 top = glm::mix(glm::dvec2(0.15, 0.05), glm::dvec2(0.85, 0.05), st.x),
                       bottom = glm::mix(glm::dvec2(-0.1, 1.0), glm::dvec2(1.1, 1.0), st.x);
      const glm::dvec2 uv = glm::mix(top, bottom, st.y);
      const glm::dvec2 where = uv * 256.0 - 0.5;  // in the picture's pixels
      if (where.x < 0 || where.y < 0 || where.x > 255 || where.y > 255) continue;
      if (uv.x < 0 || uv.x > 1) continue;
      const uint8_t* p = &out.rgba[(size_t(y) * 256 + x) * 4];
      ASSERT_NEAR(p[0], where.x, 0.51) << x << "," << y;
      ASSERT_NEAR(p[1], where.y, 0.51) << x << "," << y;
      // The inverse finds the projector point again.
      const auto back = WarpInverse(map)(uv);
      ASSERT_TRUE(back);
      ASSERT_NEAR(back->x, st.x, 1e-6);  // the grid's vertices are floats
      ASSERT_NEAR(back->y, st.y, 1e-6);
      ++checked;
    }
  }
  EXPECT_GT(checked, 1500);
  // Pixels landing off the screen are black; screen points outside the footprint are reached
  // by no pixel.
  EXPECT_EQ(out.rgba[(size_t(255) * 256 + 0) * 4], 0);
  EXPECT_EQ(out.rgba[(size_t(255) * 256 + 0) * 4 + 1], 0);
  EXPECT_FALSE(WarpInverse(map)(glm::dvec2(0.02, 0.02)));
}

void writeBytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                              std::streamsize(bytes.size()));
}

TEST_F(ProjectorTest, WarpedAndBlendedProjectorsRecomposeTheScreen) {
  writeBytes(mDir / "a.pfm", writePfm(wavyWarp(17, 9, 0.0)));
  writeBytes(mDir / "b.pfm", writePfm(wavyWarp(13, 7, 1.3)));
  config::WallConfig wall = overlappingPair();
  wall.mutable_tiles(0)->set_warp((mDir / "a.pfm").string());
  wall.mutable_tiles(1)->set_warp((mDir / "b.pfm").string());
  ASSERT_TRUE(hasProjectors(wall));
  const std::vector<ProjectorMap> maps = loadProjectorMaps(wall);
  const std::vector<Image> pictures = {project(maps[0], renderTile(wall.tiles(0))),
                                       project(maps[1], renderTile(wall.tiles(1)))};
  // The master's screenshot is the recomposed screen.
  const Image screen = assembleWallMosaic(wall, pictures);
  ASSERT_EQ(screen.width, 200u);
  ASSERT_EQ(screen.height, 60u);
  // The screen as one render shows screenColour() at its pixel centres; compare where both
  // projectors' footprints (their rectangles less the warp's margins) reach.
  double sum = 0, worst = 0;
  int n = 0;
  for (uint32_t y = 4; y < 56; ++y)
    for (uint32_t x = 5; x < 195; ++x) {
      const glm::dvec3 c = screenColour({(x + 0.5) / 100.0, 0.6 - (y + 0.5) / 100.0});
      for (int k = 0; k < 3; ++k) {
        const double d = std::abs(screen.rgba[(size_t(y) * 200 + x) * 4 + k] - c[k] * 255);
        sum += d;
        worst = std::max(worst, d);
        ++n;
      }
    }
  std::printf("recomposed screen against one render: mean %.3f, largest %.2f levels of 255\n",
              sum / n, worst);
  EXPECT_LT(sum / n, 1.0);
  EXPECT_LT(worst, 4.0);
}

/// Writes a zip of (name, bytes) entries.
void writeZip(const fs::path& path,
              const std::vector<std::pair<std::string, std::vector<uint8_t>>>& entries) {
  int err = 0;
  zip_t* z = zip_open(path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
  ASSERT_NE(z, nullptr);
  for (const auto& [name, bytes] : entries) {
    zip_source_t* s = zip_source_buffer(z, bytes.data(), bytes.size(), 0);
    ASSERT_GE(zip_file_add(z, name.c_str(), s, ZIP_FL_OVERWRITE), 0);
  }
  ASSERT_EQ(zip_close(z), 0);
}

std::vector<uint8_t> readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

std::vector<uint8_t> text(const std::string& s) {
  return std::vector<uint8_t>(s.begin(), s.end());
}

std::string mpcdiXml(const std::string& profile, uint32_t xres) {
  return R"(<?xml version="1.0" encoding="utf-8"?>
<MPCDI profile=")" + profile + R"(" geometry="1" version="1.0">
  <display><buffer id="buffer" xResolution="240" yResolution="60">
    <region id="a" x="0" y="0" xsize="0.5" ysize="1" xResolution=")" + std::to_string(xres) + R"(" yResolution="60"/>
    <region id="b" x="0.5" y="0" xsize="0.5" ysize="1" xResolution="120" yResolution="60"/>
  </buffer></display>
  <files>
    <fileset region="a">
      <geometryWarpFile><path>a.pfm</path><interpolation>linear</interpolation></geometryWarpFile>
      <alphaMap><path>a_alpha.png</path><componentDepth>1</componentDepth><bitDepth>8</bitDepth><gammaEmbedded>2.2</gammaEmbedded></alphaMap>
    </fileset>
    <fileset region="b">
      <geometryWarpFile><path>b.pfm</path></geometryWarpFile>
    </fileset>
  </files>
</MPCDI>
)";
}

TEST_F(ProjectorTest, AnMpcdiFileWrittenHereReadsBack) {
  const FloatImage wa = wavyWarp(9, 5, 0.2), wb = wavyWarp(5, 3, 0.7);
  // The alpha map: a ramp across, gamma 2.2 embedded.
  Image alpha;
  alpha.width = 120;
  alpha.height = 60;
  for (uint32_t y = 0; y < 60; ++y)
    for (uint32_t x = 0; x < 120; ++x) {
      const uint8_t v = uint8_t(x * 2);
      alpha.rgba.insert(alpha.rgba.end(), {v, v, v, 255});
    }
  writePng((mDir / "alpha.png").string(), alpha);
  const fs::path file = mDir / "pair.mpcdi";
  writeZip(file, {{"mpcdi.xml", text(mpcdiXml("2d", 120))},
                  {"a.pfm", writePfm(wa)},
                  {"b.pfm", writePfm(wb)},
                  {"a_alpha.png", readBytes(mDir / "alpha.png")}});
  config::WallConfig wall = overlappingPair();
  for (auto& t : *wall.mutable_tiles()) t.clear_blend();
  wall.set_mpcdi(file.string());
  const std::vector<ProjectorMap> maps = loadProjectorMaps(wall);
  ASSERT_EQ(maps[0].grid_width, 9u);
  ASSERT_EQ(maps[0].grid_height, 5u);
  ASSERT_EQ(maps[1].grid_width, 5u);
  for (size_t i = 0; i < maps[0].warp.size(); ++i) {
    EXPECT_EQ(maps[0].warp[i].x, wa.values[i * 3]);
    EXPECT_EQ(maps[0].warp[i].y, wa.values[i * 3 + 1]);
  }
  ASSERT_EQ(maps[0].blend.size(), 120u * 60);
  EXPECT_TRUE(maps[1].blend.empty());
  for (uint32_t x = 0; x < 120; x += 7)
    EXPECT_NEAR(maps[0].blend[30 * 120 + x], std::pow(x * 2 / 255.0, 2.2), 0.01) << x;

  // A 3d profile's warp holds points of the screen: the same (u, v) through the eye.
  FloatImage w3 = wa;
  const config::Tile& t = wall.tiles(0);
  for (size_t i = 0; i < w3.values.size(); i += 3) {
    const double u = w3.values[i], v = w3.values[i + 1];
    w3.values[i] = float(t.x() + u * t.width());
    w3.values[i + 1] = float(t.y() + (1 - v) * t.height());
    w3.values[i + 2] = 0.0f;
  }
  writeZip(file, {{"mpcdi.xml", text(mpcdiXml("3d", 120))},
                  {"a.pfm", writePfm(w3)},
                  {"b.pfm", writePfm(wb)},
                  {"a_alpha.png", readBytes(mDir / "alpha.png")}});
  const std::vector<ProjectorMap> maps3 = loadProjectorMaps(wall);
  for (size_t i = 0; i < maps3[0].warp.size(); ++i) {
    EXPECT_NEAR(maps3[0].warp[i].x, wa.values[i * 3], 1e-5);
    EXPECT_NEAR(maps3[0].warp[i].y, wa.values[i * 3 + 1], 1e-5);
  }
}

void expectRefused(const config::WallConfig& wall, const std::string& what) {
  try {
    loadProjectorMaps(wall);
    ADD_FAILURE() << "accepted, expected: " << what;
  } catch (const RenderError& e) {
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
  }
}

TEST_F(ProjectorTest, BadFilesAreRefusedByNameAndField) {
  config::WallConfig wall = overlappingPair();
  const std::string pfm = (mDir / "bad.pfm").string();
  // NaN in a warp.
  FloatImage w = wavyWarp(4, 3, 0);
  w.values[7] = NAN;
  writeBytes(pfm, writePfm(w));
  wall.mutable_tiles(1)->set_warp(pfm);
  expectRefused(wall, "bad.pfm: tiles[1].warp: value 7 of row 2 (from the bottom) is not finite");
  // Too short.
  std::vector<uint8_t> bytes = writePfm(wavyWarp(4, 3, 0));
  bytes.resize(bytes.size() - 4);
  writeBytes(pfm, bytes);
  expectRefused(wall, "bad.pfm: tiles[1].warp: 4 x 3 x 3 floats need 144 bytes of data, the file has 140");
  // One channel.
  FloatImage one;
  one.width = 4;
  one.height = 3;
  one.channels = 1;
  one.values.assign(12, 0.5f);
  writeBytes(pfm, writePfm(one));
  expectRefused(wall, "bad.pfm: tiles[1].warp: a warp needs three channels");
  // Not a PFM at all, a missing one.
  writeBytes(pfm, text("P6\n4 3\n255\n"));
  expectRefused(wall, "bad.pfm: tiles[1].warp: not a PFM");
  wall.mutable_tiles(1)->set_warp((mDir / "missing.pfm").string());
  expectRefused(wall, "missing.pfm: tiles[1].warp: cannot open");
  wall.mutable_tiles(1)->clear_warp();
  // A blend PNG of the wrong size.
  Image small;
  small.width = small.height = 8;
  small.rgba.assign(8 * 8 * 4, 255);
  writePng((mDir / "mask.png").string(), small);
  wall.mutable_tiles(0)->set_blend((mDir / "mask.png").string());
  expectRefused(wall, "mask.png: tiles[0].blend: is 8 x 8 pixels; the tile's projector has 120 x 60");
  writeBytes(mDir / "mask.png", text("not a png"));
  expectRefused(wall, "mask.png: tiles[0].blend: not a PNG");
  wall.mutable_tiles(0)->set_blend("auto");
  // MPCDI: not a zip, no mpcdi.xml, a missing element, a wrong profile, a wrong resolution.
  const fs::path file = mDir / "bad.mpcdi";
  wall.set_mpcdi(file.string());
  writeBytes(file, text("this is no zip"));
  expectRefused(wall, "bad.mpcdi: not a readable MPCDI zip");
  writeZip(file, {{"other.xml", text("<x/>")}});
  expectRefused(wall, "bad.mpcdi: mpcdi.xml: the zip has no file 'mpcdi.xml'");
  writeZip(file, {{"mpcdi.xml", text("<MPCDI profile=\"2d\"><files/></MPCDI>")}});
  expectRefused(wall, "bad.mpcdi: MPCDI/display: missing element");
  writeZip(file, {{"mpcdi.xml", text("<MPCDI profile=\"a4\"><display/><files/></MPCDI>")}});
  expectRefused(wall, "bad.mpcdi: MPCDI@profile: is 'a4'");
  writeZip(file, {{"mpcdi.xml", text(mpcdiXml("2d", 100))}});
  expectRefused(wall, "bad.mpcdi: region 'a'@xResolution: 100 x 60 but tile 'a' has 120 x 60");
  writeZip(file, {{"mpcdi.xml", text(mpcdiXml("2d", 120))}, {"b.pfm", writePfm(wavyWarp(4, 3, 0))}});
  expectRefused(wall, "bad.mpcdi: fileset 'a'/geometryWarpFile a.pfm: the zip has no file 'a.pfm'");
}

}  // namespace
// The PFM fuzz target's seeds read, and every input it kept (fuzz/regressions/pfm) and a few
// made here pass its checks: a RenderError or a map holding exactly its values.
TEST(ProjectorFuzz, PfmSeedsReadAndRegressionsPassTheFuzzChecks) {
  namespace fs = std::filesystem;
  auto bytesOf = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
  };
  size_t seeds = 0;
  for (const auto& e : fs::directory_iterator(fs::path(TESSERA_FUZZ_SEEDS) / "pfm")) {
    const std::vector<uint8_t> b = bytesOf(e.path());
    EXPECT_NO_THROW(render::readPfm(b, e.path().string())) << e.path();
    ++seeds;
  }
  EXPECT_GE(seeds, 2u);
  const fs::path kept = fs::path(TESSERA_FUZZ_REGRESSIONS) / "pfm";
  if (fs::exists(kept))
    for (const auto& e : fs::directory_iterator(kept)) {
      const std::vector<uint8_t> b = bytesOf(e.path());
      tessera::fuzz::readPfm(b.data(), b.size());
    }
  for (const std::string text : {std::string("PF\n4 3\n-1\n"), std::string("Pf\n65537 1\n-1\n"),
                                 std::string("PF\n-3 2\n-1\n"),
                                 std::string("PF\n99999999999999999999 1\n-1\n"), std::string("P")}) {
    const std::vector<uint8_t> b(text.begin(), text.end());
    tessera::fuzz::readPfm(b.data(), b.size());
    EXPECT_THROW(render::readPfm(b, "made.pfm"), render::RenderError) << text;
  }
}

}  // namespace tessera::render
