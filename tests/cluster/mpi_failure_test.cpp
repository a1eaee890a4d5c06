// The MPI job's failures as a user meets them: real mpirun jobs (master + 2 headless nodes on a
// small 1x2 wall, loopback), one rank made to fail in turn. Whichever rank it is, the master must
// name it (tile, host, pid) and the job must end with the one exit code the README documents for
// that kind of failure: 4 a node hung, 1 a node failed, 17 the master hung, mpirun's 137 a node
// killed by SIGKILL.
//
// Processes are stopped and killed by PID only: mpirun is the test's child, and a rank is only
// signalled after checking it descends from that mpirun. Every wait is bounded; ctest's TIMEOUT
// is the last guard. Nothing asserts on time.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/types.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "../support/command.h"
#include "../support/process.h"
#include "../support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using tessera::test::Process;
const std::string kData = TESSERA_DATA_DIR;
/// The master's --timeout in these jobs, seconds: how long a hung rank keeps the job waiting.
/// Every wait of the master has it, also a node's startup (a GL context, shaders) on two cores
/// shared with other jobs: short enough for a test, long enough never to catch a healthy node.
const std::string kTimeout = "10";
/// An upper bound for a job to end after its failure (startup of three processes on two shared
/// cores, the timeout, mpirun's teardown): only a guard against hanging, never asserted on.
constexpr double kJobEndS = 120.0;

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

/// The parent of `pid` (0 when it is gone).
pid_t parentOf(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string text;
  std::getline(stat, text);
  const size_t close = text.rfind(')');  // the command name may hold spaces and parentheses
  if (close == std::string::npos) return 0;
  char state = 0;
  int ppid = 0;
  if (std::sscanf(text.c_str() + close + 1, " %c %d", &state, &ppid) != 2) return 0;
  return pid_t(ppid);
}

bool descendsFrom(pid_t pid, pid_t ancestor) {
  for (int depth = 0; pid > 1 && depth < 16; ++depth) {
    pid = parentOf(pid);
    if (pid == ancestor) return true;
  }
  return false;
}

/// The command name of `pid` (/proc/PID/comm; empty when it is gone).
std::string commandName(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/comm");
  std::string comm;
  std::getline(in, comm);
  return comm;
}

/// The processes under `root` whose command name is `comm`.
std::vector<pid_t> descendantsNamed(pid_t root, const std::string& comm) {
  std::vector<pid_t> found;
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    const pid_t pid = pid_t(std::stol(name));
    if (commandName(pid) == comm && descendsFrom(pid, root)) found.push_back(pid);
  }
  return found;
}

/// A process this test stopped: continued and killed at the end if it is still there (mpirun
/// ends it when the job is aborted; this covers a test that failed before that).
class Stopped {
 public:
  /// Stops `pid` if it descends from `job` and its command name is `comm`.
  Stopped(pid_t pid, pid_t job, std::string comm) : mPid(pid), mComm(std::move(comm)) {
    if (descendsFrom(mPid, job) && commandName(mPid) == mComm) kill(mPid, SIGSTOP);
  }
  ~Stopped() {
    if (commandName(mPid) != mComm) return;  // gone, or the PID was reused: not ours
    kill(mPid, SIGKILL);
    kill(mPid, SIGCONT);
  }
  Stopped(const Stopped&) = delete;
  Stopped& operator=(const Stopped&) = delete;

 private:
  pid_t mPid;
  std::string mComm;
};

/// What the master said about each tile's node when it joined.
struct Joined {
  std::string tile, host;
  pid_t pid = 0;
  int rank = 0;
};

std::vector<Joined> joins(const std::string& log) {
  std::vector<Joined> out;
  const std::regex line(R"(tile (\S+) \(host ([^,]+), pid (\d+)\) joined \(rank (\d+)\))");
  for (auto it = std::sregex_iterator(log.begin(), log.end(), line); it != std::sregex_iterator();
       ++it)
    out.push_back({(*it)[1], (*it)[2], pid_t(std::stol((*it)[3])), std::stoi((*it)[4])});
  return out;
}

