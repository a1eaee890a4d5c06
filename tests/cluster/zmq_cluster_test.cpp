// The wall over ZeroMQ as a user runs it: a real tessera-master and real tessera-node processes
// on loopback (ephemeral ports), killed, stopped and restarted by PID. Every wall screenshot is
// checked tile by tile: a tile with a live node must be exactly tessera-render --mosaic's pixels
// for the camera the master printed, a tile without one exactly render::lostTileImage(). Every
// wait is bounded and every process is reaped (tests/support/process.h); ctest's TIMEOUT is the
// last guard.
#include <gtest/gtest.h>

#include <zmq.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <sstream>
#include <string>

#include <tessera/cluster.pb.h>
#include <tessera/render/image.h>
#include <tessera/render/tile_frustum.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/cluster_link.h>
#include <tessera/sync/config.h>

#include "../support/command.h"
#include "../support/process.h"
#include "../support/site_scripts.h"
#include "../support/small_wall.h"
#include "../support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using tessera::test::Process;
const std::string kData = TESSERA_DATA_DIR;

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

using tessera::test::smallWallJson;

/// A slow turn around the bunny with a screenshot every half second of script time.
std::string orbitJson(double seconds) {
  std::string actions;
  for (double t = 0.45; t < seconds; t += 0.5) {
    char a[96];
    std::snprintf(a, sizeof a, R"(%s{"time": %.2f, "screenshot": "shot-%05.2f.png"})",
                  actions.empty() ? "" : ",", t, t);
    actions += a;
  }
  return R"({"name": "orbit", "keyframes": [
    {"time": 0, "eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027, "y": 0.1, "z": 0},
     "up": {"x": 0, "y": 1, "z": 0}},
    {"time": )" +
         std::to_string(seconds) +
         R"(, "eye": {"x": 0.2, "y": 0.14, "z": 0.3}, "target": {"x": -0.027, "y": 0.1, "z": 0},
     "up": {"x": 0, "y": 1, "z": 0}}], "actions": [)" +
         actions + "]}";
}

struct Shot {
  uint64_t frame = 0;
  std::string path, camera;
};

std::vector<Shot> screenshots(const std::string& log) {
  std::vector<Shot> shots;
  const std::regex line("frame (\\d+): wrote (\\S+) \\(\\d+x\\d+\\); camera (\\S+)");
  for (std::sregex_iterator it(log.begin(), log.end(), line), end; it != end; ++it)
    shots.push_back({std::stoull((*it)[1].str()), (*it)[2].str(), (*it)[3].str()});
  return shots;
}

/// The frame of the first log line matching `pattern` (which must capture the frame number).
std::optional<uint64_t> frameOf(const std::string& log, const std::string& pattern) {
  std::smatch m;
  if (!std::regex_search(log, m, std::regex(pattern))) return std::nullopt;
  return std::stoull(m[1].str());
}

/// How many times `pattern` matches `text`.
size_t countOf(const std::string& text, const std::string& pattern) {
  const std::regex re(pattern);
  return size_t(
      std::distance(std::sregex_iterator(text.begin(), text.end(), re), std::sregex_iterator()));
}

enum class TileLooks { kReference, kLost, kOther };

