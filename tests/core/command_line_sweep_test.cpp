// Every numeric command-line option of every tool, given NaN, infinities, zero, negative and
// overflowing values, as a user would type them: each must exit 2 (README, "Exit codes") with
// a message naming the option, before any work. Real processes; each base command line is
// otherwise valid but names nothing that exists, so a value wrongly taken ends the run at once
// (exit 1) instead of rendering or building. No network beyond loopback.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "../support/command.h"

namespace {

using tessera::test::CommandResult;

struct Tool {
  const char* name;
  std::string base;  ///< the tool and an otherwise valid command line
};

/// One numeric option and what it takes.
struct Option {
  const char* name;
  bool zero_ok;      ///< 0 is a valid value
  bool integer;      ///< an integer option: 1.5 is refused
  bool wide = true;  ///< false: 32 bits, so 4294967297 is refused too
};

const std::string kTimeout = "timeout 60 ";

Tool lodScan() {
  return {"tessera-lod scan",
          kTimeout + TESSERA_LOD_TOOL + " scan /nonexistent.ply -o /nonexistent-dir"};
}
Tool lodBuild() {
  return {"tessera-lod build",
          kTimeout + TESSERA_LOD_TOOL + " build /nonexistent.las -o /nonexistent.tlod"};
}
Tool lodVerify() {
  return {"tessera-lod verify",
          kTimeout + TESSERA_LOD_TOOL + " verify /nonexistent.tlod /nonexistent.las"};
}
/// `photo` with its required vectors, but for `without` (the one under test).
Tool lodPhoto(const std::string& without = "") {
  std::string base = kTimeout + TESSERA_LOD_TOOL + " photo /nonexistent.png -o /nonexistent.tlod";
  for (const char* v : {"--corner=0,0,0", "--u=1,0,0", "--v=0,1,0"}) {
    if (without.empty() || std::string(v).rfind(without + "=", 0) != 0)
      base += " " + std::string(v);
  }
  return {"tessera-lod photo", base};
}
Tool render() {
  return {"tessera-render",
          kTimeout + TESSERA_RENDER_TOOL + " --model /nonexistent.tlod -o /nonexistent.png"};
}
Tool master() {
  return {"tessera-master",
          kTimeout + TESSERA_MASTER +
              " --transport zmq --listen tcp://127.0.0.1:* --wall /nonexistent.json --scene "
              "/nonexistent.json"};
}
Tool node() {
  // --join-timeout keeps a wrongly taken value's join short (nothing listens on port 9).
  return {"tessera-node", kTimeout + TESSERA_NODE + " --master tcp://127.0.0.1:9 --headless"};
}

Tool site() {
  // A syntactically valid master key; the key file does not exist, so a wrongly taken value
  // ends at reading it (a message that does not name the option under test).
  return {"tessera-site", kTimeout + TESSERA_SITE +
                              " --master tcp://127.0.0.1:9 --master-key "
                              "'rq:rM>}U?@Lns47E1%kR.o@n%FcmmsL/@{H8]yf7' --name x --key "
                              "/nonexistent.key --headless"};
}

std::vector<std::string> badValues(const Option& o) {
  std::vector<std::string> v = {
      "nan", "NaN", "inf", "-inf", "-1", "1e400", "-1e400", "18446744073709551617", "abc", "''"};
  if (!o.zero_ok) v.push_back("0");
  if (o.integer) {
    v.insert(v.end(), {"1.5", "1e3", "0x10", "99999999999999999999999"});
    if (!o.wide) v.push_back("4294967297");
  }
  return v;
}

void expectRefused(const Tool& tool, const std::string& option, const std::string& value) {
  // OPTION=VALUE: "-1" after a space could be taken for a short option by CLI11.
  const std::string cmd = tool.base + " " + option + "=" + value;
  const CommandResult r = tessera::test::runCommand(cmd);
  EXPECT_EQ(r.code, 2) << cmd << "\n" << r.out;
  EXPECT_NE(r.out.find(option), std::string::npos)
      << cmd << ": the message does not name " << option << ":\n"
      << r.out;
}

void sweep(const Tool& tool, const std::vector<Option>& options) {
  for (const Option& o : options) {
    for (const std::string& value : badValues(o)) expectRefused(tool, o.name, value);
  }
}

TEST(CommandLineSweep, TesseraLod) {
  sweep(lodScan(), {{"--scanners", false, true, false},
                    {"--noise-mm", true, false},
                    {"--units-per-mm", false, false},
                    {"--seed", true, true},
                    {"--max-incidence", true, false},
                    {"--threads", true, true, false}});
  sweep(lodBuild(), {{"--memory-mb", false, true}, {"--threads", true, true, false}});
  sweep(lodVerify(), {{"--memory-mb", false, true}});
  sweep(lodPhoto(), {{"--height-scale", true, false}, {"--seed", true, true}});
}

TEST(CommandLineSweep, TesseraLodComposites) {
  for (const char* res : {"4294967297x480", "512x4294967296", "0x480", "512x0", "-1x480", "nanx480",
                          "512x", "x400", "512x400x3", "65536x1", "1.5x400"}) {
    expectRefused(lodScan(), "--resolution", res);
  }
  for (const char* opt : {"--corner", "--u", "--v"}) {
    for (const char* v : {"nan,0,0", "0,inf,0", "0,0,-inf", "1e400,0,0", "1,2", "1,2,3,4"})
      expectRefused(lodPhoto(opt), opt, v);
  }
}

TEST(CommandLineSweep, TesseraLodConfigFileValuesAreCheckedAsTheCommandLine) {
  // tessera-lod --config F.toml: the same validators (before: noise-mm = nan was taken).
  const auto dir =
      std::filesystem::temp_directory_path() / ("tessera-sweep-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (const char* line : {"noise-mm = nan", "threads = 100000", "units-per-mm = 0",
                           "scanners = 4294967297", "seed = -1", "max-incidence = inf"}) {
    const auto toml = dir / "scan.toml";
    std::ofstream(toml) << "[scan]\n" << line << "\n";
    const std::string option = "--" + std::string(line).substr(0, std::string(line).find(' '));
    const CommandResult r =
        tessera::test::runCommand(kTimeout + TESSERA_LOD_TOOL + " --config " + toml.string() +
                                  " scan /nonexistent.ply -o /nonexistent-dir");
    EXPECT_EQ(r.code, 2) << line << "\n" << r.out;
    EXPECT_NE(r.out.find(option), std::string::npos) << line << "\n" << r.out;
  }
  std::filesystem::remove_all(dir);
}

