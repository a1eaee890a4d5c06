// Video insets with real processes on loopback: tessera-master with a wall of two
// tiles side by side, a tessera-node per tile, and sites sending H.264 over CURVE. What the wall
// shows is read back from the master's screenshots: the test pattern's burned-in frame number
// and clock give the glass-to-glass latency (the master says when it swapped each screenshot's
// frame), the inset is compared with the picture sent (PSNR over the quad, across the tiles'
// seam), and damaged, truncated, oversized and over-cap video never stops a node or the master
// and never shows: the inset keeps its last good picture.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <random>
#include <regex>
#include <thread>

#include <tessera/collab/site_client.h>
#include <tessera/media/video_packet.h>
#include <tessera/media/video_pattern.h>
#include <tessera/render/image.h>

#include "../support/command.h"
#include "../support/process.h"
#include "../support/site_scripts.h"
#include "../support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using namespace tessera;
using test::Process;

/// Keys for the master and `sites`, the allow list, and a wall of two 400x600 tiles side by
/// side without a bezel (one 800x600 picture) with an empty scene. Returns the camera.
struct VideoWall {
  std::map<std::string, std::string> keys;  // public keys by name
  std::string camera;
};

VideoWall writeSetup(const fs::path& dir, const std::vector<std::string>& sites) {
  VideoWall s;
  std::string allow;
  for (const std::string& name : sites) {
    const auto k = test::runCommand(std::string(TESSERA_SITE) + " keygen -o " +
                                    (dir / (name + ".key")).string());
    EXPECT_EQ(k.code, 0) << k.out;
    s.keys[name] = test::publicKeyOf(k.out);
    if (name != "master") allow += s.keys[name] + "  site " + name + "\n";
  }
  test::writeText(dir / "allow.txt", allow);
  test::writeText(
      dir / "wall.json",
      R"({"name": "two tiles", "tiles": [)"
      R"({"name": "left", "x": 0, "y": 0, "width": 0.4, "height": 0.6, "pixelWidth": 400, "pixelHeight": 600},)"
      R"({"name": "right", "x": 0.4, "y": 0, "width": 0.4, "height": 0.6, "pixelWidth": 400, "pixelHeight": 600}],)"
      R"( "eye": {"x": 0.4, "y": 0.3, "z": 1.5}})");
  s.camera = test::cameraJson({0, 0, 1}, {0, 0, 0});
  test::writeText(dir / "scene.json", R"({"nodes": [], "camera": )" + s.camera + "}");
  return s;
}

/// The master holding the camera for `seconds` at 60 frames a second at most, taking a wall
/// screenshot every `every` seconds from `from` on; `extra` appended.
std::vector<std::string> masterArgv(const fs::path& dir, const VideoWall& s, double seconds,
                                    double from, double every,
                                    const std::vector<std::string>& extra) {
  std::vector<std::string> argv =
      test::masterWithSites(TESSERA_MASTER, dir, dir, seconds, s.camera, extra);
  test::setOption(argv, "--max-fps", "60");
  argv.insert(argv.end(), {"--out-dir", dir.string()});
  test::writeHoldWithScreenshots(dir / "hold.json", s.camera, seconds, from, every);
  return argv;
}

/// The master (masterArgv) and a node per tile, started; `sites` is where sites join; with
/// `site_options`, a headless tessera-site "site a" (no rendering, still) with them.
struct RunningWall {
  std::unique_ptr<Process> master, left, right, site;
  std::string sites;
};

std::unique_ptr<RunningWall> startWall(const fs::path& dir, const VideoWall& s, double seconds,
                                       double from, double every,
                                       const std::vector<std::string>& extra,
                                       const std::vector<std::string>& site_options = {}) {
  auto w = std::make_unique<RunningWall>();
  w->master = std::make_unique<Process>(masterArgv(dir, s, seconds, from, every, extra),
                                        dir / "master.log");
  if (!w->master->waitFor("remote sites join on (tcp://\\S+)", 30)) {
    ADD_FAILURE() << w->master->output();
    return nullptr;
  }
  const std::string out = w->master->output();
  const std::string wall = test::captured(out, "listening on (tcp://\\S+)");
  w->sites = "tcp://127.0.0.1:" + test::captured(out, "remote sites join on tcp://[^:]+:(\\d+)");
  w->left = std::make_unique<Process>(
      std::vector<std::string>{TESSERA_NODE, "--master", wall, "--headless", "--tile", "left"},
      dir / "left.log");
  w->right = std::make_unique<Process>(
      std::vector<std::string>{TESSERA_NODE, "--master", wall, "--headless", "--tile", "right"},
      dir / "right.log");
  if (!site_options.empty()) {
    test::writeText(dir / "still.json", R"({"actions": []})");
    std::vector<std::string> options = {"--no-render"};
    options.insert(options.end(), site_options.begin(), site_options.end());
    w->site = std::make_unique<Process>(
        test::headlessSite(TESSERA_SITE, w->sites, s.keys.at("master"), "site a", dir / "a.key",
                           dir, dir / "still.json", options),
        dir / "a.log");
  }
  return w;
}

