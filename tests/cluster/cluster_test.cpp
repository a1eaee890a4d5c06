// The cluster as a user starts it: mpirun with tessera-master and 2 or 4 headless tessera-nodes
// on a store of the real bunny scans. The wall screenshot must be pixel-identical to
// `tessera-render --mosaic` of the same scene and camera; failures must end the job non-zero
// with a message saying what and where (ctest's TIMEOUT catches a hang: tests never time).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <regex>
#include <string>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/render/image.h>
#include <tessera/render/projector_pass.h>

#include "../support/command.h"
#include "../support/decoded_movie.h"
#include "../support/temp_dir.h"
#include "../support/wavy_warp.h"

namespace {

namespace fs = std::filesystem;
const std::string kData = TESSERA_DATA_DIR;
const std::string kConfigs = TESSERA_CONFIG_DIR;

using tessera::test::CommandResult;

CommandResult run(const std::string& command) {
  return tessera::test::runCommand(command);
}

std::string mpirun() {
  // Oversubscribed: this machine has 2 cores for 3 to 5 processes.
  std::string m = std::string(TESSERA_MPIRUN) + " --oversubscribe";
  if (getuid() == 0) m += " --allow-run-as-root";
  return m;
}

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

/// The scene of configs/scenes/bunny.json with the store replaced and the given shading.
std::string sceneJson(const std::string& store, const std::string& shading = "edl") {
  return R"({"nodes": [{"kind": "MODEL", "name": "bunny scans", "model": {"store": ")" + store +
         R"("}}], "camera": {"eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027,
         "y": 0.1, "z": 0.0}, "up": {"x": 0, "y": 1, "z": 0}}, "settings": {"background": {"r":
         0.05, "g": 0.05, "b": 0.08}, "lodPixels": 1.0, "shading": ")" +
         (shading == "edl" ? "SHADING_EDL" : "SHADING_COLOR") + R"("}})";
}

class Cluster : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new tessera::test::TempDir();
    const CommandResult r =
        run(std::string(TESSERA_LOD_TOOL) + " build " + kData +
            "/stanford-bunny/scans/bun.conf -o " + (*sDir / "bunny.tlod").string() + " --quiet");
    ASSERT_EQ(r.code, 0) << r.out;
    write(*sDir / "scene.json", sceneJson("bunny.tlod"));
    write(*sDir / "scene-color.json", sceneJson("bunny.tlod", "color"));
    // Relative depth and contour lines over eye-dome lighting: kernels that reach across the
    // tiles' edges and a colour range the tiles must agree on.
    std::string analysis = sceneJson("bunny.tlod");
    analysis.replace(analysis.rfind("}}"), 2,
                     R"(, "analysis": {"relativeDepthRadius": 20, "contourInterval": 0.004, )"
                     R"("aoStrength": 1.0}}})");
    write(*sDir / "scene-analysis.json", analysis);
  }
  static void TearDownTestSuite() {
    delete sDir;
    sDir = nullptr;
  }

  /// mpirun master ARGS : K nodes, from the suite's folder, after `prefix` (environment, a
  /// wrapper such as xvfb-run).
  static CommandResult cluster(const std::string& master_args, int nodes,
                               const std::string& prefix = "") {
    return run("cd " + sDir->path().string() + " && " + prefix + mpirun() + " -np 1 " +
               TESSERA_MASTER + " " + master_args + " : -np " + std::to_string(nodes) + " " +
               TESSERA_NODE + " --headless");
  }

  /// tessera-render --mosaic of `scene` on `wall` with the camera the master printed for `png`.
  static void expectSameAsMosaic(const CommandResult& r, const std::string& png,
                                 const std::string& wall, const std::string& scene,
                                 const std::string& extra = "") {
    const std::regex line("wrote (\\S*" + png + ") \\(\\d+x\\d+\\); camera (\\S+)");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(r.out, m, line)) << r.out;
    const fs::path mosaic = *sDir / ("mosaic-" + png);
    const CommandResult ref = run("cd " + sDir->path().string() + " && " + TESSERA_RENDER_TOOL +
                                  " --scene " + scene + " --wall " + wall + " --mosaic --camera '" +
                                  m[2].str() + "' -o " + mosaic.string() + extra);
    ASSERT_EQ(ref.code, 0) << ref.out;
    const auto wall_png = tessera::test::readBytes(sDir->path() / m[1].str());
    const auto ref_png = tessera::test::readBytes(mosaic);
    ASSERT_FALSE(wall_png.empty());
    // Same encoder, same settings: equal files are equal pixels, and different pixels give
    // different files.
    EXPECT_TRUE(wall_png == ref_png)
        << png << " differs from tessera-render --mosaic (" << wall_png.size() << " against "
        << ref_png.size() << " bytes)";
  }

  /// The cluster started with `master_args` and `nodes` nodes stops before rendering, saying
  /// `says`.
  static void expectRefusedAtStart(const std::string& master_args, int nodes,
                                   const std::string& says) {
    const CommandResult r = cluster(master_args, nodes);
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.out.find(says), std::string::npos) << r.out;
  }

  /// sceneJson("bunny.tlod") with `settings` (", \"inset\": ...") added to its settings, written
  /// as `name` in the suite's folder.
  static void writeSceneWith(const std::string& name, const std::string& settings) {
    std::string scene = sceneJson("bunny.tlod");
    scene.replace(scene.rfind("}}"), 2, settings + "}}");
    write(sDir->path() / name, scene);
  }

  static tessera::test::TempDir* sDir;
};
tessera::test::TempDir* Cluster::sDir = nullptr;