TEST(CommandLineSweep, TesseraRender) {
  sweep(render(), {{"--fovy", false, false},
                   {"--lod-px", false, false},
                   {"--point-budget", true, true},
                   {"--points-per-pixel", true, false},
                   {"--splat-scale", false, false},
                   {"--gpu-budget-mb", false, false},
                   {"--loader-threads", true, true, false},
                   {"--spbr-L", false, true, false},
                   {"--spbr-progressive", true, true, false},
                   {"--spbr-max-k", false, false},
                   {"--frames", true, true, false},
                   {"--poster-part", false, true, false},
                   {"--poster-memory-mb", false, false},
                   {"--eye-separation", false, false},
                   {"--fps", false, false},
                   {"--preview-points", false, true}});
}

TEST(CommandLineSweep, TesseraRenderComposites) {
  for (const char* size :
       {"4294967297x480", "1280x4294967297", "0x480", "-1x480", "nanx480", "16385x480", "1280"}) {
    expectRefused(render(), "--size", size);
  }
  for (const char* size :
       {"0x100", "100x0", "nanx100", "-1x100", "65536x100", "100x4294967297", "100", "1.5x100"}) {
    expectRefused(render(), "--poster", size);
  }
  for (const char* bg : {"5,-1,nan", "nan,0,0", "0,0,inf", "2,0,0", "0,-0.5,0", "1,1"}) {
    expectRefused(render(), "--background", bg);
  }
  for (const char* camera :
       {"'eye=nan,0,0;target=0,0,0;up=0,1,0'", "'eye=0,0,5;target=0,0,inf;up=0,1,0'",
        "'eye=1,2,3;target=1,2,3;up=0,1,0'", "'eye=0,0,5;target=0,0,0;up=0,0,0'",
        "'eye=0,0,5;target=0,0,0;up=0,0,1'", "'eye=0,0,5;target=0,0,0;up=0,0,-3'",
        "'eye=0,0,5;target=0,0,0'", "'eye=0,0,5;target=0,0,0;up=0,1,0;up=0,1,0'"}) {
    expectRefused(render(), "--camera", camera);
  }
}

TEST(CommandLineSweep, TesseraMaster) {
  sweep(master(), {{"--frames", true, true, false},
                   {"--fps", false, false},
                   {"--max-fps", true, false},
                   {"--console-width", false, true, false},
                   {"--splat-scale", false, false},
                   {"--gpu-budget-mb", false, false},
                   {"--node-timeout", true, false},
                   {"--join-wait", true, false},
                   {"--first-frame-timeout", false, false},
                   {"--site-timeout", false, false},
                   {"--timeout", false, false},
                   {"--video-cap", false, false}});
  for (const char* v : {"nan,0.1,0.2", "0.1,inf,0.2", "0.9,0.1,0.2", "0.1,0.1,0", "0.1,0.1",
                        "0.1,0.1,0.2,0.3", "-0.1,0,0.5", "abc"})
    expectRefused(master(), "--video-screen", v);
  // A filmed path's --size, by its text, before anything is read.
  const Tool film{"tessera-master --path", master().base + " --path /nonexistent.json --movie "
                                                          "/nonexistent.mp4"};
  for (const char* size : {"0x480", "4294967297x480", "nanx480", "-1x480", "16385x480", "1280"})
    expectRefused(film, "--size", size);
}

