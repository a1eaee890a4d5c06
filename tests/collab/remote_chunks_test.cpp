// Chunks on demand as users run them: a real tessera-master serving the bunny's
// store from its chunk server (--chunks, throttled with --chunk-rate) beside its site hub, one
// real tessera-node for the wall, and real tessera-site processes that take the store from the
// master instead of this host (--remote-stores) into a disk cache (--cache). Checked from what
// people see: a remote site's settled screenshot against a site's with the local store, the
// bytes it fetched (cold, warm, with cache files broken on purpose), and raw ZeroMQ clients
// asking for what they must not get while the wall goes on. Every wait is bounded; every
// process is reaped by PID.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <regex>

#include <zmq.hpp>

#include <tessera/collab/curve.h>
#include <tessera/collab/site_messages.h>
#include <tessera/render/image.h>
#include <tessera/site.pb.h>
#include <tessera/sync/cluster_link.h>
#include <tessera/sync/scene_graph.h>
#include <tessera/sync/wire.h>

#include "../support/command.h"
#include "../support/process.h"
#include "../support/site_scripts.h"
#include "../support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using tessera::test::cameraJson;
using tessera::test::Process;
using tessera::test::writeText;

const glm::dvec3 kTarget{-0.027, 0.1, 0.0};
const glm::dvec3 kWallEye{-0.027, 0.11, 0.75};
const glm::dvec3 kSiteEye{-0.06, 0.13, 0.30};

/// What a site said about its chunks when it left (site_session.cpp).
struct ChunkReport {
  uint64_t fetched = 0, requests = 0, retries = 0, cache_hits = 0, cache_bytes = 0, refetched = 0;
  uint64_t withdrawn = 0;
  bool found = false;
};

ChunkReport chunkReport(const std::string& log) {
  ChunkReport r;
  std::smatch m;
  if (!std::regex_search(log, m,
                         std::regex("chunks: fetched (\\d+) bytes in (\\d+) requests \\((\\d+) "
                                    "sent again\\); (\\d+) ranges \\((\\d+) bytes\\) from the "
                                    "cache, (\\d+) cached ranges failed")))
    return r;
  r.found = true;
  r.fetched = std::stoull(m[1]);
  r.requests = std::stoull(m[2]);
  r.retries = std::stoull(m[3]);
  r.cache_hits = std::stoull(m[4]);
  r.cache_bytes = std::stoull(m[5]);
  r.refetched = std::stoull(m[6]);
  if (std::regex_search(log, m, std::regex("(\\d+) requests withdrawn")))
    r.withdrawn = std::stoull(m[1]);
  return r;
}

/// A site's lines about its join and its chunks, for the test's output.
void showProgress(const std::string& name, const std::string& log) {
  const std::regex line("(joined as|first image|view settled|chunks:)[^\n]*");
  for (std::sregex_iterator it(log.begin(), log.end(), line), end; it != end; ++it)
    std::printf("%s: %s\n", name.c_str(), it->str().c_str());
}

/// Pixels alike (every channel equal) in two images of one size, as a fraction.
double samePixels(const tessera::render::Image& a, const tessera::render::Image& b) {
  if (a.rgba.size() != b.rgba.size() || a.rgba.empty()) return 0.0;
  size_t same = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4)
    same +=
        a.rgba[i] == b.rgba[i] && a.rgba[i + 1] == b.rgba[i + 1] && a.rgba[i + 2] == b.rgba[i + 2];
  return double(same) / double(a.rgba.size() / 4);
}

/// The range files of a site's disk cache (named OFFSET+LENGTH), largest first.
std::vector<fs::path> cachedRanges(const fs::path& cache) {
  std::vector<fs::path> ranges;
  for (const auto& d : fs::recursive_directory_iterator(cache))
    if (d.is_regular_file() && d.path().filename().string().find('+') != std::string::npos)
      ranges.push_back(d.path());
  std::sort(ranges.begin(), ranges.end(), [](const fs::path& a, const fs::path& b) {
    return fs::file_size(a) > fs::file_size(b);
  });
  return ranges;
}

/// Pixels that are not the background (the bunny covers a good part of the view).
double modelPixels(const tessera::render::Image& img) {
  size_t n = 0;
  for (size_t i = 0; i < img.rgba.size(); i += 4)
    n += img.rgba[i] > 40 || img.rgba[i + 1] > 40 || img.rgba[i + 2] > 40;
  return double(n) / double(img.rgba.size() / 4);
}

