// bench/sites: what remote sites cost the wall and how fast their poses reach it.
//
//  1. The master's frame rate with 0, 4 and 16 sites (goal: 16 sites cost at most 10%). The
//     wall is one tessera-node tile (640x360); the sites are K real site connections (CURVE,
//     each its own key, replica and name) without rendering, driven from one thread of this
//     process: each sends its pose 30 times a second along a moving path, a stroke of 40
//     samples every two seconds undone a second later, and applies every frame; so the figure is
//     the master's and the node's cost (checking, applying, sending frames to every site, drawing
//     the avatars and sketches) and not this machine's two cores shared by K site processes.
//     That thread and the sites' ZeroMQ threads run at nice 19 (--traffic-nice): the sites stand
//     for other machines, so their own encryption and parsing take the cycles the wall leaves
//     instead of competing with its node as equals; their CPU is reported beside.
//     Each count runs the same seconds of real time; the master's own time before the nodes
//     render (its `sync_ms`, the sites' work included) is reported too.
//  2. Latency from a site's pose message to the frame that carries it: an in-process site
//     (collab::SiteClient) moves its pose every half second and times the frame whose avatar
//     has moved (the frame the nodes render at the same moment), and the frame in which the
//     avatar has reached the pose; the wall's median frame time is added for the glass.
//  3. Bytes per second per site, each way, at 30 Hz poses.
//
//   sites [--seconds S] [--counts 0,4,16] [--rounds 3] [--traffic-nice 19 | --traffic-idle]
//         [--out DIR]
//
// Each count is measured --rounds times in turn (0, 4, 16, 0, 4, 16, ...) and the medians are
// reported: this virtual machine's speed drifts by 10% from one minute to the next, which a
// single window per count turns into its ratio.
//
// Writes DIR/sites_overhead.csv, DIR/sites_latency.csv and DIR/sites.png (gnuplot); prints the
// figures. Every process runs on THIS machine (2 cores). --split-cores puts the node alone on
// CPU 0 (llvmpipe with one thread) and the master and the traffic on CPU 1, as a master on a
// machine of its own; its files are named sites_*_split_cores.
#include <CLI/CLI.hpp>

#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <tessera/collab/curve.h>
#include <tessera/collab/site_client.h>
#include <tessera/collab/site_messages.h>
#include <tessera/collab/site_roster.h>
#include <tessera/core/cli.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/scene_draw_list.h>
#include <tessera/render/scene_overlay.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/cluster_link.h>
#include <tessera/sync/scene_edits.h>
#include <tessera/sync/transform.h>
#include <tessera/sync/wire.h>

#include "../tests/support/process.h"
#include "bench_walls.h"

namespace {

namespace fs = std::filesystem;
using tessera::test::Process;
using Clock = std::chrono::steady_clock;

double now_s() {
  return std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(q * double(v.size())))];
}

/// The master's own rows of --stats: frame start (steady clock s) and a column (9: frame ms,
/// 5: sync ms, everything the master does before the nodes render, the sites' work included).
std::vector<std::pair<double, double>> masterFrames(const fs::path& csv, int column = 9) {
  std::vector<std::pair<double, double>> out;
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    if (f.size() < 19 || f[3] != "master") continue;
    out.emplace_back(std::stod(f[18]), std::stod(f[size_t(column)]));
  }
  return out;
}

/// CPU seconds (user + system) a process has used so far (/proc/PID/stat), or 0.
double cpuSeconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t close = text.rfind(')');
  if (close == std::string::npos) return 0;
  std::istringstream fields(text.substr(close + 2));
  std::string f;
  double ticks = 0;
  for (int i = 3; i <= 15 && fields >> f; ++i)
    if (i == 14 || i == 15) ticks += std::stod(f);  // utime, stime
  return ticks / double(sysconf(_SC_CLK_TCK));
}

std::string cameraJson(double x, double y, double z) {
  char s[200];
  std::snprintf(
      s, sizeof s,
      R"({"eye": {"x": %.6f, "y": %.6f, "z": %.6f}, "target": {"x": -0.027, "y": 0.1, "z": 0}, "up": {"y": 1}})",
      x, y, z);
  return s;
}

struct Setup {
  fs::path dir;
  std::string master_bin, node_bin;
  /// --split-cores: the node alone on CPU 0 with one llvmpipe thread, the master (and this
  /// process's site traffic) on CPU 1.
  bool split_cores = false;
  std::string master_public;
  std::vector<fs::path> site_keys;
};

/// A master with one node, the sites' socket open; returns once the tile has its node.
struct Wall {
  std::unique_ptr<Process> master, node;
  std::string sites;  // the site endpoint
  fs::path stats, log;
};

