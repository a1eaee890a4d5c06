// Remote sites as users run them: a real tessera-master with four real tessera-node processes
// (the wall, over ZeroMQ on loopback) and real tessera-site processes joining over CURVE with
// their own keys, each rendering headless from its own script. Checked from what people see:
// the wall's screenshot (each avatar where its pose projects through the tile frusta, the
// sketch on the bunny, a killed site's avatar gone), the sites' screenshots (a follower sees
// exactly what its leader sees) and the strokes' samples against the bunny's reconstruction
// (on the surface within a pixel). Every wait is bounded; every process is reaped by PID.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>

#include <glm/glm.hpp>

#include <tessera/lod/mesh.h>
#include <tessera/render/image.h>
#include <tessera/render/tile_frustum.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/config.h>

#include "../support/command.h"
#include "../support/mesh_distance.h"
#include "../support/process.h"
#include "../support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using tessera::test::Process;
const std::string kData = TESSERA_DATA_DIR;

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

std::string read(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A small 2x2 wall (320x180 tiles, 2 cm bezels) so that many processes share two cores.
std::string wallJson() {
  auto tile = [](const std::string& name, double x, double y) {
    return R"({"name": ")" + name + R"(", "x": )" + std::to_string(x) + R"(, "y": )" +
           std::to_string(y) +
           R"(, "width": 0.48, "height": 0.27, "pixelWidth": 320, "pixelHeight": 180})";
  };
  return R"({"name": "small 2x2", "tiles": [)" + tile("tile-0-0", 0, 0.29) + "," +
         tile("tile-1-0", 0.5, 0.29) + "," + tile("tile-0-1", 0, 0) + "," + tile("tile-1-1", 0.5, 0) +
         R"(], "eye": {"x": 0.49, "y": 0.28, "z": 1.5}})";
}

std::string cameraJson(glm::dvec3 eye, glm::dvec3 target) {
  char s[256];
  std::snprintf(s, sizeof s,
                R"({"eye": {"x": %.17g, "y": %.17g, "z": %.17g}, "target": {"x": %.17g, "y": %.17g, "z": %.17g}, "up": {"y": 1}})",
                eye.x, eye.y, eye.z, target.x, target.y, target.z);
  return s;
}

// The bunny's middle; the wall looks at it from further back than the sites stand.
const glm::dvec3 kTarget{-0.027, 0.1, 0.0};
const glm::dvec3 kWallEye{-0.027, 0.11, 0.75};
const glm::dvec3 kEyeA{-0.09, 0.13, 0.32}, kEyeB{0.04, 0.08, 0.36}, kEyeC{0.0, 0.16, 0.42};
// The master's palette: participants 1, 2, 3 (collab/src/site_roster.cpp).
const glm::vec3 kColorA{0.90f, 0.62f, 0.00f}, kColorB{0.34f, 0.71f, 0.91f},
    kColorC{0.00f, 0.62f, 0.45f};

/// Where `world` lands in the wall screenshot (bezels included), if on a tile.
std::optional<glm::dvec2> onWall(const tessera::config::WallConfig& wall,
                                 const tessera::config::Camera& camera, glm::dvec3 world) {
  for (const auto& tile : wall.tiles()) {
    const tessera::render::ViewSetup v = tessera::render::tileView(wall, tile, camera);
    const glm::dvec4 clip = v.projection * v.view * glm::dvec4(world, 1.0);
    if (clip.w <= 0) continue;
    const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
    if (std::abs(ndc.x) > 1 || std::abs(ndc.y) > 1 || std::abs(ndc.z) > 1) continue;
    const glm::ivec2 off = tessera::render::tileOffsetInWhole(wall, tile);
    return glm::dvec2(off.x + (ndc.x + 1) * 0.5 * v.width, off.y + (1 - ndc.y) * 0.5 * v.height);
  }
  return std::nullopt;
}

/// Pixels within `radius` of `at` whose colour is within `tolerance` (0..1 per channel) of `c`.
int pixelsNear(const tessera::render::Image& img, glm::dvec2 at, int radius, glm::vec3 c,
               float tolerance = 0.12f) {
  int n = 0;
  for (int y = int(at.y) - radius; y <= int(at.y) + radius; ++y)
    for (int x = int(at.x) - radius; x <= int(at.x) + radius; ++x) {
      if (x < 0 || y < 0 || x >= int(img.width) || y >= int(img.height)) continue;
      const uint8_t* p = &img.rgba[(size_t(y) * img.width + x) * 4];
      if (std::abs(p[0] / 255.0f - c.r) < tolerance && std::abs(p[1] / 255.0f - c.g) < tolerance &&
          std::abs(p[2] / 255.0f - c.b) < tolerance)
        ++n;
    }
  return n;
}

std::string publicKeyOf(const std::string& keygen_output) {
  std::smatch m;
  if (!std::regex_search(keygen_output, m, std::regex("^(\\S{40})$", std::regex::multiline)))
    return "";
  return m[1].str();
}

class SiteSession : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new tessera::test::TempDir();
    const auto r = tessera::test::runCommand(std::string(TESSERA_LOD_TOOL) + " build " + kData +
                                             "/stanford-bunny/scans/bun.conf -o " +
                                             (*sDir / "bunny.tlod").string() + " --quiet");
    ASSERT_EQ(r.code, 0) << r.out;
    write(*sDir / "scene.json",
          R"({"nodes": [{"kind": "MODEL", "name": "bunny", "model": {"store": "bunny.tlod"}}],
          "camera": )" + cameraJson(kWallEye, kTarget) +
              R"(, "settings": {"background": {"r": 0.05, "g": 0.05, "b": 0.08},
          "lodPixels": 1.0, "shading": "SHADING_EDL"}})");
    write(*sDir / "wall.json", wallJson());
    std::string allow = "# the sites of the test\n";
    for (const std::string name : {"master", "a", "b", "c", "stranger"}) {
      const auto k = tessera::test::runCommand(std::string(TESSERA_SITE) + " keygen -o " +
                                               (*sDir / (name + ".key")).string());
      ASSERT_EQ(k.code, 0) << k.out;
      const std::string pub = publicKeyOf(k.out);
      ASSERT_EQ(pub.size(), 40u) << k.out;
      sKeys[name] = pub;
      if (name != "master" && name != "stranger") allow += pub + "  site " + name + "\n";
    }
    write(*sDir / "allow.txt", allow);
  }
  static void TearDownTestSuite() {
    delete sDir;
    sDir = nullptr;
  }

  void SetUp() override {
    mRun = sDir->path() / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(mRun);
  }

  /// The master (wall over ZeroMQ, sites over CURVE), holding the camera at kWallEye for
  /// `seconds` of real time, then the wall's screenshot; returns once both sockets listen.
  std::unique_ptr<Process> startMaster(double seconds) {
    write(mRun / "hold.json", R"({"name": "hold", "keyframes": [{"time": 0, )" +
                                  cameraJson(kWallEye, kTarget).substr(1) + R"(, {"time": )" +
                                  std::to_string(seconds) + ", " +
                                  cameraJson(kWallEye, kTarget).substr(1) + "]}");
    const std::vector<std::string> argv = {
        TESSERA_MASTER, "--transport", "zmq", "--listen", "tcp://127.0.0.1:*", "--wall",
        (*sDir / "wall.json").string(), "--scene", (*sDir / "scene.json").string(), "--script",
        (mRun / "hold.json").string(), "--max-fps", "30", "--screenshot",
        (mRun / "wall.png").string(), "--stats", (mRun / "stats.csv").string(), "--sites",
        "tcp://127.0.0.1:*", "--site-key", (*sDir / "master.key").string(), "--allow",
        (*sDir / "allow.txt").string(), "--node-timeout", "5000"};
    auto m = std::make_unique<Process>(argv, mRun / "master.log");
    EXPECT_TRUE(m->waitFor("remote sites join on (tcp://\\S+)", 30)) << m->output();
    std::smatch match;
    const std::string out = m->output();
    std::regex_search(out, match, std::regex("listening on (tcp://\\S+)"));
    mWall = match[1].str();
    std::regex_search(out, match, std::regex("remote sites join on tcp://[^:]+:(\\d+)"));
    mSites = "tcp://127.0.0.1:" + match[1].str();
    return m;
  }

  std::vector<std::unique_ptr<Process>> startNodes() {
    std::vector<std::unique_ptr<Process>> nodes;
    for (const std::string t : {"tile-0-0", "tile-1-0", "tile-0-1", "tile-1-1"})
      nodes.push_back(std::make_unique<Process>(
          std::vector<std::string>{TESSERA_NODE, "--master", mWall, "--headless", "--tile", t},
          mRun / ("node-" + t + ".log")));
    return nodes;
  }

  std::unique_ptr<Process> startSite(const std::string& key, const std::string& name,
                                     const std::string& script_json,
                                     std::vector<std::string> extra = {}) {
    write(mRun / (name + ".json"), script_json);
    fs::create_directories(mRun / name);
    std::vector<std::string> argv = {TESSERA_SITE,  "--master", mSites, "--master-key",
                                     sKeys["master"], "--name",  name,   "--key",
                                     (*sDir / (key + ".key")).string(), "--headless", "-o",
                                     (mRun / name).string(), "--script",
                                     (mRun / (name + ".json")).string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, mRun / (name + ".log"));
  }

  static tessera::test::TempDir* sDir;
  static std::map<std::string, std::string> sKeys;  // public keys by name
  fs::path mRun;
  std::string mWall, mSites;
};
tessera::test::TempDir* SiteSession::sDir = nullptr;
std::map<std::string, std::string> SiteSession::sKeys;