/// One screenshot as the wall showed it: the frame number and clock burned into the inset at
/// the wall's pixels (x, y, w, h), and when the master swapped that frame.
struct Shot {
  fs::path path;
  double swapped_ms = 0;
  std::optional<media::PatternCode> code;
  render::Image image;
};

std::vector<Shot> readShots(const std::string& log, int x, int y, int w, int h) {
  std::vector<Shot> shots;
  const std::regex wrote("frame (\\d+): wrote (\\S+) \\(");
  for (auto it = std::sregex_iterator(log.begin(), log.end(), wrote); it != std::sregex_iterator();
       ++it) {
    Shot s;
    s.path = (*it)[2].str();
    const std::string swapped =
        test::captured(log, "frame " + (*it)[1].str() + ": swapped at unix ms ([0-9.]+)");
    if (!swapped.empty()) s.swapped_ms = std::stod(swapped);
    s.image = render::readPng(s.path.string());
    s.code = media::readTestPattern(s.image.rgba.data(), int(s.image.width), x, y, w, h);
    shots.push_back(std::move(s));
  }
  return shots;
}

/// PSNR of the wall's pixels (x, y, w, h) against the pattern of `code` drawn at that size.
double insetPsnr(const render::Image& image, const media::PatternCode& code, int x, int y, int w,
                 int h) {
  media::VideoPicture sent, shown;
  media::drawTestPattern(sent, w, h, code);
  shown.resize(w, h);
  for (int yy = 0; yy < h; ++yy)
    std::copy_n(&image.rgba[(size_t(y + yy) * image.width + size_t(x)) * 4], size_t(w) * 4,
                shown.pixel(0, yy));
  return media::videoPsnr(sent, shown, 0, 0, w, h);
}

// The inset pinned at 0.1, 0.1 of the wall, 0.8 wide: 640x480 wall pixels from (80, 60), one
// to one with the 640x480 picture, across the seam between the tiles at x = 400.
constexpr int kX = 80, kY = 60, kW = 640, kH = 480;

TEST(VideoSites, TheWallShowsASitesVideoLiveAndFaithfully) {
  test::TempDir dir;
  const VideoWall s = writeSetup(dir.path(), {"master", "a"});
  const auto w = startWall(dir.path(), s, 7.0, 2.0, 0.25, {"--video-screen", "0.1,0.1,0.8"},
                           {"--video", "test"});
  ASSERT_TRUE(w);
  Process &master = *w->master, &left = *w->left, &right = *w->right, &site = *w->site;
  ASSERT_EQ(master.wait(120), std::optional<int>(0)) << master.output();
  EXPECT_EQ(left.wait(15), std::optional<int>(0)) << left.output();
  EXPECT_EQ(right.wait(15), std::optional<int>(0)) << right.output();
  EXPECT_EQ(site.wait(15), std::optional<int>(0)) << site.output();
  const std::string log = master.output();
  EXPECT_NE(log.find("sends video (640x480): inset"), std::string::npos) << log;
  EXPECT_EQ(log.find("dropped:"), std::string::npos) << log;

  const std::vector<Shot> shots = readShots(log, kX, kY, kW, kH);
  ASSERT_GE(shots.size(), 15u) << log;
  std::vector<double> latency;
  uint32_t previous = 0;
  size_t advanced = 0;
  for (const Shot& shot : shots) {
    ASSERT_TRUE(shot.code) << shot.path << ": no readable test pattern in the inset";
    // Never backwards, and forward on many shots: a loaded machine (the suite's other tests
    // beside this one) may show one picture on several screenshots 0.25 s apart; a frozen inset
    // shows it on all.
    EXPECT_GE(shot.code->frame, previous) << shot.path << ": the inset went back in time";
    advanced += shot.code->frame > previous;
    previous = shot.code->frame;
    // The clocks are one machine's: the picture was made before the wall showed it (an order,
    // not a duration: how late it is depends on the machine, and bench/video measures it).
    const int64_t ms = media::patternDelayMs(shot.code->time_ms,
                                              uint32_t(uint64_t(shot.swapped_ms) & 0xFFFFFFFFu));
    EXPECT_GE(ms, 0) << shot.path;
    latency.push_back(double(ms));
    // The picture over the whole quad, the seam between the tiles included.
    const double psnr = insetPsnr(shot.image, *shot.code, kX, kY, kW, kH);
    EXPECT_GT(psnr, 30.0) << shot.path;
    // ... and a test that can fail: the picture three frames earlier scores far lower.
    media::PatternCode earlier = *shot.code;
    earlier.frame -= 3;
    EXPECT_LT(insetPsnr(shot.image, earlier, kX, kY, kW, kH), psnr - 6.0) << shot.path;
  }
  EXPECT_GE(advanced * 4, shots.size()) << "the inset is not live: it moved on " << advanced
                                        << " of " << shots.size() << " screenshots";
  EXPECT_GE(previous, shots.front().code->frame + 15) << "half a second of video at least";
  std::sort(latency.begin(), latency.end());
  std::printf("glass-to-glass over %zu screenshots: median %.0f ms, max %.0f ms\n", latency.size(),
              latency[latency.size() / 2], latency.back());
  // Each tile decoded the inset (it spans both); the site said what it sent.
  for (Process* node : {&left, &right}) {
    const std::string decoded =
        test::captured(node->output(), "video: \\d+ packets \\(0 refused\\), (\\d+) pictures");
    ASSERT_FALSE(decoded.empty()) << node->output();
    EXPECT_GT(std::stoi(decoded), 60) << node->output();
  }
  EXPECT_TRUE(site.waitFor("video: sent \\d+ pictures", 1)) << site.output();
}