class ZmqWall : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new tessera::test::TempDir();
    const auto r = tessera::test::runCommand(std::string(TESSERA_LOD_TOOL) + " build " + kData +
                                             "/stanford-bunny/scans/bun.conf -o " +
                                             (*sDir / "bunny.tlod").string() + " --quiet");
    ASSERT_EQ(r.code, 0) << r.out;
    write(*sDir / "scene.json",
          R"({"nodes": [{"kind": "MODEL", "name": "bunny", "model": {"store": "bunny.tlod"}}],
          "camera": {"eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027, "y": 0.1,
          "z": 0.0}, "up": {"y": 1}}, "settings": {"background": {"r": 0.05, "g": 0.05, "b": 0.08},
          "lodPixels": 1.0, "shading": "SHADING_EDL"}})");
    write(*sDir / "wall.json", smallWallJson());
  }
  static void TearDownTestSuite() {
    delete sDir;
    sDir = nullptr;
  }

  void SetUp() override {
    mRun = sDir->path() / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(mRun);
  }

  /// tessera-master over ZeroMQ on an ephemeral loopback port; returns once it listens.
  std::unique_ptr<Process> startMaster(const std::vector<std::string>& args,
                                       const std::string& wall = "wall.json",
                                       const std::string& scene = "scene.json") {
    std::vector<std::string> argv =
        tessera::test::zmqMaster(TESSERA_MASTER, sDir->path() / wall, sDir->path() / scene);
    argv.insert(argv.end(), {"--out-dir", mRun.string()});
    argv.insert(argv.end(), args.begin(), args.end());
    auto m = std::make_unique<Process>(argv, mRun / "master.log");
    EXPECT_TRUE(m->waitFor("listening on (tcp://\\S+)", 30)) << m->output();
    std::smatch match;
    const std::string out = m->output();
    std::regex_search(out, match, std::regex("listening on (tcp://\\S+)"));
    mEndpoint = match[1].str();
    return m;
  }

  std::unique_ptr<Process> startNode(const std::string& tile, const std::string& log_name = "") {
    std::vector<std::string> argv = {TESSERA_NODE, "--master", mEndpoint, "--headless"};
    if (!tile.empty()) argv.insert(argv.end(), {"--tile", tile});
    return std::make_unique<Process>(
        argv, mRun / ((log_name.empty() ? "node-" + tile : log_name) + ".log"));
  }

  /// tessera-render --mosaic of the scene on `wall` with `camera`, cached per camera.
  const tessera::render::Image& reference(const std::string& camera,
                                          const std::string& wall = "wall.json") {
    auto it = mReferences.find(camera);
    if (it != mReferences.end()) return it->second;
    const fs::path out = mRun / ("ref-" + std::to_string(mReferences.size()) + ".png");
    const auto r =
        tessera::test::runCommand("cd " + sDir->path().string() + " && " + TESSERA_RENDER_TOOL +
                                  " --scene scene.json --wall " + wall + " --mosaic --camera '" +
                                  camera + "' -o " + out.string());
    EXPECT_EQ(r.code, 0) << r.out;
    return mReferences.emplace(camera, tessera::render::readPng(out.string())).first->second;
  }

 public:
  /// What tile `name` of a wall screenshot shows.
  TileLooks looks(const Shot& shot, const std::string& name,
                  const std::string& wall_file = "wall.json") {
    const auto wall = tessera::sync::loadWallConfig(sDir->path() / wall_file);
    const tessera::render::Image png = tessera::render::readPng(shot.path);
    const tessera::render::Image& ref = reference(shot.camera, wall_file);
    EXPECT_EQ(png.width, ref.width);
    if (png.width != ref.width || png.height != ref.height) return TileLooks::kOther;
    for (const auto& tile : wall.tiles()) {
      if (tile.name() != name) continue;
      const glm::ivec2 off = tessera::render::tileOffsetInWhole(wall, tile);
      const auto lost = tessera::render::lostTileImage(tile.pixel_width(), tile.pixel_height());
      bool same_ref = true, same_lost = true;
      for (uint32_t y = 0; y < tile.pixel_height(); ++y) {
        const size_t row = (size_t(off.y + y) * png.width + off.x) * 4;
        const size_t n = size_t(tile.pixel_width()) * 4;
        same_ref &= std::equal(&png.rgba[row], &png.rgba[row] + n, &ref.rgba[row]);
        same_lost &= std::equal(&png.rgba[row], &png.rgba[row] + n,
                                &lost.rgba[size_t(y) * tile.pixel_width() * 4]);
      }
      return same_ref ? TileLooks::kReference : same_lost ? TileLooks::kLost : TileLooks::kOther;
    }
    ADD_FAILURE() << "no tile " << name;
    return TileLooks::kOther;
  }

 protected:
  static tessera::test::TempDir* sDir;
  fs::path mRun;
  std::string mEndpoint;
  std::map<std::string, tessera::render::Image> mReferences;
};
tessera::test::TempDir* ZmqWall::sDir = nullptr;

const std::vector<std::string> kTiles = {"tile-0-0", "tile-1-0", "tile-0-1", "tile-1-1"};

