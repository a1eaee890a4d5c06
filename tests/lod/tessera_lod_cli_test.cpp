// The tessera-lod command as a user runs it: output, JSON keys and exit codes.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <array>
#include <cstdio>
#include <string>

#include "../support/command.h"
#include "../support/temp_dir.h"

namespace {

const std::string kData = TESSERA_DATA_DIR;
const std::string kTool = TESSERA_LOD_TOOL;

using tessera::test::CommandResult;

CommandResult run(const std::string& args) {
  return tessera::test::runCommand(kTool + " " + args);
}

TEST(TesseraLodCli, InfoJsonHasTheDocumentedKeys) {
  CommandResult r = run("info --json " + kData + "/lidar/autzen_trim.las");
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* key : {"\"format\": \"las\"", "\"points\": 110000", "\"triangles\": 0",
                          "\"bbox_min\": [636001.76", "\"bbox_max\": [637179.22",
                          "\"attributes\": [\"color\", \"intensity\", \"classification\"]",
                          "\"skipped\": {}", "\"scans\": []"}) {
    EXPECT_NE(r.out.find(key), std::string::npos) << key << " in " << r.out;
  }
  CommandResult conf = run("info --json " + kData + "/stanford-bunny/scans/bun.conf");
  ASSERT_EQ(conf.code, 0) << conf.out;
  EXPECT_NE(conf.out.find("\"points\": 362272"), std::string::npos);
  EXPECT_NE(conf.out.find("\"name\": \"ear_back.ply\", \"points\": 32193, \"grid\": [512, 400]"),
            std::string::npos)
      << conf.out;
}

TEST(TesseraLodCli, BadInputExitsNonZeroWithTheMessage) {
  CommandResult laz = run("info " + kData + "/lidar/autzen_trim.laz");
  EXPECT_EQ(laz.code, 1);
  EXPECT_NE(laz.out.find("LAZ-compressed"), std::string::npos) << laz.out;
  // One bad file among good ones: the good ones are still described.
  CommandResult mixed = run("info " + kData + "/lidar/1.2-with-color.las /nonexistent.ply");
  EXPECT_EQ(mixed.code, 1);
  EXPECT_NE(mixed.out.find("points: 1065"), std::string::npos) << mixed.out;
  EXPECT_NE(mixed.out.find("/nonexistent.ply: no such file"), std::string::npos) << mixed.out;
  CommandResult usage = run("scan");
  EXPECT_NE(usage.code, 0);
  CommandResult res =
      run("scan " + kData +
          "/stanford-bunny/reconstruction/bun_zipper_res4.ply -o /tmp/x --resolution 12by4");
  EXPECT_EQ(res.code, 2);
  EXPECT_NE(res.out.find("expected WxH"), std::string::npos) << res.out;
  CommandResult cloud = run("scan " + kData + "/stanford-bunny/scans/bun000.ply -o /tmp/x");
  EXPECT_EQ(cloud.code, 1);
  EXPECT_NE(cloud.out.find("no triangles"), std::string::npos) << cloud.out;
}

TEST(TesseraLodCli, HelpOnEverySubcommand) {
  for (const char* sub : {"", "info ", "scan ", "build ", "verify "}) {
    CommandResult r = run(std::string(sub) + "--help");
    EXPECT_EQ(r.code, 0) << sub;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << sub << r.out;
  }
}

TEST(TesseraLodCli, ScanWritesAConfThatInfoReads) {
  tessera::test::TempDir dir;
  CommandResult r =
      run("scan " + kData + "/stanford-bunny/reconstruction/bun_zipper_res2.ply -o " +
          dir.path().string() + " --scanners 3 --resolution 128x100 --noise-mm 0.2 --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  CommandResult info = run("info --json " + (dir / "scans.conf").string());
  ASSERT_EQ(info.code, 0) << info.out;
  EXPECT_NE(info.out.find("\"grid\": [128, 100]"), std::string::npos) << info.out;
}

}  // namespace

