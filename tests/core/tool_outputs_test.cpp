// The tools that write (tessera-render -o and --stats, tessera-master --screenshot and --stats)
// never write over what they read, by any path, and say why an output cannot be written.
// (tessera-lod's own outputs: tests/lod/tessera_lod_cli_test.cpp.)
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "../support/command.h"
#include "../support/temp_dir.h"

namespace {

using tessera::test::CommandResult;
using tessera::test::runCommand;
using tessera::test::TempDir;

const std::string kData = TESSERA_DATA_DIR;

std::string contentOf(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// A 1065-point store, dir/s.tlod ("" if it could not be built).
std::string smallStore(const TempDir& dir) {
  const std::string store = (dir / "s.tlod").string();
  const CommandResult r = runCommand(std::string(TESSERA_LOD_TOOL) + " build " + kData +
                                     "/lidar/1.2-with-color.las -o " + store + " --quiet");
  return r.code == 0 ? store : "";
}

TEST(ToolOutputs, RenderNeverWritesOverItsInputs) {
  TempDir dir;
  const std::string store = smallStore(dir);
  ASSERT_FALSE(store.empty());
  std::filesystem::create_symlink(store, dir / "link.tlod");
  const std::string before = contentOf(store);
  const std::string render = "EGL_PLATFORM=surfaceless timeout 120 " +
                             std::string(TESSERA_RENDER_TOOL) + " --size 32x24 --model " + store;
  // Before: the store was replaced by a PNG (exit 0).
  for (const std::string& args : {" -o " + store, " -o " + (dir / "." / "s.tlod").string(),
                                  " -o " + (dir / "link.tlod").string(),
                                  " -o " + (dir / "a.png").string() + " --stats " + store}) {
    const CommandResult r = runCommand(render + args);
    EXPECT_EQ(r.code, 2) << args << ": " << r.out;
    EXPECT_NE(r.out.find("refusing to write over an input"), std::string::npos) << r.out;
    EXPECT_TRUE(contentOf(store) == before) << args;
  }
  const CommandResult same = runCommand(render + " -o " + (dir / "a.png").string() + " --stats " +
                                        (dir / "a.png").string());
  EXPECT_EQ(same.code, 2) << same.out;
  EXPECT_NE(same.out.find("are the same file"), std::string::npos) << same.out;
  // A --stats folder that does not exist: say so (before: "cannot write").
  const CommandResult folder = runCommand(render + " -o " + (dir / "a.png").string() + " --stats " +
                                          (dir / "none" / "s.csv").string());
  EXPECT_EQ(folder.code, 2) << folder.out;
  EXPECT_NE(folder.out.find("does not exist"), std::string::npos) << folder.out;
}

/// A PNG file's width and height from its header (0, 0 when it is not a PNG).
std::pair<uint32_t, uint32_t> pngSize(const std::filesystem::path& p) {
  const std::string b = contentOf(p);
  if (b.size() < 24 || b.compare(1, 3, "PNG") != 0) return {0, 0};
  auto be = [&](size_t at) {
    return uint32_t(uint8_t(b[at])) << 24 | uint32_t(uint8_t(b[at + 1])) << 16 |
           uint32_t(uint8_t(b[at + 2])) << 8 | uint32_t(uint8_t(b[at + 3]));
  };
  return {be(16), be(20)};
}

// Posters, stereo pictures and movies from the command line: what each writes, and what each
// refuses (a bad path file: exit 1 naming it; an output that cannot be made: exit 3 saying why;
// too little poster memory and a movie over an input: exit 2).
TEST(ToolOutputs, RenderWritesPostersStereoPicturesAndMovies) {
  TempDir dir;
  const std::string store = smallStore(dir);
  ASSERT_FALSE(store.empty());
  const std::string render = "EGL_PLATFORM=surfaceless timeout 300 " +
                             std::string(TESSERA_RENDER_TOOL) + " --edl --model " + store;
  const CommandResult poster =
      runCommand(render + " --poster 100x70 --poster-part 32 -o " + (dir / "poster.png").string());
  ASSERT_EQ(poster.code, 0) << poster.out;
  EXPECT_NE(poster.out.find("4x3 parts"), std::string::npos) << poster.out;
  EXPECT_EQ(pngSize(dir / "poster.png"), std::make_pair(100u, 70u));
  const CommandResult memory = runCommand(
      render + " --poster 65535x65535 --poster-memory-mb 1 -o " + (dir / "big.png").string());
  EXPECT_EQ(memory.code, 2) << memory.out;
  EXPECT_NE(memory.out.find("needs at least"), std::string::npos) << memory.out;

  const std::string small = render + " --size 64x48";
  ASSERT_EQ(runCommand(small + " --stereo sbs -o " + (dir / "sbs.png").string()).code, 0);
  EXPECT_EQ(pngSize(dir / "sbs.png"), std::make_pair(128u, 48u));
  ASSERT_EQ(runCommand(small + " --stereo tb -o " + (dir / "tb.png").string()).code, 0);
  EXPECT_EQ(pngSize(dir / "tb.png"), std::make_pair(64u, 96u));
  ASSERT_EQ(runCommand(small + " --stereo pair -o " + (dir / "pair.png").string()).code, 0);
  EXPECT_EQ(pngSize(dir / "pair-left.png"), std::make_pair(64u, 48u));
  EXPECT_EQ(pngSize(dir / "pair-right.png"), std::make_pair(64u, 48u));
  EXPECT_FALSE(std::filesystem::exists(dir / "pair.png"));

  // A path of 0.5 s at 4 fps: 3 frames.
  const auto path = dir / "path.json";
  std::ofstream(path) << R"({"keyframes": [
    {"time": 0, "eye": {"x": 0, "y": 0, "z": 50}, "target": {"x": 0, "y": 0, "z": 0},
     "up": {"x": 0, "y": 1, "z": 0}},
    {"time": 0.5, "eye": {"x": 10, "y": 0, "z": 50}, "target": {"x": 0, "y": 0, "z": 0},
     "up": {"x": 0, "y": 1, "z": 0}}]})";
  const std::string movie = small + " --path " + path.string() + " --fps 4";
  const CommandResult ok = runCommand(movie + " --movie " + (dir / "m.mp4").string() +
                                      " --frames-dir " + (dir / "frames").string());
  ASSERT_EQ(ok.code, 0) << ok.out;
  EXPECT_NE(ok.out.find("3 frames"), std::string::npos) << ok.out;
  EXPECT_GT(std::filesystem::file_size(dir / "m.mp4"), 100u);
  EXPECT_EQ(pngSize(dir / "frames" / "frame-000002.png"), std::make_pair(64u, 48u));
  EXPECT_FALSE(std::filesystem::exists(dir / "frames" / "frame-000003.png"));
  const auto bad = dir / "bad.json";
  std::ofstream(bad) << R"({"keyframes": [{"time": 1.0}, {"time": 0.5}]})";
  const CommandResult refused =
      runCommand(small + " --path " + bad.string() + " --movie " + (dir / "b.mp4").string());
  EXPECT_EQ(refused.code, 1) << refused.out;
  EXPECT_NE(refused.out.find(bad.string()), std::string::npos) << refused.out;
  const CommandResult unwritable =
      runCommand(movie + " --movie " + (dir / "none" / "m.mp4").string());
  EXPECT_EQ(unwritable.code, 3) << unwritable.out;
  EXPECT_NE(unwritable.out.find("cannot create " + (dir / "none" / "m.mp4").string()),
            std::string::npos)
      << unwritable.out;
  const CommandResult over = runCommand(movie + " --movie " + store);
  EXPECT_EQ(over.code, 2) << over.out;
  EXPECT_NE(over.out.find("refusing to write over an input"), std::string::npos) << over.out;
}