TEST(VideoSites, OnlyTheTilesThatShowAnInsetDecodeIt) {
  test::TempDir dir;
  const VideoWall s = writeSetup(dir.path(), {"master", "a"});
  // The inset within the left tile (0.05 .. 0.45 of the wall; the seam is at 0.5).
  const auto w = startWall(dir.path(), s, 5.0, 4.0, 1.0, {"--video-screen", "0.05,0.3,0.4"},
                           {"--video", "test", "--video-size", "320x240"});
  ASSERT_TRUE(w);
  Process &master = *w->master, &left = *w->left, &right = *w->right;
  ASSERT_EQ(master.wait(120), std::optional<int>(0)) << master.output();
  ASSERT_EQ(left.wait(15), std::optional<int>(0)) << left.output();
  ASSERT_EQ(right.wait(15), std::optional<int>(0)) << right.output();
  const std::regex stats(
      "video: (\\d+) packets \\(0 refused\\), (\\d+) pictures decoded, (\\d+) "
      "access units skipped");
  std::smatch l, r;
  const std::string left_log = left.output(), right_log = right.output();
  ASSERT_TRUE(std::regex_search(left_log, l, stats)) << left_log;
  ASSERT_TRUE(std::regex_search(right_log, r, stats)) << right_log;
  EXPECT_GT(std::stoi(l[2].str()), 60) << left_log;
  EXPECT_EQ(std::stoi(r[2].str()), 0) << "the right tile decoded an inset it does not show";
  EXPECT_GT(std::stoi(r[3].str()), 60) << right_log;
  EXPECT_EQ(l[1].str(), r[1].str()) << "both tiles received every packet";
}

TEST(VideoSites, WithoutAPinTheInsetStandsBesideTheAvatarAndTheTilesThatSeeItDecodeIt) {
  test::TempDir dir;
  const VideoWall s = writeSetup(dir.path(), {"master", "a"});
  const auto w = startWall(dir.path(), s, 5.0, 4.0, 1.0, {});
  ASSERT_TRUE(w);
  Process &master = *w->master, &left = *w->left, &right = *w->right;
  // The site stands in front of the wall's camera, a little left, looking into the scene.
  test::writeText(dir / "moved.json", R"({"actions": [{"frame": 0, "camera": )" +
                                          test::cameraJson({-0.3, 0.05, 0.4}, {0.2, 0.0, -1.0}) +
                                          "}]}");
  Process site(test::headlessSite(TESSERA_SITE, w->sites, s.keys.at("master"), "site a",
                                  dir / "a.key", dir.path(), dir / "moved.json",
                                  {"--no-render", "--video", "test", "--video-size", "320x240"}),
               dir / "a.log");
  ASSERT_EQ(master.wait(120), std::optional<int>(0)) << master.output();
  ASSERT_EQ(left.wait(15), std::optional<int>(0)) << left.output();
  ASSERT_EQ(right.wait(15), std::optional<int>(0)) << right.output();
  EXPECT_TRUE(master.waitFor("sends video \\(320x240\\): inset \\d+ beside its avatar", 1))
      << master.output();
  int decoded = 0;
  for (Process* node : {&left, &right}) {
    const std::string d = test::captured(node->output(), "(\\d+) pictures decoded");
    ASSERT_FALSE(d.empty()) << node->output();
    decoded += std::stoi(d);
  }
  EXPECT_GT(decoded, 30) << "no tile decoded the inset beside the avatar";
}

