// tessera-master: rank 0 of the cluster (DESIGN.md, master/). Started by mpirun before the
// render nodes (MPMD):
//   mpirun -np 1 tessera-master --wall W.json --scene S.json [--script P.json] [--frames N]
//                               [--screenshot OUT.png] [--stats OUT.csv] [--console]
//        : -np K tessera-node [--headless]
// Owns the scene graph; each frame plays the script and the console's input into it, broadcasts
// what changed (sync::SceneGraph::takeFrame), waits at the swap barrier with the nodes, gathers
// their statistics, and on screenshot frames their tiles, assembled into the wall picture.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>

#include <tessera/cluster.pb.h>
#include <tessera/master/script_player.h>
#include <tessera/master/tile_assignment.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/camera_path.h>
#include <tessera/sync/mpi_transport.h>
#include <tessera/sync/wire.h>

#include <tessera/core/stopwatch.h>
#include "console.h"

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// A reason to stop before rendering (bad config, wrong node count): printed, exit code 1.
struct StartError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Options {
  std::string wall, scene, script, screenshot, stats, out_dir = ".";
  int frames = 0;
  bool console = false;
  double timeout_s = 120.0, splat_scale = 2.0, gpu_budget_mb = 1024.0, fps = 60.0;
  uint32_t console_width = 960;
};

const char* failureName(int32_t code) {
  switch (sync::NodeFailure(code)) {
    case sync::NodeFailure::kNoGl:
      return "no GL";
    case sync::NodeFailure::kBadStore:
      return "unreadable store";
    case sync::NodeFailure::kBadTile:
      return "bad tile";
    case sync::NodeFailure::kBadFrame:
      return "bad frame";
    case sync::NodeFailure::kRender:
      return "render failure";
    default:
      return "failure";
  }
}

/// `eye=X,Y,Z;target=X,Y,Z;up=X,Y,Z` with every digit, as tessera-render --camera reads it.
std::string cameraArgument(const config::Camera& c) {
  char s[512];
  std::snprintf(s, sizeof s, "eye=%.17g,%.17g,%.17g;target=%.17g,%.17g,%.17g;up=%.17g,%.17g,%.17g",
                c.eye().x(), c.eye().y(), c.eye().z(), c.target().x(), c.target().y(),
                c.target().z(), c.up().x(), c.up().y(), c.up().z());
  return s;
}

class Master {
 public:
  Master(sync::MpiTransport& mpi, Options o) : mMpi(mpi), mOpt(std::move(o)) {}

  /// Loads and checks everything, maps nodes to tiles. Throws StartError / ConfigError.
  void prepare(const std::vector<std::string>& hosts) {
    mWall = sync::loadWallConfig(mOpt.wall);
    const config::SceneConfig scene = sync::loadSceneConfig(mOpt.scene);
    for (int i = 0; i < scene.models_size(); ++i) {
      const fs::path store = scene.models(i).store();
      if (store.extension() != ".tlod")
        throw StartError("tessera-master: " + mOpt.scene + ": models[" + std::to_string(i) +
                         "].store: " + store.string() +
                         " is not a .tlod store; build one first: tessera-lod build " +
                         store.string() + " -o " + store.stem().string() + ".tlod");
    }
    if (!mOpt.script.empty()) {
      config::CameraPath path = sync::loadCameraPath(mOpt.script);
      sync::checkPathModels(path, scene, mOpt.script);
      mPlayer.emplace(std::move(path));
    }
    // hosts[0] is the master's own.
    mTileOf = master::assignTiles(mWall, {hosts.begin() + 1, hosts.end()}, mOpt.wall);
    mHosts = hosts;
    mGraph = sync::SceneGraph::fromConfig(scene);
    (void)mGraph.takeFrame(0, 0);  // the loaded scene is the snapshot; frames count from 1
  }