TEST_F(SiteSession, AvatarsSketchFollowMeAndAKilledSiteOnTheWall) {
  auto master = startMaster(24.0);
  auto nodes = startNodes();
  ASSERT_TRUE(master->waitFor("4 of 4 tiles have a node", 60)) << master->output();

  // A: its own view of the bunny; a stroke across the bunny's middle placed on the surface;
  // leads the view for a while (a screenshot meanwhile), then gives it back.
  std::string stroke_px;
  for (int x = 110; x <= 210; x += 4) stroke_px += (stroke_px.empty() ? "" : ", ") + std::to_string(x) + ", 130";
  auto a = startSite("a", "A", R"({"width": 320, "height": 240, "actions": [
      {"frame": 0, "camera": )" + cameraJson(kEyeA, kTarget) + R"(},
      {"frame": 8, "stroke": {"pixels": [)" + stroke_px + R"(], "color": {"r": 1}, "width": 5}},
      {"frame": 20, "lead": true},
      {"frame": 60, "screenshot": "lead.png"},
      {"frame": 240, "release": true}]})");
  ASSERT_TRUE(a->waitFor("leads the view", 60)) << a->output();
  // B joins while A leads, follows it, takes a screenshot, then goes its own way.
  auto b = startSite("b", "B", R"({"width": 320, "height": 240, "actions": [
      {"frame": 0, "camera": )" + cameraJson(kEyeB, kTarget) + R"(},
      {"frame": 5, "follow": true},
      {"frame": 45, "screenshot": "follow.png"},
      {"frame": 60, "camera": )" + cameraJson(kEyeB, kTarget) + R"(}]})");
  // C joins without rendering and is killed.
  auto c = startSite("c", "C", R"({"actions": [{"frame": 0, "camera": )" +
                                   cameraJson(kEyeC, kTarget) + "}]}",
                     {"--no-render"});
  ASSERT_TRUE(master->waitFor("C \\(key \\S+\\) joined", 60)) << master->output();
  ASSERT_TRUE(b->waitFor("wrote \\S+follow.png", 90)) << b->output();
  c->signal(SIGKILL);
  ASSERT_TRUE(master->waitFor("C \\(key \\S+\\) left: its connection closed", 15))
      << master->output();
  ASSERT_TRUE(master->waitFor("A gave the view back", 60)) << master->output();

  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  for (auto& n : nodes) EXPECT_EQ(n->wait(15), std::optional<int>(0)) << n->output();
  EXPECT_EQ(a->wait(15), std::optional<int>(0)) << a->output();
  EXPECT_EQ(b->wait(15), std::optional<int>(0)) << b->output();
  EXPECT_EQ(c->wait(1), std::optional<int>(-SIGKILL));
  const std::string log = master->output();
  EXPECT_EQ(log.find("dropped"), std::string::npos) << "no tile or site was dropped:\n" << log;

  // The wall at the last frame: the camera is the master's again (A gave it back).
  const auto wall = tessera::sync::loadWallConfig(*sDir / "wall.json");
  tessera::config::Camera camera;
  auto set = [](tessera::config::Vec3* v, glm::dvec3 x) {
    v->set_x(x.x);
    v->set_y(x.y);
    v->set_z(x.z);
  };
  set(camera.mutable_eye(), kWallEye);
  set(camera.mutable_target(), kTarget);
  set(camera.mutable_up(), {0, 1, 0});
  const tessera::render::Image shot = tessera::render::readPng((mRun / "wall.png").string());
  for (const auto& [eye, colour, name] :
       {std::tuple{kEyeA, kColorA, "A"}, std::tuple{kEyeB, kColorB, "B"}}) {
    const auto at = onWall(wall, camera, eye);
    ASSERT_TRUE(at) << name << "'s eye is off the wall: the test's geometry is wrong";
    // The head is a 14 px dot; its centre within 2 px of where the pose projects.
    EXPECT_GE(pixelsNear(shot, *at, 2, colour), 9) << name << "'s avatar head at " << at->x << ","
                                                    << at->y << " in " << mRun / "wall.png";
  }
  const auto at_c = onWall(wall, camera, kEyeC);
  ASSERT_TRUE(at_c);
  EXPECT_EQ(pixelsNear(shot, *at_c, 6, kColorC), 0) << "the killed site's avatar is gone";

  // A's stroke: every sample on the bunny within a pixel of A's view, and drawn on the wall.
  const tessera::lod::Mesh recon = tessera::lod::readMesh(kData + "/stanford-bunny/reconstruction/bun_zipper.ply");
  const tessera::test::MeshDistance surface(recon.positions, recon.triangles, 0.004);
  std::istringstream csv(read(mRun / "A" / "strokes.csv"));
  std::string line;
  std::getline(csv, line);
  int samples = 0, on_wall = 0, seen = 0;
  double worst_px = 0;
  while (std::getline(csv, line)) {
    double s, px, py, x, y, z, d;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &s, &px, &py, &x, &y, &z, &d), 7);
    const glm::dvec3 p(x, y, z);
    // One pixel of A's view (320x240, 45 degrees) at the sample's distance.
    const double pixel = 2.0 * glm::length(p - kEyeA) * std::tan(glm::radians(22.5)) / 240.0;
    worst_px = std::max(worst_px, surface.distance(p) / pixel);
    ++samples;
    if (const auto w = onWall(wall, camera, p)) {
      ++on_wall;
      seen += pixelsNear(shot, *w, 2, {1, 0, 0}, 0.25f) > 0;
    }
  }
  EXPECT_GE(samples, 20) << "the stroke's pixels lie on the bunny";
  EXPECT_LE(worst_px, 1.0) << "every stroke sample within one pixel of the surface";
  EXPECT_GE(on_wall, samples * 9 / 10);
  EXPECT_GE(seen, on_wall * 8 / 10) << "the sketch is drawn on the wall";
  RecordProperty("stroke_worst_px", std::to_string(worst_px));

  // Follow-me: B, following A, saw what A saw.
  const tessera::render::Image lead = tessera::render::readPng((mRun / "A" / "lead.png").string());
  const tessera::render::Image follow =
      tessera::render::readPng((mRun / "B" / "follow.png").string());
  ASSERT_EQ(lead.rgba.size(), follow.rgba.size());
  size_t same = 0;
  double se = 0;
  for (size_t i = 0; i < lead.rgba.size(); i += 4) {
    bool eq = true;
    for (int k = 0; k < 3; ++k) {
      const double d = double(lead.rgba[i + k]) - follow.rgba[i + k];
      se += d * d;
      eq &= d == 0;
    }
    same += eq;
  }
  const double pixels = double(lead.rgba.size() / 4);
  const double psnr = 10 * std::log10(255.0 * 255.0 / std::max(1e-9, se / (3 * pixels)));
  EXPECT_GE(same / pixels, 0.99) << "follower and leader pixels alike; PSNR " << psnr;
  EXPECT_GE(psnr, 40.0);
  RecordProperty("follow_identical", std::to_string(same / pixels));

  // The wall never waited for the sites: every frame of the session is in the statistics.
  std::istringstream stats(read(mRun / "stats.csv"));
  std::getline(stats, line);
  uint64_t frames = 0, last = 0;
  while (std::getline(stats, line)) {
    if (line.find(",master,") == std::string::npos) continue;
    const uint64_t f = std::stoull(line.substr(0, line.find(',')));
    EXPECT_EQ(f, last + 1);
    last = f;
    ++frames;
  }
  EXPECT_GE(frames, 100u);
}

}  // namespace