class RemoteChunks : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new tessera::test::TempDir();
    const auto r = tessera::test::runCommand(
        std::string(TESSERA_LOD_TOOL) + " build " + TESSERA_DATA_DIR +
        "/stanford-bunny/scans/bun.conf -o " + (*sDir / "bunny.tlod").string() + " --quiet");
    ASSERT_EQ(r.code, 0) << r.out;
    writeText(*sDir / "scene.json",
              R"({"nodes": [{"kind": "MODEL", "name": "bunny", "model": {"store": "bunny.tlod"}}],
          "camera": )" +
                  cameraJson(kWallEye, kTarget) +
                  R"(, "settings": {"background": {"r": 0.05, "g": 0.05, "b": 0.08},
          "lodPixels": 1.0, "shading": "SHADING_EDL"}})");
    // One small tile: the wall is there to keep going, not to be looked at.
    writeText(*sDir / "wall.json", R"({"name": "one tile", "tiles": [{"name": "tile", "x": 0,
          "y": 0, "width": 0.48, "height": 0.27, "pixelWidth": 320, "pixelHeight": 180}],
          "eye": {"x": 0.24, "y": 0.135, "z": 1.0}})");
    std::string allow;
    for (const std::string name : {"master", "local", "remote", "raw", "stranger"}) {
      const auto k = tessera::test::runCommand(std::string(TESSERA_SITE) + " keygen -o " +
                                               (*sDir / (name + ".key")).string());
      ASSERT_EQ(k.code, 0) << k.out;
      sKeys[name] = tessera::test::publicKeyOf(k.out);
      ASSERT_EQ(sKeys[name].size(), 40u) << k.out;
      if (name != "master" && name != "stranger") allow += sKeys[name] + "  " + name + "\n";
    }
    writeText(*sDir / "allow.txt", allow);
    fs::permissions(*sDir / "allow.txt", fs::perms::owner_read | fs::perms::owner_write);
  }
  static void TearDownTestSuite() {
    delete sDir;
    sDir = nullptr;
  }

  void SetUp() override {
    mRun = sDir->path() / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(mRun);
  }

  /// The master for `seconds` of real time with its chunk server at `mbit` Mbit/s per site,
  /// and its one node; returns once the tile has its node. `dir`: where its wall, scene, key
  /// and allow list are (the suite's folder by default).
  std::unique_ptr<Process> startMaster(double seconds, double mbit,
                                       const std::vector<std::string>& extra = {},
                                       const fs::path& dir = {}) {
    std::vector<std::string> options = {"--chunks",           "tcp://127.0.0.1:*", "--chunk-rate",
                                        std::to_string(mbit), "--site-timeout",    "60"};
    options.insert(options.end(), extra.begin(), extra.end());
    const auto argv =
        tessera::test::masterWithSites(TESSERA_MASTER, dir.empty() ? sDir->path() : dir, mRun,
                                       seconds, cameraJson(kWallEye, kTarget), options);
    auto m = std::make_unique<Process>(argv, mRun / "master.log");
    EXPECT_TRUE(m->waitFor("chunks served on (tcp://\\S+)", 30)) << m->output();
    const std::string out = m->output();
    const std::string wall = tessera::test::captured(out, "listening on (tcp://\\S+)");
    mSites = "tcp://127.0.0.1:" +
             tessera::test::captured(out, "remote sites join on tcp://[^:]+:(\\d+)");
    mChunks = tessera::test::captured(out, "chunks served on (tcp://\\S+)");
    mNode = std::make_unique<Process>(
        std::vector<std::string>{TESSERA_NODE, "--master", wall, "--headless", "--tile", "tile"},
        mRun / "node.log");
    EXPECT_TRUE(m->waitFor("1 of 1 tiles have a node", 60)) << m->output();
    return m;
  }

  /// A headless site taking one settled screenshot of kSiteEye ("view.png"), then leaving.
  std::unique_ptr<Process> startSite(const std::string& key, const std::string& name,
                                     std::vector<std::string> extra = {}) {
    writeText(mRun / (name + ".json"), R"({"width": 320, "height": 240, "actions": [
        {"frame": 0, "camera": )" + cameraJson(kSiteEye, kTarget) +
                                           R"(},
        {"frame": 2, "screenshot": "view.png"}, {"frame": 4, "bye": true}]})");
    fs::create_directories(mRun / name);
    const auto argv = tessera::test::headlessSite(TESSERA_SITE, mSites, sKeys["master"], name,
                                                  *sDir / (key + ".key"), mRun / name,
                                                  mRun / (name + ".json"), extra);
    return std::make_unique<Process>(argv, mRun / (name + ".log"));
  }

  /// The master ran to its end without a stalled frame: every frame number in the statistics.
  void expectEveryFrame(uint64_t at_least) {
    std::istringstream stats(tessera::test::readText(mRun / "stats.csv"));
    std::string line;
    std::getline(stats, line);
    uint64_t last = 0;
    while (std::getline(stats, line)) {
      if (line.find(",master,") == std::string::npos) continue;
      const uint64_t f = std::stoull(line.substr(0, line.find(',')));
      EXPECT_EQ(f, last + 1) << "every frame of the session";
      last = f;
    }
    EXPECT_GE(last, at_least);
  }

  /// The bunny's reconstruction as a mesh store, `opacity` its node's, in a scene
  /// of its own in `dir` (the wall, the keys and the allow list are the suite's). Returns the
  /// store's path.
  fs::path meshScene(const fs::path& dir, double opacity) {
    fs::create_directories(dir);
    const fs::path mesh = dir / "bunny.tmesh";
    const auto built =
        tessera::test::runCommand(std::string(TESSERA_LOD_TOOL) + " build " + TESSERA_DATA_DIR +
                                  "/stanford-bunny/reconstruction/bun_zipper.ply -o " +
                                  mesh.string() + " --patch-triangles 512 --quiet");
    EXPECT_EQ(built.code, 0) << built.out;
    for (const char* f : {"wall.json", "master.key", "allow.txt"})
      fs::copy_file(*sDir / f, dir / f);
    writeText(dir / "scene.json", R"({"nodes": [{"kind": "MODEL", "name": "bunny mesh",
          "opacity": )" + std::to_string(opacity) +
                                      R"(, "model": {"store": ")" + mesh.string() +
                                      R"("}}], "camera": )" + cameraJson(kWallEye, kTarget) +
                                      R"(, "settings": {"background": {"r": 0.05, "g": 0.05,
          "b": 0.08}, "lodPixels": 1.0, "shading": "SHADING_EDL"}})");
    return mesh;
  }

  static tessera::test::TempDir* sDir;
  static std::map<std::string, std::string> sKeys;
  fs::path mRun;
  std::string mSites, mChunks;
  std::unique_ptr<Process> mNode;
};
tessera::test::TempDir* RemoteChunks::sDir = nullptr;
std::map<std::string, std::string> RemoteChunks::sKeys;