Wall startWall(const Setup& s, const std::string& name, double seconds) {
  Wall w;
  const fs::path run = s.dir / name;
  fs::create_directories(run);
  std::ofstream(run / "hold.json")
      << R"({"name": "hold", "keyframes": [{"time": 0, )" << cameraJson(-0.027, 0.12, 0.6).substr(1)
      << R"(, {"time": )" << seconds << ", " << cameraJson(-0.027, 0.12, 0.6).substr(1) << "]}";
  w.stats = run / "stats.csv";
  w.log = run / "master.log";
  fs::remove(w.log);
  // taskset and env exec the program: the process keeps its pid.
  const std::vector<std::string> on_master_cpu =
      s.split_cores ? std::vector<std::string>{"/usr/bin/taskset", "-c", "1"}
                    : std::vector<std::string>{};
  const std::vector<std::string> on_node_cpu =
      s.split_cores ? std::vector<std::string>{"/usr/bin/env", "LP_NUM_THREADS=1",
                                               "/usr/bin/taskset", "-c", "0"}
                    : std::vector<std::string>{};
  auto launch = [](std::vector<std::string> prefix, const std::vector<std::string>& argv) {
    prefix.insert(prefix.end(), argv.begin(), argv.end());
    return prefix;
  };
  w.master = std::make_unique<Process>(launch(on_master_cpu, {s.master_bin,
                                                              "--transport",
                                                              "zmq",
                                                              "--listen",
                                                              "tcp://127.0.0.1:*",
                                                              "--wall",
                                                              (s.dir / "wall.json").string(),
                                                              "--scene",
                                                              (s.dir / "scene.json").string(),
                                                              "--script",
                                                              (run / "hold.json").string(),
                                                              "--stats",
                                                              w.stats.string(),
                                                              "--sites",
                                                              "tcp://127.0.0.1:*",
                                                              "--site-key",
                                                              (s.dir / "master.key").string(),
                                                              "--allow",
                                                              (s.dir / "allow.txt").string(),
                                                              "--site-timeout",
                                                              "30"}),
                                       w.log);
  if (!w.master->waitFor("remote sites join on tcp://[^:]+:(\\d+)", 30))
    throw std::runtime_error("the master did not start: " + w.master->output());
  const std::string out = w.master->output();
  std::smatch m;
  std::regex_search(out, m, std::regex("listening on (tcp://\\S+)"));
  const std::string wall_endpoint = m[1].str();
  std::regex_search(out, m, std::regex("remote sites join on tcp://[^:]+:(\\d+)"));
  w.sites = "tcp://127.0.0.1:" + m[1].str();
  w.node = std::make_unique<Process>(
      launch(on_node_cpu, {s.node_bin, "--master", wall_endpoint, "--headless"}), run / "node.log");
  if (!w.master->waitFor("1 of 1 tiles have a node", 60))
    throw std::runtime_error("the node did not join: " + w.master->output());
  return w;
}

/// K sites in one thread of this process, each on its own CURVE connection with its own key,
/// replica and name, as K remote machines would be: 30 poses a second along a moving circle, a
/// stroke of 40 samples every two seconds, undone a second later (so each site keeps at most one
/// sketch: the scene stays the same size), every frame from the master applied.
/// One light process instead of K, so the wall's figures are the master's and the node's cost,
/// not this machine's two cores shared with K site processes.
class TrafficSites {
 public:
  /// `nice`: the scheduling priority (0..19) of the thread that joins and drives the sites,
  /// and so of the ZeroMQ I/O threads their contexts start (threads inherit it). The sites
  /// stand for other machines: at 19 their encryption and parsing take what the wall leaves of
  /// this machine's two cores instead of competing with its render node as an equal. kIdle:
  /// SCHED_IDLE, they run only on a core nothing else wants (a nice-19 thread that wakes still
  /// preempts a render thread, and llvmpipe's other thread then waits for it at the frame's end).
  static constexpr int kIdle = -1;
  TrafficSites(const std::string& endpoint, const std::string& master_key,
               const std::vector<tessera::collab::KeyPair>& keys, int k, bool still, int nice)
      : mStill(still) {
    std::atomic<int> joined{0};
    std::exception_ptr failed;
    mThread = std::thread([&, k, nice] {
      if (nice == kIdle) {
        sched_param none{};
        if (::sched_setscheduler(0, SCHED_IDLE, &none) != 0) std::perror("sites: SCHED_IDLE");
      } else if (nice != 0 &&
                 ::setpriority(PRIO_PROCESS, pid_t(::syscall(SYS_gettid)), nice) != 0) {
        std::perror("sites: setpriority");
      }
      try {
        for (int i = 0; i < k; ++i) {
          tessera::collab::SiteClientOptions o;
          o.master = endpoint;
          o.master_key = master_key;
          o.keys = keys[size_t(i)];
          o.name = "traffic " + std::to_string(i);
          mSites.push_back({std::make_unique<tessera::collab::SiteClient>(o), {}});
          mSites.back().client->join(mSites.back().replica,
                                     Clock::now() + std::chrono::seconds(30));
        }
      } catch (...) {
        failed = std::current_exception();
      }
      joined = 1;
      joined.notify_all();
      if (!failed) run();
    });
    joined.wait(0);
    if (failed) {
      mThread.join();
      std::rethrow_exception(failed);
    }
  }
  ~TrafficSites() {
    mStop = true;
    if (mThread.joinable()) mThread.join();
  }