/// Checks every screenshot: tiles other than `victim` always the reference; `victim` the
/// reference until frame `lost_from`, then lost, then (once back) the reference to the end.
void expectDropAndReturn(ZmqWall* test, const std::vector<Shot>& shots, const std::string& victim,
                         uint64_t lost_from, uint64_t back_from) {
  ASSERT_GE(shots.size(), 6u);
  bool back = false;
  size_t lost_shots = 0;
  for (const Shot& s : shots) {
    for (const std::string& t : kTiles) {
      if (t == victim) continue;
      EXPECT_EQ(int(test->looks(s, t)), int(TileLooks::kReference))
          << t << " in " << s.path << " (frame " << s.frame << ")";
    }
    const TileLooks v = test->looks(s, victim);
    if (s.frame < lost_from) {
      EXPECT_EQ(int(v), int(TileLooks::kReference))
          << victim << " before the loss, frame " << s.frame;
    } else if (s.frame == lost_from && lost_from > 0) {
      // Dropped in this frame: while it was collected (lost), or between it and the next one
      // (the node had sent this frame's pixels before it died).
      EXPECT_NE(int(v), int(TileLooks::kOther)) << victim << " at the loss, frame " << s.frame;
    } else if (s.frame <= back_from) {
      EXPECT_EQ(int(v), int(TileLooks::kLost)) << victim << " while lost, frame " << s.frame;
      lost_shots += v == TileLooks::kLost;
    } else {
      // Joining: the lost pattern until its first report, then the exact pixels for good.
      if (v == TileLooks::kReference) back = true;
      EXPECT_EQ(int(v), int(back ? TileLooks::kReference : TileLooks::kLost))
          << victim << " after rejoining, frame " << s.frame;
    }
  }
  EXPECT_GE(lost_shots, 1u) << "no screenshot while the tile was lost";
  EXPECT_TRUE(back) << victim << " never came back to the reference pixels";
}

}  // namespace

TEST_F(ZmqWall, KilledNodeIsDroppedTheWallGoesOnAndTheRestartedNodeMatches) {
  write(mRun / "orbit.json", orbitJson(8.0));
  auto master = startMaster({"--script", (mRun / "orbit.json").string(), "--frames", "80", "--fps",
                             "10", "--max-fps", "10", "--node-timeout", "1500"});
  std::vector<std::unique_ptr<Process>> nodes;
  for (const std::string& t : kTiles) nodes.push_back(startNode(t));
  ASSERT_TRUE(master->waitFor("frame \\d+: wrote \\S+shot-02.45", 90)) << master->output();
  nodes[1]->signal(SIGKILL);  // tile-1-0
  ASSERT_TRUE(master->waitFor("tile-1-0 \\([^)]*\\) dropped: dead", 30)) << master->output();
  ASSERT_TRUE(master->waitFor("frame \\d+: wrote \\S+shot-03.95", 30)) << master->output();
  auto restarted = startNode("tile-1-0", "node-tile-1-0-restarted");
  ASSERT_TRUE(master->waitFor("tile-1-0 \\([^)]*\\) rejoined", 30)) << master->output();
  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  EXPECT_EQ(restarted->wait(10), std::optional<int>(0)) << restarted->output();
  for (size_t i : {0, 2, 3})
    EXPECT_EQ(nodes[i]->wait(10), std::optional<int>(0)) << nodes[i]->output();
  EXPECT_EQ(nodes[1]->wait(1), std::optional<int>(-SIGKILL));

  const std::string log = master->output();
  const auto lost = frameOf(log, "frame (\\d+): tile tile-1-0 \\([^)]*\\) dropped");
  const auto back = frameOf(log, "frame (\\d+): tile tile-1-0 \\([^)]*\\) rejoined");
  ASSERT_TRUE(lost && back) << log;
  expectDropAndReturn(this, screenshots(log), "tile-1-0", *lost, *back);
}

