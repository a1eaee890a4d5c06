// bench/cluster_link: the cluster link's cost and its behaviour under faults.
//
//  1. Frame overhead: what a frame costs beyond rendering (the master's frame time minus the
//     slowest node's render time: take the frame, send it, collect the reports, release the
//     swap), for 1, 2, 4 and 8 nodes, MPI against ZeroMQ, at a light scene (tiny tiles, a far
//     LOD threshold) so the protocol shows; bytes per frame on the wire for both.
//  2. Fault timeline (ZeroMQ, 4 nodes): frame times around a kill -9 of one node, how many
//     frames were late and by how much, the time from the kill to the master dropping the tile,
//     the frame rate before and after, and the time from a restarted node's process start to its
//     tile being back in the wall (warm page cache, then cold: the store evicted with
//     posix_fadvise(DONTNEED)).
//
// Every process runs on THIS machine (2 cores for up to 9 processes): the overhead includes the
// scheduling of oversubscribed processes, equally for both transports.
//
//   cluster_link [--frames N] [--nodes 1,2,4,8] [--node-timeout MS] [--out DIR]
//
// Writes DIR/cluster_link_overhead.csv, cluster_link_timeline.csv, cluster_link_faults.csv and
// cluster_link.png (gnuplot); prints the figures.
#include <CLI/CLI.hpp>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <tessera/lod/store_builder.h>

#include "../tests/support/process.h"
#include "bench_walls.h"

namespace {

namespace fs = std::filesystem;
using tessera::test::Process;
using Clock = std::chrono::steady_clock;

struct Row {  // one CSV row of tessera-master --stats
  uint64_t frame = 0;
  std::string tile, state;
  double render_ms = 0, frame_ms = 0, start_s = 0;
};

std::vector<Row> readStats(const fs::path& csv) {
  std::vector<Row> rows;
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    if (f.size() < 19) continue;
    Row r;
    r.frame = std::stoull(f[0]);
    r.tile = f[3];
    r.render_ms = std::stod(f[6]);
    r.frame_ms = std::stod(f[9]);
    r.state = f[17];
    r.start_s = std::stod(f[18]);
    rows.push_back(r);
  }
  return rows;
}

double now_s() {
  return std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
}

struct Overhead {
  double overhead_ms = 0, frame_ms = 0, render_ms = 0, sent_per_frame = 0, received_per_frame = 0;
};