  std::string setupMessage() const {
    cluster::ClusterSetup setup;
    *setup.mutable_wall() = mWall;
    for (uint32_t t : mTileOf) setup.add_tile_of_node(t);
    *setup.mutable_snapshot() = mGraph.snapshot();
    setup.set_settled(mOpt.frames > 0 && !mOpt.console);
    setup.set_splat_scale(float(mOpt.splat_scale));
    setup.set_gpu_budget_bytes(uint64_t(mOpt.gpu_budget_mb * 1048576.0));
    return setup.SerializeAsString();
  }

  std::string describeNode(int rank) const {
    const config::Tile& t = mWall.tiles(int(mTileOf[size_t(rank - 1)]));
    return "node rank " + std::to_string(rank) + " (tile " + t.name() + ", host " +
           mHosts[size_t(rank)] + ")";
  }

  /// Prints every failed node; returns whether any failed.
  bool reportFailures(const std::vector<sync::NodeStatus>& statuses) const {
    bool any = false;
    for (size_t r = 1; r < statuses.size(); ++r) {
      if (statuses[r].code == 0) continue;
      any = true;
      std::fprintf(stderr, "tessera-master: %s failed (%s, code %d): %s\n",
                   describeNode(int(r)).c_str(), failureName(statuses[r].code), statuses[r].code,
                   statuses[r].message().c_str());
    }
    return any;
  }

  void openConsole() {
    if (!mOpt.console) return;
    try {
      mConsole =
          std::make_unique<master::Console>(mWall, mOpt.console_width, float(mOpt.splat_scale));
      std::printf(
          "tessera-master: console open (one button: click sets a target, drag orbits "
          "it, click it to fly there; right-hand bar: forward/back; wheel zooms; 1-9 "
          "select a model, +/- opacity, H hide, E eye-dome lighting; Esc quits)\n");
    } catch (const render::RenderError& e) {
      std::printf("tessera-master: --console: %s; running headless\n", e.what());
    }
  }

  /// The frame loop. Returns the exit code.
  int run() {
    std::ofstream csv;
    if (!mOpt.stats.empty()) {
      csv.open(mOpt.stats);
      if (!csv) throw StartError("tessera-master: --stats " + mOpt.stats + ": cannot write");
      csv << "frame,time_s,rank,tile,frame_bytes,sync_ms,render_ms,barrier_ms,present_ms,"
             "frame_ms,settle_frames,points,nodes,resident_bytes,resident_disk_bytes,"
             "store_bytes,chunks_queued\n";
    }
    const bool deterministic = mOpt.frames > 0;
    const auto session_start = Clock::now();
    for (uint64_t f = 0;; ++f) {
      const auto frame_start = Clock::now();
      const double t = deterministic
                           ? double(f) / mOpt.fps
                           : std::chrono::duration<double>(frame_start - session_start).count();
      std::vector<std::string> shots;
      if (mPlayer) {
        for (const std::string& s : mPlayer->advance(mGraph, t))
          shots.push_back((fs::path(mOpt.out_dir) / s).string());
      }
      bool last = deterministic ? f + 1 >= uint64_t(mOpt.frames)
                                : (mPlayer ? t >= mPlayer->duration() : !mConsole);
      if (mConsole && !mConsole->handleInput(mGraph)) last = true;
      if (last && !mOpt.screenshot.empty()) shots.push_back(mOpt.screenshot);
      for (const std::string& s : shots) {
        scene::Command c;
        c.mutable_screenshot()->set_path(s);
        mGraph.addCommand(c);
      }

      std::string bytes = sync::serializeFrame(mGraph.takeFrame(f + 1, uint64_t(t * 1e6)));
      sync::ClusterMessage kind = sync::ClusterMessage::kFrame;
      uint32_t flags = shots.empty() ? 0 : sync::kFrameScreenshot;
      const size_t frame_bytes = bytes.size();
      mMpi.broadcast(kind, flags, bytes, "frame broadcast");
      const double sync_ms = msSince(frame_start);
      // The console renders while the nodes do.
      double present_ms = 0;
      if (mConsole) {
        const auto p = Clock::now();
        mConsole->draw(mGraph);
        present_ms = msSince(p);
      }
      const double barrier_ms = mMpi.swapBarrier();
      if (!shots.empty()) writeScreenshots(shots, f + 1);
      sync::NodeFrameStats mine;
      mine.barrier_ms = barrier_ms;
      mine.present_ms = present_ms;
      const std::vector<sync::NodeFrameStats> stats = mMpi.gatherStats(mine);
      const double frame_ms = msSince(frame_start);
      if (csv) writeStats(csv, f + 1, t, frame_bytes, sync_ms, frame_ms, stats);

      bool failed = false;
      for (size_t r = 1; r < stats.size(); ++r) failed |= stats[r].failure != 0;
      if (failed) {
        kind = sync::ClusterMessage::kFailed;
        std::string none;
        flags = 0;
        mMpi.broadcast(kind, flags, none, "failure notice");
        reportFailures(mMpi.gatherStatus(sync::NodeStatus()));
        return 1;
      }
      if (last) break;
    }
    std::string none;
    sync::ClusterMessage quit = sync::ClusterMessage::kQuit;
    uint32_t flags = 0;
    mMpi.broadcast(quit, flags, none, "quit");
    return 0;
  }