// A node killed and restarted again and again while the camera moves: each kill drops its tile
// once ("dead") and each restart rejoins it once; no other tile is ever dropped. The master
// matches a closed connection to its peer by probing the members; a frame must never be lost
// behind those probes.
TEST_F(ZmqWall, HealthyNodesAreNeverDroppedWhileAnotherIsKilledAgainAndAgain) {
  write(mRun / "orbit.json", orbitJson(600.0));
  auto master = startMaster(
      {"--script", (mRun / "orbit.json").string(), "--max-fps", "10", "--node-timeout", "1500"});
  std::vector<std::unique_ptr<Process>> nodes;
  for (const std::string& t : kTiles) nodes.push_back(startNode(t));
  ASSERT_TRUE(master->waitFor("4 of 4 tiles have a node", 60)) << master->output();
  const size_t kRounds = 10;
  auto waitCount = [&](const std::string& pattern, size_t n) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (std::chrono::steady_clock::now() < end && master->running()) {
      if (countOf(master->output(), pattern) >= n) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return countOf(master->output(), pattern) >= n;
  };
  std::vector<std::unique_ptr<Process>> killed;
  for (size_t round = 1; round <= kRounds; ++round) {
    // Some frames with every tile live, then the kill lands at a different point of a frame.
    std::this_thread::sleep_for(std::chrono::milliseconds(700 + 130 * (round % 5)));
    nodes[1]->signal(SIGKILL);  // tile-1-0
    ASSERT_TRUE(waitCount("tile tile-1-0 \\([^)]*\\) dropped: dead", round)) << master->output();
    killed.push_back(std::move(nodes[1]));
    nodes[1] = startNode("tile-1-0", "node-tile-1-0-" + std::to_string(round));
    ASSERT_TRUE(waitCount("tile tile-1-0 \\([^)]*\\) rejoined", round)) << master->output();
  }
  std::this_thread::sleep_for(std::chrono::seconds(1));
  master->signal(SIGTERM);
  ASSERT_EQ(master->wait(60), std::optional<int>(0)) << master->output();
  for (auto& n : nodes) EXPECT_EQ(n->wait(10), std::optional<int>(0)) << n->output();
  for (auto& n : killed) EXPECT_EQ(n->wait(1), std::optional<int>(-SIGKILL));
  const std::string log = master->output();
  EXPECT_EQ(countOf(log, "dropped"), kRounds) << log;
  EXPECT_EQ(countOf(log, "tile tile-1-0 \\([^)]*\\) dropped: dead"), kRounds) << log;
  EXPECT_EQ(countOf(log, "tile tile-1-0 \\([^)]*\\) rejoined"), kRounds) << log;
}

// A frame whose cost jumps past the node timeout (the bunny turns see-through with 64
// ensembles, tens of times an opaque frame) is slow, not hung: a node at work says so, and no
// tile is dropped while it stays within ten timeouts.
TEST_F(ZmqWall, AFrameWhoseCostJumpsPastTheTimeoutIsSlowNotHung) {
  write(sDir->path() / "scene-heavy.json",
        R"({"nodes": [{"kind": "MODEL", "name": "bunny", "model": {"store": "bunny.tlod"}}],
        "camera": {"eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027, "y": 0.1,
        "z": 0.0}, "up": {"y": 1}}, "settings": {"lodPixels": 1.0, "spbrEnsembles": 64}})");
  write(mRun / "heavy.json", R"({"name": "heavy", "keyframes": [
    {"time": 0, "eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027, "y": 0.1, "z": 0},
     "up": {"x": 0, "y": 1, "z": 0}},
    {"time": 6, "eye": {"x": 0.2, "y": 0.14, "z": 0.3}, "target": {"x": -0.027, "y": 0.1, "z": 0},
     "up": {"x": 0, "y": 1, "z": 0}}],
    "actions": [{"time": 1.5, "setOpacity": {"model": "bunny", "opacity": 0.4}}]})");
  const double timeout_ms = 200;
  auto master = startMaster({"--script", (mRun / "heavy.json").string(), "--max-fps", "10",
                             "--node-timeout", "200", "--stats", (mRun / "stats.csv").string()},
                            "wall.json", "scene-heavy.json");
  std::vector<std::unique_ptr<Process>> nodes;
  for (const std::string& t : kTiles) nodes.push_back(startNode(t));
  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  for (auto& n : nodes) EXPECT_EQ(n->wait(10), std::optional<int>(0)) << n->output();
  EXPECT_EQ(master->output().find("dropped"), std::string::npos) << master->output();
  // The premise: some frame took longer than the timeout to render.
  std::ifstream csv(mRun / "stats.csv");
  std::string line;
  double slowest = 0;
  while (std::getline(csv, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    if (f.size() > 6 && f[3].rfind("tile-", 0) == 0) slowest = std::max(slowest, std::stod(f[6]));
  }
  EXPECT_GT(slowest, timeout_ms) << "no frame was slow enough to test the timeout";
}