TEST_F(RemoteChunks, AColdSiteOnASlowLinkConvergesToTheLocalPixelsAndItsCacheKeepsThem) {
  auto master = startMaster(30.0, 5.0);
  const fs::path cache = mRun / "cache";
  // The local site reads the store from this host; the remote one takes every byte from the
  // master at 5 Mbit/s into an empty cache.
  auto local = startSite("local", "local");
  auto cold = startSite("remote", "cold", {"--remote-stores", "--cache", cache.string()});
  ASSERT_EQ(local->wait(60), std::optional<int>(0)) << local->output();
  ASSERT_EQ(cold->wait(60), std::optional<int>(0)) << cold->output();
  const ChunkReport l = chunkReport(local->output());
  EXPECT_TRUE(l.found && l.requests == 0 && l.fetched == 0) << "the local site fetched nothing:\n"
                                                            << local->output();
  showProgress("local", local->output());
  showProgress("cold", cold->output());
  const ChunkReport c = chunkReport(cold->output());
  ASSERT_TRUE(c.found) << cold->output();
  const uint64_t store_bytes = fs::file_size(*sDir / "bunny.tlod");
  EXPECT_GT(c.fetched, 0u);
  EXPECT_LE(c.fetched, store_bytes) << "no range twice";
  EXPECT_EQ(c.cache_hits, 0u);
  RecordProperty("cold_fetched_bytes", std::to_string(c.fetched));
  RecordProperty("store_bytes", std::to_string(store_bytes));
  std::printf("cold site: fetched %llu of the store's %llu bytes in %llu requests\n",
              (unsigned long long)c.fetched, (unsigned long long)store_bytes,
              (unsigned long long)c.requests);

  const auto shot_local = tessera::render::readPng((mRun / "local" / "view.png").string());
  const auto shot_cold = tessera::render::readPng((mRun / "cold" / "view.png").string());
  EXPECT_GT(modelPixels(shot_local), 0.1) << "the view shows the bunny";
  EXPECT_EQ(samePixels(shot_local, shot_cold), 1.0)
      << "the remote site's settled view is the local one";

  // Warm: the same view from the cache; only the store's identity is asked for.
  auto warm = startSite("remote", "warm", {"--remote-stores", "--cache", cache.string()});
  ASSERT_EQ(warm->wait(60), std::optional<int>(0)) << warm->output();
  showProgress("warm", warm->output());
  const ChunkReport w = chunkReport(warm->output());
  ASSERT_TRUE(w.found) << warm->output();
  EXPECT_EQ(w.fetched, 0u) << warm->output();
  EXPECT_EQ(w.requests, 1u) << "one identity request for the one store";
  EXPECT_EQ(w.cache_bytes, c.fetched);
  EXPECT_EQ(samePixels(shot_local, tessera::render::readPng((mRun / "warm" / "view.png").string())),
            1.0);

  // Broken on purpose: a byte flipped in the largest cached range (a chunk payload), and
  // another cached range cut short. The store's checksums catch the first, the cache its size
  // the second: both fetched again, the same pixels, no crash.
  const std::vector<fs::path> ranges = cachedRanges(cache);
  ASSERT_GE(ranges.size(), 3u);
  std::vector<uint8_t> bytes = tessera::test::readBytes(ranges[0]);
  bytes[bytes.size() / 2] ^= 0x5A;
  tessera::test::writeBytes(ranges[0], bytes);
  const uint64_t broken_bytes = bytes.size(), cut_bytes = fs::file_size(ranges[1]);
  fs::resize_file(ranges[1], cut_bytes / 2);
  auto mended = startSite("remote", "mended", {"--remote-stores", "--cache", cache.string()});
  ASSERT_EQ(mended->wait(60), std::optional<int>(0)) << mended->output();
  showProgress("mended", mended->output());
  const ChunkReport b = chunkReport(mended->output());
  ASSERT_TRUE(b.found) << mended->output();
  EXPECT_EQ(b.refetched, 2u) << mended->output();
  EXPECT_EQ(b.fetched, broken_bytes + cut_bytes) << "exactly the two broken ranges again";
  EXPECT_EQ(fs::file_size(ranges[1]), cut_bytes) << "the cut range is whole again";
  EXPECT_EQ(tessera::test::readBytes(ranges[0]).size(), broken_bytes);
  EXPECT_EQ(
      samePixels(shot_local, tessera::render::readPng((mRun / "mended" / "view.png").string())),
      1.0);

  // A cache bounded at a third of what the view needs (--cache-mb): the oldest ranges make
  // room, the folder stays within the bound, and the view is the same.
  const fs::path small = mRun / "cache-small";
  const double bound_mb = double(c.fetched) / 3.0 / 1e6;
  char mb[32];
  std::snprintf(mb, sizeof mb, "%.6f", bound_mb);
  auto bounded = startSite("remote", "bounded",
                           {"--remote-stores", "--cache", small.string(), "--cache-mb", mb});
  ASSERT_EQ(bounded->wait(60), std::optional<int>(0)) << bounded->output();
  EXPECT_NE(bounded->output().find("removed to keep the cache within"), std::string::npos)
      << bounded->output();
  uint64_t kept = 0, largest = 0;
  for (const auto& d : fs::recursive_directory_iterator(small))
    if (d.is_regular_file() && d.path().filename().string().find('+') != std::string::npos) {
      kept += d.file_size();
      largest = std::max<uint64_t>(largest, d.file_size());
    }
  // Within the bound, unless the last range written is larger than the bound by itself.
  EXPECT_LE(double(kept), std::max(bound_mb * 1e6, double(largest))) << kept << " bytes kept";
  EXPECT_GT(kept, 0u);
  EXPECT_EQ(
      samePixels(shot_local, tessera::render::readPng((mRun / "bounded" / "view.png").string())),
      1.0);

  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  EXPECT_EQ(mNode->wait(15), std::optional<int>(0)) << mNode->output();
  EXPECT_NE(master->output().find("0 refused, 0 discarded"), std::string::npos) << master->output();
  expectEveryFrame(100);
}