TEST(CommandLineSweep, TesseraSite) {
  sweep(site(), {{"--join-timeout", false, false},
                 {"--video-kbps", false, true, false},
                 {"--video-fps", false, false}});
  for (const char* size : {"0x480", "641x480", "640x481", "nanx480", "15x15", "4096x480", "640"})
    expectRefused(site(), "--video-size", size);
  for (const std::string size : {"0x480", "4294967297x480", "640x0", "nanx480", "640", "15x15"}) {
    const CommandResult r =
        tessera::test::runCommand(site().base + " --size " + size + " --window --headless");
    EXPECT_EQ(r.code, 2) << size << "\n" << r.out;
  }
  for (const std::string size : {"0x480", "4294967297x480", "nanx480", "15x15"}) {
    const std::string cmd = kTimeout + TESSERA_SITE +
                            " --master tcp://127.0.0.1:9 --master-key "
                            "'rq:rM>}U?@Lns47E1%kR.o@n%FcmmsL/@{H8]yf7' --name x --key "
                            "/nonexistent.key --window --size " +
                            size;
    const CommandResult r = tessera::test::runCommand(cmd);
    EXPECT_EQ(r.code, 2) << cmd << "\n" << r.out;
    EXPECT_NE(r.out.find("--size"), std::string::npos) << cmd << "\n" << r.out;
  }
  // Names that are not 1..64 bytes of printable UTF-8, and keys that are not keys.
  for (const std::string& bad : std::vector<std::string>{
           "--name ''", "--name 'a\tb'", "--name " + std::string(65, 'n'), "--master-key short"}) {
    const std::string cmd = kTimeout + TESSERA_SITE +
                            " --master tcp://127.0.0.1:9 --master-key "
                            "'rq:rM>}U?@Lns47E1%kR.o@n%FcmmsL/@{H8]yf7' --name x --key "
                            "/nonexistent.key --headless " +
                            bad;
    const CommandResult r = tessera::test::runCommand(cmd);
    EXPECT_EQ(r.code, 2) << cmd << "\n" << r.out;
  }
}

Tool annotate(const std::string& sub) {
  // A database in a folder that does not exist: a value wrongly taken ends at opening it.
  return {"tessera-annotate", kTimeout + TESSERA_ANNOTATE_TOOL + " -d /nonexistent/x.tadb " + sub};
}

TEST(CommandLineSweep, TesseraAnnotate) {
  sweep(annotate("search crack"), {{"--limit", false, true}});
  const std::string add = "add --layer a --title t --at=0,0,0";
  sweep(annotate(add), {{"--radius", false, false},
                        {"--fovy", false, false},
                        {"--count", false, true}});
  sweep(annotate("add --layer a --title t --kind link"), {{"--link-item", false, true}});
  sweep(annotate("add --layer a --title t"), {{"--place", false, true}});
  // Any finite number is a number item's value; nothing else.
  for (const char* v : {"nan", "inf", "-inf", "1e400", "abc", "''"})
    expectRefused(annotate("add --layer a --title t --kind number"), "--number", v);
  for (const char* opt : {"--at", "--eye", "--target", "--up"}) {
    for (const char* v : {"nan,0,0", "0,inf,0", "0,0,-inf", "1e400,0,0", "1,2", "1,2,3,4", "abc"})
      expectRefused(annotate("add --layer a --title t --at=0,0,1 --radius 0.5 --eye=0,0,5"), opt,
                    v);
  }
  for (const char* v : {"nan,0,0", "1,2", "0,inf,0"}) {
    expectRefused(annotate("georef --crs EPSG:32633"), "--origin", v);
    expectRefused(annotate("export --format geojson -o /nonexistent/x.json --crs EPSG:32633"),
                  "--origin", v);
  }
}

TEST(CommandLineSweep, TesseraNode) {
  sweep(node(), {{"--join-timeout", false, false},
                 {"--wait-master", true, false},
                 {"--master-timeout", false, false},
                 {"--timeout", false, false}});
}

TEST(CommandLineSweep, ParseErrorsExitTwoAndHelpZero) {
  // Before: CLI11's own codes (105 validation, 106 required, 109 extras).
  for (const Tool& t : {lodScan(), render(), master(), node(), site()}) {
    const CommandResult extra = tessera::test::runCommand(t.base + " --no-such-option");
    EXPECT_EQ(extra.code, 2) << t.name << "\n" << extra.out;
    EXPECT_NE(extra.out.find("--no-such-option"), std::string::npos) << extra.out;
  }
  for (const std::string& tool : {std::string(TESSERA_LOD_TOOL) + " build",
                                  std::string(TESSERA_MASTER) + " --transport zmq"}) {
    const CommandResult missing = tessera::test::runCommand(kTimeout + tool);
    EXPECT_EQ(missing.code, 2) << tool << "\n" << missing.out;
    EXPECT_NE(missing.out.find("required"), std::string::npos) << missing.out;
  }
  for (const std::string& tool :
       {std::string(TESSERA_LOD_TOOL), std::string(TESSERA_RENDER_TOOL),
        std::string(TESSERA_MASTER), std::string(TESSERA_NODE), std::string(TESSERA_SITE)}) {
    const CommandResult help = tessera::test::runCommand(kTimeout + tool + " --help");
    EXPECT_EQ(help.code, 0) << tool << "\n" << help.out;
  }
}

}  // namespace