TEST_F(ZmqWall, StoppedNodeIsDroppedAsHungAndRejoinsWhenContinued) {
  // 12 s of script: the continued node has 8 s to rejoin while the master runs, on a machine
  // loaded by other tests too.
  write(mRun / "orbit.json", orbitJson(12.0));
  auto master = startMaster({"--script", (mRun / "orbit.json").string(), "--frames", "120", "--fps",
                             "10", "--max-fps", "10", "--node-timeout", "1000"});
  std::vector<std::unique_ptr<Process>> nodes;
  for (const std::string& t : kTiles) nodes.push_back(startNode(t));
  ASSERT_TRUE(master->waitFor("frame \\d+: wrote \\S+shot-01.95", 90)) << master->output();
  nodes[2]->signal(SIGSTOP);  // tile-0-1
  ASSERT_TRUE(master->waitFor("tile-0-1 \\([^)]*\\) dropped: hung", 30)) << master->output();
  ASSERT_TRUE(master->waitFor("frame \\d+: wrote \\S+shot-03.45", 30)) << master->output();
  nodes[2]->signal(SIGCONT);
  ASSERT_TRUE(master->waitFor("tile-0-1 \\([^)]*\\) rejoined", 30))
      << master->output() << "\n-- the continued node:\n" << nodes[2]->output();
  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  for (auto& n : nodes) EXPECT_EQ(n->wait(10), std::optional<int>(0)) << n->output();
  const std::string log = master->output();
  const auto lost = frameOf(log, "frame (\\d+): tile tile-0-1 \\([^)]*\\) dropped");
  const auto back = frameOf(log, "frame (\\d+): tile tile-0-1 \\([^)]*\\) rejoined");
  ASSERT_TRUE(lost && back) << log;
  // One drop and one rejoin: the continued node reads its queued "dropped" and joins again on a
  // new connection, never twice.
  EXPECT_EQ(countOf(log, "dropped"), 1u) << log;
  EXPECT_EQ(countOf(log, "rejoined"), 1u) << log;
  expectDropAndReturn(this, screenshots(log), "tile-0-1", *lost, *back);
}

TEST_F(ZmqWall, NodesExitWhenTheMasterIsKilled) {
  auto master = startMaster({"--frames", "100000", "--max-fps", "20"});
  std::vector<std::unique_ptr<Process>> nodes;
  for (const std::string& t : kTiles) nodes.push_back(startNode(t));
  ASSERT_TRUE(master->waitFor("4 of 4 tiles have a node", 60)) << master->output();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  master->signal(SIGKILL);
  for (auto& n : nodes) {
    // NODE_MASTER_LOST; the bound only keeps a broken build from hanging (bench/cluster_link
    // measures how soon).
    EXPECT_EQ(n->wait(20), std::optional<int>(tessera::cluster::NODE_MASTER_LOST)) << n->output();
    EXPECT_NE(n->output().find("lost the master"), std::string::npos) << n->output();
  }
}

TEST_F(ZmqWall, NodeStartedAfterFrame50JoinsAndMatches) {
  write(mRun / "orbit.json", orbitJson(8.0));
  auto master =
      startMaster({"--script", (mRun / "orbit.json").string(), "--frames", "80", "--fps", "10",
                   "--max-fps", "10", "--node-timeout", "1500", "--join-wait", "1"});
  std::vector<std::unique_ptr<Process>> nodes;
  for (size_t i = 0; i < 3; ++i) nodes.push_back(startNode(kTiles[i]));
  ASSERT_TRUE(master->waitFor("frame 5\\d: wrote", 90)) << master->output();
  nodes.push_back(startNode("", "node-late"));  // the first free tile: tile-1-1
  ASSERT_TRUE(master->waitFor("tile tile-1-1 \\([^)]*\\) joined", 30)) << master->output();
  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  for (auto& n : nodes) EXPECT_EQ(n->wait(10), std::optional<int>(0)) << n->output();
  const std::string log = master->output();
  const auto joined = frameOf(log, "frame (\\d+): tile tile-1-1 \\([^)]*\\) joined");
  ASSERT_TRUE(joined);
  EXPECT_GE(*joined, 50u);
  expectDropAndReturn(this, screenshots(log), "tile-1-1", 0, *joined);
}