 private:
  struct Site {
    std::unique_ptr<tessera::collab::SiteClient> client;
    tessera::sync::SceneGraph replica;
  };
  void run() {
    const auto start = Clock::now();
    for (uint64_t f = 0; !mStop; ++f) {
      std::this_thread::sleep_until(start + std::chrono::microseconds(int64_t(f * 1e6 / 30)));
      for (size_t i = 0; i < mSites.size(); ++i) {
        Site& s = mSites[i];
        try {
          s.client->receive(s.replica, Clock::now());
        } catch (const tessera::collab::SiteSessionEnded&) {
          return;  // the master ended the session
        }
        const double a = (mStill ? 0.0 : 0.05 * double(f)) + double(i);
        tessera::site::ToMaster m;
        auto& p = *m.mutable_pose();
        p.set_sequence(f + 1);
        for (double v : {-0.027 + 0.3 * std::cos(a), 0.15, 0.05 + 0.3 * std::sin(a)}) p.add_eye(v);
        for (double v : {-0.027, 0.1, 0.0}) p.add_target(v);
        for (double v : {0.0, 1.0, 0.0}) p.add_up(v);
        p.set_fovy_deg(45);
        p.set_aspect(1.5f);
        s.client->send(m);
        if (f % 60 == 15) {
          tessera::site::ToMaster st;
          for (int k = 0; k < 40; ++k)
            for (double v : {-0.05 + 0.002 * k, 0.1 + 0.001 * double(i), 0.02})
              st.mutable_stroke()->add_points(v);
          st.mutable_stroke()->mutable_color()->set_g(1);
          st.mutable_stroke()->set_width(3);
          s.client->send(st);
        }
        if (f % 60 == 45) {
          tessera::site::ToMaster u;
          u.mutable_undo();
          s.client->send(u);
        }
      }
    }
  }
  std::vector<Site> mSites;
  bool mStill = false;  // poses held: only strokes and undos change the scene
  std::atomic<bool> mStop{false};
  std::thread mThread;
};

/// What K avatars (head, frustum, name; moving every frame) and K sketches (one per site, 40
/// samples, as the traffic below keeps) cost one node's frame at 640x360, as a node meets them:
/// the master's scene (the bunny, the avatars, the sketches) moves the avatars every frame,
/// the frames are applied to a replica, the scene draw list and the scene overlay follow it, and
/// the view is drawn and read back. Per count: the median frame (wall time), this process's CPU
/// time per frame (every thread: llvmpipe's, the loaders'), and the overlay pass.
std::vector<std::array<double, 4>> avatarDrawCost(const fs::path& store,
                                                  const std::vector<int>& counts, bool sketches) {
  auto context = tessera::render::GlContext::createHeadless();
  std::vector<std::array<double, 4>> out;
  tessera::render::ViewRenderer renderer(640, 360);
  const auto wall =
      tessera::sync::parseWallConfig(tessera::bench::gridWallJson(1, 640, 360), "wall");
  auto cpu = [] {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
  };
  for (int k : counts) {
    tessera::sync::SceneGraph master, replica;
    const uint32_t bunny = master.add(tessera::scene::SceneNode::MODEL);
    tessera::scene::ModelPayload mp;
    mp.set_store(fs::absolute(store).string());
    master.setPayload(bunny, mp);
    tessera::config::Camera cam;
    cam.mutable_eye()->set_x(-0.027);
    cam.mutable_eye()->set_y(0.12);
    cam.mutable_eye()->set_z(0.6);
    cam.mutable_target()->set_x(-0.027);
    cam.mutable_target()->set_y(0.1);
    cam.mutable_up()->set_y(1);
    master.setCamera(cam);
    master.setShading(tessera::scene::SHADING_EDL);
    std::vector<uint32_t> avatars;
    for (int i = 0; i < k; ++i) {
      avatars.push_back(master.add(tessera::scene::SceneNode::AVATAR));
      tessera::scene::AvatarPayload p;
      p.set_site("site " + std::to_string(i));
      p.mutable_color()->set_r(1);
      p.set_fovy_deg(45);
      p.set_aspect(1.5f);
      p.set_reach(0.3f);
      master.setPayload(avatars.back(), p);
    }
    // And one sketch per site, as the traffic keeps at most one: 40 samples across the bunny.
    const uint32_t layer = sketches ? tessera::sync::layerGroup(master, "sketches", "bench") : 0;
    for (int i = 0; sketches && i < k; ++i) {
      std::vector<glm::dvec3> pts;
      for (int q = 0; q < 40; ++q) pts.emplace_back(-0.05 + 0.002 * q, 0.1 + 0.001 * i, 0.02);
      tessera::scene::Color green;
      green.set_g(1);
      tessera::sync::addSketch(master, layer, "bench", pts, green, 3.0f);
    }
    (void)master.takeFrame(0, 0);
    replica.apply(master.snapshot());
    tessera::render::SceneDrawList models;
    tessera::render::SceneOverlay overlay;
    tessera::render::ChunkStreamer* streamers[] = {&renderer.streamer()};
    auto instances = models.update(replica, tessera::sync::SceneChanges::all(), streamers);
    const tessera::render::ViewSetup view =
        tessera::render::tileView(wall, wall.tiles(0), replica.camera());
    const tessera::render::RenderOptions options =
        tessera::render::SceneDrawList::options(replica, 2.0f);
    (void)renderer.renderSettled(instances, view, options);
    std::vector<double> frame_ms, cpu_ms, overlay_ms;
    for (int f = 1; f <= 45; ++f) {
      const double t_cpu = cpu();
      const auto t0 = Clock::now();
      for (int i = 0; i < k; ++i) {  // as the traffic's poses: on a circle, facing the bunny
        const double a = 0.05 * f + i;
        const glm::dmat4 m =
            tessera::collab::poseFrame({-0.027 + 0.3 * std::cos(a), 0.15, 0.05 + 0.3 * std::sin(a)},
                                       {-0.027, 0.1, 0.0}, {0.0, 1.0, 0.0});
        master.setTransform(avatars[size_t(i)], std::span<const double>(&m[0][0], 16));
      }
      const tessera::sync::SceneChanges changes = replica.apply(tessera::sync::parseFrame(
          tessera::sync::serializeFrame(master.takeFrame(uint64_t(f), uint64_t(f) * 33333))));
      instances = models.update(replica, changes, streamers);
      const tessera::render::Overlay& o = overlay.update(replica, changes);
      tessera::render::RenderStats st;
      (void)renderer.render(instances, view, options, &st, o.empty() ? nullptr : &o);
      if (f > 5) {
        frame_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
        cpu_ms.push_back(cpu() - t_cpu);
        overlay_ms.push_back(st.overlay_ms);
      }
    }
    models.clear(streamers);
    out.push_back({double(k), percentile(frame_ms, 0.5), percentile(cpu_ms, 0.5),
                   percentile(overlay_ms, 0.5)});
  }
  return out;
}