class MpiFailure : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new tessera::test::TempDir();
    const auto r = tessera::test::runCommand(std::string(TESSERA_LOD_TOOL) + " build " + kData +
                                             "/stanford-bunny/scans/bun000.ply -o " +
                                             (*sDir / "bunny.tlod").string() + " --quiet");
    ASSERT_EQ(r.code, 0) << r.out;
    write(*sDir / "scene.json",
          R"({"nodes": [{"kind": "MODEL", "name": "bunny", "model": {"store": "bunny.tlod"}}],
          "camera": {"eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027, "y": 0.1,
          "z": 0.0}, "up": {"y": 1}}, "settings": {"lodPixels": 1.0}})");
    write(*sDir / "wall.json", R"({"name": "small 1x2", "tiles": [
          {"name": "left", "x": 0, "y": 0, "width": 0.48, "height": 0.27, "pixelWidth": 160,
           "pixelHeight": 90},
          {"name": "right", "x": 0.5, "y": 0, "width": 0.48, "height": 0.27, "pixelWidth": 160,
           "pixelHeight": 90}], "eye": {"x": 0.49, "y": 0.135, "z": 1.5}})");
  }
  static void TearDownTestSuite() {
    delete sDir;
    sDir = nullptr;
  }

  /// mpirun: the master with `master_args` (frames paced at 20/s until stopped), then one app
  /// context per entry of `ranks` (each an argv, e.g. the node).
  static std::unique_ptr<Process> job(const std::vector<std::vector<std::string>>& ranks,
                                      const std::string& log_name,
                                      const std::vector<std::string>& master_args = {}) {
    std::vector<std::string> argv = {TESSERA_MPIRUN, "--oversubscribe"};
    if (getuid() == 0) argv.push_back("--allow-run-as-root");
    for (const std::string& a :
         {std::string("-np"), std::string("1"), std::string(TESSERA_MASTER), std::string("--wall"),
          (*sDir / "wall.json").string(), std::string("--scene"), (*sDir / "scene.json").string(),
          std::string("--timeout"), kTimeout})
      argv.push_back(a);
    if (master_args.empty()) {
      for (const char* a : {"--frames", "1000000", "--max-fps", "20"}) argv.push_back(a);
    } else {
      argv.insert(argv.end(), master_args.begin(), master_args.end());
    }
    for (const auto& rank : ranks) {
      argv.insert(argv.end(), {":", "-np", "1"});
      argv.insert(argv.end(), rank.begin(), rank.end());
    }
    return std::make_unique<Process>(argv, *sDir / log_name);
  }

  static std::vector<std::string> node() { return {TESSERA_NODE, "--headless"}; }

  static tessera::test::TempDir* sDir;
};
tessera::test::TempDir* MpiFailure::sDir = nullptr;

