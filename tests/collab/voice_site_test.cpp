// Voice over the site link with real processes on loopback: tessera-master --voice
// with a one-tile wall and the wall room's microphone from a WAV file, and two headless
// tessera-site processes (no rendering), each talking from its own WAV file and writing what it
// hears. Each voice is a tone of its own pitch, so who hears whom is read from the spectra:
// the room hears both sites and not its own microphone; each site hears the wall and the other
// site and not itself.
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <thread>

#include <tessera/media/voice_alsa.h>
#include <tessera/media/voice_wav.h>

#include "../support/command.h"
#include "../support/process.h"
#include "../support/site_scripts.h"
#include "../support/temp_dir.h"
#include "../support/voice_path.h"

namespace {

namespace fs = std::filesystem;
using namespace tessera;
using test::Process;

constexpr double kWallHz = 300, kAHz = 500, kBHz = 700;

/// The power of each voice's pitch in a WAV file, dB.
struct Heard {
  double wall, a, b;
};

Heard heard(const fs::path& wav) {
  const std::vector<float> x = media::readVoiceWav(wav);
  return {test::db(test::power(x, kWallHz, 0, x.size())),
          test::db(test::power(x, kAHz, 0, x.size())), test::db(test::power(x, kBHz, 0, x.size()))};
}

/// A wall of one small tile and an empty scene in `dir` (wall.json, scene.json): the master's
/// loop and one node cost little, and the voices are what the test is about. Returns the camera.
std::string writeOneTileWall(const fs::path& dir) {
  test::writeText(dir / "wall.json",
                  R"({"name": "one tile", "tiles": [{"name": "tile", "x": 0, "y": 0, )"
                  R"("width": 0.48, "height": 0.27, "pixelWidth": 160, "pixelHeight": 90}], )"
                  R"("eye": {"x": 0.24, "y": 0.135, "z": 1.5}})");
  const std::string camera = test::cameraJson({0, 0, 1}, {0, 0, 0});
  test::writeText(dir / "scene.json", R"({"nodes": [], "camera": )" + camera + "}");
  return camera;
}

/// Key pairs for the master and `sites` in `dir` (NAME.key) and allow.txt admitting each site as
/// "site NAME": the public keys by name (empty after a failure, which is reported).
std::map<std::string, std::string> writeKeys(const fs::path& dir,
                                             const std::vector<std::string>& sites) {
  std::string allow;
  std::map<std::string, std::string> keys;
  std::vector<std::string> names = sites;
  names.insert(names.begin(), "master");
  for (const std::string& name : names) {
    const auto k = test::runCommand(std::string(TESSERA_SITE) + " keygen -o " +
                                    (dir / (name + ".key")).string());
    keys[name] = test::publicKeyOf(k.out);
    if (k.code != 0 || keys[name].size() != 40u) {
      ADD_FAILURE() << "keygen " << name << ": " << k.out;
      return {};
    }
    if (name != "master") allow += keys[name] + "  site " + name + "\n";
  }
  test::writeText(dir / "allow.txt", allow);
  return keys;
}

/// A master started with `argv` (masterWithSites) and its one-tile node, logging to `dir`, and
/// the endpoint sites join on ("" when the master did not say, which is reported).
struct VoiceWall {
  std::unique_ptr<Process> master, node;
  std::string sites;
};

VoiceWall startWall(const std::vector<std::string>& argv, const fs::path& dir) {
  VoiceWall w;
  w.master = std::make_unique<Process>(argv, dir / "master.log");
  if (!w.master->waitFor("remote sites join on (tcp://\\S+)", 30)) {
    ADD_FAILURE() << w.master->output();
    return w;
  }
  const std::string out = w.master->output();
  const std::string wall = test::captured(out, "listening on (tcp://\\S+)");
  w.sites = "tcp://127.0.0.1:" + test::captured(out, "remote sites join on tcp://[^:]+:(\\d+)");
  w.node = std::make_unique<Process>(
      std::vector<std::string>{TESSERA_NODE, "--master", wall, "--headless", "--tile", "tile"},
      dir / "node.log");
  test::writeText(dir / "still.json", R"({"actions": []})");
  return w;
}

TEST(VoiceSites, TheWallAndTwoSitesHearEachOtherButNotThemselves) {
  test::TempDir dir;
  auto keys = writeKeys(dir.path(), {"a", "b"});
  ASSERT_FALSE(keys.empty());
  const std::string camera = writeOneTileWall(dir.path());
  // 8 s of each voice (pausing every 1.2 s); the session lasts 14 s.
  media::writeWav(dir / "wall-mic.wav", test::talking(kWallHz, 8));
  media::writeWav(dir / "a-mic.wav", test::talking(kAHz, 8));
  media::writeWav(dir / "b-mic.wav", test::talking(kBHz, 8));

  const auto argv = test::masterWithSites(TESSERA_MASTER, dir.path(), dir.path(), 14.0, camera,
                                          {"--voice", "--audio-in", (dir / "wall-mic.wav").string(),
                                           "--audio-out", (dir / "room.wav").string()});
  VoiceWall w = startWall(argv, dir.path());
  ASSERT_FALSE(w.sites.empty());
  Process& master = *w.master;
  Process& node = *w.node;
  const std::string& sites = w.sites;
  std::vector<std::unique_ptr<Process>> site_processes;
  for (const std::string name : {"a", "b"})
    site_processes.push_back(std::make_unique<Process>(
        test::headlessSite(TESSERA_SITE, sites, keys["master"], "site " + name,
                           dir / (name + ".key"), dir.path(), dir / "still.json",
                           {"--no-render", "--audio-in", (dir / (name + "-mic.wav")).string(),
                            "--audio-out", (dir / (name + "-heard.wav")).string()}),
        dir / (name + ".log")));

  ASSERT_EQ(master.wait(120), std::optional<int>(0)) << master.output();
  EXPECT_EQ(node.wait(15), std::optional<int>(0)) << node.output();
  for (auto& s : site_processes) {
    EXPECT_EQ(s->wait(15), std::optional<int>(0)) << s->output();
    EXPECT_TRUE(s->waitFor("wrote what this site heard", 1)) << s->output();
  }
  const std::string log = master.output();
  EXPECT_EQ(log.find("dropped:"), std::string::npos) << log;
  const int in = std::stoi(test::captured(log, "voice: (\\d+) packets from sites"));
  const int sent = std::stoi(test::captured(log, "packets from sites, (\\d+) to them"));
  // Two sites talking 2/3 of 8 s at 50 packets a second: about 530 packets each.
  EXPECT_GT(in, 700) << log;
  EXPECT_GT(sent, 700) << log;

  const Heard room = heard(dir / "room.wav"), a = heard(dir / "a-heard.wav"),
              b = heard(dir / "b-heard.wav");
  std::printf("room: wall %.0f dB, A %.0f dB, B %.0f dB\n", room.wall, room.a, room.b);
  std::printf("A hears: wall %.0f dB, A %.0f dB, B %.0f dB\n", a.wall, a.a, a.b);
  std::printf("B hears: wall %.0f dB, B %.0f dB, A %.0f dB\n", b.wall, b.b, b.a);
  // Heard: a tone of 0.25 peak over part of the file is well above -50 dB; not heard: 25 dB
  // below what is.
  EXPECT_GT(std::min(room.a, room.b), -50);
  EXPECT_LT(room.wall, std::min(room.a, room.b) - 25) << "the room hears its own microphone";
  EXPECT_GT(std::min(a.wall, a.b), -50);
  EXPECT_LT(a.a, std::min(a.wall, a.b) - 25) << "site A hears itself";
  EXPECT_GT(std::min(b.wall, b.a), -50);
  EXPECT_LT(b.b, std::min(b.wall, b.a) - 25) << "site B hears itself";
}

// Sessions end as people end them. A site sent SIGTERM says goodbye and writes what it heard,
// as at the end of its script. The master run under `timeout`, which is sent SIGTERM (and
// passes it to the master and then to its whole group: two signals at once), ends the session
// once: its last picture and the room's audio written, the node and the site told, every
// process exiting 0.
TEST(VoiceSites, SignalsEndSessionsAsTheirScriptsDo) {
  test::TempDir dir;
  auto keys = writeKeys(dir.path(), {"a"});
  ASSERT_FALSE(keys.empty());
  const std::string camera = writeOneTileWall(dir.path());
  media::writeWav(dir / "wall-mic.wav", test::talking(kWallHz, 30));
  media::writeWav(dir / "a-mic.wav", test::talking(kAHz, 30));
  auto argv = test::masterWithSites(
      TESSERA_MASTER, dir.path(), dir.path(), 120.0, camera,
      {"--voice", "--audio-in", (dir / "wall-mic.wav").string(), "--audio-out",
       (dir / "room.wav").string(), "--screenshot", (dir / "wall.png").string()});
  argv.insert(argv.begin(), {"/usr/bin/timeout", "300"});
  VoiceWall w = startWall(argv, dir.path());
  ASSERT_FALSE(w.sites.empty());
  Process site(test::headlessSite(TESSERA_SITE, w.sites, keys["master"], "site a", dir / "a.key",
                                  dir.path(), dir / "still.json",
                                  {"--no-render", "--audio-in", (dir / "a-mic.wav").string(),
                                   "--audio-out", (dir / "a-heard.wav").string()}),
               dir / "a.log");
  ASSERT_TRUE(w.master->waitFor("site a\\S* .*joined", 60)) << w.master->output() << site.output();
  std::this_thread::sleep_for(std::chrono::seconds(3));  // a few seconds of voices

  site.signal(SIGTERM);
  EXPECT_EQ(site.wait(30), std::optional<int>(0)) << site.output();
  EXPECT_TRUE(site.waitFor("left \\(SIGTERM\\)", 1)) << site.output();
  EXPECT_TRUE(site.waitFor("wrote what this site heard", 1)) << site.output();
  EXPECT_GT(heard(dir / "a-heard.wav").wall, -50) << "the site's recording holds the wall";
  EXPECT_TRUE(w.master->waitFor("site a\\S* .*left: ", 30)) << w.master->output();
  EXPECT_EQ(w.master->output().find("site a dropped"), std::string::npos) << w.master->output();

  w.master->signal(SIGTERM);  // to `timeout`, which signals the master and then its group
  EXPECT_EQ(w.master->wait(120), std::optional<int>(0)) << w.master->output();
  EXPECT_TRUE(w.master->waitFor("SIGTERM: ending the session with frame \\d+", 1))
      << w.master->output();
  EXPECT_EQ(w.node->wait(30), std::optional<int>(0)) << w.node->output();
  EXPECT_TRUE(fs::exists(dir / "wall.png")) << w.master->output();
  EXPECT_GT(heard(dir / "room.wav").a, -50) << "the room's recording holds the site";
}

// An output written at the end that could not be written is refused at the start (exit 2),
// on the master and on a site.
TEST(VoiceSites, UnwritableOutputsAreRefusedAtTheStart) {
  test::TempDir dir;
  auto keys = writeKeys(dir.path(), {"a"});
  ASSERT_FALSE(keys.empty());
  const std::string camera = writeOneTileWall(dir.path());
  for (const char* option : {"--audio-out", "--screenshot", "--stats"}) {
    const bool stats = std::string(option) == "--stats";  // masterWithSites gives one
    std::vector<std::string> extra{"--voice"};
    if (!stats) extra.insert(extra.end(), {option, "/missing/dir/x.out"});
    auto argv = test::masterWithSites(TESSERA_MASTER, dir.path(), dir.path(), 5.0, camera, extra);
    if (stats) test::setOption(argv, "--stats", "/missing/dir/x.out");
    std::string command;
    for (const std::string& a : argv) command += "'" + a + "' ";
    const auto r = test::runCommand(command);
    EXPECT_EQ(r.code, 2) << option << ": " << r.out;
    EXPECT_NE(r.out.find(std::string(option) +
                         " /missing/dir/x.out: cannot be written: the folder /missing/dir does "
                         "not exist"),
              std::string::npos)
        << r.out;
  }
  const auto r = test::runCommand(
      std::string(TESSERA_SITE) + " --master tcp://127.0.0.1:9 --master-key '" + keys["master"] +
      "' --name x --key " + (dir / "a.key").string() +
      " --headless --no-render --join-timeout 1 --audio-out /missing/dir/heard.wav");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--audio-out /missing/dir/heard.wav: cannot be written"), std::string::npos)
      << r.out;
}

TEST(VoiceSites, VoiceOptionsAreChecked) {
  test::TempDir dir;
  writeOneTileWall(dir.path());
  const std::string master = std::string(TESSERA_MASTER) + " --transport zmq --listen " +
                             "tcp://127.0.0.1:* --wall " + (dir / "wall.json").string() +
                             " --scene " + (dir / "scene.json").string();
  auto r = test::runCommand(master + " --audio-out x.wav");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--audio-in and --audio-out need --voice"), std::string::npos) << r.out;
  r = test::runCommand(master + " --voice");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--voice needs --sites"), std::string::npos) << r.out;
  // A site whose microphone file is missing says which and stops before it joins.
  const auto k =
      test::runCommand(std::string(TESSERA_SITE) + " keygen -o " + (dir / "s.key").string());
  ASSERT_EQ(k.code, 0) << k.out;
  // (Z85 keys hold shell characters such as '(' and '&': quoted.)
  r = test::runCommand(std::string(TESSERA_SITE) + " --master tcp://127.0.0.1:9 --master-key '" +
                       test::publicKeyOf(k.out) + "' --name x --key " + (dir / "s.key").string() +
                       " --headless --no-render --join-timeout 1 --audio-in " +
                       (dir / "missing.wav").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("missing.wav: No such file"), std::string::npos) << r.out;
}

TEST(VoiceSites, SoundDevicesThroughAlsa) {
  try {
    media::AlsaPcm probe("null", media::AlsaPcm::Direction::kPlayback, 960);
  } catch (const media::AlsaError& e) {
    GTEST_SKIP() << "alsa-lib's null PCM cannot be opened here: " << e.what();
  }
  test::TempDir dir;
  auto keys = writeKeys(dir.path(), {"a"});
  ASSERT_FALSE(keys.empty());
  const std::string camera = writeOneTileWall(dir.path());
  // A site with an unknown device says which and stops before it joins.
  auto r =
      test::runCommand(std::string(TESSERA_SITE) + " --master tcp://127.0.0.1:9 --master-key '" +
                       keys["master"] + "' --name x --key " + (dir / "a.key").string() +
                       " --headless --no-render --join-timeout 1 --audio-out alsa:nosuchdevice");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("playback device 'nosuchdevice'"), std::string::npos) << r.out;