TEST_F(RemoteChunks, ASiteWhoseViewMovesOnWithdrawsWhatItNoLongerNeeds) {
  // A site close to the bunny's flank on a 2 Mbit/s link asks for fine chunks; a few frames
  // later it steps far back, where coarse levels are all it draws. The fine chunks still
  // waiting at the server are withdrawn (the loaders take the new view's chunks instead), and
  // the settled far view is the local one.
  auto master = startMaster(30.0, 2.0);
  const glm::dvec3 close = kTarget + glm::dvec3(-0.011, 0.01, 0.1);
  const glm::dvec3 far = kTarget + glm::dvec3(0.3, 0.2, 1.4);
  for (const std::string name : {"local-moves", "remote-moves"})
    writeText(mRun / (name + ".json"), R"({"width": 320, "height": 240, "actions": [
        {"frame": 0, "camera": )" + cameraJson(close, kTarget) +
                                           R"(},
        {"frame": 6, "camera": )" + cameraJson(far, kTarget) +
                                           R"(},
        {"frame": 8, "screenshot": "view.png"}, {"frame": 10, "bye": true}]})");
  auto run = [&](const std::string& key, const std::string& name, std::vector<std::string> extra) {
    fs::create_directories(mRun / name);
    Process p(tessera::test::headlessSite(TESSERA_SITE, mSites, sKeys["master"], name,
                                          *sDir / (key + ".key"), mRun / name,
                                          mRun / (name + ".json"), extra),
              mRun / (name + ".log"));
    EXPECT_EQ(p.wait(90), std::optional<int>(0)) << p.output();
    showProgress(name, p.output());
    return p.output();
  };
  const std::string local = run("local", "local-moves", {});
  const std::string remote = run("remote", "remote-moves", {"--remote-stores"});
  const ChunkReport r = chunkReport(remote);
  ASSERT_TRUE(r.found) << remote;
  EXPECT_GE(r.withdrawn, 1u) << remote;
  const auto shot_local = tessera::render::readPng((mRun / "local-moves" / "view.png").string());
  const auto shot_remote = tessera::render::readPng((mRun / "remote-moves" / "view.png").string());
  EXPECT_GT(modelPixels(shot_local), 0.005) << "the far view shows the bunny";
  EXPECT_EQ(samePixels(shot_local, shot_remote), 1.0)
      << "the remote site's settled far view is the local one";
  std::printf("a site that moved on: %llu requests withdrawn, %llu bytes fetched\n",
              (unsigned long long)r.withdrawn, (unsigned long long)r.fetched);
  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  EXPECT_EQ(mNode->wait(15), std::optional<int>(0)) << mNode->output();
  std::smatch m;
  const std::string log = master->output();
  ASSERT_TRUE(std::regex_search(log, m, std::regex("(\\d+) withdrawn by their site"))) << log;
  EXPECT_GE(std::stoull(m[1]), 1u) << "dropped at the server before they were sent";
}

}  // namespace

