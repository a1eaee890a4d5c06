// The tessera-lod command as a user runs it: output, JSON keys and exit codes.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

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
  EXPECT_EQ(laz.code, 0) << laz.out;
  EXPECT_NE(laz.out.find("LAZ 1.2 format 3"), std::string::npos) << laz.out;
  EXPECT_NE(laz.out.find("110000"), std::string::npos) << laz.out;
  // A LAZ file cut short: the chunk and its bytes are named.
  tessera::test::TempDir dir;
  std::ifstream in(kData + "/lidar/autzen_trim.laz", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(dir / "cut.laz", std::ios::binary).write(bytes.data(), 400000);
  CommandResult cut = run("build " + (dir / "cut.laz").string() + " -o " +
                          (dir / "cut.tlod").string() + " --quiet");
  EXPECT_EQ(cut.code, 1) << cut.out;
  EXPECT_NE(cut.out.find("cut.laz"), std::string::npos) << cut.out;
  EXPECT_NE(cut.out.find("chunk"), std::string::npos) << cut.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "cut.tlod"));
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
  CommandResult d = run("build " + dir.path().string() + " -o " + out + " --quiet");
  EXPECT_EQ(d.code, 1);
  EXPECT_FALSE(std::filesystem::exists(out));
  CommandResult v = run("info " + kData + "/lidar/autzen_trim.las.tlod");
  EXPECT_EQ(v.code, 1);
}

TEST(TesseraLodBuild, ALazBuildsAStoreThatVerifiesAgainstItsLasTwin) {
  TempDir dir;
  const std::string out = (dir / "laz.tlod").string();
  CommandResult b = run("build " + kData + "/lidar/autzen_trim.laz -o " + out + " --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  CommandResult v = run("verify " + out + " " + kData + "/lidar/autzen_trim.las --quiet");
  EXPECT_EQ(v.code, 0) << v.out;
  EXPECT_NE(v.out.find("OK"), std::string::npos) << v.out;
}

TEST(TesseraLodExport, CutsAScanAndRefusesBadRequestsWithTheirExitCodes) {
  TempDir dir;
  const std::string out = (dir / "cut.laz").string();
  CommandResult e = run("export " + kData + "/lidar/autzen_trim.laz -o " + out +
                        " --box 636500,849000,0,637000,849400,1000 --quiet");
  ASSERT_EQ(e.code, 0) << e.out;
  EXPECT_NE(e.out.find("38155 of 110000 points"), std::string::npos) << e.out;
  CommandResult i = run("info " + out);
  EXPECT_NE(i.out.find("points: 38155"), std::string::npos) << i.out;
  // The output is an input: refused before anything is written (exit 2).
  CommandResult same = run("export " + out + " -o " + out);
  EXPECT_EQ(same.code, 2) << same.out;
  EXPECT_NE(same.out.find("refusing to write over an input"), std::string::npos) << same.out;
  CommandResult box = run("export " + out + " -o " + (dir / "b.las").string() + " --box 1,2,3");
  EXPECT_EQ(box.code, 2) << box.out;
  EXPECT_NE(box.out.find("expected 6 numbers"), std::string::npos) << box.out;
  CommandResult nan = run("export " + out + " -o " + (dir / "b.las").string() +
                          " --plane 0,0,nan,1");
  EXPECT_EQ(nan.code, 2) << nan.out;
  CommandResult zero = run("export " + out + " -o " + (dir / "b.las").string() +
                           " --plane 0,0,0,1");
  EXPECT_EQ(zero.code, 2) << zero.out;
  EXPECT_NE(zero.out.find("normal (A,B,C) is zero"), std::string::npos) << zero.out;
  CommandResult kind = run("export " + out + " -o " + (dir / "b.xyz").string());
  EXPECT_EQ(kind.code, 3) << kind.out;
  EXPECT_NE(kind.out.find(".las, .laz or .ply"), std::string::npos) << kind.out;
  CommandResult bad = run("export /nonexistent.las -o " + (dir / "b.las").string());
  EXPECT_EQ(bad.code, 1) << bad.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "b.las"));
}