TEST_F(ZmqWall, BadPeersAreRefusedAndTheWallIsUndisturbed) {
  write(mRun / "orbit.json", orbitJson(6.0));
  auto master = startMaster({"--script", (mRun / "orbit.json").string(), "--frames", "60", "--fps",
                             "10", "--max-fps", "10", "--node-timeout", "1500"});
  std::vector<std::unique_ptr<Process>> nodes;
  for (const std::string& t : kTiles) nodes.push_back(startNode(t));
  ASSERT_TRUE(master->waitFor("frame \\d+: wrote \\S+shot-00.95", 90)) << master->output();

  // A second node for a driven tile, and one for a tile the wall does not have.
  auto duplicate = startNode("tile-0-0", "node-duplicate");
  EXPECT_EQ(duplicate->wait(20), std::optional<int>(tessera::cluster::NODE_REFUSED));
  EXPECT_NE(duplicate->output().find("tile 'tile-0-0' is already driven by the node on"),
            std::string::npos)
      << duplicate->output();
  auto unknown = startNode("nope", "node-unknown");
  EXPECT_EQ(unknown->wait(20), std::optional<int>(tessera::cluster::NODE_REFUSED));
  EXPECT_NE(unknown->output().find("has no tile 'nope'"), std::string::npos) << unknown->output();

  // A peer of another protocol version, and one that sends bytes that are no message at all.
  zmq::context_t ctx;
  auto refusalTo = [&](const std::string& bytes) {
    zmq::socket_t s(ctx, zmq::socket_type::dealer);
    s.set(zmq::sockopt::linger, 0);
    s.set(zmq::sockopt::rcvtimeo, 10000);
    s.connect(mEndpoint);
    s.send(zmq::buffer(bytes));
    zmq::message_t reply;
    if (!s.recv(reply)) return std::string("(no answer)");
    tessera::cluster::ToNode t;
    EXPECT_TRUE(t.ParseFromArray(reply.data(), int(reply.size())));
    return t.has_refused() ? t.refused().reason() : std::string("(not a refusal)");
  };
  tessera::cluster::FromNode old;
  old.set_protocol(1);
  old.mutable_hello()->set_tile("tile-1-1");
  EXPECT_NE(refusalTo(old.SerializeAsString()).find("protocol version 1, this build speaks"),
            std::string::npos);
  EXPECT_NE(refusalTo(std::string("\xff\xfe garbage \x01\x02", 14)).find("are not a FromNode"),
            std::string::npos);
  // Raw bytes on the TCP port (no ZMTP handshake): libzmq closes the connection.
  {
    std::smatch m;
    ASSERT_TRUE(std::regex_search(mEndpoint, m, std::regex(":(\\d+)$")));
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(uint16_t(std::stoi(m[1].str())));
    inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
    ASSERT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    const std::string junk(4096, '\x5a');
    EXPECT_GT(::write(fd, junk.data(), junk.size()), 0);
    close(fd);
  }
  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  for (auto& n : nodes) EXPECT_EQ(n->wait(10), std::optional<int>(0)) << n->output();
  const std::string log = master->output();
  EXPECT_EQ(log.find("dropped"), std::string::npos) << log;
  EXPECT_NE(log.find("refused a node on"), std::string::npos) << log;
  for (const Shot& s : screenshots(log))
    for (const std::string& t : kTiles)
      EXPECT_EQ(int(looks(s, t)), int(TileLooks::kReference)) << t << " frame " << s.frame;
}

/// Every node's exit (if it ended) and log, for a failure's message.
std::string nodeReports(std::vector<std::unique_ptr<Process>>& nodes) {
  std::string out;
  for (auto& n : nodes) {
    const auto code = n->wait(0.0);
    out += "\n--- " + n->log().filename().string() + " (pid " + std::to_string(n->pid()) + ", " +
           (code ? "exit " + std::to_string(*code) : std::string("running")) + "):\n" + n->output();
  }
  return out;
}

TEST_F(ZmqWall, LosingACriticalTileStopsTheWall) {
  write(sDir->path() / "wall-critical.json", smallWallJson(R"(, "critical": true)"));
  auto master = startMaster({"--frames", "100000", "--max-fps", "10", "--node-timeout", "1000"},
                            "wall-critical.json");
  std::vector<std::unique_ptr<Process>> nodes;
  for (const std::string& t : kTiles) nodes.push_back(startNode(t));
  ASSERT_TRUE(master->waitFor("4 of 4 tiles have a node", 60))
      << master->output() << nodeReports(nodes);
  nodes[0]->signal(SIGKILL);  // not critical: the wall goes on
  ASSERT_TRUE(master->waitFor("tile-0-0 \\([^)]*\\) dropped", 30)) << master->output();
  EXPECT_TRUE(master->running());
  nodes[3]->signal(SIGKILL);  // critical
  EXPECT_EQ(master->wait(30), std::optional<int>(5)) << master->output();
  EXPECT_NE(master->output().find("stopping the wall: critical tile tile-1-1 has no node"),
            std::string::npos)
      << master->output();
  for (size_t i : {1, 2})
    EXPECT_EQ(nodes[i]->wait(20), std::optional<int>(0)) << nodes[i]->output();
}