TEST_F(Cluster, TwoNodesWallScreenshotIsTheMosaic) {
  const std::string wall = kConfigs + "/walls/1x2.json";
  const CommandResult r = cluster("--wall " + wall +
                                      " --scene scene.json --frames 3 --screenshot two.png "
                                      "--stats two.csv",
                                  2);
  ASSERT_EQ(r.code, 0) << r.out;
  expectSameAsMosaic(r, "two.png", wall, "scene.json");
  // One row per rank and frame: master + 2 nodes, 3 frames.
  std::ifstream csv(sDir->path() / "two.csv");
  std::string row;
  int rows = 0, node_rows_with_points = 0;
  std::getline(csv, row);
  EXPECT_EQ(row.rfind("frame,time_s,rank,tile,", 0), 0u) << row;
  while (std::getline(csv, row)) {
    ++rows;
    if ((row.find(",left,") != std::string::npos || row.find(",right,") != std::string::npos) &&
        row.find(",0,0,0,0,0,0") == std::string::npos)
      ++node_rows_with_points;
  }
  EXPECT_EQ(rows, 9);
  EXPECT_EQ(node_rows_with_points, 6);
}

// Ambient occlusion, relative depth and contour lines over eye-dome lighting: each node draws
// its tile with the guard band the filters reach and the relative depth range
// the master agreed from the tiles' last reports: the wall shows one picture, the same as
// tessera-render --mosaic, whose tiles agree on their range the same way.
TEST_F(Cluster, TheAnalysisFiltersAreOnePictureAcrossTheTiles) {
  const std::string wall = kConfigs + "/walls/1x2.json";
  const CommandResult r = cluster(
      "--wall " + wall + " --scene scene-analysis.json --frames 3 --screenshot rd.png", 2);
  ASSERT_EQ(r.code, 0) << r.out;
  expectSameAsMosaic(r, "rd.png", wall, "scene-analysis.json");
}

TEST_F(Cluster, AMeshBesideTheScansOnTheWallIsTheMosaic) {
  // The bunny's reconstruction as a .tmesh beside its scans: every node cuts and streams the
  // patches its own tile needs; the wall screenshot is tessera-render --mosaic's, pixel for pixel.
  const CommandResult b =
      run(std::string(TESSERA_LOD_TOOL) + " build " + kData +
          "/stanford-bunny/reconstruction/bun_zipper.ply -o " + (*sDir / "bunny.tmesh").string() +
          " --patch-triangles 1024 --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  write(*sDir / "mesh.json",
        R"({"nodes": [{"kind": "MODEL", "model": {"store": "bunny.tlod"}},
            {"kind": "MODEL", "transform": {"m": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0.17,0,0,1]},
             "model": {"store": "bunny.tmesh", "color": {"r": 0.85, "g": 0.75, "b": 0.6}}}],
            "camera": {"eye": {"x": 0.068, "y": 0.14, "z": 0.52}, "target": {"x": 0.068,
            "y": 0.1, "z": 0.0}, "up": {"x": 0, "y": 1, "z": 0}}, "settings": {"background":
            {"r": 0.05, "g": 0.05, "b": 0.08}, "lodPixels": 1.0, "shading": "SHADING_EDL"}})");
  const std::string wall = kConfigs + "/walls/2x2.json";
  const CommandResult r = cluster(
      "--wall " + wall + " --scene mesh.json --frames 2 --screenshot mesh.png --stats mesh.csv", 4);
  ASSERT_EQ(r.code, 0) << r.out;
  expectSameAsMosaic(r, "mesh.png", wall, "mesh.json");
  const tessera::render::Image img = tessera::render::readPng((sDir->path() / "mesh.png").string());
  // The mesh (warm beige) covers its half of the wall: many pixels with red well above blue.
  size_t warm = 0;
  for (size_t i = 0; i + 3 < img.rgba.size(); i += 4)
    warm += img.rgba[i] > 60 && img.rgba[i] > img.rgba[i + 2] + 25;
  EXPECT_GT(warm, 50000u);
}

TEST_F(Cluster, SketchesAvatarsAndAnnotationsAreDrawnOnEveryTile) {
  // The scene overlay (render/scene_overlay.h) on the nodes' settled frames: a magenta stroke in
  // front of the bunny across the bezel, a remote site's avatar and a note. The wall screenshot
  // is tessera-render --mosaic's, and the stroke shows on both tiles.
  std::string stroke;
  for (int k = 0; k <= 20; ++k) {
    const double t = k / 20.0;
    char xyz[96];
    std::snprintf(xyz, sizeof xyz, "%s%.6f, %.6f, 0.065", k ? ", " : "", -0.1 + 0.15 * t,
                  0.08 + 0.04 * std::sin(3.0 * t));
    stroke += xyz;
  }
  const glm::dmat4 pose = glm::inverse(
      glm::lookAt(glm::dvec3(0.07, 0.16, 0.17), glm::dvec3(-0.027, 0.1, 0.0), glm::dvec3(0, 1, 0)));
  std::string m;
  for (int i = 0; i < 16; ++i) {
    char v[40];
    std::snprintf(v, sizeof v, "%s%.17g", i ? ", " : "", pose[i / 4][i % 4]);
    m += v;
  }
  std::string scene = sceneJson("bunny.tlod", "color");
  scene.insert(scene.find("}}]") + 2,
               R"(, {"kind": "SKETCH", "sketch": {"points": [)" + stroke +
                   R"(], "color": {"r": 1, "g": 0, "b": 1}, "width": 4}},
               {"kind": "AVATAR", "name": "pisa", "transform": {"m": [)" +
                   m +
                   R"(]}, "avatar": {"site": "Pisa", "color": {"r": 0.2, "g": 0.9, "b": 0.4},
               "fovyDeg": 40, "aspect": 1.5, "reach": 0.07}},
               {"kind": "ANNOTATION", "annotation": {"text": "left ear 左耳 الأذن Ναός 🐇", "anchor": {"x": -0.07,
               "y": 0.15, "z": 0.03}}})");
  write(sDir->path() / "overlay.json", scene);
  const std::string wall = kConfigs + "/walls/1x2.json";
  const CommandResult r =
      cluster("--wall " + wall + " --scene overlay.json --frames 2 --screenshot ov.png", 2);
  ASSERT_EQ(r.code, 0) << r.out;
  // The note's title in four scripts and an emoji, each from a font that has it, on the wall.
  EXPECT_EQ(r.out.find("no installed font has"), std::string::npos) << r.out;
  expectSameAsMosaic(r, "ov.png", wall, "overlay.json");
  const tessera::render::Image img = tessera::render::readPng((sDir->path() / "ov.png").string());
  size_t left = 0, right = 0, avatar = 0;
  for (uint32_t y = 0; y < img.height; ++y) {
    for (uint32_t x = 0; x < img.width; ++x) {
      const uint8_t* p = &img.rgba[(size_t(y) * img.width + x) * 4];
      if (p[0] > 230 && p[1] < 30 && p[2] > 230) (x < img.width / 2 ? left : right) += 1;
      avatar += p[0] < 80 && p[1] > 200 && p[2] > 80 && p[2] < 130;
    }
  }
  EXPECT_GT(left, 300u);
  EXPECT_GT(right, 300u);
  EXPECT_GT(avatar, 100u);
}