/// The master's own work per frame for K sites, in this process without sockets: each frame
/// every site's newest pose (moving) and, once a second, a stroke and an undo go through the
/// message check and the roster, then the avatars are animated and the frame is taken and
/// serialized, as SiteHub and the master's loop do at 30 frames a second. Microseconds, median.
std::vector<std::array<double, 2>> masterWork(const std::vector<int>& counts) {
  std::vector<std::array<double, 2>> out;
  for (int k : counts) {
    tessera::sync::SceneGraph g;
    tessera::collab::SiteRoster roster;
    std::vector<uint32_t> ids;
    for (int i = 0; i < k; ++i) ids.push_back(roster.join(g, "site " + std::to_string(i), "key"));
    std::vector<double> us;
    for (int f = 0; f < 600; ++f) {
      const double now = f / 30.0;
      const auto t0 = Clock::now();
      for (int i = 0; i < k; ++i) {
        const double a = 0.05 * f + i;
        tessera::site::ToMaster m;
        auto& p = *m.mutable_pose();
        p.set_sequence(uint64_t(f + 1));
        for (double v : {-0.027 + 0.3 * std::cos(a), 0.15, 0.05 + 0.3 * std::sin(a)}) p.add_eye(v);
        for (double v : {-0.027, 0.1, 0.0}) p.add_target(v);
        for (double v : {0.0, 1.0, 0.0}) p.add_up(v);
        p.set_fovy_deg(45);
        p.set_aspect(1.5f);
        tessera::site::ToMaster parsed;
        if (!tessera::collab::parseToMaster(m.SerializeAsString(), parsed))
          roster.apply(g, ids[size_t(i)], parsed, now);
        if (f % 30 == (i % 30)) {
          tessera::site::ToMaster st;
          for (int q = 0; q < 40; ++q)
            for (double v : {-0.05 + 0.002 * q, 0.1, 0.02}) st.mutable_stroke()->add_points(v);
          st.mutable_stroke()->mutable_color()->set_g(1);
          st.mutable_stroke()->set_width(3);
          roster.apply(g, ids[size_t(i)], st, now);
        }
        if (f % 60 == (i % 60)) {
          tessera::site::ToMaster u;
          u.mutable_undo();
          roster.apply(g, ids[size_t(i)], u, now);
        }
      }
      roster.animate(g, now);
      const std::string bytes =
          g.takeFrame(uint64_t(f + 1), uint64_t(now * 1e6)).SerializeAsString();
      if (f >= 60)
        us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
      if (bytes.empty() && k > 0) std::abort();
    }
    out.push_back({double(k), percentile(us, 0.5)});
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  return tessera::cli::runMain("sites", [&]() -> int {
    CLI::App app{"bench/sites: the master's frame rate with remote sites, pose latency, bytes"};
    double seconds = 12.0;
    std::string counts_text = "0,4,16", out = std::string(TESSERA_BENCH_RESULTS_DIR);
    app.add_option("--seconds", seconds, "Seconds of real time per measurement")
        ->check(tessera::cli::finiteRange(4.0, 600.0))
        ->capture_default_str();
    app.add_option("--counts", counts_text, "Site counts for the overhead")->capture_default_str();
    app.add_option("--out", out, "Output folder")->capture_default_str();
    bool still = false;
    app.add_flag("--still", still,
                 "The sites hold their poses (only strokes and undos change the scene): the cost "
                 "of sites that look, against sites that move");
    int traffic_nice = 19;
    app.add_option("--traffic-nice", traffic_nice,
                   "Scheduling priority of the thread driving the K sites and of their ZeroMQ "
                   "threads (0..19): they stand for other machines, so by default they take what "
                   "the wall leaves of this machine; 0 makes them compete with it as equals")
        ->check(CLI::Range(0, 19))
        ->capture_default_str();
    bool traffic_idle = false;
    app.add_flag("--traffic-idle", traffic_idle,
                 "Run that thread and its ZeroMQ threads under SCHED_IDLE instead of a nice "
                 "value: only on a core the wall does not want");
    int rounds = 3;
    app.add_option("--rounds", rounds,
                   "Measure the counts this many times in turn (0, 4, 16, 0, 4, 16 ...): the "
                   "medians over rounds are reported (this machine's speed drifts by 10% "
                   "between minutes)")
        ->check(CLI::Range(1, 20))
        ->capture_default_str();
    bool draw_only = false;
    app.add_flag("--draw-only", draw_only,
                 "Only what the master's logic and a node's drawing cost per frame, in process "
                 "(no processes, no sockets)");
    bool split_cores = false;
    app.add_flag("--split-cores", split_cores,
                 "Put the render node alone on CPU 0 (llvmpipe with one thread) and the master "
                 "and the sites' traffic on CPU 1: a master on a machine of its own, as a "
                 "cluster runs it, so the figure is what the sites cost the master and the "
                 "node, not the node's cores shared with the master");
    if (const auto code = tessera::cli::parse(app, argc, argv, "sites")) return *code;
    std::vector<int> counts;
    {
      std::stringstream ks(counts_text);
      for (std::string k; std::getline(ks, k, ',');) {
        int v = 0;
        if (auto why = tessera::cli::parseInteger<int>(k, 0, 64, v))
          throw tessera::cli::UsageError("--counts " + k + ": " + *why);
        counts.push_back(v);
      }
    }

    Setup s;
    s.split_cores = split_cores;
    if (split_cores) {
      cpu_set_t cpus;
      CPU_ZERO(&cpus);
      if (::sched_getaffinity(0, sizeof cpus, &cpus) != 0 || !CPU_ISSET(0, &cpus) ||
          !CPU_ISSET(1, &cpus))
        throw tessera::cli::UsageError("--split-cores needs CPUs 0 and 1 (see nproc, taskset)");
      for (const char* tool : {"/usr/bin/taskset", "/usr/bin/env"})
        if (::access(tool, X_OK) != 0)
          throw tessera::cli::UsageError(std::string("--split-cores needs ") + tool +
                                         " (Debian: util-linux, coreutils)");
    }
    s.dir = fs::path(out) / "sites-work";
    fs::remove_all(s.dir);
    fs::create_directories(s.dir);
    const std::string bin = fs::canonical("/proc/self/exe").parent_path().parent_path().string();
    s.master_bin = bin + "/master/tessera-master";
    s.node_bin = bin + "/render_node/tessera-node";
    const fs::path store = fs::path(out) / "inputs" / "bunny-scans.tlod";
    if (!fs::exists(store)) {
      fs::create_directories(store.parent_path());
      tessera::lod::BuildOptions o;
      o.quiet = true;
      tessera::lod::buildStore({std::string(TESSERA_DATA_DIR) + "/stanford-bunny/scans/bun.conf"},
                               store.string(), o);
    }
    std::ofstream(s.dir / "scene.json")
        << R"({"nodes": [{"kind": "MODEL", "name": "bunny", "model": {"store": ")"
        << fs::absolute(store).string() << R"("}}], "camera": )" << cameraJson(-0.027, 0.12, 0.6)
        << R"(, "settings": {"background": {"r": 0.05, "g": 0.05, "b": 0.08}, "lodPixels": 2}})";
    std::ofstream(s.dir / "wall.json") << tessera::bench::gridWallJson(1, 640, 360);
    const tessera::collab::KeyPair master_keys = tessera::collab::generateKeyPair();
    tessera::collab::writeKeyFile(s.dir / "master.key", master_keys);
    s.master_public = master_keys.public_key;
    std::ofstream allow(s.dir / "allow.txt");
    const int most = std::max(1, *std::max_element(counts.begin(), counts.end()) + 1);
    std::vector<tessera::collab::KeyPair> site_keys;
    for (int i = 0; i < most; ++i) {
      site_keys.push_back(tessera::collab::generateKeyPair());
      s.site_keys.push_back(s.dir / ("site-" + std::to_string(i) + ".key"));
      tessera::collab::writeKeyFile(s.site_keys.back(), site_keys.back());
      allow << site_keys.back().public_key << " bench site " << i << "\n";
    }
    allow.close();
    fs::permissions(s.dir / "allow.txt", fs::perms::owner_read | fs::perms::owner_write);

    // ---- 0. the master's work for K sites, and what drawing avatars costs a node ----
    std::ofstream wcsv(fs::path(out) / "sites_master_work.csv");
    wcsv << "sites,master_us_per_frame_median\n";
    std::printf("the master's work per frame for K sites (checks, roster, frame), in process:\n");
    for (const auto& [k, us] : masterWork(counts)) {
      wcsv << k << "," << us << "\n";
      std::printf("  %2.0f sites: %.0f us\n", k, us);
    }
    wcsv.close();

    std::ofstream dcsv(fs::path(out) / "sites_draw.csv");
    dcsv << "avatars,frame_ms_median,cpu_ms_median,overlay_ms_median\n";
    std::printf("a node's frame (640x360, the bunny, eye-dome lighting) with K moving avatars:\n");
    for (const auto& [k, frame, cpu_ms, overlay] : avatarDrawCost(store, counts, true)) {
      dcsv << k << "," << frame << "," << cpu_ms << "," << overlay << "\n";
      std::printf(
          "  %2.0f avatars: frame %.2f ms, CPU %.2f ms (medians), the overlay pass %.2f ms\n", k,
          frame, cpu_ms, overlay);
    }
    dcsv.close();
    if (draw_only) return 0;
    if (split_cores) {  // this thread, and the traffic and ZeroMQ threads it starts from now on
      cpu_set_t cpus;
      CPU_ZERO(&cpus);
      CPU_SET(1, &cpus);
      if (::sched_setaffinity(0, sizeof cpus, &cpus) != 0)
        throw std::runtime_error(std::string("--split-cores: sched_setaffinity: ") +
                                 std::strerror(errno));
    }

    // ---- 1. overhead ----
    const std::string tag = split_cores ? "_split_cores" : "";  // its own files
    std::ofstream ocsv(fs::path(out) / ("sites_overhead" + tag + ".csv"));
    ocsv << "sites,frames_per_s,frame_ms_median,frame_ms_p99,ratio_to_no_sites,"
            "in_bytes_per_site_s,out_bytes_per_site_s,master_sync_ms_mean,master_cpu_ms_per_frame,"
            "node_cpu_ms_per_frame,traffic_cpu_percent,rounds,frames_per_s_min,frames_per_s_max\n";
    const std::string traffic_how =
        traffic_idle ? std::string("SCHED_IDLE") : "nice " + std::to_string(traffic_nice);
    std::printf(
        "master frame rate with sites (1 tile 640x360, %.0f s each, %d rounds in turn, sites "
        "--no-render, their traffic at %s%s):\n",
        seconds, rounds, traffic_how.c_str(),
        split_cores ? "; the node alone on CPU 0, the master and the traffic on CPU 1" : "");
    /// One window of one count: its figures.
    struct Window {
      double fps = 0, frame_median = 0, frame_p99 = 0, in_rate = 0, out_rate = 0, sync_mean = 0,
             master_cpu_ms = 0, node_cpu_ms = 0, traffic_percent = 0;
    };
    std::map<int, std::vector<Window>> windows;
    auto measure = [&](int k, int round) {
      const double total = seconds + 16.0;  // joins, the warm-up, then the measured window
      Wall w = startWall(s, "overhead-" + std::to_string(k) + "-" + std::to_string(round), total);
      std::unique_ptr<TrafficSites> sites;
      if (k > 0)
        sites = std::make_unique<TrafficSites>(w.sites, s.master_public, site_keys, k, still,
                                               traffic_idle ? TrafficSites::kIdle : traffic_nice);
      // The same warm-up for every count: the node's first cut loads in about 2 s here, and a
      // window that began in it would make the count that joins fastest (none) look slower.
      std::this_thread::sleep_for(std::chrono::seconds(4));
      const double from = now_s();
      const double master_cpu0 = cpuSeconds(w.master->pid()), node_cpu0 = cpuSeconds(w.node->pid()),
                   sites_cpu0 = cpuSeconds(getpid());
      std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
      const double to = now_s();
      const double master_cpu = cpuSeconds(w.master->pid()) - master_cpu0,
                   node_cpu = cpuSeconds(w.node->pid()) - node_cpu0,
                   sites_cpu = cpuSeconds(getpid()) - sites_cpu0;
      std::vector<double> ms;
      for (const auto& [start, frame_ms] : masterFrames(w.stats))
        if (start >= from && start + frame_ms / 1000.0 <= to) ms.push_back(frame_ms);
      std::vector<double> sync_ms;
      for (const auto& [start, frame_ms] : masterFrames(w.stats, 5))
        if (start >= from && start <= to) sync_ms.push_back(frame_ms);
      (void)w.master->wait(total + 60);
      sites.reset();
      (void)w.node->wait(10);
      Window win;
      win.fps = double(ms.size()) / (to - from);
      double in_rate = 0, out_rate = 0;
      std::smatch m;
      const std::string log = slurp(w.log);
      if (k > 0 && std::regex_search(log, m,
                                     std::regex("received (\\d+) bytes in \\d+ messages, sent "
                                                "(\\d+) bytes"))) {
        in_rate = std::stod(m[1].str()) / total / k;
        out_rate = std::stod(m[2].str()) / total / k;
      }
      for (double v : sync_ms) win.sync_mean += v / double(std::max<size_t>(1, sync_ms.size()));
      const double frames_n = std::max<double>(1.0, double(ms.size()));
      win.master_cpu_ms = master_cpu * 1000.0 / frames_n;
      win.node_cpu_ms = node_cpu * 1000.0 / frames_n;
      win.frame_median = percentile(ms, 0.5);
      win.frame_p99 = percentile(ms, 0.99);
      win.in_rate = in_rate;
      win.out_rate = out_rate;
      win.traffic_percent = 100.0 * sites_cpu / (to - from);
      std::printf("    round %d, %2d sites: %6.1f frames/s\n", round + 1, k, win.fps);
      std::fflush(stdout);
      windows[k].push_back(win);
    };
    for (int round = 0; round < rounds; ++round)
      for (int k : counts) measure(k, round);
    // Per count, the medians over its rounds.
    auto median = [](const std::vector<Window>& ws, double Window::*field) {
      std::vector<double> v;
      for (const Window& w : ws) v.push_back(w.*field);
      return percentile(v, 0.5);
    };
    double base_fps = 0;
    for (int k : counts) {
      const std::vector<Window>& ws = windows[k];
      const double fps = median(ws, &Window::fps);
      if (k == 0) base_fps = fps;
      const double ratio = base_fps > 0 ? fps / base_fps : 1.0;
      double lo = 1e300, hi = 0;
      for (const Window& w : ws) {
        lo = std::min(lo, w.fps);
        hi = std::max(hi, w.fps);
      }
      ocsv << k << "," << fps << "," << median(ws, &Window::frame_median) << ","
           << median(ws, &Window::frame_p99) << "," << ratio << "," << median(ws, &Window::in_rate)
           << "," << median(ws, &Window::out_rate) << "," << median(ws, &Window::sync_mean) << ","
           << median(ws, &Window::master_cpu_ms) << "," << median(ws, &Window::node_cpu_ms) << ","
           << median(ws, &Window::traffic_percent) << "," << ws.size() << "," << lo << "," << hi
           << "\n";
      std::printf(
          "  %2d sites: %6.1f frames/s (%.2f of none; rounds %.1f-%.1f), frame %.2f ms median, "
          "%.2f ms p99; master before the nodes %.2f ms; CPU per frame: master %.2f ms, node "
          "%.2f ms; the K sites' traffic itself %.0f%% of a core; per site %.0f B/s in, %.0f "
          "B/s out\n",
          k, fps, ratio, lo, hi, median(ws, &Window::frame_median), median(ws, &Window::frame_p99),
          median(ws, &Window::sync_mean), median(ws, &Window::master_cpu_ms),
          median(ws, &Window::node_cpu_ms), median(ws, &Window::traffic_percent),
          median(ws, &Window::in_rate), median(ws, &Window::out_rate));
      std::fflush(stdout);
    }
    ocsv.close();

    // ---- 2. latency, 3. bytes ----
    Wall w = startWall(s, "latency", seconds + 8.0);
    tessera::collab::SiteClientOptions co;
    co.master = w.sites;
    co.master_key = s.master_public;
    co.keys = site_keys.back();
    co.name = "latency probe";
    tessera::collab::SiteClient client(co);
    tessera::sync::SceneGraph replica;
    const tessera::site::SiteWelcome welcome =
        client.join(replica, Clock::now() + std::chrono::seconds(20));
    std::ofstream lcsv(fs::path(out) / ("sites_latency" + tag + ".csv"));
    lcsv << "move,first_frame_ms,reached_ms\n";
    std::vector<double> first_ms, reached_ms;
    uint64_t seq = 0;
    double x = 0.1, moved_at = 0;
    bool waiting_first = false, waiting_reach = false;
    int moves = 0;
    const double start = now_s();
    const uint64_t sent0 = client.bytesSent(), received0 = client.bytesReceived();
    std::optional<uint32_t> avatar;
    auto avatarX = [&]() -> std::optional<double> {
      if (!avatar)
        for (uint32_t id : replica.ids())
          if (replica.node(id).kind() == tessera::scene::SceneNode::AVATAR &&
              replica.node(id).avatar().site() == welcome.name())
            avatar = id;
      if (!avatar || !replica.contains(*avatar) || !replica.node(*avatar).visible()) return {};
      return tessera::sync::transformMatrix(replica.node(*avatar).transform())[3][0];
    };
    for (int frame = 0; now_s() - start < seconds; ++frame) {
      const double tick = start + frame / 30.0;
      // Receive until the next tick, timing each frame as it arrives.
      while (now_s() < tick) {
        client.receive(replica, Clock::now() + std::chrono::milliseconds(2));
        const auto ax = avatarX();
        if (!ax) continue;
        const double t = now_s();
        if (waiting_first && std::abs(*ax - (x - 0.1)) > 1e-9) {
          first_ms.push_back((t - moved_at) * 1000);
          waiting_first = false;
        }
        if (waiting_reach && std::abs(*ax - x) < 1e-9) {
          reached_ms.push_back((t - moved_at) * 1000);
          lcsv << moves << "," << first_ms.back() << "," << reached_ms.back() << "\n";
          waiting_reach = false;
        }
      }
      // Every half second (once the last move arrived), the pose moves 10 cm.
      const bool move = frame % 15 == 14 && !waiting_first && !waiting_reach && avatarX();
      if (move) {
        x += 0.1;
        ++moves;
      }
      tessera::site::ToMaster m;
      auto& p = *m.mutable_pose();
      p.set_sequence(++seq);
      for (double v : {x, 0.15, 0.5}) p.add_eye(v);
      for (double v : {-0.027, 0.1, 0.0}) p.add_target(v);
      for (double v : {0.0, 1.0, 0.0}) p.add_up(v);
      p.set_fovy_deg(45);
      p.set_aspect(1.5f);
      client.send(m);
      if (move) {
        moved_at = now_s();
        waiting_first = waiting_reach = true;
      }
    }
    const double elapsed = now_s() - start;
    const double up = double(client.bytesSent() - sent0) / elapsed,
                 down = double(client.bytesReceived() - received0) / elapsed;
    lcsv.close();
    (void)w.master->wait(60);
    (void)w.node->wait(10);
    std::vector<double> wall_ms;
    for (const auto& [st, ms] : masterFrames(w.stats)) wall_ms.push_back(ms);
    const double wall_median = percentile(wall_ms, 0.5);
    std::printf(
        "\npose to frame (loopback, %zu moves): first frame that shows it %.1f ms median, "
        "%.1f ms p99; reached %.1f ms median, %.1f ms p99; the wall's frame %.1f ms "
        "median (glass: + one frame)\n",
        first_ms.size(), percentile(first_ms, 0.5), percentile(first_ms, 0.99),
        percentile(reached_ms, 0.5), percentile(reached_ms, 0.99), wall_median);
    std::printf("bytes per site at 30 Hz poses: %.0f B/s to the master, %.0f B/s from it\n", up,
                down);
    std::ofstream(fs::path(out) / ("sites_summary" + tag + ".csv"))
        << "what,value\nfirst_frame_ms_median," << percentile(first_ms, 0.5)
        << "\nfirst_frame_ms_p99," << percentile(first_ms, 0.99) << "\nreached_ms_median,"
        << percentile(reached_ms, 0.5) << "\nreached_ms_p99," << percentile(reached_ms, 0.99)
        << "\nwall_frame_ms_median," << wall_median << "\nsite_up_bytes_per_s," << up
        << "\nsite_down_bytes_per_s," << down << "\n";

    // ---- chart ----
    const fs::path res = fs::path(out);
    std::ofstream gp(res / ("sites" + tag + ".gp"));
    gp << "set terminal pngcairo noenhanced size 1300,480 font ',10'\n"
       << "set output '" << (res / ("sites" + tag + ".png")).string() << "'\n"
       << "set datafile separator ','\nset multiplot layout 1,2\nset grid\n"
       << "set title 'Wall frame rate with K sites (a 640x360 tile; "
       << (split_cores ? "node on CPU 0, master on CPU 1" : "node and master share 2 CPUs")
       << ")'\nset xlabel 'sites'\nset ylabel 'frames per second'\nset yrange [0:*]\n"
       << "set style fill solid 0.6\nset boxwidth 0.6\nset key top right\n"
       << "set offsets 0, 0, graph 0.15, 0\n"  // room for the key above the bars
       << "plot '" << (res / ("sites_overhead" + tag + ".csv")).string()
       << "' skip 1 using 0:2:xtic(1) with boxes lc rgb '#1f77b4' title 'frames/s', \\\n"
       << "  '' skip 1 using 0:($2*0+" << base_fps * 0.9
       << ") with lines dt 2 lw 2 lc rgb '#d62728' title 'goal: 90% of no sites'\n"
       << "set title 'Pose message to the frame that carries it (loopback)'\n"
       << "set xlabel 'move'\nset ylabel 'ms'\nset yrange [0:*]\nset key top left\n"
       << "plot '" << (res / ("sites_latency" + tag + ".csv")).string()
       << "' skip 1 using 1:2 with points pt 7 title 'first frame that moves', \\\n"
       << "  '' skip 1 using 1:3 with points pt 6 title 'frame that reaches it', \\\n"
       << "  " << wall_median << " with lines dt 2 title \"the wall's median frame\"\n"
       << "unset multiplot\n";
    gp.close();
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(
            ("'" + gnuplot + "' '" + (res / ("sites" + tag + ".gp")).string() + "'").c_str()))
      std::cerr << "sites: gnuplot failed; the CSVs are still there\n";
    else
      std::cerr << "chart: " << (res / ("sites" + tag + ".png")).string() << "\n";
    return 0;
  });
}