TEST(VideoSites, AnotherSiteSeesTheInsetInItsOwnView) {
  test::TempDir dir;
  const VideoWall s = writeSetup(dir.path(), {"master", "a", "b"});
  // Pinned to the screen: on a site's own 640x480 view at 0.1, 0.1, 0.8 wide, 512x384 pixels
  // from (64, 48).
  const auto w = startWall(dir.path(), s, 7.0, 6.0, 1.0, {"--video-screen", "0.1,0.1,0.8"},
                           {"--video", "test"});
  ASSERT_TRUE(w);
  test::writeText(dir / "viewer.json",
                  R"({"width": 640, "height": 480, "actions": [{"frame": 90, "screenshot": )"
                  R"("b-view.png"}, {"frame": 100, "bye": true}]})");
  fs::create_directories(dir / "b");
  Process viewer(test::headlessSite(TESSERA_SITE, w->sites, s.keys.at("master"), "site b",
                                    dir / "b.key", dir / "b", dir / "viewer.json", {}),
                 dir / "b.log");
  EXPECT_EQ(viewer.wait(120), std::optional<int>(0)) << viewer.output();
  ASSERT_EQ(w->master->wait(120), std::optional<int>(0)) << w->master->output();
  EXPECT_TRUE(viewer.waitFor("video from other sites: \\d+ packets, [1-9]\\d* pictures decoded", 1))
      << viewer.output();
  const render::Image view = render::readPng((dir / "b" / "b-view.png").string());
  ASSERT_EQ(view.width, 640u);
  const auto code = media::readTestPattern(view.rgba.data(), int(view.width), 64, 48, 512, 384);
  ASSERT_TRUE(code) << "no readable inset in site b's own view";
  EXPECT_GT(code->frame, 30u);
}

/// A site of this test process (collab::SiteClient): it sends what the test wants, good or bad.
struct TestSite {
  TestSite(const std::string& sites, const std::string& master_key, const fs::path& key_file,
           const std::string& name) {
    collab::SiteClientOptions o;
    o.master = sites;
    o.master_key = master_key;
    o.keys = collab::readKeyFile(key_file);
    o.name = name;
    client = std::make_unique<collab::SiteClient>(o);
    participant = client->join(graph, collab::SiteClient::Clock::now() + std::chrono::seconds(20))
                      .participant();
  }
  void send(const std::vector<uint8_t>& bytes) {
    site::ToMaster m;
    m.set_video(bytes.data(), bytes.size());
    client->send(m);
  }
  void keepUp() { client->receive(graph, collab::SiteClient::Clock::now()); }

  sync::SceneGraph graph;
  std::unique_ptr<collab::SiteClient> client;
  uint32_t participant = 0;
};