TEST_F(Cluster, FourNodesFollowTheScriptAndMatchTheMosaic) {
  // Two keyframes (a straight move), shading switched to plain colour after the first frame, a
  // screenshot by the script at frame 3 (t = 2/60 s) and one by --screenshot at the last.
  write(sDir->path() / "path.json", R"({"name": "test move", "keyframes": [
    {"time": 0, "eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027, "y": 0.1, "z": 0},
     "up": {"x": 0, "y": 1, "z": 0}},
    {"time": 0.1, "eye": {"x": 0.05, "y": 0.14, "z": 0.33}, "target": {"x": -0.027, "y": 0.1, "z": 0},
     "up": {"x": 0, "y": 1, "z": 0}}],
    "actions": [{"time": 0.01, "setShading": "color"}, {"time": 0.03, "screenshot": "mid.png"}]})");
  const std::string wall = kConfigs + "/walls/2x2.json";
  const CommandResult r = cluster("--wall " + wall +
                                      " --scene scene.json --script path.json --frames 5 "
                                      "--screenshot last.png",
                                  4);
  ASSERT_EQ(r.code, 0) << r.out;
  expectSameAsMosaic(r, "mid.png", wall, "scene-color.json");
  expectSameAsMosaic(r, "last.png", wall, "scene-color.json");
  EXPECT_NE(r.out.find("frame 3: wrote ./mid.png"), std::string::npos) << r.out;
}

/// Two 320x180 tiles (0.48 x 0.27 m, a 2 cm bezel) and a mono foveal inset of 0.24 x 0.09 m at
/// twice their density over the bezel, near the top.
const std::string kInsetWall = R"({"name": "1x2 and a fovea", "tiles": [
  {"name": "left", "x": 0, "y": 0, "width": 0.48, "height": 0.27, "pixelWidth": 320,
   "pixelHeight": 180},
  {"name": "right", "x": 0.5, "y": 0, "width": 0.48, "height": 0.27, "pixelWidth": 320,
   "pixelHeight": 180}],
  "insets": [{"name": "fovea", "x": 0.37, "y": 0.17, "width": 0.24, "height": 0.09,
              "pixelWidth": 320, "pixelHeight": 120}],
  "eye": {"x": 0.49, "y": 0.135, "z": 1.5}})";

bool bezelGrey(const tessera::render::Image& img, uint32_t x, uint32_t y) {
  const uint8_t* p = &img.rgba[(size_t(y) * img.width + x) * 4];
  return p[0] == 24 && p[1] == 24 && p[2] == 24;
}

TEST_F(Cluster, AFovealInsetNodeAndTwoTilesMakeTheMosaic) {
  // Three nodes: the two context tiles and the inset (a slot named "fovea"). The context is
  // black under the inset, the inset cross-fades over the band; the master's screenshot and
  // the inset's own picture are tessera-render --mosaic's, byte for byte.
  write(sDir->path() / "inset-wall.json", kInsetWall);
  const CommandResult r =
      cluster("--wall inset-wall.json --scene scene.json --frames 3 --screenshot fov.png", 3);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("tile fovea"), std::string::npos) << r.out;
  expectSameAsMosaic(r, "fov.png", "inset-wall.json", "scene.json");
  EXPECT_NE(r.out.find("wrote fov-inset-fovea.png (320x120); inset fovea at (0.49, 0.215)"),
            std::string::npos)
      << r.out;
  const auto inset = tessera::test::readBytes(sDir->path() / "fov-inset-fovea.png");
  const auto ref = tessera::test::readBytes(sDir->path() / "mosaic-fov-inset-fovea.png");
  ASSERT_FALSE(inset.empty());
  EXPECT_TRUE(inset == ref) << "the inset's picture differs from tessera-render --mosaic's";
}

TEST_F(Cluster, AStereoInsetHasANodePerEyeAndMatchesTheMosaic) {
  // Four nodes: two tiles and the inset's eyes ("fovea/left", "fovea/right"). The screenshot
  // shows the left eye; each eye's picture is written beside it, all as tessera-render's.
  std::string wall = kInsetWall;
  wall.replace(wall.find(R"("pixelHeight": 120})"), 19,
               R"("pixelHeight": 120, "stereo": true, "eyeSeparation": 0.065})");
  write(sDir->path() / "stereo-inset-wall.json", wall);
  const CommandResult r =
      cluster("--wall stereo-inset-wall.json --scene scene.json --frames 2 --screenshot st.png", 4);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("tile fovea/left"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("tile fovea/right"), std::string::npos) << r.out;
  expectSameAsMosaic(r, "st.png", "stereo-inset-wall.json", "scene.json");
  for (const char* eye : {"left", "right"}) {
    const std::string name = std::string("st-inset-fovea-") + eye + ".png";
    const auto inset = tessera::test::readBytes(sDir->path() / name);
    const auto ref = tessera::test::readBytes(sDir->path() / ("mosaic-" + name));
    ASSERT_FALSE(inset.empty()) << name;
    EXPECT_TRUE(inset == ref) << name << " differs from tessera-render --mosaic's";
  }
  // The eyes see the bunny (behind the wall plane) from 6.5 cm apart: different pictures.
  EXPECT_NE(tessera::test::readBytes(sDir->path() / "st-inset-fovea-left.png"),
            tessera::test::readBytes(sDir->path() / "st-inset-fovea-right.png"));
}