TEST_F(ZmqWall, MpiAndZmqGiveByteIdenticalScreenshots) {
  write(mRun / "orbit.json", orbitJson(1.0));
  auto master = startMaster({"--script", (mRun / "orbit.json").string(), "--frames", "12", "--fps",
                             "10", "--screenshot", (mRun / "zmq-last.png").string()});
  std::vector<std::unique_ptr<Process>> nodes;
  for (const std::string& t : kTiles) nodes.push_back(startNode(t));
  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  std::string mpirun = std::string(TESSERA_MPIRUN) + " --oversubscribe";
  if (getuid() == 0) mpirun += " --allow-run-as-root";
  fs::create_directories(mRun / "mpi");
  const auto r = tessera::test::runCommand(
      mpirun + " -np 1 " + TESSERA_MASTER + " --wall " + (sDir->path() / "wall.json").string() +
      " --scene " + (sDir->path() / "scene.json").string() + " --script " +
      (mRun / "orbit.json").string() + " --frames 12 --fps 10 --out-dir " +
      (mRun / "mpi").string() + " --screenshot " + (mRun / "mpi-last.png").string() + " : -np 4 " +
      TESSERA_NODE + " --headless");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto same = [](const fs::path& a, const fs::path& b) {
    const auto x = tessera::render::readPng(a.string()), y = tessera::render::readPng(b.string());
    return x.width == y.width && x.height == y.height && x.rgba == y.rgba;
  };
  EXPECT_TRUE(same(mRun / "zmq-last.png", mRun / "mpi-last.png"));
  EXPECT_TRUE(same(mRun / "shot-00.45.png", mRun / "mpi" / "shot-00.45.png"));
  EXPECT_TRUE(same(mRun / "shot-00.95.png", mRun / "mpi" / "shot-00.95.png"));
}

TEST_F(ZmqWall, NodeWaitingForAMasterJoinsTheNextOne) {
  write(sDir->path() / "wall-one.json",
        R"({"name": "one", "tiles": [{"name": "solo", "width": 0.48, "height": 0.27,
            "pixelWidth": 320, "pixelHeight": 180}], "eye": {"x": 0.24, "y": 0.135, "z": 1.5}})");
  auto first = startMaster({"--frames", "100000", "--max-fps", "20"}, "wall-one.json");
  std::smatch port;
  ASSERT_TRUE(std::regex_search(mEndpoint, port, std::regex(":(\\d+)$")));
  auto n = std::make_unique<Process>(std::vector<std::string>{TESSERA_NODE, "--master", mEndpoint,
                                                              "--headless", "--wait-master", "60"},
                                     mRun / "node.log");
  ASSERT_TRUE(first->waitFor("1 of 1 tiles have a node", 60)) << first->output();
  first->signal(SIGKILL);
  ASSERT_TRUE(n->waitFor("waiting up to 60 s for a master", 20)) << n->output();
  // A new master on the same port: the node joins it by itself.
  std::vector<std::string> argv = {TESSERA_MASTER,
                                   "--transport",
                                   "zmq",
                                   "--listen",
                                   "tcp://127.0.0.1:" + port[1].str(),
                                   "--wall",
                                   (sDir->path() / "wall-one.json").string(),
                                   "--scene",
                                   (sDir->path() / "scene.json").string(),
                                   "--frames",
                                   "5",
                                   "--screenshot",
                                   (mRun / "second.png").string()};
  Process second(argv, mRun / "second-master.log");
  ASSERT_EQ(second.wait(120), std::optional<int>(0)) << second.output();
  EXPECT_EQ(n->wait(20), std::optional<int>(0)) << n->output();
  const auto shots = screenshots(second.output());
  ASSERT_EQ(shots.size(), 1u) << second.output();
  EXPECT_EQ(int(looks(shots[0], "solo", "wall-one.json")), int(TileLooks::kReference));
}