TEST_F(MpiFailure, AHungNodeIsNamedAndTheJobExits4WhicheverRankHangs) {
  // A node stopped (SIGSTOP) mid-run: the master's wait for its report ends after --timeout and
  // names that node, and only it; the job's code is 4 whether the first or the second rank hung.
  for (const std::string stopped_tile : {"left", "right"}) {
    SCOPED_TRACE("stopped: tile " + stopped_tile);
    auto mpirun = job({node(), node()}, "hung-" + stopped_tile + ".log");
    ASSERT_TRUE(mpirun->waitFor("mpi transport; 2 of 2 tiles have a node", kJobEndS))
        << mpirun->output();
    const std::vector<Joined> joined = joins(mpirun->output());
    ASSERT_EQ(joined.size(), 2u) << mpirun->output();
    const Joined* hung = nullptr;
    const Joined* live = nullptr;
    for (const Joined& j : joined) (j.tile == stopped_tile ? hung : live) = &j;
    ASSERT_TRUE(hung && live) << mpirun->output();
    ASSERT_TRUE(descendsFrom(hung->pid, mpirun->pid())) << "pid " << hung->pid;
    const Stopped stop(hung->pid, mpirun->pid(), "tessera-node");
    const std::optional<int> code = mpirun->wait(kJobEndS);
    ASSERT_TRUE(code.has_value()) << "the job did not end:\n" << mpirun->output();
    const std::string out = mpirun->output();
    EXPECT_EQ(*code, 4) << out;
    const std::string named = "tile " + hung->tile + " (host " + hung->host + ", pid " +
                              std::to_string(hung->pid) + ", rank " + std::to_string(hung->rank) +
                              "): hung: no report within " + kTimeout + " s";
    EXPECT_NE(out.find(named), std::string::npos) << "expected \"" << named << "\" in\n" << out;
    EXPECT_NE(out.find("1 of 2 render nodes hung"), std::string::npos) << out;
    EXPECT_EQ(
        out.find("tile " + live->tile + " (host " + live->host + ", pid " +
                 std::to_string(live->pid) + ", rank " + std::to_string(live->rank) + "): hung"),
        std::string::npos)
        << out;
    // The master decided: no node gave up on it first.
    EXPECT_EQ(out.find("from the master within"), std::string::npos) << out;
  }
}

TEST_F(MpiFailure, ARankThatNeverJoinsIsNamedAndTheJobExits4WhicheverRankItIs) {
  // A rank that starts MPI and never sends its hello, first or second: the master's wait for the
  // joins ends after --timeout naming that rank (it never said its host or pid).
  for (const int silent : {1, 2}) {
    SCOPED_TRACE("silent rank " + std::to_string(silent));
    std::vector<std::vector<std::string>> ranks = {node(), node()};
    ranks[size_t(silent - 1)] = {TESSERA_SILENT_RANK, "60"};
    auto mpirun = job(ranks, "silent-" + std::to_string(silent) + ".log");
    const std::optional<int> code = mpirun->wait(kJobEndS);
    ASSERT_TRUE(code.has_value()) << "the job did not end:\n" << mpirun->output();
    const std::string out = mpirun->output();
    EXPECT_EQ(*code, 4) << out;
    const std::string named = "rank " + std::to_string(silent) +
                              " (it never joined: its tile, host and pid are unknown): hung: no "
                              "join within " +
                              kTimeout + " s";
    EXPECT_NE(out.find(named), std::string::npos) << "expected \"" << named << "\" in\n" << out;
    EXPECT_NE(out.find("1 of 2 render nodes hung"), std::string::npos) << out;
    EXPECT_EQ(out.find("from the master within"), std::string::npos) << out;
  }
}

TEST_F(MpiFailure, AFailedNodeEndsEveryRankWithTheMastersCodeWhicheverRankFails) {
  // One node without GL (no EGL vendor library): it reports NODE_NO_GL (10) at startup, the
  // master names it and stops the wall with 1, and every rank exits with the master's 1 (the
  // nodes are wrapped to print their own exit code), so mpirun's is 1 whichever rank failed.
  for (const int failing : {1, 2}) {
    SCOPED_TRACE("failing rank " + std::to_string(failing));
    auto wrapped = [](const std::string& env) {
      return std::vector<std::string>{
          "/bin/sh", "-c",
          env +
              "\"$0\" --headless; code=$?; echo \"node rank exited $code\"; "
              "exit $code",
          TESSERA_NODE};
    };
    std::vector<std::vector<std::string>> ranks = {wrapped(""), wrapped("")};
    ranks[size_t(failing - 1)] = wrapped("__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent.json ");
    auto mpirun = job(ranks, "failed-" + std::to_string(failing) + ".log");
    const std::optional<int> code = mpirun->wait(kJobEndS);
    ASSERT_TRUE(code.has_value()) << "the job did not end:\n" << mpirun->output();
    const std::string out = mpirun->output();
    EXPECT_EQ(*code, 1) << out;
    const std::string tile = failing == 1 ? "left" : "right";
    EXPECT_TRUE(std::regex_search(
        out, std::regex("tile " + tile + R"( \(host [^,]+, pid \d+\) failed \(no GL, code 10\))")))
        << out;
    const std::regex exited(R"(node rank exited (\d+))");
    std::set<std::string> codes;
    for (auto it = std::sregex_iterator(out.begin(), out.end(), exited);
         it != std::sregex_iterator(); ++it)
      codes.insert((*it)[1]);
    EXPECT_TRUE(codes.empty() || codes == std::set<std::string>{"1"}) << out;
  }
}