TEST_F(Cluster, AScriptedSetInsetMovesTheInsetOnEveryNode) {
  // The inset starts near the top (the scene does not place it) and the script moves it down at
  // t = 0.02 s (frame 2): the bezel it covers (no grey there) follows it.
  write(sDir->path() / "inset-wall.json", kInsetWall);
  write(sDir->path() / "move.json", R"({"name": "move the inset", "keyframes": [
    {"time": 0, "eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027, "y": 0.1,
     "z": 0}, "up": {"x": 0, "y": 1, "z": 0}}],
    "actions": [{"time": 0, "screenshot": "before.png"},
                {"time": 0.02, "setInset": {"name": "fovea", "x": 0.49, "y": 0.055}}]})");
  const CommandResult r = cluster(
      "--wall inset-wall.json --scene scene.json --script move.json --frames 4 "
      "--screenshot moved.png",
      3);
  ASSERT_EQ(r.code, 0) << r.out;
  expectSameAsMosaic(r, "moved.png", "inset-wall.json", "scene.json", " --inset fovea=0.49,0.055");
  EXPECT_NE(r.out.find("inset fovea at (0.49, 0.055)"), std::string::npos) << r.out;
  const tessera::render::Image before =
      tessera::render::readPng((sDir->path() / "before.png").string());
  const tessera::render::Image moved =
      tessera::render::readPng((sDir->path() / "moved.png").string());
  // The bezel is columns 320..332; the inset's rows at the top are 7..66, at the bottom 113..173.
  for (uint32_t x : {324u, 326u, 328u}) {
    EXPECT_FALSE(bezelGrey(before, x, 40)) << x;
    EXPECT_TRUE(bezelGrey(before, x, 143)) << x;
    EXPECT_TRUE(bezelGrey(moved, x, 40)) << x;
    EXPECT_FALSE(bezelGrey(moved, x, 143)) << x;
  }
  // A scene placing the inset off the wall, or placing one the wall lacks, is refused at the
  // start, by field.
  writeSceneWith("off-scene.json",
                 R"(, "inset": {"centres": [{"name": "fovea", "x": 0.1, "y": 0.1}]})");
  expectRefusedAtStart("--wall inset-wall.json --scene off-scene.json --frames 2", 3,
                       "off-scene.json: settings.inset.centres[0]: inset 'fovea' centred at "
                       "(0.1, 0.1)");
  // A setInset that leaves the wall is refused when the script is loaded, by field.
  write(sDir->path() / "off.json", R"({"name": "off", "keyframes": [
    {"time": 0, "eye": {"x": 0, "y": 0, "z": 1}, "target": {"x": 0, "y": 0, "z": 0},
     "up": {"x": 0, "y": 1, "z": 0}}],
    "actions": [{"time": 0, "setInset": {"name": "fovea", "x": 0.9, "y": 0.1}}]})");
  expectRefusedAtStart("--wall inset-wall.json --scene scene.json --script off.json --frames 2", 3,
                       "off.json: actions[0].setInset: inset 'fovea'");
}

/// Two 320x180 tiles (0.48 x 0.27 m, a 2 cm bezel), the viewer's eye 1.5 m in front of the
/// bezel; `extra` goes into the wall's object (stereo).
std::string smallWall(const std::string& extra = "") {
  return R"({"name": "1x2", "tiles": [
  {"name": "left", "x": 0, "y": 0, "width": 0.48, "height": 0.27, "pixelWidth": 320,
   "pixelHeight": 180},
  {"name": "right", "x": 0.5, "y": 0, "width": 0.48, "height": 0.27, "pixelWidth": 320,
   "pixelHeight": 180}],
  "eye": {"x": 0.49, "y": 0.135, "z": 1.5})" +
         extra + "}";
}