TEST(TesseraLodBuild, AnE57sScansAreSourcesOfTheirOwnAsAConfsAre) {
  TempDir dir;
  const std::string out = (dir / "e.tlod").string();
  CommandResult b = run("build " + kData + "/e57/bunnyDouble.e57 " + kData +
                        "/lidar/1.2-with-color.las -o " + out + " --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  CommandResult i = run("info " + out);
  // The scan is named by its file and the name its data3D element gives it.
  EXPECT_NE(i.out.find("[0] bunnyDouble.e57:"), std::string::npos) << i.out;
  EXPECT_NE(i.out.find("[1] 1.2-with-color.las"), std::string::npos) << i.out;
}

TEST(TesseraLodBuild, ExactLeavesByDefaultLossyOnRequest) {
  // Leaves keep the file's 1 cm integers by default (--exact-leaves says the same); verify
  // checks every point's integers; --lossy stores them within their bound and says so.
  TempDir dir;
  const std::string las = kData + "/lidar/autzen_trim.las";
  for (const std::string flag : {"", " --exact-leaves"}) {
    const std::string out = (dir / "exact.tlod").string();
    std::filesystem::remove(out);
    ASSERT_EQ(run("build " + las + " -o " + out + flag + " --quiet").code, 0);
    CommandResult v = run("verify " + out + " " + las + " --quiet");
    EXPECT_EQ(v.code, 0) << v.out;
    EXPECT_NE(v.out.find("110000 matched, 0 unmatched"), std::string::npos) << v.out;
    EXPECT_NE(v.out.find("exact leaves: 110000 of 110000"), std::string::npos) << v.out;
    CommandResult i = run("info " + out);
    EXPECT_NE(i.out.find("leaves: exact (the input's integers at 0.01)"), std::string::npos)
        << i.out;
  }
  const std::string lossy = (dir / "lossy.tlod").string();
  ASSERT_EQ(run("build " + las + " -o " + lossy + " --lossy --quiet").code, 0);
  CommandResult v = run("verify " + lossy + " " + las + " --quiet");
  EXPECT_EQ(v.code, 0) << v.out;
  EXPECT_NE(v.out.find("within its error bound"), std::string::npos) << v.out;
  EXPECT_EQ(v.out.find("exact leaves:"), std::string::npos) << v.out;
  EXPECT_LT(std::filesystem::file_size(lossy), std::filesystem::file_size(dir / "exact.tlod"));
  // Both at once is a bad command line, and nothing is written.
  const std::string both = (dir / "both.tlod").string();
  CommandResult b = run("build " + las + " -o " + both + " --lossy --exact-leaves 2>&1");
  EXPECT_EQ(b.code, 2) << b.out;
  EXPECT_NE(b.out.find("--lossy and --exact-leaves contradict each other"), std::string::npos)
      << b.out;
  EXPECT_FALSE(std::filesystem::exists(both));
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

// No lost input, no crash, no hang from anything a user can type.
namespace {

using tessera::test::TempDir;

/// Bytes of a file, to show it was not touched.
std::string contentOf(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(TesseraLodHardening, AnOutputThatIsAnInputIsRefusedBeforeAnythingIsWritten) {
  TempDir dir;
  const auto scan = dir / "copy.las";
  std::filesystem::copy_file(kData + "/lidar/1.2-with-color.las", scan);
  const std::string before = contentOf(scan);
  std::filesystem::create_symlink(scan, dir / "link.las");
  std::filesystem::create_hard_link(scan, dir / "hard.las");
  // Before: exit 0, and copy.las was a store.
  for (const std::string& out : {scan.string(), (dir / "." / "copy.las").string(),
                                 (dir / "link.las").string(), (dir / "hard.las").string()}) {
    CommandResult r = run("build " + scan.string() + " -o " + out + " --quiet");
    EXPECT_EQ(r.code, 2) << out << ": " << r.out;
    EXPECT_NE(r.out.find("refusing to write over an input"), std::string::npos) << r.out;
    EXPECT_TRUE(contentOf(scan) == before) << out;
    EXPECT_FALSE(std::filesystem::exists(out + ".partial"));
    EXPECT_FALSE(std::filesystem::exists(out + ".build-tmp"));
  }
  // One input among several, and a scan a .conf lists.
  CommandResult several = run("build " + kData + "/lidar/autzen_trim.las " + scan.string() +
                              " -o " + (dir / "link.las").string() + " --quiet");
  EXPECT_EQ(several.code, 2) << several.out;
  std::filesystem::copy_file(kData + "/stanford-bunny/scans/bun000.ply", dir / "bun000.ply");
  tessera::test::writeText(dir / "one.conf", "bmesh bun000.ply 0 0 0 0 0 0 1\n");
  const std::string scan_before = contentOf(dir / "bun000.ply");
  CommandResult conf = run("build " + (dir / "one.conf").string() + " -o " +
                           (dir / "bun000.ply").string() + " --quiet");
  EXPECT_EQ(conf.code, 2) << conf.out;
  EXPECT_TRUE(contentOf(dir / "bun000.ply") == scan_before);
  EXPECT_TRUE(contentOf(scan) == before);
}

TEST(TesseraLodHardening, PhotoAndScanNeverWriteOverTheirInput) {
  TempDir dir;
  // Never decoded: the refusal comes before anything is read or written.
  tessera::test::writeText(dir / "p.png", "the user's only copy of the photo");
  const std::string before = contentOf(dir / "p.png");
  for (const char* out : {"p.png", "./p.png"}) {
    CommandResult r = run("photo " + (dir / "p.png").string() +
                          " --corner 0,0,0 --u 1,0,0 --v 0,1,0 --quiet -o " + (dir / out).string());
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find("refusing to write over an input"), std::string::npos) << r.out;
    EXPECT_TRUE(contentOf(dir / "p.png") == before);
  }
  // The scanner writes scan_NNN.ply and scans.conf into -o: the mesh may be one of them.
  std::filesystem::copy_file(kData + "/stanford-bunny/reconstruction/bun_zipper_res4.ply",
                             dir / "scan_001.ply");
  const std::string mesh = contentOf(dir / "scan_001.ply");
  CommandResult s = run("scan " + (dir / "scan_001.ply").string() + " -o " + dir.path().string() +
                        " --scanners 3 --resolution 16x16 --quiet");
  EXPECT_EQ(s.code, 2) << s.out;
  EXPECT_NE(s.out.find("refusing to write over an input"), std::string::npos) << s.out;
  EXPECT_TRUE(contentOf(dir / "scan_001.ply") == mesh);
  EXPECT_FALSE(std::filesystem::exists(dir / "scans.conf"));
}

TEST(TesseraLodHardening, FifosAndDevicesAreRefusedNotWaitedOn) {
  TempDir dir;
  const auto fifo = dir / "f.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Before: blocked forever in open(); `timeout` turns a hang into exit 124.
  for (const std::string& args :
       {"info " + fifo.string(), "build " + fifo.string() + " -o " + (dir / "o.tlod").string(),
        "verify " + fifo.string() + " " + kData + "/lidar/1.2-with-color.las",
        std::string("info /dev/zero"), "build /dev/null -o " + (dir / "n.tlod").string()}) {
    CommandResult r = tessera::test::runCommand("timeout 20 " + kTool + " " + args + " --quiet");
    EXPECT_EQ(r.code, 1) << args << ": " << r.out;
    EXPECT_NE(r.out.find("not a regular file"), std::string::npos) << args << ": " << r.out;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "o.tlod.build-tmp"));
  // The options file is read by CLI11 itself, before any validator.
  CommandResult config = tessera::test::runCommand("timeout 20 " + kTool + " --config " +
                                                   fifo.string() + " info " + fifo.string());
  EXPECT_EQ(config.code, 2) << config.out;
  EXPECT_NE(config.out.find("--config " + fifo.string() + ": not a regular file (a FIFO"),
            std::string::npos)
      << config.out;
}

TEST(TesseraLodHardening, AConfThatNamesItselfIsACycleNotACrash) {
  TempDir dir;
  tessera::test::writeText(dir / "self.conf", "bmesh self.conf 0 0 0 0 0 0 1\n");
  tessera::test::writeText(dir / "a.conf", "bmesh b.conf 0 0 0 0 0 0 1\n");
  tessera::test::writeText(dir / "b.conf", "bmesh ./a.conf 0 0 0 0 0 0 1\n");
  // Before: recursion until SIGSEGV (exit -1 here).
  for (const char* conf : {"self.conf", "a.conf"}) {
    for (const std::string& args :
         {"info " + (dir / conf).string(),
          "build " + (dir / conf).string() + " -o " + (dir / "x.tlod").string() + " --quiet"}) {
      CommandResult r = run(args);
      EXPECT_EQ(r.code, 1) << args << ": " << r.out;
      EXPECT_NE(r.out.find("cycle"), std::string::npos) << r.out;
      EXPECT_NE(r.out.find(conf), std::string::npos) << r.out;
    }
  }
}

TEST(TesseraLodHardening, TooManyThreadsIsABadCommandLineAndLeavesNothing) {
  TempDir dir;
  const std::string out = (dir / "t.tlod").string();
  // Before: an uncaught std::system_error (abort) and t.tlod.build-tmp left behind.
  CommandResult r =
      run("build " + kData + "/lidar/1.2-with-color.las -o " + out + " --threads 100000 --quiet");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--threads: at most 256"), std::string::npos) << r.out;
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
  CommandResult ok =
      run("build " + kData + "/lidar/1.2-with-color.las -o " + out + " --threads 256 --quiet");
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_FALSE(std::filesystem::exists(out + ".build-tmp"));
}

}  // namespace

/// Builds the Stanford bunny mesh `ply` (a file of reconstruction/) into dir/b.tmesh: the
/// build's exit code and output.
CommandResult buildBunnyStore(const tessera::test::TempDir& dir, const std::string& ply,
                              int patch_triangles) {
  return run("build " + kData + "/stanford-bunny/reconstruction/" + ply + " -o " +
             (dir.path() / "b.tmesh").string() + " --patch-triangles " +
             std::to_string(patch_triangles) + " --quiet");
}

TEST(TesseraLodMesh, BuildInfoVerifyRoundTripAndBadInput) {
  tessera::test::TempDir dir;
  const std::string mesh = kData + "/stanford-bunny/reconstruction/bun_zipper_res2.ply";
  const std::string out = (dir.path() / "b.tmesh").string();
  CommandResult b = buildBunnyStore(dir, "bun_zipper_res2.ply", 512);
  ASSERT_EQ(b.code, 0) << b.out;
  EXPECT_NE(b.out.find("16301 triangles (0 dropped)"), std::string::npos) << b.out;
  EXPECT_NE(b.out.find("bytes/triangle"), std::string::npos) << b.out;
  EXPECT_FALSE(std::filesystem::exists(out + ".partial"));
  CommandResult i = run("info " + out);
  ASSERT_EQ(i.code, 0) << i.out;
  EXPECT_NE(i.out.find("Tessera mesh store (.tmesh) version 1"), std::string::npos) << i.out;
  EXPECT_NE(i.out.find("16301 input triangles"), std::string::npos) << i.out;
  EXPECT_NE(i.out.find("depth 0: 1 patches"), std::string::npos) << i.out;
  CommandResult v = run("verify " + out + " " + mesh + " --quiet");
  ASSERT_EQ(v.code, 0) << v.out;
  EXPECT_NE(v.out.find("16301 matched, 0 missing, 0 extra"), std::string::npos) << v.out;
  // Against another mesh: triangles missing and extra, exit 4 (verification failed).
  CommandResult wrong =
      run("verify " + out + " " + kData + "/stanford-bunny/reconstruction/bun_zipper_res3.ply --quiet");
  EXPECT_EQ(wrong.code, 4) << wrong.out;
  EXPECT_NE(wrong.out.find("FAILED"), std::string::npos) << wrong.out;
  // A point cloud is not a mesh: exit 1, named.
  CommandResult points = run("build " + kData + "/lidar/1.2-with-color.las -o " +
                             (dir.path() / "p.tmesh").string() + " --quiet");
  EXPECT_EQ(points.code, 1) << points.out;
  EXPECT_NE(points.out.find("no triangles"), std::string::npos) << points.out;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "p.tmesh"));
  // Out of range options: exit 2, named.
  CommandResult patch = run("build " + mesh + " -o " + out + " --patch-triangles 10");
  EXPECT_EQ(patch.code, 2) << patch.out;
  EXPECT_NE(patch.out.find("--patch-triangles"), std::string::npos) << patch.out;
  CommandResult arity = run("build " + mesh + " -o " + out + " --arity nan");
  EXPECT_EQ(arity.code, 2) << arity.out;
  // The output must not be the input, by any path (here a hard link): exit 2, nothing written.
  const std::string copy = (dir.path() / "copy.ply").string();
  std::filesystem::copy_file(mesh, copy);
  std::filesystem::create_hard_link(copy, dir.path() / "copy.tmesh");
  CommandResult self = run("build " + copy + " -o " + (dir.path() / "copy.tmesh").string());
  EXPECT_EQ(self.code, 2) << self.out;
  EXPECT_EQ(std::filesystem::file_size(copy), std::filesystem::file_size(mesh));
  // A corrupt store: info and verify name the file and exit 1.
  {
    std::fstream f(out, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(20);
    f.put('\x7f');
  }
  CommandResult bad = run("info " + out);
  EXPECT_EQ(bad.code, 1) << bad.out;
  EXPECT_NE(bad.out.find("header checksum"), std::string::npos) << bad.out;
}