 private:
  void writeScreenshots(const std::vector<std::string>& paths, uint64_t frame) {
    const std::vector<std::string> parts = mMpi.gatherBytes({});
    std::vector<render::Image> tiles(size_t(mWall.tiles_size()));
    for (size_t r = 1; r < parts.size(); ++r) {
      const config::Tile& tile = mWall.tiles(int(mTileOf[r - 1]));
      render::Image& img = tiles[mTileOf[r - 1]];
      img.width = tile.pixel_width();
      img.height = tile.pixel_height();
      if (parts[r].size() != size_t(img.width) * img.height * 4) {
        std::fprintf(stderr, "tessera-master: %s sent %zu bytes for a %ux%u tile; left dark\n",
                     describeNode(int(r)).c_str(), parts[r].size(), img.width, img.height);
        img.rgba.assign(size_t(img.width) * img.height * 4, 0);
        continue;
      }
      img.rgba.assign(parts[r].begin(), parts[r].end());
    }
    const render::Image wall = render::assembleWallMosaic(mWall, tiles);
    for (const std::string& p : paths) {
      try {
        if (fs::path(p).has_parent_path()) fs::create_directories(fs::path(p).parent_path());
        render::writePng(p, wall);
        std::printf("tessera-master: frame %llu: wrote %s (%ux%u); camera %s\n",
                    (unsigned long long)frame, p.c_str(), wall.width, wall.height,
                    cameraArgument(mGraph.camera()).c_str());
      } catch (const std::exception& e) {
        std::fprintf(stderr, "tessera-master: frame %llu: screenshot %s: %s\n",
                     (unsigned long long)frame, p.c_str(), e.what());
      }
    }
    std::fflush(stdout);
  }

  void writeStats(std::ofstream& csv, uint64_t frame, double t, size_t frame_bytes, double sync_ms,
                  double frame_ms, const std::vector<sync::NodeFrameStats>& stats) const {
    for (size_t r = 0; r < stats.size(); ++r) {
      const sync::NodeFrameStats& s = stats[r];
      const std::string tile = r == 0 ? "master" : mWall.tiles(int(mTileOf[r - 1])).name();
      csv << frame << "," << t << "," << r << "," << tile << "," << (r == 0 ? frame_bytes : 0)
          << "," << (r == 0 ? sync_ms : 0.0) << "," << s.render_ms << "," << s.barrier_ms << ","
          << s.present_ms << "," << (r == 0 ? frame_ms : 0.0) << "," << s.frames << "," << s.points
          << "," << s.nodes << "," << s.resident_bytes << "," << s.resident_disk_bytes << ","
          << s.store_bytes << "," << s.chunks_queued << "\n";
    }
    csv.flush();
  }

  sync::MpiTransport& mMpi;
  Options mOpt;
  config::WallConfig mWall;
  std::vector<uint32_t> mTileOf;
  std::vector<std::string> mHosts;
  sync::SceneGraph mGraph;
  std::optional<master::ScriptPlayer> mPlayer;
  std::unique_ptr<master::Console> mConsole;
};