  // The wall room's microphone and speakers and a site's on alsa-lib's null device (silence in,
  // sound discarded): the session runs and ends as with files.
  const auto argv =
      test::masterWithSites(TESSERA_MASTER, dir.path(), dir.path(), 4.0, camera,
                            {"--voice", "--audio-in", "alsa:null", "--audio-out", "alsa:null"});
  VoiceWall w = startWall(argv, dir.path());
  ASSERT_FALSE(w.sites.empty());
  Process& master = *w.master;
  Process& node = *w.node;
  const std::string& sites = w.sites;
  Process site(
      test::headlessSite(TESSERA_SITE, sites, keys["master"], "site a", dir / "a.key", dir.path(),
                         dir / "still.json",
                         {"--no-render", "--audio-in", "alsa:null", "--audio-out", "alsa:null"}),
      dir / "a.log");
  ASSERT_EQ(master.wait(120), std::optional<int>(0)) << master.output();
  EXPECT_EQ(node.wait(15), std::optional<int>(0)) << node.output();
  EXPECT_EQ(site.wait(15), std::optional<int>(0)) << site.output();
  const std::string log = master.output();
  EXPECT_NE(log.find("the wall room's microphone: capture device 'null'"), std::string::npos)
      << log;
  EXPECT_NE(log.find("the wall room's speakers: playback device 'null'"), std::string::npos) << log;
  EXPECT_NE(log.find("voice: "), std::string::npos) << log;
  EXPECT_EQ(log.find("the wall room's audio:"), std::string::npos) << "no WAV file: " << log;
  EXPECT_NE(site.output().find("microphone capture device 'null'"), std::string::npos)
      << site.output();
  EXPECT_NE(site.output().find("speaker playback device 'null'"), std::string::npos)
      << site.output();
  EXPECT_EQ(site.output().find("wrote what this site heard"), std::string::npos) << site.output();
}

}  // namespace