TEST_F(Cluster, AScriptedHeadMoveReachesEveryNode) {
  // The head moves 5 cm left, 2.5 cm up and 5 cm nearer and turns 20 degrees at t = 0.02 s
  // (frame 2): both nodes see their tiles from it, so the screenshot is tessera-render --mosaic
  // --head's, byte for byte, and not the picture from the wall's eye.
  write(sDir->path() / "head-wall.json", smallWall());
  write(sDir->path() / "head.json", R"({"name": "move the head", "keyframes": [
    {"time": 0, "eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027, "y": 0.1,
     "z": 0}, "up": {"x": 0, "y": 1, "z": 0}}],
    "actions": [{"time": 0, "screenshot": "from-eye.png"},
                {"time": 0.02, "setHead": {"eye": {"x": 0.44, "y": 0.16, "z": 1.45},
                 "right": {"x": 0.9397, "y": 0, "z": 0.342}, "eyeSeparation": 0.07}}]})");
  const CommandResult r = cluster(
      "--wall head-wall.json --scene scene.json --script head.json --frames 4 "
      "--screenshot head.png",
      2);
  ASSERT_EQ(r.code, 0) << r.out;
  expectSameAsMosaic(r, "head.png", "head-wall.json", "scene.json",
                     " --head 'eye=0.44,0.16,1.45;right=0.9397,0,0.342;separation=0.07'");
  expectSameAsMosaic(r, "from-eye.png", "head-wall.json", "scene.json");
  EXPECT_NE(tessera::test::readBytes(sDir->path() / "from-eye.png"),
            tessera::test::readBytes(sDir->path() / "head.png"));
  // The bunny is still in view from the moved head (light grey on the dark background).
  const tessera::render::Image moved =
      tessera::render::readPng((sDir->path() / "head.png").string());
  size_t light = 0;
  for (size_t i = 0; i + 3 < moved.rgba.size(); i += 4) light += moved.rgba[i] > 120;
  EXPECT_GT(light, 10000u);
  // A setHead behind the wall stops the start, naming the action's field; so does a scene
  // whose head is behind it.
  write(sDir->path() / "behind.json", R"({"name": "behind", "keyframes": [
    {"time": 0, "eye": {"x": 0, "y": 0, "z": 1}, "target": {"x": 0, "y": 0, "z": 0},
     "up": {"x": 0, "y": 1, "z": 0}}],
    "actions": [{"time": 0, "setHead": {"eye": {"x": 0.3, "y": 0.2, "z": -0.4},
                 "right": {"x": 1, "y": 0, "z": 0}}}]})");
  expectRefusedAtStart("--wall head-wall.json --scene scene.json --script behind.json --frames 2",
                       2,
                       "behind.json: actions[0].setHead.eye: the head (0.3, 0.2, -0.4) is behind "
                       "the plane of tiles[0] ('left')");
  // The head 1 cm from the wall, its eyes along the wall's normal: the left one behind it.
  writeSceneWith("behind-scene.json", R"(, "head": {"eye": {"x": 0.49, "y": 0.1, "z": 0.01},
                                         "right": {"x": 0, "y": 0, "z": 1}})");
  expectRefusedAtStart("--wall head-wall.json --scene behind-scene.json --frames 2", 2,
                       "behind-scene.json: settings.head.eye: its left eye");
  // tessera-render refuses the same head on its command line, by field.
  const CommandResult bad_cli = run("cd " + sDir->path().string() + " && " + TESSERA_RENDER_TOOL +
                                    " --scene scene.json --wall head-wall.json --mosaic -o x.png "
                                    "--head 'eye=0.3,0.2,1;right=0,0,0'");
  EXPECT_EQ(bad_cli.code, 2) << bad_cli.out;
  EXPECT_NE(bad_cli.out.find("head.right: the head's right axis must not be zero"),
            std::string::npos)
      << bad_cli.out;
}

TEST_F(Cluster, AStereoWallHasANodePerEyeAndEachEyeIsTheMosaics) {
  // Four nodes, one per tile and eye ("left/left", "left/right", "right/left",
  // "right/right"). The screenshot shows the left eye; each eye's wall is written beside it,
  // equal to tessera-render --mosaic --stereo pair's, and the eyes differ. Then two nodes, each
  // drawing both eyes of its tile.
  write(sDir->path() / "stereo-wall.json",
        smallWall(R"(, "stereo": true, "eyeSeparation": 0.065)"));
  const CommandResult r =
      cluster("--wall stereo-wall.json --scene scene.json --frames 2 --screenshot stw.png", 4);
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* slot : {"left/left", "left/right", "right/left", "right/right"})
    EXPECT_NE(r.out.find(std::string("tile ") + slot), std::string::npos) << slot << r.out;
  EXPECT_TRUE(
      std::regex_search(r.out, std::regex("wrote \\S*stw-left.png \\(\\d+x180\\); the left eye")))
      << r.out;
  EXPECT_TRUE(
      std::regex_search(r.out, std::regex("wrote \\S*stw-right.png \\(\\d+x180\\); the right eye")))
      << r.out;
  expectSameAsMosaic(r, "stw.png", "stereo-wall.json", "scene.json");
  const std::regex line("wrote \\S*stw.png \\(\\d+x\\d+\\); camera (\\S+)");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.out, m, line)) << r.out;
  const CommandResult ref =
      run("cd " + sDir->path().string() + " && " + TESSERA_RENDER_TOOL +
          " --scene scene.json --wall stereo-wall.json --mosaic --stereo pair --camera '" +
          m[1].str() + "' -o mosaic-stw.png");
  ASSERT_EQ(ref.code, 0) << ref.out;
  for (const char* eye : {"left", "right"}) {
    const auto wall_eye =
        tessera::test::readBytes(sDir->path() / ("stw-" + std::string(eye) + ".png"));
    const auto ref_eye =
        tessera::test::readBytes(sDir->path() / ("mosaic-stw-" + std::string(eye) + ".png"));
    ASSERT_FALSE(wall_eye.empty()) << eye;
    EXPECT_TRUE(wall_eye == ref_eye) << eye << " differs from tessera-render --mosaic --stereo's";
  }
  EXPECT_EQ(tessera::test::readBytes(sDir->path() / "stw.png"),
            tessera::test::readBytes(sDir->path() / "stw-left.png"));
  EXPECT_NE(tessera::test::readBytes(sDir->path() / "stw-left.png"),
            tessera::test::readBytes(sDir->path() / "stw-right.png"));

  // One node per tile drawing both eyes side by side into its two outputs (slots "left" and
  // "right", 640x180 each): the same eyes' pictures, byte for byte.
  write(sDir->path() / "pair-wall.json",
        smallWall(R"(, "stereo": true, "eyeSeparation": 0.065, "eyesOnOneNode": true)"));
  const CommandResult p =
      cluster("--wall pair-wall.json --scene scene.json --frames 2 --screenshot pw.png", 2);
  ASSERT_EQ(p.code, 0) << p.out;
  EXPECT_NE(p.out.find("tile left"), std::string::npos) << p.out;
  EXPECT_EQ(p.out.find("tile left/"), std::string::npos) << p.out;
  for (const char* eye : {"left", "right"})
    EXPECT_TRUE(
        tessera::test::readBytes(sDir->path() / ("pw-" + std::string(eye) + ".png")) ==
        tessera::test::readBytes(sDir->path() / ("mosaic-stw-" + std::string(eye) + ".png")))
        << eye << " of the nodes of both eyes differs from tessera-render --mosaic --stereo's";
  EXPECT_EQ(tessera::test::readBytes(sDir->path() / "pw.png"),
            tessera::test::readBytes(sDir->path() / "stw.png"));
}