namespace {

/// A raw ZeroMQ client of the chunk server, as an attacker would write one.
struct RawChunkClient {
  zmq::context_t context{1};
  zmq::socket_t socket{context, zmq::socket_type::dealer};
  RawChunkClient(const std::string& endpoint, const tessera::collab::KeyPair& keys,
                 const std::string& server_key) {
    tessera::collab::curveClient(socket, keys, server_key);
    socket.set(zmq::sockopt::linger, 0);
    socket.connect(endpoint);
  }
  void send(const std::string& bytes) { socket.send(zmq::buffer(bytes), zmq::send_flags::none); }
  void ask(uint64_t id, const std::string& store, uint64_t offset, uint32_t length) {
    tessera::site::ChunkRequest q;
    q.set_id(id);
    q.set_store(store);
    q.set_offset(offset);
    q.set_length(length);
    send(q.SerializeAsString());
  }
  void withdraw(const std::vector<uint64_t>& ids) {
    tessera::site::ChunkRequest q;
    for (const uint64_t id : ids) q.add_cancel(id);
    send(q.SerializeAsString());
  }
  std::optional<tessera::site::ChunkReply> receive(double seconds) {
    zmq::pollitem_t item{socket.handle(), 0, ZMQ_POLLIN, 0};
    if (zmq::poll(&item, 1, std::chrono::milliseconds(int64_t(seconds * 1000))) <= 0)
      return std::nullopt;
    zmq::message_t msg;
    if (!socket.recv(msg, zmq::recv_flags::dontwait)) return std::nullopt;
    tessera::site::ChunkReply r;
    if (!r.ParseFromArray(msg.data(), int(msg.size()))) return std::nullopt;
    return r;
  }
};

/// The store's path as the master's scene names it, from the snapshot a raw site (`keys`) is
/// welcomed with at `sites`; "" (and a test failure) without a welcome.
std::string sceneStore(const std::string& sites, const tessera::collab::KeyPair& keys,
                       const std::string& master_key) {
  zmq::context_t ctx{1};
  zmq::socket_t site{ctx, zmq::socket_type::dealer};
  tessera::collab::curveClient(site, keys, master_key);
  site.set(zmq::sockopt::linger, 0);
  site.connect(sites);
  tessera::site::ToMaster hello;
  hello.mutable_hello()->set_protocol(tessera::sync::kProtocolVersion);
  hello.mutable_hello()->set_name("raw");
  site.send(zmq::buffer(hello.SerializeAsString()));
  zmq::pollitem_t item{site.handle(), 0, ZMQ_POLLIN, 0};
  zmq::message_t msg;
  tessera::site::ToSite w;
  if (zmq::poll(&item, 1, std::chrono::milliseconds(20000)) <= 0 || !site.recv(msg) ||
      !w.ParseFromArray(msg.data(), int(msg.size())) || !w.has_welcome()) {
    ADD_FAILURE() << "no welcome from " << sites;
    return "";
  }
  EXPECT_FALSE(w.welcome().chunks().empty()) << "the welcome names the chunk server";
  tessera::sync::SceneGraph g;
  g.apply(tessera::sync::parseSnapshot(w.welcome().snapshot()));
  std::string store;
  for (const auto id : g.ids())
    if (g.node(id).kind() == tessera::scene::SceneNode::MODEL) store = g.node(id).model().store();
  tessera::site::ToMaster bye;
  bye.mutable_bye();
  site.send(zmq::buffer(bye.SerializeAsString()));
  return store;
}

}  // namespace