/// Mean over frames past the first 10: frame - slowest render; bytes from the master's summary.
Overhead summarize(const fs::path& stats, const std::string& log) {
  std::map<uint64_t, std::pair<double, double>> per_frame;  // frame_ms, slowest render
  for (const Row& r : readStats(stats)) {
    auto& f = per_frame[r.frame];
    if (r.tile == "master")
      f.first = r.frame_ms;
    else
      f.second = std::max(f.second, r.render_ms);
  }
  Overhead o;
  int n = 0;
  for (const auto& [frame, f] : per_frame) {
    if (frame <= 10) continue;
    o.overhead_ms += f.first - f.second;
    o.frame_ms += f.first;
    o.render_ms += f.second;
    ++n;
  }
  if (n) {
    o.overhead_ms /= n;
    o.frame_ms /= n;
    o.render_ms /= n;
  }
  std::smatch m;
  if (std::regex_search(log, m,
                        std::regex("sent (\\d+) bytes in \\d+ messages, received (\\d+) bytes in "
                                   "\\d+ messages, over (\\d+) frames"))) {
    const double frames = std::stod(m[3].str());
    o.sent_per_frame = std::stod(m[1].str()) / frames;
    o.received_per_frame = std::stod(m[2].str()) / frames;
  }
  return o;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Waits until the stats CSV has a row of `frame` (or `timeout_s`, or the master ended).
bool waitForFrame(Process& master, const fs::path& stats, uint64_t frame, double timeout_s) {
  const double end = now_s() + timeout_s;
  while (now_s() < end && master.running()) {
    const auto rows = readStats(stats);
    if (!rows.empty() && rows.back().frame >= frame) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

/// The last frame in the stats CSV (0 before the first).
uint64_t lastFrame(const fs::path& stats) {
  const std::vector<Row> rows = readStats(stats);
  return rows.empty() ? 0 : rows.back().frame;
}

/// Drops `path` from the page cache (clean pages only; no root needed).
void evict(const fs::path& path) {
  const int fd = open(path.c_str(), O_RDONLY);
  if (fd < 0) return;
  fdatasync(fd);
  posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
  close(fd);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cluster_link: the cluster link's frame overhead (MPI against ZeroMQ) and a "
      "fault timeline (kill -9, drop, restart, rejoin)"};
  std::string out = TESSERA_BENCH_RESULTS_DIR, nodes_list = "1,2,4,8";
  int frames = 200, rounds = 3;
  double node_timeout_ms = 500;
  app.add_option("--frames", frames, "Frames per overhead run")->check(CLI::Range(20, 100000));
  app.add_option("--rounds", rounds,
                 "Overhead runs per transport and node count, interleaved; the median is kept")
      ->check(CLI::Range(1, 50))
      ->capture_default_str();
  app.add_option("--nodes", nodes_list, "Node counts for the overhead runs (1, 2, 4, 8)")
      ->capture_default_str();
  app.add_option("--node-timeout", node_timeout_ms, "The fault run's --node-timeout, ms")
      ->check(CLI::Range(50.0, 60000.0))
      ->capture_default_str();
  app.add_option("--out", out, "Results folder")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  const fs::path dir = fs::path(out) / "cluster_link";
  fs::create_directories(dir);
  const fs::path store = dir / "bunny.tlod";
  if (!fs::exists(store)) {
    tessera::lod::BuildOptions o;
    o.quiet = true;
    tessera::lod::buildStore({fs::path(TESSERA_DATA_DIR) / "stanford-bunny/scans/bun.conf"},
                             store.string(), o);
  }
  // Light: a coarse LOD cut, plain colour.
  std::ofstream(dir / "scene.json")
      << R"({"nodes": [{"kind": "MODEL", "name": "bunny scans", "model": {"store": ")"
      << fs::absolute(store).string()
      << R"("}}], "camera": {"eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027,
      "y": 0.1, "z": 0}, "up": {"y": 1}}, "settings": {"background": {"r": 0.05, "g": 0.05,
      "b": 0.08}, "lodPixels": 8, "shading": "SHADING_COLOR"}})";
  const std::string bin = fs::canonical("/proc/self/exe").parent_path().parent_path().string();
  const std::string master = bin + "/master/tessera-master",
                    node = bin + "/render_node/tessera-node";
  const std::string mpirun =
      std::string("mpirun --oversubscribe") + (getuid() == 0 ? " --allow-run-as-root" : "");

  // ---- 1. overhead ----
  std::vector<int> counts;
  {
    std::stringstream ks(nodes_list);
    for (std::string k_text; std::getline(ks, k_text, ',');) {
      const int k = std::stoi(k_text);
      if (k != 1 && k != 2 && k != 4 && k != 8) {
        std::cerr << "cluster_link: --nodes: " << k << " is not 1, 2, 4 or 8\n";
        return 2;
      }
      counts.push_back(k);
      std::ofstream(dir / ("wall-" + std::to_string(k) + ".json"))
          << tessera::bench::gridWallJson(k, 256, 144);
    }
  }
  // One run: the transport's figures for k nodes.
  auto overheadRun = [&](const std::string& transport, int k) -> std::optional<Overhead> {
    const std::string tag = transport + "-" + std::to_string(k);
    const fs::path wall = dir / ("wall-" + std::to_string(k) + ".json");
    const fs::path stats = dir / ("stats-" + tag + ".csv"), log = dir / ("log-" + tag + ".txt");
    fs::remove(log);
    const std::string common = " --wall " + wall.string() + " --scene " +
                               (dir / "scene.json").string() + " --frames " +
                               std::to_string(frames) + " --stats " + stats.string();
    if (transport == "mpi") {
      const std::string cmd = mpirun + " -np 1 " + master + common + " : -np " + std::to_string(k) +
                              " " + node + " --headless > " + log.string() + " 2>&1";
      if (std::system(cmd.c_str()) != 0) return std::nullopt;
    } else {
      std::vector<std::string> args = {master, "--transport", "zmq", "--listen",
                                       "tcp://127.0.0.1:*"};
      std::stringstream cs(common);
      for (std::string a; cs >> a;) args.push_back(a);
      Process m(args, log);
      if (!m.waitFor("listening on (tcp://\\S+)", 30)) return std::nullopt;
      std::smatch em;
      const std::string mo = m.output();
      std::regex_search(mo, em, std::regex("listening on (tcp://\\S+)"));
      std::vector<std::unique_ptr<Process>> ns;
      for (int i = 0; i < k; ++i)
        ns.push_back(std::make_unique<Process>(
            std::vector<std::string>{node, "--master", em[1].str(), "--headless"},
            dir / ("node-" + tag + ".txt")));
      if (m.wait(600) != std::optional<int>(0)) return std::nullopt;
      for (auto& n : ns) n->wait(10);
    }
    return summarize(stats, slurp(log));
  };
  std::map<std::pair<std::string, int>, std::vector<Overhead>> runs;
  for (int round = 1; round <= rounds; ++round) {
    for (int k : counts) {
      for (const std::string transport : {"mpi", "zmq"}) {
        std::cerr << "cluster_link: round " << round << "/" << rounds << ", " << transport << ", "
                  << k << " nodes ...\n";
        const auto o = overheadRun(transport, k);
        if (!o) {
          std::cerr << "cluster_link: the " << transport << " run with " << k
                    << " nodes failed; see "
                    << (dir / ("log-" + transport + "-" + std::to_string(k) + ".txt")) << "\n";
          return 1;
        }
        runs[{transport, k}].push_back(*o);
      }
    }
  }
  auto medianRun = [](std::vector<Overhead> v) {
    std::sort(v.begin(), v.end(),
              [](const Overhead& a, const Overhead& b) { return a.overhead_ms < b.overhead_ms; });
    return v[v.size() / 2];
  };
  std::ofstream ocsv(fs::path(out) / "cluster_link_overhead.csv");
  const std::string head =
      "nodes,mpi_overhead_ms,zmq_overhead_ms,mpi_frame_ms,zmq_frame_ms,mpi_sent_bytes_per_frame,"
      "zmq_sent_bytes_per_frame,mpi_received_bytes_per_frame,zmq_received_bytes_per_frame";
  ocsv << head << "\n";
  std::cout << head << "\n";
  for (int k : counts) {
    const Overhead a = medianRun(runs[{"mpi", k}]), z = medianRun(runs[{"zmq", k}]);
    char line[256];
    std::snprintf(line, sizeof line, "%d,%.3f,%.3f,%.2f,%.2f,%.0f,%.0f,%.0f,%.0f", k, a.overhead_ms,
                  z.overhead_ms, a.frame_ms, z.frame_ms, a.sent_per_frame, z.sent_per_frame,
                  a.received_per_frame, z.received_per_frame);
    ocsv << line << "\n";
    std::cout << line << std::endl;
  }
  ocsv.close();

  // ---- 2. fault timeline ----
  std::cerr << "cluster_link: fault timeline (ZeroMQ, 4 nodes) ...\n";
  const fs::path wall4 = dir / "wall-4.json", stats = dir / "stats-faults.csv",
                 log = dir / "log-faults.txt";
  std::ofstream(wall4) << tessera::bench::gridWallJson(4, 640, 360);
  // A slow opaque turn: frame times show the faults, not the scene.
  std::ofstream(dir / "turn.json") << R"({"name": "turn", "keyframes": [
    {"time": 0, "eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027, "y": 0.1, "z": 0},
     "up": {"y": 1}},
    {"time": 60, "eye": {"x": 0.3, "y": 0.14, "z": 0.2}, "target": {"x": -0.027, "y": 0.1, "z": 0},
     "up": {"y": 1}}]})";
  fs::remove(log);
  char timeout_text[32];
  std::snprintf(timeout_text, sizeof timeout_text, "%.0f", node_timeout_ms);
  Process m({master,
             "--transport",
             "zmq",
             "--listen",
             "tcp://127.0.0.1:*",
             "--wall",
             wall4.string(),
             "--scene",
             (dir / "scene.json").string(),
             "--script",
             (dir / "turn.json").string(),
             "--frames",
             "100000",
             "--fps",
             "20",
             "--max-fps",
             "20",
             "--node-timeout",
             timeout_text,
             "--join-wait",
             "120",
             "--stats",
             stats.string()},
            log);
  if (!m.waitFor("listening on (tcp://\\S+)", 30)) return 1;
  std::smatch em;
  const std::string mo = m.output();
  std::regex_search(mo, em, std::regex("listening on (tcp://\\S+)"));
  const std::string endpoint = em[1].str();
  std::vector<std::unique_ptr<Process>> ns;
  for (const std::string t : {"tile-0-0", "tile-1-0", "tile-0-1", "tile-1-1"})
    ns.push_back(std::make_unique<Process>(
        std::vector<std::string>{node, "--master", endpoint, "--headless", "--tile", t},
        dir / ("node-faults-" + t + ".txt")));
  if (!m.waitFor("4 of 4 tiles have a node", 120)) {
    std::cerr << "cluster_link: the four nodes did not join; see " << log << "\n";
    return 1;
  }
  const std::string victim = "tile-1-0";
  std::map<std::string, double> events;
  auto restart = [&](const std::string& name) {
    events[name] = now_s();
    ns[1] = std::make_unique<Process>(
        std::vector<std::string>{node, "--master", endpoint, "--headless", "--tile", victim},
        dir / ("node-faults-" + name + ".txt"));
  };
  if (!waitForFrame(m, stats, 60, 120)) {
    std::cerr << "cluster_link: the fault run did not start; see " << log << "\n";
    return 1;
  }
  events["kill"] = now_s();
  ns[1]->signal(SIGKILL);
  ns[1]->wait(5);
  waitForFrame(m, stats, lastFrame(stats) + 60, 60);
  restart("start_warm");
  waitForFrame(m, stats, lastFrame(stats) + 90, 60);
  events["kill_2"] = now_s();
  ns[1]->signal(SIGKILL);
  ns[1]->wait(5);
  evict(store);
  waitForFrame(m, stats, lastFrame(stats) + 60, 60);
  restart("start_cold");
  waitForFrame(m, stats, lastFrame(stats) + 90, 60);
  // The master dies: how soon every node notices and exits.
  events["master_kill"] = now_s();
  m.signal(SIGKILL);
  m.wait(10);
  double last_exit = 0;
  for (auto& n : ns) {
    while (n->running() && now_s() < events["master_kill"] + 30)
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    last_exit = std::max(last_exit, now_s());
  }

  // The timeline: the master's frame times; the victim's state per frame.
  const std::vector<Row> rows = readStats(stats);
  std::map<uint64_t, Row> frame_of;  // master rows
  std::map<uint64_t, std::string> victim_state;
  for (const Row& r : rows) {
    if (r.tile == "master") frame_of[r.frame] = r;
    if (r.tile == victim) victim_state[r.frame] = r.state;
  }
  const double t0 = frame_of.empty() ? 0 : frame_of.begin()->second.start_s;
  std::ofstream tcsv(fs::path(out) / "cluster_link_timeline.csv");
  tcsv << "frame,time_s,frame_ms," << victim << "\n";
  for (const auto& [f, r] : frame_of)
    tcsv << f << "," << r.start_s - t0 << "," << r.frame_ms << ","
         << (victim_state.count(f) ? victim_state[f] : "lost") << "\n";
  tcsv.close();
  auto end_s = [](const Row& r) { return r.start_s + r.frame_ms / 1000.0; };
  // First frame after `t` in which the victim has state `state`.
  auto firstWith = [&](double t, const std::string& state) -> const Row* {
    for (const auto& [f, r] : frame_of)
      if (end_s(r) >= t && victim_state.count(f) && victim_state[f] == state) return &r;
    return nullptr;
  };
  auto meanFrameMs = [&](double from, double to) {
    double sum = 0;
    int n = 0;
    for (const auto& [f, r] : frame_of)
      if (r.start_s >= from && end_s(r) <= to) sum += r.frame_ms, ++n;
    return n ? sum / n : 0.0;
  };
  std::ofstream fcsv(fs::path(out) / "cluster_link_faults.csv");
  fcsv << "what,value\n";
  std::cout << "\nfault timeline (ZeroMQ, 4 nodes, --node-timeout " << node_timeout_ms
            << " ms, frames paced at 20/s):\n";
  auto put = [&](const std::string& what, double v) {
    fcsv << what << "," << v << "\n";
    std::printf("  %-52s %10.1f\n", what.c_str(), v);
  };
  for (const std::string kill : {"kill", "kill_2"}) {
    const Row* drop = firstWith(events[kill], "lost");
    if (!drop) {
      std::cerr << "cluster_link: " << kill << ": the tile was never dropped; see " << log << "\n";
      continue;
    }
    put(kill + ": ms from kill -9 to the tile dropped", (end_s(*drop) - events[kill]) * 1000.0);
    // A frame's delay: its time beyond the median frame of the 2 s before the kill.
    std::vector<double> before;
    for (const auto& [f, r] : frame_of)
      if (r.start_s >= events[kill] - 2.0 && end_s(r) <= events[kill]) before.push_back(r.frame_ms);
    std::sort(before.begin(), before.end());
    const double median = before.empty() ? 0.0 : before[before.size() / 2];
    int late = 0;
    double worst = 0;
    // From the kill to 5 frames after the drop: what the kill cost, not what the scene did.
    for (const auto& [f, r] : frame_of) {
      if (end_s(r) < events[kill] || f > drop->frame + 5) continue;
      if (r.frame_ms - median > node_timeout_ms) ++late;
      worst = std::max(worst, r.frame_ms - median);
    }
    put(kill + ": frames delayed by more than the node timeout", late);
    put(kill + ": largest delay, kill to 5 frames after the drop, ms", worst);
    put(kill + ": mean frame ms, 2 s before", meanFrameMs(events[kill] - 2.0, events[kill]));
    put(kill + ": mean frame ms, 0.5 to 2 s after",
        meanFrameMs(events[kill] + 0.5, events[kill] + 2.0));
  }
  for (const std::string start : {"start_warm", "start_cold"}) {
    const Row* back = firstWith(events[start], "live");
    if (back)
      put(start + ": ms from process start to its pixels in the wall",
          (end_s(*back) - events[start]) * 1000.0);
  }
  put("master kill -9: ms until the last node exited",
      (last_exit - events["master_kill"]) * 1000.0);
  fcsv.close();

  // ---- chart ----
  const fs::path res = fs::path(out);
  std::ofstream gp(res / "cluster_link.gp");
  gp << "set terminal pngcairo noenhanced size 1300,520 font ',10'\n"
     << "set output '" << (res / "cluster_link.png").string() << "'\n"
     << "set datafile separator ','\nset multiplot layout 1,2\nset grid\n"
     << "set title 'Frame overhead beyond rendering (" << frames
     << " frames, 256x144 tiles, median of " << rounds << ", 2 cores)'\n"
     << "set xlabel 'render nodes'\nset ylabel 'ms per frame (mean)'\nset logscale x 2\n"
     << "set xtics (1,2,4,8)\nset key top left\n"
     << "plot '" << (res / "cluster_link_overhead.csv").string()
     << "' skip 1 using 1:2 with linespoints lw 2 pt 7 title 'MPI', \\\n"
     << "  '' skip 1 using 1:3 with linespoints lw 2 pt 5 title 'ZeroMQ'\n"
     << "unset logscale x\nset xtics auto\n"
     << "set title 'ZeroMQ, 4 nodes: master frame time; kill -9 and restarts of " << victim
     << "'\nset xlabel 'seconds'\nset ylabel 'frame ms'\nset logscale y\nset key bottom right\n";
  for (const auto& [name, t] : events)
    gp << "set arrow from " << t - t0 << ", graph 0 to " << t - t0
       << ", graph 1 nohead dt 2 lc rgb '#888888'\n"
       << "set label '" << name << "' at " << t - t0 << ", graph 0.95 rotate by 90 right\n";
  gp << "plot '" << (res / "cluster_link_timeline.csv").string()
     << "' skip 1 using 2:3 with lines lw 1 lc rgb '#1f77b4' title 'frame ms', \\\n"
     << "  '' skip 1 using (strcol(4) eq 'lost' ? $2 : 1/0):3 with points pt 7 ps 0.5 lc rgb "
        "'#d62728' "
        "title 'tile lost', \\\n"
     << "  " << node_timeout_ms << " with lines dt 3 lc rgb '#ff7f0e' title 'node timeout'\n"
     << "unset multiplot\n";
  gp.close();
  std::string gnuplot = TESSERA_GNUPLOT;
  if (gnuplot.empty()) gnuplot = "gnuplot";
  if (std::system(("'" + gnuplot + "' '" + (res / "cluster_link.gp").string() + "'").c_str()))
    std::cerr << "cluster_link: gnuplot failed; the CSVs are still there\n";
  else
    std::cerr << "chart: " << (res / "cluster_link.png").string() << "\n";
  return 0;
}
