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