TEST_F(RemoteChunks, AMeshTheSiteDoesNotHaveIsStreamedPatchByPatchToTheLocalPixels) {
  const fs::path dir = mRun / "mesh-scene";
  const fs::path mesh = meshScene(dir, 1.0);
  auto master = startMaster(24.0, 20.0, {}, dir);
  const fs::path cache = mRun / "cache";
  auto local = startSite("local", "local");
  auto remote = startSite("remote", "remote", {"--remote-stores", "--cache", cache.string()});
  ASSERT_EQ(local->wait(60), std::optional<int>(0)) << local->output();
  ASSERT_EQ(remote->wait(60), std::optional<int>(0)) << remote->output();
  showProgress("local", local->output());
  showProgress("remote", remote->output());
  const ChunkReport l = chunkReport(local->output()), r = chunkReport(remote->output());
  EXPECT_TRUE(l.found && l.requests == 0 && l.fetched == 0) << local->output();
  ASSERT_TRUE(r.found) << remote->output();
  // The header and patch table, then the patches the cut needs, each once: more than the
  // table, at most the store.
  const uint64_t store_bytes = fs::file_size(mesh);
  EXPECT_GT(r.requests, 2u) << "patches fetched one by one, not the file in one piece";
  EXPECT_GT(r.fetched, 0u);
  EXPECT_LE(r.fetched, store_bytes) << "no range twice";
  std::printf("remote site: fetched %llu of the mesh store's %llu bytes in %llu requests\n",
              (unsigned long long)r.fetched, (unsigned long long)store_bytes,
              (unsigned long long)r.requests);
  const auto shot_local = tessera::render::readPng((mRun / "local" / "view.png").string());
  const auto shot_remote = tessera::render::readPng((mRun / "remote" / "view.png").string());
  EXPECT_GT(modelPixels(shot_local), 0.1) << "the view shows the bunny's mesh";
  EXPECT_EQ(samePixels(shot_local, shot_remote), 1.0)
      << "the remote site's settled view of the mesh is the local one";

  // A patch broken in the cache: its checksum catches it, it is fetched again, the same view.
  const std::vector<fs::path> ranges = cachedRanges(cache);
  ASSERT_GE(ranges.size(), 2u);
  // The largest range is the patch table (its own checksum is the header's); the next a patch.
  std::vector<uint8_t> bytes = tessera::test::readBytes(ranges[1]);
  bytes[bytes.size() / 2] ^= 0x5A;
  tessera::test::writeBytes(ranges[1], bytes);
  auto mended = startSite("remote", "mended", {"--remote-stores", "--cache", cache.string()});
  ASSERT_EQ(mended->wait(60), std::optional<int>(0)) << mended->output();
  showProgress("mended", mended->output());
  const ChunkReport m = chunkReport(mended->output());
  ASSERT_TRUE(m.found) << mended->output();
  EXPECT_EQ(m.refetched, 1u) << mended->output();
  // The broken patch again, and the rest from the cache (the way to the settled cut may ask for
  // a few other coarse patches than the cold run's did: it arrives faster).
  EXPECT_GE(m.fetched, bytes.size());
  EXPECT_LT(m.fetched, r.fetched / 4) << "the rest from the cache";
  EXPECT_EQ(
      samePixels(shot_local, tessera::render::readPng((mRun / "mended" / "view.png").string())),
      1.0);
  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  EXPECT_EQ(mNode->wait(15), std::optional<int>(0)) << mNode->output();
}

TEST_F(RemoteChunks, ASeeThroughMeshReachesTheSiteAsTheMastersSampledPoints) {
  // A see-through mesh is drawn from points sampled on its triangles into the store cache of
  // the host that draws it (the master makes them at load); a site without the mesh takes the
  // master's through the chunk server. One cache folder for this test's processes.
  const fs::path xdg = mRun / "xdg-cache";
  ::setenv("XDG_CACHE_HOME", xdg.c_str(), 1);
  const fs::path dir = mRun / "see-through-scene";
  meshScene(dir, 0.5);
  auto master = startMaster(24.0, 20.0, {}, dir);
  auto local = startSite("local", "local");
  auto remote =
      startSite("remote", "remote", {"--remote-stores", "--cache", (mRun / "cache").string()});
  ASSERT_EQ(local->wait(60), std::optional<int>(0)) << local->output();
  ASSERT_EQ(remote->wait(60), std::optional<int>(0)) << remote->output();
  ::unsetenv("XDG_CACHE_HOME");
  showProgress("local", local->output());
  showProgress("remote", remote->output());
  std::vector<fs::path> sampled;
  for (const auto& d : fs::directory_iterator(xdg / "tessera"))
    if (d.path().extension() == ".tlod") sampled.push_back(d.path());
  ASSERT_EQ(sampled.size(), 1u) << "one store of sampled points, made by the master";
  const ChunkReport r = chunkReport(remote->output());
  ASSERT_TRUE(r.found) << remote->output();
  EXPECT_GT(r.fetched, 0u);
  EXPECT_LE(r.fetched, fs::file_size(sampled[0])) << "the points' ranges, each once";
  const auto shot_local = tessera::render::readPng((mRun / "local" / "view.png").string());
  const auto shot_remote = tessera::render::readPng((mRun / "remote" / "view.png").string());
  EXPECT_GT(modelPixels(shot_local), 0.05) << "the view shows the see-through bunny";
  EXPECT_EQ(samePixels(shot_local, shot_remote), 1.0)
      << "the remote site's settled see-through view is the local one";
  ASSERT_EQ(master->wait(120), std::optional<int>(0)) << master->output();
  EXPECT_EQ(mNode->wait(15), std::optional<int>(0)) << mNode->output();
}