namespace {

using tessera::test::TempDir;

TEST(TesseraLodBuild, BuildInfoVerifyRoundTrip) {
  TempDir dir;
  std::string out = (dir / "a.tlod").string();
  CommandResult b = run("build " + kData + "/lidar/autzen_trim.las -o " + out + " --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  CommandResult i = run("info --json " + out);
  ASSERT_EQ(i.code, 0) << i.out;
  for (const char* key : {"\"format\": \"tlod\"", "\"points\": 110000", "\"nodes\": ",
                          "\"depth\": ", "\"bytes_per_point\": ", "\"spacing_root\": ",
                          "\"spacing_finest\": ", "\"bbox_min\": [636001.76"}) {
    EXPECT_NE(i.out.find(key), std::string::npos) << key << " in " << i.out;
  }
  CommandResult v = run("verify " + out + " " + kData + "/lidar/autzen_trim.las --quiet");
  EXPECT_EQ(v.code, 0) << v.out;
  EXPECT_NE(v.out.find("OK"), std::string::npos);
  // Verifying against other data fails with exit code 4.
  CommandResult w = run("verify " + out + " " + kData + "/lidar/1.2-with-color.las --quiet");
  EXPECT_EQ(w.code, 4) << w.out;
}

TEST(TesseraLodBuild, BadInputsFailBeforeAnyWork) {
  TempDir dir;
  std::string out = (dir / "a.tlod").string();
  CommandResult m =
      run("build " + kData + "/lidar/autzen_trim.las /nonexistent.las -o " + out + " --quiet");
  EXPECT_EQ(m.code, 1);
  EXPECT_NE(m.out.find("/nonexistent.las: no such file"), std::string::npos) << m.out;
  CommandResult laz = run("build " + kData + "/lidar/autzen_trim.laz -o " + out + " --quiet");
  EXPECT_EQ(laz.code, 1);
  EXPECT_NE(laz.out.find("LAZ-compressed"), std::string::npos) << laz.out;
  CommandResult d = run("build " + dir.path().string() + " -o " + out + " --quiet");
  EXPECT_EQ(d.code, 1);
  EXPECT_FALSE(std::filesystem::exists(out));
  CommandResult v = run("info " + kData + "/lidar/autzen_trim.las.tlod");
  EXPECT_EQ(v.code, 1);
}

TEST(TesseraLodBuild, DiskFullLeavesNoOutput) {
  TempDir dir;
  std::string out = (dir / "a.tlod").string();
  // A file-size limit makes every write past 64 kB fail as on a full disk (EFBIG).
  CommandResult r =
      run("build " + kData + "/lidar/autzen_trim.las -o " + out + " --quiet 2>&1; true");
  ASSERT_TRUE(std::filesystem::exists(out));
  std::filesystem::remove(out);
  std::string cmd = "sh -c \"trap '' XFSZ; ulimit -f 128; exec " + kTool + " build " + kData +
                    "/lidar/autzen_trim.las -o " + out + " --quiet\" 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  std::string text;
  char buf[512];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) text.append(buf, n);
  int status = pclose(p);
  EXPECT_EQ(WEXITSTATUS(status), 3) << text;
  EXPECT_NE(text.find("disk full?"), std::string::npos) << text;
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_FALSE(std::filesystem::exists(out + ".partial"));
}

TEST(TesseraLodBuild, KilledBuildLeavesNoHalfFile) {
  TempDir dir;
  std::string out = (dir / "b.tlod").string();
  // Kill the build at several moments: the output is either absent or complete and valid.
  for (int ms : {50, 150, 300, 600}) {
    std::filesystem::remove(out);
    std::string cmd = "sh -c '" + kTool + " build " + kData + "/stanford-bunny/scans/bun.conf -o " +
                      out + " --quiet & pid=$!; sleep " + std::to_string(ms / 1000.0) +
                      "; kill -9 $pid; wait $pid' 2>/dev/null";
    int rc = std::system(cmd.c_str());
    (void)rc;
    if (std::filesystem::exists(out)) {
      CommandResult v =
          run("verify " + out + " " + kData + "/stanford-bunny/scans/bun.conf --quiet");
      EXPECT_EQ(v.code, 0) << "killed after " << ms
                           << " ms: output exists but does not verify: " << v.out;
    }
    CommandResult i = run("info " + out + ".partial");
    EXPECT_NE(i.code, 0) << "a partial file must never open as a store";
  }
}

}  // namespace