TEST_F(MpiFailure, AKilledNodeEndsTheJobWithMpirunsCodeNamingItsRank) {
  // kill -9 of a node: mpirun notices, names the rank and the signal and exits 128 + 9, for the
  // first rank as for the second; the master's join lines map the rank to its tile.
  for (const std::string killed_tile : {"left", "right"}) {
    SCOPED_TRACE("killed: tile " + killed_tile);
    auto mpirun = job({node(), node()}, "killed-" + killed_tile + ".log");
    ASSERT_TRUE(mpirun->waitFor("mpi transport; 2 of 2 tiles have a node", kJobEndS))
        << mpirun->output();
    const std::vector<Joined> joined = joins(mpirun->output());
    const Joined* killed = nullptr;
    for (const Joined& j : joined)
      if (j.tile == killed_tile) killed = &j;
    ASSERT_TRUE(killed) << mpirun->output();
    ASSERT_TRUE(descendsFrom(killed->pid, mpirun->pid())) << "pid " << killed->pid;
    ASSERT_EQ(commandName(killed->pid), "tessera-node");
    kill(killed->pid, SIGKILL);
    const std::optional<int> code = mpirun->wait(kJobEndS);
    ASSERT_TRUE(code.has_value()) << "the job did not end:\n" << mpirun->output();
    const std::string out = mpirun->output();
    EXPECT_EQ(*code, 128 + SIGKILL) << out;
    EXPECT_NE(out.find("process rank " + std::to_string(killed->rank)), std::string::npos) << out;
    EXPECT_NE(out.find("exited on signal 9"), std::string::npos) << out;
  }
}

TEST_F(MpiFailure, AHungMasterEndsTheJobWith17) {
  // The master stopped mid-run: each node waits twice the master's --timeout for its next
  // message, then ends the job with NODE_MASTER_LOST (17), the same whichever node noticed.
  // The nodes' own --timeout as the master's: they give up after twice that, 20 s.
  const std::vector<std::string> quick_node = {TESSERA_NODE, "--headless", "--timeout", kTimeout};
  auto mpirun = job({quick_node, quick_node}, "master.log");
  ASSERT_TRUE(mpirun->waitFor("mpi transport; 2 of 2 tiles have a node", kJobEndS))
      << mpirun->output();
  const std::vector<pid_t> masters = descendantsNamed(mpirun->pid(), "tessera-master");
  ASSERT_EQ(masters.size(), 1u) << mpirun->output();
  const Stopped stop(masters[0], mpirun->pid(), "tessera-master");
  const std::optional<int> code = mpirun->wait(kJobEndS);
  ASSERT_TRUE(code.has_value()) << "the job did not end:\n" << mpirun->output();
  const std::string out = mpirun->output();
  EXPECT_EQ(*code, 17) << out;
  EXPECT_NE(out.find("no message from the master within 20 s (the master hung or died)"),
            std::string::npos)
      << out;
  // The nodes decided. (mpirun's teardown continues the stopped master before it kills it, and
  // what the master says then comes after.)
  const size_t nodes_said = out.find("from the master within");
  EXPECT_NE(nodes_said, std::string::npos) << out;
  const size_t master_said = out.find("render nodes hung");
  EXPECT_TRUE(master_said == std::string::npos || master_said > nodes_said) << out;
}

}  // namespace