TEST_F(RemoteChunks, OnlyTheScenesStoresWithinTheirBoundsAreServedAndTheWallGoesOn) {
  auto master = startMaster(14.0, 100.0);
  const auto keys = tessera::collab::readKeyFile(*sDir / "raw.key");
  const auto stranger = tessera::collab::readKeyFile(*sDir / "stranger.key");
  // The store's path as the scene names it: from the snapshot a site is welcomed with.
  const std::string store = sceneStore(mSites, keys, sKeys["master"]);
  ASSERT_FALSE(store.empty());
  const std::vector<uint8_t> file = tessera::test::readBytes(store);
  const uint64_t size = file.size();

  RawChunkClient raw(mChunks, keys, sKeys["master"]);
  // The controls: the store's size, and a range of its bytes as they are.
  raw.ask(1, store, 0, 0);
  auto r = raw.receive(10);
  ASSERT_TRUE(r) << master->output();
  EXPECT_EQ(r->id(), 1u);
  ASSERT_TRUE(r->has_info()) << r->refused();
  EXPECT_EQ(r->info().size(), size);
  raw.ask(2, store, 100, 1000);
  r = raw.receive(10);
  ASSERT_TRUE(r && r->kind_case() == tessera::site::ChunkReply::kData);
  EXPECT_EQ(r->data(), std::string(file.begin() + 100, file.begin() + 1100));

  // Refused, each with its reason: a file the scene does not name (by any spelling), a range
  // past the end, one overflowing, one too long, bytes that are no request.
  const std::vector<std::tuple<uint64_t, std::string, uint64_t, uint32_t, std::string>> bad = {
      {3, "/etc/passwd", 0, 100, "is not in the scene"},
      {4, store + "/../" + fs::path(store).filename().string(), 0, 100, "is not in the scene"},
      {5, (*sDir / "allow.txt").string(), 0, 10, "is not in the scene"},
      {6, store, size - 10, 100, "lie beyond the end"},
      {7, store, size + 1, 1, "lie beyond the end"},
      {8, store, UINT64_MAX - 5, 100, "overflows"},
      {9, store, 0, tessera::collab::kMaxChunkRangeBytes + 1, "more than the"}};
  for (const auto& [id, path, offset, length, why] : bad) {
    raw.ask(id, path, offset, length);
    r = raw.receive(10);
    ASSERT_TRUE(r) << "request " << id;
    EXPECT_EQ(r->id(), id);
    ASSERT_EQ(r->kind_case(), tessera::site::ChunkReply::kRefused) << "request " << id;
    EXPECT_NE(r->refused().find(why), std::string::npos) << id << ": " << r->refused();
  }
  raw.send(std::string("\xff\xfe\x01 not a request", 17));
  r = raw.receive(10);
  ASSERT_TRUE(r);
  EXPECT_NE(r->refused().find("not a chunk request"), std::string::npos) << r->refused();
  // A flood of garbage: answered or discarded, never a stall of the wall.
  for (int i = 0; i < 20000; ++i) raw.send("garbage");
  // A key not on the allow list gets nothing at all.
  RawChunkClient intruder(mChunks, stranger, sKeys["master"]);
  intruder.ask(1, store, 0, 0);
  EXPECT_FALSE(intruder.receive(3.0));
  // A site that asks without --sites' keys (plaintext) gets nothing either.
  {
    zmq::context_t ctx{1};
    zmq::socket_t plain{ctx, zmq::socket_type::dealer};
    plain.set(zmq::sockopt::linger, 0);
    plain.connect(mChunks);
    tessera::site::ChunkRequest q;
    q.set_id(1);
    q.set_store(store);
    plain.send(zmq::buffer(q.SerializeAsString()));
    zmq::pollitem_t item{plain.handle(), 0, ZMQ_POLLIN, 0};
    EXPECT_EQ(zmq::poll(&item, 1, std::chrono::milliseconds(2000)), 0);
  }

  ASSERT_EQ(master->wait(60), std::optional<int>(0)) << master->output();
  EXPECT_EQ(mNode->wait(15), std::optional<int>(0)) << mNode->output();
  EXPECT_NE(master->output().find("refused a request"), std::string::npos) << master->output();
  expectEveryFrame(200);
}

TEST_F(RemoteChunks, TheCapOnAllSitesTogetherHoldsAndIsSharedInTurn) {
  // Each site may take 100 Mbit/s, all together 2 Mbit/s (250 kB/s): two raw sites asking for
  // 8 ranges of 32 KiB each get their 512 KiB in no less than the cap allows, replies
  // alternating between them.
  auto master = startMaster(20.0, 100.0, {"--chunk-total-rate", "2"});
  const auto a_keys = tessera::collab::readKeyFile(*sDir / "raw.key");
  const auto b_keys = tessera::collab::readKeyFile(*sDir / "local.key");
  const std::string store = sceneStore(mSites, a_keys, sKeys["master"]);
  ASSERT_FALSE(store.empty());
  ASSERT_GE(fs::file_size(store), 8u * 32768u);
  RawChunkClient a(mChunks, a_keys, sKeys["master"]), b(mChunks, b_keys, sKeys["master"]);
  // Connected and served once each (the size), so both queue their ranges at once below.
  a.ask(100, store, 0, 0);
  b.ask(100, store, 0, 0);
  ASSERT_TRUE(a.receive(10) && b.receive(10)) << master->output();
  constexpr int kRanges = 8;
  constexpr uint32_t kBytes = 32768;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < kRanges; ++i) {
    a.ask(uint64_t(i + 1), store, uint64_t(i) * kBytes, kBytes);
    b.ask(uint64_t(i + 1), store, uint64_t(i) * kBytes, kBytes);
  }
  std::string order;  // which site each reply went to, in arrival order
  int got_a = 0, got_b = 0;
  for (int polls = 0; (got_a < kRanges || got_b < kRanges) && polls < 2000; ++polls) {
    for (auto [client, tag, got] : {std::tuple{&a, 'a', &got_a}, std::tuple{&b, 'b', &got_b}})
      if (auto r = client->receive(0.01)) {
        ASSERT_TRUE(r->has_data()) << r->refused();
        ASSERT_EQ(r->data().size(), kBytes);
        ++*got;
        order += tag;
      }
  }
  const double took =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(got_a, kRanges) << master->output();
  ASSERT_EQ(got_b, kRanges) << master->output();
  // A reply goes when the bucket is out of debt and then takes its bytes: 16 replies of 32 KiB
  // at 250 kB/s take at least 15 replies' time less the bucket's 0.05 s burst, 1.92 s, whatever
  // the machine (a slow one only takes longer).
  EXPECT_GE(took, ((2.0 * kRanges - 1.0) * kBytes - 0.05 * 250e3) / 250e3 * 0.98) << order;
  // In turn: neither site is ever more than two replies ahead of the other.
  int lead = 0, most = 0;
  for (char c : order) most = std::max(most, std::abs(lead += c == 'a' ? 1 : -1));
  EXPECT_LE(most, 2) << order;
  std::printf("two sites under a 2 Mbit/s cap: 512 KiB in %.2f s, replies %s\n", took,
              order.c_str());
  ASSERT_EQ(master->wait(60), std::optional<int>(0)) << master->output();
  EXPECT_EQ(mNode->wait(15), std::optional<int>(0)) << mNode->output();
}