/// Tells the nodes to leave before any setup (they wait for it).
void sendQuit(sync::MpiTransport& mpi) {
  sync::ClusterMessage quit = sync::ClusterMessage::kQuit;
  uint32_t flags = 0;
  std::string none;
  mpi.broadcast(quit, flags, none, "quit");
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"tessera-master: rank 0 of the wall cluster; owns the scene and drives the nodes"};
  app.add_option("--wall", o.wall, "Wall configuration (JSON)")->required();
  app.add_option("--scene", o.scene, "Scene configuration (JSON): models, camera, shading")
      ->required();
  app.add_option("--script", o.script, "Camera path with timed actions (configs/paths/*.json)");
  app.add_option("--frames", o.frames,
                 "Run this many frames, deterministic: script time = frame / fps, every frame "
                 "rendered complete (0: real time until the script or console ends)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--fps", o.fps, "With --frames: script frames per second (fewer: coarser steps)")
      ->check(CLI::Range(0.1, 1000.0))
      ->capture_default_str();
  app.add_option("--screenshot", o.screenshot, "Write the wall picture (PNG) of the last frame");
  app.add_option("--stats", o.stats, "Per-frame, per-node statistics (CSV)");
  app.add_option("--out-dir", o.out_dir, "Where the script's screenshot paths are relative to")
      ->capture_default_str();
  app.add_flag("--console", o.console,
               "A window with the whole wall at low resolution and one-button navigation");
  app.add_option("--console-width", o.console_width, "Console width, pixels")
      ->check(CLI::Range(64, 4096))
      ->capture_default_str();
  app.add_option("--splat-scale", o.splat_scale, "As tessera-render --splat-scale")
      ->check(CLI::Range(0.25, 8.0))
      ->capture_default_str();
  app.add_option("--gpu-budget-mb", o.gpu_budget_mb, "Per node GPU bytes for chunks, MiB")
      ->check(CLI::Range(1.0, 1e6))
      ->capture_default_str();
  app.add_option("--timeout", o.timeout_s,
                 "Seconds any rank may keep the others waiting before the job is aborted")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();

  std::unique_ptr<sync::MpiTransport> mpi;
  try {
    mpi = std::make_unique<sync::MpiTransport>(&argc, &argv, "tessera-master", o.timeout_s);
  } catch (const sync::TransportError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  if (mpi->rank() != 0) {
    mpi->abort(2,
               "tessera-master must be rank 0: start it first, `mpirun -np 1 tessera-master ... "
               ": -np K tessera-node`");
  }
  int parse_code = -1;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    parse_code = app.exit(e);
  }
  mpi->setTimeout(o.timeout_s);
  const std::vector<std::string> hosts = mpi->gatherHosts();
  if (parse_code >= 0) {
    sendQuit(*mpi);
    return parse_code;
  }

  Master master(*mpi, o);
  try {
    if (mpi->size() < 2)
      throw StartError(
          "tessera-master: no render nodes; start them after the master: mpirun "
          "-np 1 tessera-master ... : -np K tessera-node --headless");
    master.prepare(hosts);
  } catch (const std::runtime_error& e) {  // StartError, ConfigError, AssignmentError
    std::fprintf(stderr, "%s\n", e.what());
    sendQuit(*mpi);
    return 1;
  }
  std::string setup = master.setupMessage();
  sync::ClusterMessage kind = sync::ClusterMessage::kSetup;
  uint32_t flags = 0;
  mpi->broadcast(kind, flags, setup, "setup broadcast");
  if (master.reportFailures(mpi->gatherStatus(sync::NodeStatus()))) {
    std::fprintf(stderr, "tessera-master: the wall cannot start; stopping every node\n");
    sendQuit(*mpi);
    return 1;
  }
  try {
    master.openConsole();
    return master.run();
  } catch (const std::runtime_error& e) {  // the console's stores, the stats file
    std::fprintf(stderr, "%s\n", e.what());
    mpi->abort(1, "stopping the wall");
  }
}