TEST(ToolOutputs, MasterNeverWritesOverItsConfigs) {
  TempDir dir;
  for (const char* f : {"w.json", "s.json"}) std::ofstream(dir / f) << "{}";
  const std::string base = "timeout 60 " + std::string(TESSERA_MASTER) +
                           " --transport zmq --listen tcp://127.0.0.1:* --wall " +
                           (dir / "w.json").string() + " --scene " + (dir / "s.json").string();
  for (const std::string& args : {" --screenshot " + (dir / "w.json").string(),
                                  " --stats " + (dir / "." / "s.json").string()}) {
    const CommandResult r = runCommand(base + args);
    EXPECT_EQ(r.code, 2) << args << ": " << r.out;
    EXPECT_NE(r.out.find("refusing to write over an input"), std::string::npos) << r.out;
    EXPECT_EQ(contentOf(dir / "w.json"), "{}");
    EXPECT_EQ(contentOf(dir / "s.json"), "{}");
  }
}

/// tessera-master on a one-tile wall (w.json) and a scene of dir/s.tlod (s.json) in `dir`, over
/// ZeroMQ on loopback, with `args`; the store is built first.
CommandResult runMaster(const TempDir& dir, const std::string& args) {
  if (smallStore(dir).empty()) return {};
  std::ofstream(dir / "s.json") << R"({"camera": {"eye": {"z": 100}, "target": {}, "up": {"y": 1}},
    "nodes": [{"kind": "MODEL", "model": {"store": "s.tlod"}}]})";
  std::ofstream(dir / "w.json") << R"({"tiles": [{"name": "a", "width": 1, "height": 1,
    "pixelWidth": 16, "pixelHeight": 16}], "eye": {"z": 2}})";
  return runCommand("timeout 60 " + std::string(TESSERA_MASTER) +
                    " --transport zmq --listen tcp://127.0.0.1:* --join-wait 0 --wall " +
                    (dir / "w.json").string() + " --scene " + (dir / "s.json").string() + " " +
                    args);
}

TEST(ToolOutputs, MasterNeverWritesOverTheScenesStores) {
  TempDir dir;
  const CommandResult r = runMaster(dir, "--screenshot " + (dir / "." / "s.tlod").string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("refusing to write over an input"), std::string::npos) << r.out;
  EXPECT_EQ(contentOf(dir / "s.tlod").substr(0, 4), "TLOD");
}

TEST(ToolOutputs, MasterSaysWhyItsStatsCannotBeWritten) {
  TempDir dir;
  // Refused at the start (a bad command line), with the reason.
  const CommandResult r = runMaster(dir, "--stats " + (dir / "none" / "stats.csv").string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("cannot be written: the folder " + (dir / "none").string() +
                       " does not exist"),
            std::string::npos)
      << r.out;
}

}  // namespace