// `info`, plain and --json, on a mesh store alone and among other inputs. The JSON is parsed by
// Python's json module (independent of the writer) and its facts compared with the mesh.
TEST(TesseraLodMesh, InfoDescribesAMeshStoreInEveryForm) {
  tessera::test::TempDir dir;
  CommandResult b = buildBunnyStore(dir, "bun_zipper_res3.ply", 256);
  ASSERT_EQ(b.code, 0) << b.out;
  const std::string mesh = kData + "/stanford-bunny/reconstruction/bun_zipper_res3.ply";
  const std::string out = (dir.path() / "b.tmesh").string();
  CommandResult json = run("info --json " + out);
  ASSERT_EQ(json.code, 0) << json.out;  // before: exit 1, "unknown point format"
  std::filesystem::path saved = dir.path() / "info.json";
  std::ofstream(saved) << json.out;
  // The levels' patches add up to the nodes and their triangles to the stored ones; the mesh's
  // 1889 vertices less the 2 no triangle uses are its points.
  CommandResult facts = tessera::test::runCommand(
      "python3 -c 'import json, sys\n"
      "d = json.load(open(sys.argv[1]))\n"
      "levels = d[\"levels\"]\n"
      "print(d[\"format\"], d[\"version\"], d[\"points\"], d[\"vertices\"], d[\"triangles\"],\n"
      "      sum(l[\"patches\"] for l in levels) == d[\"nodes\"], len(levels) == d[\"depth\"],\n"
      "      levels[0][\"patches\"], sum(l[\"triangles\"] for l in levels) == "
      "d[\"stored_triangles\"],\n"
      "      d[\"stored_triangles\"] > d[\"triangles\"], d[\"attributes\"], d[\"skipped\"],\n"
      "      all(a < b for a, b in zip(d[\"bbox_min\"], d[\"bbox_max\"])), d[\"grid_step\"] > 0,\n"
      "      d[\"file_bytes\"] == " +
      std::to_string(std::filesystem::file_size(out)) + ")' " + saved.string());
  ASSERT_EQ(facts.code, 0) << facts.out << "\nfrom: " << json.out;
  EXPECT_EQ(facts.out, "tmesh 1 1887 1887 3851 True True 1 True True [] {} True True True\n")
      << json.out;
  // The plain form says the same.
  CommandResult plain = run("info " + out);
  ASSERT_EQ(plain.code, 0) << plain.out;
  EXPECT_NE(plain.out.find("3851 input triangles, 1887 vertices"), std::string::npos) << plain.out;
  // Among a point store and a scan, in either form: each described as itself.
  const std::string store = (dir.path() / "p.tlod").string();
  ASSERT_EQ(run("build " + kData + "/lidar/1.2-with-color.las -o " + store + " --quiet").code, 0);
  const std::string all = out + " " + store + " " + mesh;
  CommandResult mixed = run("info " + all);
  ASSERT_EQ(mixed.code, 0) << mixed.out;
  for (const char* fact : {"Tessera mesh store (.tmesh)", "format: tlod", "points: 1065",
                           "format: ply", "triangles: 3851"})
    EXPECT_NE(mixed.out.find(fact), std::string::npos) << fact << " in " << mixed.out;
  CommandResult array = run("info --json " + all);
  ASSERT_EQ(array.code, 0) << array.out;
  std::ofstream(saved) << array.out;
  CommandResult formats = tessera::test::runCommand(
      "python3 -c 'import json, sys\n"
      "print([(d[\"format\"], d[\"triangles\"]) for d in json.load(open(sys.argv[1]))])' " +
      saved.string());
  EXPECT_EQ(formats.out, "[('tmesh', 3851), ('tlod', 0), ('ply', 3851)]\n") << array.out;
  // A file named .tmesh that is not one, and a corrupt store: exit 1, the error in the object.
  const std::string fake = (dir.path() / "fake.tmesh").string();
  std::ofstream(fake) << std::string(4096, 'x');
  CommandResult bad = run("info --json " + fake);
  EXPECT_EQ(bad.code, 1) << bad.out;
  EXPECT_NE(bad.out.find("\"error\": \"lod::MeshStore: " + fake +
                         ": not a Tessera mesh store (.tmesh): wrong magic\""),
            std::string::npos)
      << bad.out;
}