TEST_F(RemoteChunks, AWithdrawnRequestIsDroppedUnansweredAndTheSiteIsServedOn) {
  // 0.5 Mbit/s a site: a 32 KiB reply every half second, so requests queue at the server. Six
  // asked, four of them withdrawn at once, then a seventh: the replies are 1, 2 and 7, in that
  // order (the server answers a site in order, so 3 would come before 7 had it stayed).
  auto master = startMaster(14.0, 0.5);
  const auto keys = tessera::collab::readKeyFile(*sDir / "raw.key");
  const std::string store = sceneStore(mSites, keys, sKeys["master"]);
  ASSERT_FALSE(store.empty());
  ASSERT_GE(fs::file_size(store), 7u * 32768u);
  RawChunkClient raw(mChunks, keys, sKeys["master"]);
  raw.ask(100, store, 0, 0);
  ASSERT_TRUE(raw.receive(10)) << master->output();
  constexpr uint32_t kBytes = 32768;
  for (uint64_t id = 1; id <= 6; ++id) raw.ask(id, store, (id - 1) * kBytes, kBytes);
  raw.withdraw({3, 4, 5, 6, 999});  // 999: never asked for, nothing to drop
  raw.ask(7, store, 6 * kBytes, kBytes);
  std::vector<uint64_t> ids;
  while (ids.size() < 3) {
    auto r = raw.receive(10);
    ASSERT_TRUE(r) << "replies so far: " << ids.size() << "\n" << master->output();
    ASSERT_TRUE(r->has_data()) << r->refused();
    ids.push_back(r->id());
  }
  EXPECT_EQ(ids, (std::vector<uint64_t>{1, 2, 7}));
  EXPECT_FALSE(raw.receive(1.5)) << "nothing after 7: the withdrawn ranges never come";

  // A withdrawal that also asks for a range, or names too many ids, is refused with why.
  tessera::site::ChunkRequest mixed;
  mixed.set_id(8);
  mixed.set_store(store);
  mixed.set_length(100);
  mixed.add_cancel(1);
  raw.send(mixed.SerializeAsString());
  auto r = raw.receive(10);
  ASSERT_TRUE(r && r->kind_case() == tessera::site::ChunkReply::kRefused);
  EXPECT_NE(r->refused().find("a cancel names no store"), std::string::npos) << r->refused();
  std::vector<uint64_t> many(tessera::collab::kMaxChunkCancelIds + 1);
  std::iota(many.begin(), many.end(), 1000);
  raw.withdraw(many);
  r = raw.receive(10);
  ASSERT_TRUE(r && r->kind_case() == tessera::site::ChunkReply::kRefused);
  EXPECT_NE(r->refused().find("more than the 256"), std::string::npos) << r->refused();

  ASSERT_EQ(master->wait(60), std::optional<int>(0)) << master->output();
  EXPECT_EQ(mNode->wait(15), std::optional<int>(0)) << mNode->output();
  EXPECT_NE(master->output().find("4 withdrawn by their site"), std::string::npos)
      << master->output();
  expectEveryFrame(100);
}

TEST_F(RemoteChunks, ChunksWithoutSitesIsABadCommandLine) {
  const auto r = tessera::test::runCommand(
      std::string(TESSERA_MASTER) + " --transport zmq --wall " + (*sDir / "wall.json").string() +
      " --scene " + (*sDir / "scene.json").string() + " --chunks tcp://127.0.0.1:*");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--chunks needs --sites"), std::string::npos) << r.out;
}