TEST_F(Cluster, WrongNodeCountStopsBeforeRendering) {
  const CommandResult r = cluster(
      "--wall " + kConfigs + "/walls/2x2.json --scene scene.json --frames 2 --screenshot no.png",
      3);
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("has 4 tiles but 3 render nodes were started"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(sDir->path() / "no.png"));
}

TEST_F(Cluster, NodeWithAnUnreadableStoreSaysWhichAndWhy) {
  write(sDir->path() / "broken.tlod", std::string(4096, 'x'));
  write(sDir->path() / "broken.json", sceneJson("broken.tlod"));
  const CommandResult r =
      cluster("--wall " + kConfigs + "/walls/1x2.json --scene broken.json --frames 2", 2);
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("tile left (host "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("unreadable store"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("broken.tlod: not a Tessera point store"), std::string::npos) << r.out;
}

TEST_F(Cluster, BadSceneJsonNamesFileAndField) {
  write(sDir->path() / "bad.json",
        R"({"nodes": [{"kind": "MODEL", "model": {"store": "bunny.tlod"}, "opacity": 2}],
            "camera": {"eye": {"z": 1}, "target": {}, "up": {"y": 1}}})");
  const CommandResult r =
      cluster("--wall " + kConfigs + "/walls/1x2.json --scene bad.json --frames 2", 2);
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("bad.json: nodes[0] (node 1): opacity"), std::string::npos) << r.out;
}

TEST_F(Cluster, BadScriptNamesFileAndField) {
  write(sDir->path() / "bad-path.json",
        R"({"keyframes": [{"time": 0, "eye": {"x": 0, "y": 0, "z": 1}, "target": {},
            "up": {"y": 1}}], "actions": [{"time": 0, "setOpacity": {"model": "nobody",
            "opacity": 0.5}}]})");
  const CommandResult r = cluster("--wall " + kConfigs +
                                      "/walls/1x2.json --scene scene.json --script bad-path.json "
                                      "--frames 2",
                                  2);
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("bad-path.json: actions[0].setOpacity.model"), std::string::npos) << r.out;
}

TEST_F(Cluster, ConsoleWithoutADisplaySaysSoAndRunsHeadless) {
  const std::string wall = kConfigs + "/walls/1x2.json";
  const CommandResult r =
      cluster("--wall " + wall + " --scene scene.json --frames 2 --console --screenshot nd.png", 2,
              "env -u DISPLAY -u WAYLAND_DISPLAY ");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("--console: "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("running headless"), std::string::npos) << r.out;
  expectSameAsMosaic(r, "nd.png", wall, "scene.json");
}

#ifdef TESSERA_XVFB_RUN
TEST_F(Cluster, ConsoleUnderXvfbDrivesTheWall) {
  // The console's frames do not wait for data, the nodes' neither (no --frames determinism with
  // a console), but a screenshot frame is rendered complete, so the wall picture is still exact.
  const std::string wall = kConfigs + "/walls/1x2.json";
  const CommandResult r =
      cluster("--wall " + wall +
                  " --scene scene.json --frames 4 --console --screenshot con.png "
                  "--console-screenshot console.png --console-width 640",
              2, std::string(TESSERA_XVFB_RUN) + " -a -s '-screen 0 1280x720x24' ");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("console open"), std::string::npos) << r.out;
  expectSameAsMosaic(r, "con.png", wall, "scene.json");
  // The console shows the wall with the navigation's bar drawn by the overlay pass: a quarter
  // white over the scene on its right 8%, so its background is lighter than the rest's.
  const tessera::render::Image shown = tessera::render::readPng(sDir->path() / "console.png");
  ASSERT_EQ(shown.width, 640u);
  auto red = [&](uint32_t x, uint32_t y) {
    return int(shown.rgba[(size_t(y) * shown.width + x) * 4]);
  };
  const int bg = red(2, 2), bar = red(shown.width - 2, 2);
  EXPECT_NEAR(bar, bg * (191.0 / 255.0) + 64.0, 1.5) << "background " << bg;
  size_t model = 0;  // the scene is drawn beside the bar
  for (uint32_t y = 0; y < shown.height; ++y)
    for (uint32_t x = 0; x < shown.width * 9 / 10; ++x) model += red(x, y) != bg;
  EXPECT_GT(model, 1000u);
}
#endif

}  // namespace

namespace {

TEST_F(Cluster, SceneNamingARawScanIsConvertedOnceAndShared) {
  // No build step: the scene names the registered scans' .conf; the master converts it into the
  // cache before the nodes get the scene, and they open the same store.
  const fs::path cache = sDir->path() / "cache";
  write(sDir->path() / "raw.json", sceneJson(kData + "/stanford-bunny/scans/bun.conf"));
  const std::string env = "env XDG_CACHE_HOME=" + cache.string() + " ";
  const std::string wall = kConfigs + "/walls/1x2.json";
  const CommandResult r =
      cluster("--wall " + wall + " --scene raw.json --frames 2 --screenshot raw.png", 2, env);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("tessera-master: converting " + kData + "/stanford-bunny/scans/bun.conf"),
            std::string::npos)
      << r.out;
  size_t stores = 0;
  for (const auto& e : fs::directory_iterator(cache / "tessera"))
    stores += e.path().extension() == ".tlod";
  EXPECT_EQ(stores, 1u);
  // tessera-render --scene on the same scene finds the cached store and draws the same wall.
  const std::regex line("wrote (\\S*raw.png) \\(\\d+x\\d+\\); camera (\\S+)");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.out, m, line)) << r.out;
  const CommandResult ref = run("cd " + sDir->path().string() + " && " + env + TESSERA_RENDER_TOOL +
                                " --scene raw.json --wall " + wall + " --mosaic --camera '" +
                                m[2].str() + "' -o raw-ref.png");
  ASSERT_EQ(ref.code, 0) << ref.out;
  EXPECT_EQ(ref.out.find("converting"), std::string::npos) << ref.out;
  EXPECT_TRUE(tessera::test::readBytes(sDir->path() / "raw.png") ==
              tessera::test::readBytes(sDir->path() / "raw-ref.png"));
}

}  // namespace