TEST_F(ZmqWall, ANodeLyingAboutItsPixelsIsDropped) {
  write(sDir->path() / "wall-one.json",
        R"({"name": "one", "tiles": [{"name": "solo", "width": 0.48, "height": 0.27,
            "pixelWidth": 320, "pixelHeight": 180}], "eye": {"x": 0.24, "y": 0.135, "z": 1.5}})");
  auto master = startMaster({"--frames", "100000", "--max-fps", "20", "--node-timeout", "2000"},
                            "wall-one.json");
  // A peer that joins properly, then reports pixels the frame did not ask for.
  zmq::context_t ctx;
  zmq::socket_t s(ctx, zmq::socket_type::dealer);
  s.set(zmq::sockopt::linger, 0);
  s.set(zmq::sockopt::rcvtimeo, 20000);
  s.connect(mEndpoint);
  tessera::cluster::FromNode hello;
  hello.mutable_hello()->set_tile("solo");
  hello.mutable_hello()->set_host("liar");
  s.send(zmq::buffer(tessera::sync::envelope(hello)));
  auto next = [&] {
    zmq::message_t m;
    tessera::cluster::ToNode t;
    if (s.recv(m)) {
      EXPECT_TRUE(t.ParseFromArray(m.data(), int(m.size())));
    }
    return t;
  };
  ASSERT_TRUE(next().has_welcome());
  tessera::cluster::FromNode startup;
  startup.mutable_report();  // frame 0, NODE_OK
  s.send(zmq::buffer(tessera::sync::envelope(startup)));
  tessera::cluster::ToNode t;
  do t = next();
  while (t.kind_case() != tessera::cluster::ToNode::kFrame && t.kind_case() != 0);
  ASSERT_TRUE(t.has_frame());
  tessera::cluster::FromNode lie;
  lie.mutable_report()->set_frame(1);
  lie.mutable_report()->set_rgba(std::string(12, 'x'));
  s.send(zmq::buffer(tessera::sync::envelope(lie)));
  EXPECT_TRUE(master->waitFor(
      "tile solo \\(host liar, pid 0\\) dropped: protocol error: 12 bytes of pixels for a frame "
      "that asked for 0",
      30))
      << master->output();
  do t = next();
  while (t.kind_case() != tessera::cluster::ToNode::kDropped && t.kind_case() != 0);
  EXPECT_TRUE(t.has_dropped());
  // A real node takes the tile over; the wall goes on.
  auto n = startNode("solo");
  EXPECT_TRUE(master->waitFor("tile solo \\(host (?!liar)[^)]*\\) rejoined", 30))
      << master->output();
  EXPECT_TRUE(master->running());
}

TEST_F(ZmqWall, FewerLiveTilesThanTheMinimumStopTheWall) {
  write(sDir->path() / "wall-min.json", smallWallJson("", R"(, "minLiveTiles": 4)"));
  auto master = startMaster({"--frames", "100000", "--max-fps", "10", "--node-timeout", "1000"},
                            "wall-min.json");
  std::vector<std::unique_ptr<Process>> nodes;
  for (const std::string& t : kTiles) nodes.push_back(startNode(t));
  ASSERT_TRUE(master->waitFor("4 of 4 tiles have a node", 60)) << master->output();
  nodes[2]->signal(SIGKILL);
  EXPECT_EQ(master->wait(30), std::optional<int>(5)) << master->output();
  EXPECT_NE(master->output().find("stopping the wall: 3 of 4 tiles have a node, fewer than the "
                                  "wall's minLiveTiles 4"),
            std::string::npos)
      << master->output();
}

TEST_F(ZmqWall, NonFiniteTimeoutsAreRefused) {
  for (const std::string bad : {"nan", "inf", "-1", "1e400"}) {
    const auto r = tessera::test::runCommand(
        std::string(TESSERA_MASTER) + " --transport zmq --wall x --scene y --node-timeout " + bad);
    EXPECT_EQ(r.code, 2) << bad << ": " << r.out;  // a bad command line (README, "Exit codes")
    EXPECT_NE(r.out.find("--node-timeout"), std::string::npos) << r.out;
    const auto n = tessera::test::runCommand(std::string(TESSERA_NODE) +
                                             " --master tcp://127.0.0.1:1 --wait-master " + bad);
    EXPECT_EQ(n.code, 2) << bad << ": " << n.out;
    EXPECT_NE(n.out.find("--wait-master"), std::string::npos) << n.out;
  }
}