TEST(VideoSites, DamagedTruncatedOversizedAndFloodingVideoNeverShowsOrStopsTheWall) {
  test::TempDir dir;
  const VideoWall s = writeSetup(dir.path(), {"master", "good", "bad", "big", "flood"});
  // Insets 0.45 of the wall wide (360x270 pixels at (40, 270)): the flooding site's inset
  // goes beside the good one's.
  const auto w = startWall(dir.path(), s, 10.0, 1.5, 0.2,
                           {"--video-screen", "0.05,0.1,0.45", "--video-cap", "2000"});
  ASSERT_TRUE(w);
  Process &master = *w->master, &left = *w->left, &right = *w->right;
  const std::string& sites = w->sites;
  TestSite good(sites, s.keys.at("master"), dir / "good.key", "good");
  media::VideoSettings vs;
  media::VideoSender sender(vs, uint16_t(good.participant));
  std::mt19937 rng(11);
  media::VideoPicture picture;
  // Frames 0..89 clean, 90..179 damaged (payload bytes randomised, access units cut to a few
  // bytes, chunks left out), 180.. clean again: 30 a second.
  const uint32_t kDamagedFrom = 90, kCleanAgain = 180, kEnd = 240;
  const auto start = std::chrono::steady_clock::now();
  for (uint32_t f = 0; f < kEnd; ++f) {
    std::this_thread::sleep_until(start + std::chrono::milliseconds(f * 1000 / 30));
    media::drawTestPattern(picture, vs.width, vs.height, {f, media::patternClockMs()});
    for (std::vector<uint8_t> bytes : sender.send(picture)) {
      if (f >= kDamagedFrom && f < kCleanAgain) {
        media::VideoPacket p;
        ASSERT_EQ(media::decodeVideoPacket(bytes, p), std::nullopt);
        if (f % 7 == 0) continue;                                                 // missing
        if (f % 3 == 0) p.payload.resize(std::min<size_t>(p.payload.size(), 9));  // truncated
        for (size_t i = 4; i < p.payload.size(); i += 5) p.payload[i] = uint8_t(rng());
        bytes = media::encodeVideoPacket(p);
      }
      good.send(bytes);
    }
    good.keepUp();
    if (f == 40) {  // a site whose packet does not check: dropped, the wall goes on
      TestSite bad(sites, s.keys.at("master"), dir / "bad.key", "bad");
      media::VideoPacket p;
      p.width = 640;
      p.height = 480;
      p.payload.assign(2000, 0x42);
      std::vector<uint8_t> b = media::encodeVideoPacket(p);
      b.resize(b.size() - 3);  // the payload size field no longer matches
      bad.send(b);
      TestSite big(sites, s.keys.at("master"), dir / "big.key", "big");
      p.payload.assign(media::kMaxVideoChunkBytes, 0x42);
      std::vector<uint8_t> oversized = media::encodeVideoPacket(p);
      oversized.resize(oversized.size() + 4000, 0x42);  // 20 kB: more than a packet may be
      big.send(oversized);
      // A site sending twice the cap for a second: throttled, its chunks dropped.
      TestSite flood(sites, s.keys.at("master"), dir / "flood.key", "flood");
      p.payload.assign(media::kMaxVideoChunkBytes, 0);
      for (int k = 0; k < 100; ++k) {
        p.frame = uint32_t(k);
        std::generate(p.payload.begin(), p.payload.end(), [&] { return uint8_t(rng()); });
        flood.send(media::encodeVideoPacket(p));
        if (k % 10 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
      // The bad site hears why it was dropped.
      bool told = false;
      for (int k = 0; k < 50 && !told; ++k) {
        try {
          bad.keepUp();
        } catch (const collab::SiteSessionEnded& e) {
          told = std::string(e.what()).find("payload size 2000 but 1997") != std::string::npos;
          EXPECT_TRUE(told) << e.what();
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      EXPECT_TRUE(told);
    }
  }
  ASSERT_EQ(master.wait(120), std::optional<int>(0)) << master.output();
  EXPECT_EQ(left.wait(15), std::optional<int>(0)) << left.output();
  EXPECT_EQ(right.wait(15), std::optional<int>(0)) << right.output();
  const std::string log = master.output();
  EXPECT_NE(log.find("dropped: a bad message: video: video packet: payload size"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("dropped: a bad message: video: video packet: 20016 bytes, more than"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("video over its cap of 2000 kbit/s: chunks dropped"), std::string::npos)
      << log;
  EXPECT_GT(std::stoi(test::captured(log, "\\((\\d+) dropped over the cap\\)")), 0) << log;
  // The nodes met the damage and said so, and went on.
  EXPECT_NE(left.output().find("the inset keeps its last good picture"), std::string::npos)
      << left.output();
  const std::string errors =
      test::captured(left.output(),
                     "pictures decoded, \\d+ access units skipped \\([^)]*\\), "
                     "(\\d+) decoding errors");
  ASSERT_FALSE(errors.empty()) << left.output();

  // Every screenshot: a readable pattern of a clean frame (a damaged one never shows), and
  // the last ones from after the damage (recovered).
  const std::vector<Shot> shots = readShots(log, 40, 270, 360, 270);
  ASSERT_GE(shots.size(), 30u);
  int during = 0, after = 0;
  for (const Shot& shot : shots) {
    if (!shot.code) {
      // Before the good site's first picture the inset is not there yet; after it, always.
      EXPECT_EQ(after + during, 0) << shot.path << ": an unreadable inset";
      continue;
    }
    const uint32_t f = shot.code->frame;
    EXPECT_TRUE(f < kDamagedFrom || f >= kCleanAgain)
        << shot.path << " shows frame " << f << ", which was damaged";
    during += f == kDamagedFrom - 1;
    after += f >= kCleanAgain;
  }
  std::printf("%zu screenshots: %d showed the last good picture during the damage, %d after\n",
              shots.size(), during, after);
  EXPECT_GT(during, 3) << "the inset kept its last good picture while the damage lasted";
  EXPECT_GT(after, 3) << "the inset recovered";
}

}  // namespace