namespace {

void writeBinary(const fs::path& p, const std::vector<uint8_t>& bytes) {
  std::ofstream(p, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

/// Mean and largest difference of the colour channels of two pictures of one size over the
/// rectangle [x0, x1) x [y0, y1), levels of 255.
std::pair<double, int> difference(const tessera::render::Image& a, const tessera::render::Image& b,
                                  uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1) {
  double sum = 0;
  int worst = 0;
  size_t n = 0;
  for (uint32_t y = y0; y < y1; ++y)
    for (uint32_t x = x0; x < x1; ++x)
      for (int c = 0; c < 3; ++c, ++n) {
        const size_t i = (size_t(y) * a.width + x) * 4 + size_t(c);
        const int d = std::abs(int(a.rgba[i]) - int(b.rgba[i]));
        sum += d;
        worst = std::max(worst, d);
      }
  return {sum / double(n), worst};
}

/// Two projectors of 320x180 pixels on 0.6 x 0.3375 m, overlapping by 0.2 m (107 pixels), each
/// warped by a wave (PFM grids written by the test) and blended automatically.
const std::string kProjectorWall = R"({"name": "two projectors", "tiles": [
  {"name": "a", "x": 0, "y": 0, "width": 0.6, "height": 0.3375, "pixelWidth": 320,
   "pixelHeight": 180, "blend": "auto", "warp": "pa.pfm"},
  {"name": "b", "x": 0.4, "y": 0, "width": 0.6, "height": 0.3375, "pixelWidth": 320,
   "pixelHeight": 180, "blend": "auto", "warp": "pb.pfm"}],
  "eye": {"x": 0.5, "y": 0.17, "z": 1.5}})";

TEST_F(Cluster, AProjectorWallIsTheMosaicOfItsBlendedAndWarpedTiles) {
  // Each node applies its projector's blend and warp; the master's screenshot (the screen as
  // the room sees it, the projectors' light recomposed) and the projectors' own pictures are
  // tessera-render --mosaic's, byte for byte.
  writeBinary(sDir->path() / "pa.pfm",
              tessera::render::writePfm(tessera::test::wavyWarp(17, 9, 0)));
  writeBinary(sDir->path() / "pb.pfm",
              tessera::render::writePfm(tessera::test::wavyWarp(13, 7, 1.3)));
  write(sDir->path() / "projectors.json", kProjectorWall);
  const CommandResult r =
      cluster("--wall projectors.json --scene scene.json --frames 3 --screenshot pj.png", 2);
  ASSERT_EQ(r.code, 0) << r.out;
  expectSameAsMosaic(r, "pj.png", "projectors.json", "scene.json");
  EXPECT_NE(r.out.find("wrote pj-projectors.png (656x180); the projectors' pictures"),
            std::string::npos)
      << r.out;
  const auto shown = tessera::test::readBytes(sDir->path() / "pj-projectors.png");
  ASSERT_FALSE(shown.empty());
  EXPECT_TRUE(shown == tessera::test::readBytes(sDir->path() / "mosaic-pj-projectors.png"))
      << "the projectors' pictures differ from tessera-render --mosaic's";
  // The projectors' pictures are blended: projector a's last column, where its weight is 0, is
  // black; its first column, alone on the screen, is not (it shows the background there).
  const tessera::render::Image frames =
      tessera::render::readPng((sDir->path() / "pj-projectors.png").string());
  size_t lit_first = 0, lit_last = 0;
  for (uint32_t y = 20; y < 160; ++y) {
    const uint8_t* first = &frames.rgba[(size_t(y) * frames.width + 12) * 4];
    const uint8_t* last = &frames.rgba[(size_t(y) * frames.width + 319) * 4];
    lit_first += first[0] + first[1] + first[2] > 0;
    lit_last += last[0] + last[1] + last[2] > 0;
  }
  EXPECT_EQ(lit_first, 140u);
  EXPECT_EQ(lit_last, 0u);
  // The recomposed screen against a single render of it (tessera-render --whole, the same
  // camera) where both warps reach (their margins: 12 pixels at the sides, 8 at the top and
  // bottom): the same picture up to the projectors' bilinear resampling, which softens edges.
  const std::regex line("wrote \\S*pj.png \\(\\d+x\\d+\\); camera (\\S+)");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.out, m, line));
  const CommandResult whole = run("cd " + sDir->path().string() + " && " + TESSERA_RENDER_TOOL +
                                  " --scene scene.json --wall projectors.json --whole --camera '" +
                                  m[1].str() + "' -o pj-whole.png");
  ASSERT_EQ(whole.code, 0) << whole.out;
  const tessera::render::Image screen =
      tessera::render::readPng((sDir->path() / "pj.png").string());
  const tessera::render::Image one =
      tessera::render::readPng((sDir->path() / "pj-whole.png").string());
  ASSERT_EQ(screen.width, one.width);
  ASSERT_EQ(screen.height, one.height);
  const auto [mean, worst] = difference(screen, one, 12, 8, screen.width - 12, 172);
  const auto [overlap_mean, overlap_worst] = difference(screen, one, 215, 8, 318, 172);
  std::printf(
      "recomposed screen against one render: mean %.2f levels (overlap %.2f), largest %d "
      "(overlap %d)\n",
      mean, overlap_mean, worst, overlap_worst);
  EXPECT_LT(mean, 1.5);
  EXPECT_LT(overlap_mean, 1.5);
}

TEST_F(Cluster, ACavesFourNodesMakeTheMosaicsNet) {
  // The CAVE (three walls and the floor, each on its own plane) with the eye among the bunny's
  // points: four nodes, each with its own off-axis view; the master's net is tessera-render's.
  std::string scene = sceneJson("bunny.tlod");
  const std::string eye = R"("eye": {"x": -0.027, "y": 0.12, "z": 0.38})";
  scene.replace(scene.find(eye), eye.size(), R"("eye": {"x": -0.02, "y": 0.12, "z": 0.09})");
  write(sDir->path() / "cave-scene.json", scene);
  const std::string wall = kConfigs + "/walls/cave.json";
  const CommandResult r =
      cluster("--wall " + wall + " --scene cave-scene.json --frames 2 --screenshot cave.png", 4);
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* tile : {"tile left", "tile front", "tile right", "tile floor"})
    EXPECT_NE(r.out.find(tile), std::string::npos) << tile;
  expectSameAsMosaic(r, "cave.png", wall, "cave-scene.json");
  // The net: four 512-pixel tiles 16 pixels apart; the bunny on at least three of them.
  const tessera::render::Image net = tessera::render::readPng((sDir->path() / "cave.png").string());
  ASSERT_EQ(net.width, 4u * 512 + 3 * 16);
  ASSERT_EQ(net.height, 512u);
  int tiles_with_bunny = 0;
  for (uint32_t t = 0; t < 4; ++t) {
    size_t lit = 0;
    for (uint32_t y = 0; y < 512; ++y)
      for (uint32_t x = t * 528; x < t * 528 + 512; ++x)
        lit += net.rgba[(size_t(y) * net.width + x) * 4] > 60;
    tiles_with_bunny += lit > 2000;
  }
  EXPECT_GE(tiles_with_bunny, 3);
}

TEST_F(Cluster, TheMasterFilmsAPathFrameByFrameAsTesseraRenderDoes) {
  // --path at 8 fps over 0.5 s: 5 frames, each settled on every node and read back, into an MP4
  // and PNGs. The PNGs are tessera-render --path's frames byte for byte; the movie holds 5
  // frames of the wall's size over 5/8 s, each within the codec's loss of its PNG.
  write(sDir->path() / "film.json", R"({"name": "film", "keyframes": [
    {"time": 0, "eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027, "y": 0.1,
     "z": 0}, "up": {"x": 0, "y": 1, "z": 0}},
    {"time": 0.5, "eye": {"x": 0.06, "y": 0.14, "z": 0.33}, "target": {"x": -0.027, "y": 0.1,
     "z": 0}, "up": {"x": 0, "y": 1, "z": 0}}]})");
  const std::string wall = kConfigs + "/walls/1x2.json";
  const CommandResult r = cluster("--wall " + wall +
                                      " --scene scene.json --path film.json --fps 8 --movie "
                                      "film.mp4 --frames-dir film-frames",
                                  2);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("wrote film.mp4 (5 frames at 8 fps"), std::string::npos) << r.out;
  const CommandResult ref = run("cd " + sDir->path().string() + " && " + TESSERA_RENDER_TOOL +
                                " --scene scene.json --wall " + wall +
                                " --mosaic --path film.json --fps 8 --frames-dir ref-frames");
  ASSERT_EQ(ref.code, 0) << ref.out;
  std::vector<tessera::render::Image> frames;
  for (int i = 0; i < 5; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "frame-%06d.png", i);
    const auto ours = tessera::test::readBytes(sDir->path() / "film-frames" / name);
    ASSERT_FALSE(ours.empty()) << name;
    EXPECT_TRUE(ours == tessera::test::readBytes(sDir->path() / "ref-frames" / name))
        << name << " differs from tessera-render --path's";
    frames.push_back(tessera::render::readPng((sDir->path() / "film-frames" / name).string()));
  }
  EXPECT_FALSE(fs::exists(sDir->path() / "film-frames" / "frame-000005.png"));
  const tessera::test::DecodedMovie movie =
      tessera::test::decodeMovie((sDir->path() / "film.mp4").string());
  EXPECT_EQ(movie.width, 1940);
  EXPECT_EQ(movie.height, 540);
  EXPECT_NEAR(movie.fps, 8.0, 1e-6);
  EXPECT_NEAR(movie.duration_s, 5 / 8.0, 0.5 / 8.0);
  ASSERT_EQ(movie.frames.size(), 5u);
  // The camera moves: the first and last frames differ, so matching each to its own is a test.
  EXPECT_LT(tessera::test::psnr(frames.front(), frames.back()), 25.0);
  for (size_t i = 0; i < 5; ++i) {
    const double p = tessera::test::psnr(movie.frames[i], frames[i]);
    std::printf("frame %zu: PSNR %.1f dB against its PNG\n", i, p);
    EXPECT_GE(p, 35.0) << "frame " << i;
  }
  // --size scales the wall's picture; a movie of odd sides is refused before anything renders.
  const CommandResult small = cluster("--wall " + wall +
                                          " --scene scene.json --path film.json --fps 8 --movie "
                                          "small.mp4 --size 480x134",
                                      2);
  ASSERT_EQ(small.code, 0) << small.out;
  const tessera::test::DecodedMovie scaled =
      tessera::test::decodeMovie((sDir->path() / "small.mp4").string());
  EXPECT_EQ(scaled.width, 480);
  EXPECT_EQ(scaled.height, 134);
  ASSERT_EQ(scaled.frames.size(), 5u);
  EXPECT_GE(
      tessera::test::psnr(scaled.frames[4], tessera::render::resizeImage(frames[4], 480, 134)),
      35.0);
  const CommandResult odd = cluster(
      "--wall " + wall + " --scene scene.json --path film.json --movie odd.mp4 --size 481x134", 2);
  EXPECT_NE(odd.code, 0) << odd.out;
  EXPECT_NE(odd.out.find("--movie odd.mp4: the frames are 481x134"), std::string::npos) << odd.out;
  EXPECT_FALSE(fs::exists(sDir->path() / "odd.mp4"));
  const CommandResult no_path =
      cluster("--wall " + wall + " --scene scene.json --movie none.mp4", 2);
  EXPECT_NE(no_path.code, 0) << no_path.out;
  EXPECT_NE(no_path.out.find("--movie and --frames-dir film a camera path: give --path"),
            std::string::npos)
      << no_path.out;
}

}  // namespace
