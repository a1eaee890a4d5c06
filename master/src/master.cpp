#include <tessera/master/master.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include <tessera/core/cli.h>
#include <tessera/core/file_checks.h>
#include <tessera/core/progress.h>
#include <tessera/core/stopwatch.h>
#include <tessera/master/tile_assignment.h>
#include <tessera/media/movie_writer.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/inset.h>
#include <tessera/render/path_frames.h>
#include <tessera/render/projector_pass.h>
#include <tessera/render/scene_draw_list.h>
#include <tessera/render/screen_passes.h>
#include <tessera/render/stereo.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/camera_path.h>
#include <tessera/sync/viewer_head.h>
#include <tessera/sync/wire.h>

#include "console.h"

namespace tessera::master {

namespace {

namespace fs = std::filesystem;
using Clock = sync::LinkClock;
using State = TileTable::State;

const char* failureName(cluster::NodeFailure code) {
  switch (code) {
    case cluster::NODE_NO_GL:
      return "no GL";
    case cluster::NODE_BAD_STORE:
      return "unreadable store";
    case cluster::NODE_BAD_TILE:
      return "bad tile";
    case cluster::NODE_BAD_FRAME:
      return "bad frame";
    case cluster::NODE_RENDER:
      return "render failure";
    case cluster::NODE_REFUSED:
      return "refused";
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

Clock::time_point after(double ms) {
  return Clock::now() + std::chrono::microseconds(int64_t(ms * 1000.0));
}

}  // namespace

struct Master::Film {
  explicit Film(const MasterOptions& o)
      : progress(o.movie.empty() ? o.frames_dir : o.movie, uint64_t(o.frames), " frames") {}
  std::unique_ptr<media::MovieWriter> writer;  // made with the first frame
  Progress progress;
  size_t written = 0;  // frames filmed
  std::string error;   // a write that failed
};

Master::Master(sync::MasterLink& link, MasterOptions options)
    : mLink(link), mOpt(std::move(options)) {}

Master::~Master() = default;

std::string Master::message(const std::string& text) const {
  return "tessera-master: frame " + std::to_string(mFrame) + ": " + text;
}

void Master::prepare() {
  mWall = sync::loadWallConfig(mOpt.wall);
  // A raw scan (PLY, LAS, .conf ...) becomes a cached store before any node sees the scene, so
  // the nodes of this host open the same file (lod/store_cache.h).
  mGraph = render::loadSceneWithStores(mOpt.scene, "tessera-master");
  if (!mOpt.script.empty()) {
    config::CameraPath path = sync::loadCameraPath(mOpt.script);
    sync::checkPathModels(path, mGraph, mOpt.script);
    try {
      render::checkPathInsets(path, mWall, mOpt.script);
    } catch (const render::RenderError& e) {
      throw StartError("tessera-master: --script " + std::string(e.what()));
    }
    if (const auto why = sync::pathHeadProblem(path, mWall))
      throw StartError("tessera-master: --script " + mOpt.script + ": " + *why);
    if (!mOpt.movie.empty() || !mOpt.frames_dir.empty()) {
      try {
        mOpt.frames = int(render::pathFrameCount(path, mOpt.fps));
      } catch (const render::RenderError& e) {
        throw StartError("tessera-master: --path " + mOpt.script + ": " + e.what());
      }
    }
    mPlayer.emplace(std::move(path));
  }
  if (!mOpt.movie.empty()) {
    const glm::uvec2 size = mOpt.movie_width > 0 ? glm::uvec2(mOpt.movie_width, mOpt.movie_height)
                                                 : render::wallPictureSize(mWall);
    if (size.x % 2 != 0 || size.y % 2 != 0)
      throw StartError("tessera-master: --movie " + mOpt.movie + ": the frames are " +
                       std::to_string(size.x) + "x" + std::to_string(size.y) +
                       (mOpt.movie_width > 0 ? " (--size)" : " (the wall's picture)") +
                       "; a movie's sides must be even: give --size " +
                       std::to_string(size.x + size.x % 2) + "x" +
                       std::to_string(size.y + size.y % 2) + " or another even size");
  }
  // The scene's inset centres are checked against this wall (the scene's own checks know no
  // wall): every inset named and inside the wall's extent.
  const scene::InsetPlacement& insets = mGraph.settings().inset();
  for (int i = 0; i < insets.centres_size(); ++i)
    if (const auto why = render::insetPlacementProblem(mWall, insets.centres(i)))
      throw StartError("tessera-master: --scene " + mOpt.scene + ": settings.inset.centres[" +
                       std::to_string(i) + "]: " + *why);
  // The scene's head likewise: in front of every tile of this wall.
  if (mGraph.settings().has_head())
    if (const auto why = sync::headProblem(mWall, mGraph.settings().head()))
      throw StartError("tessera-master: --scene " + mOpt.scene + ": settings.head." + *why);
  mTiles = std::make_unique<TileTable>(mWall, mOpt.wall);
  if (!mOpt.annotations.empty()) {
    try {
      mAnnotations = std::make_unique<annotate::AnnotationScene>(mOpt.annotations);
      for (const std::string& p : mAnnotations->load(mGraph))
        std::printf("tessera-master: --annotations %s: %s\n", mOpt.annotations.c_str(), p.c_str());
      annotate::AnnotationDb& db = mAnnotations->db();
      std::printf("tessera-master: annotations: %s: %zu layers, %zu places, %zu items\n",
                  mOpt.annotations.c_str(), db.layers().size(), db.places().size(),
                  db.items().size());
      std::fflush(stdout);
    } catch (const annotate::AnnotationError& e) {
      throw StartError("tessera-master: --annotations: " + std::string(e.what()));
    }
  }
  (void)mGraph.takeFrame(0, 0);  // the loaded scene is the snapshot; frames count from 1
  if (!mOpt.stats.empty()) {
    mCsv = std::make_unique<std::ofstream>(mOpt.stats);
    if (!*mCsv)
      throw StartError("tessera-master: --stats " + mOpt.stats +
                       ": cannot write: " + whyNotWritable(mOpt.stats, errno));
    writeStatsHeader();
  }
}

void Master::openConsole() {
  if (!mOpt.console) return;
  try {
    mConsole = std::make_unique<Console>(mWall, mOpt.console_width, float(mOpt.splat_scale));
    mConsole->setAnnotations(mAnnotations.get());
    std::printf(
        "tessera-master: console open (one button: click sets a target, drag orbits "
        "it, click it to fly there; right-hand bar: forward/back; wheel zooms; 1-9 "
        "select a model, +/- opacity, H hide, E eye-dome lighting, G ambient occlusion, D "
        "relative depth, T contour lines; right-button drag draws "
        "on the model, U undo, C clear; M measures (distance, path, angle, area: click "
        "points, Enter ends, Backspace undoes); S lasso (drag around a region); O opens the "
        "note nearest the cursor on the wall; L leads the view; Esc quits. Panels: Models "
        "(visibility, opacity), Tools (measuring, lasso, what was measured and selected), "
        "Layers (shown or not), Notes (search, fly to, open, edit, delete; Add note, then "
        "click on the model), Shading (bottom right: lighting, ambient occlusion, relative "
        "depth, contour lines and their settings), View (beside Shading: points a pixel, the "
        "viewer's head, insets)%s)\n",
        mAnnotations ? "" : "; without --annotations notes are not kept");
  } catch (const render::RenderError& e) {
    std::printf("tessera-master: --console: %s; running headless\n", e.what());
  }
  std::fflush(stdout);
}

cluster::ClusterSetup Master::setupFor(uint32_t tile) const {
  cluster::ClusterSetup setup;
  *setup.mutable_wall() = mWall;
  setup.set_tile(mTiles->name(tile));
  *setup.mutable_snapshot() = mGraph.snapshot();
  setup.set_settled(mOpt.frames > 0 && !mOpt.console);
  setup.set_splat_scale(float(mOpt.splat_scale));
  setup.set_gpu_budget_bytes(uint64_t(mOpt.gpu_budget_mb * 1048576.0));
  return setup;
}

void Master::handleFaults(const sync::LinkEvents& events) {
  for (const auto& [peer, why] : events.faults) {
    if (const auto tile = mTiles->tileOf(peer)) {
      loseTile(*tile, "protocol error: " + why);
    } else {
      std::printf("%s\n", message("refused a peer: " + why).c_str());
    }
  }
}

void Master::handleJoins(const sync::LinkEvents& events) {
  if (events.joins.empty()) return;
  // MPI: every rank joins at once and each must get a tile, as before the cluster link.
  if (!mLink.canDropNodes() && mFrame == 0) {
    bool named = false;
    std::vector<std::string> hosts;
    for (const auto& [peer, hello] : events.joins) {
      named |= !hello.tile().empty();
      hosts.push_back(hello.host());
    }
    std::string refusal;
    std::vector<uint32_t> tile_of;
    if (!named) {
      try {
        tile_of = assignTiles(mWall, hosts, mOpt.wall);
      } catch (const AssignmentError& e) {
        refusal = e.what();
      }
    } else if (events.joins.size() != mTiles->size()) {
      refusal = mOpt.wall + " has " + std::to_string(mTiles->size()) + " tiles but " +
                std::to_string(events.joins.size()) + " render nodes were started";
    }
    for (size_t i = 0; i < events.joins.size(); ++i) {
      const auto& [peer, hello] = events.joins[i];
      std::variant<uint32_t, std::string> claim =
          !refusal.empty() ? std::variant<uint32_t, std::string>(refusal)
          : named          ? mTiles->claim(hello)
                           : std::variant<uint32_t, std::string>(tile_of[i]);
      if (auto* why = std::get_if<std::string>(&claim)) {
        std::fprintf(stderr, "tessera-master: %s\n", why->c_str());
        mStopCode = kExitStart;
        mLink.refuse(peer, *why);
        continue;
      }
      const uint32_t tile = std::get<uint32_t>(claim);
      mTiles->assign(tile, peer, hello, mGraph.frameNumber());
      mLink.welcome(peer, setupFor(tile));
      // Which process drives which tile: what a hung or failed node is named by later.
      std::printf(
          "%s\n",
          message(mTiles->describe(tile) + " joined (rank " + std::to_string(peer) + ")").c_str());
    }
    std::fflush(stdout);
    return;
  }
  for (size_t i = 0; i < events.joins.size(); ++i) {
    const auto& [peer, hello] = events.joins[i];
    // A node whose hello went unanswered says it again on a new connection (a master slower
    // than the node's retry, or a connection that never came up): only its newest is answered.
    const auto again = [&](const auto& later) {
      return later.second.host() == hello.host() && later.second.pid() == hello.pid();
    };
    if (std::any_of(events.joins.begin() + std::ptrdiff_t(i) + 1, events.joins.end(), again))
      continue;
    // A node that joins again on the same connection gives up the tile it had.
    if (const auto old = mTiles->tileOf(peer)) mTiles->lose(*old, "its node joined again");
    // A node that comes back on a new connection before its old one was dropped (it was
    // stopped, its heartbeats timed out): the old connection is gone, or is the same process's
    // (host and pid), so is its claim.
    for (uint32_t t = 0; t < mTiles->size(); ++t) {
      const TileTable::Slot& s = mTiles->slot(t);
      if (mTiles->name(t) != hello.tile() ||
          (s.state != State::kLive && s.state != State::kJoining))
        continue;
      if (s.host == hello.host() && s.pid == hello.pid())
        loseTile(t, "its node reconnected");
      else if (!mLink.connected(s.peer))
        loseTile(t, "dead: its connection closed (a new node claims the tile)");
    }
    const std::variant<uint32_t, std::string> claim = mTiles->claim(hello);
    if (auto* why = std::get_if<std::string>(&claim)) {
      std::printf("%s\n", message("refused a node on " + hello.host().substr(0, 64) + " (pid " +
                                  std::to_string(hello.pid()) + "): " + *why)
                              .c_str());
      mLink.refuse(peer, *why);
      continue;
    }
    const uint32_t tile = std::get<uint32_t>(claim);
    const bool back = mTiles->slot(tile).state == State::kLost;
    mTiles->assign(tile, peer, hello, mGraph.frameNumber());
    mLink.welcome(peer, setupFor(tile));
    std::printf("%s\n",
                message(mTiles->describe(tile) + (back ? " rejoined" : " joined") +
                        " from the snapshot of frame " + std::to_string(mGraph.frameNumber()))
                    .c_str());
  }
  std::fflush(stdout);
}

void Master::loseTile(uint32_t tile, const std::string& reason) {
  TileTable::Slot& s = mTiles->slot(tile);
  if (s.state != State::kJoining && s.state != State::kLive) return;
  std::printf("%s\n", message(mTiles->describe(tile) + " dropped: " + reason).c_str());
  std::fflush(stdout);
  if (mLink.canDropNodes()) {
    mLink.drop(s.peer, reason);
  } else if (mStopCode == 0) {
    mStopCode = kExitStart;  // MPI cannot go on without a rank
    mStopReason = mTiles->describe(tile) + ": " + reason;
  }
  mTiles->lose(tile, reason);
}

std::optional<std::string> Master::policyViolation() const {
  for (uint32_t t = 0; t < mTiles->size(); ++t) {
    const TileTable::Slot& s = mTiles->slot(t);
    if (!mTiles->tile(t).critical() || s.state == State::kJoining || s.state == State::kLive)
      continue;
    return "critical tile " + mTiles->name(t) + " has no node" +
           (s.lost_reason.empty() ? std::string() : " (" + s.lost_reason + ")");
  }
  if (mTiles->driven() < mWall.min_live_tiles())
    return std::to_string(mTiles->driven()) + " of " + std::to_string(mTiles->size()) +
           " tiles have a node, fewer than the wall's minLiveTiles " +
           std::to_string(mWall.min_live_tiles());
  return std::nullopt;
}

double Master::nodeTimeoutMs() const {
  if (mOpt.node_timeout_ms > 0) return mOpt.node_timeout_ms;
  if (mRenderMs.empty()) return 1000.0;
  std::vector<double> sorted = mRenderMs;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  return std::max(1000.0, 5.0 * sorted[sorted.size() / 2]);
}

void Master::absorb(sync::LinkEvents& events) {
  handleFaults(events);
  for (const auto& [peer, report] : events.reports) {
    const auto tile = mTiles->tileOf(peer);
    if (!tile || report.working()) continue;
    TileTable::Slot& slot = mTiles->slot(*tile);
    if (report.status().code() != cluster::NODE_OK) {
      std::fprintf(stderr, "tessera-master: %s failed (%s, code %d): %s\n",
                   mTiles->describe(*tile).c_str(), failureName(report.status().code()),
                   int(report.status().code()), report.status().message().c_str());
      loseTile(*tile, std::string("failed: ") + failureName(report.status().code()) + ": " +
                          report.status().message());
    } else if (report.frame() == 0) {
      slot.started = true;
    } else if (slot.state == State::kJoining && report.frame() > slot.welcome_frame) {
      mTiles->setLive(*tile);
    }
  }
  events.reports.clear();
  for (sync::PeerId peer : events.gone)
    if (const auto tile = mTiles->tileOf(peer)) loseTile(*tile, "dead: its connection closed");
  events.gone.clear();
  for (sync::PeerId peer : events.stalled)
    if (const auto tile = mTiles->tileOf(peer))
      loseTile(*tile, "hung: connected, but not reading (its queue of messages is full)");
  events.stalled.clear();
  handleJoins(events);
  events.joins.clear();
  events.faults.clear();
}

bool Master::start() {
  // Joins: until every tile has a node or the wait is over (MPI: every rank at once).
  const auto join_deadline = after(mOpt.join_wait_s * 1000.0);
  while (mTiles->driven() < mTiles->size()) {
    sync::LinkEvents events = mLink.poll(mLink.canDropNodes() ? join_deadline : Clock::now());
    absorb(events);
    if (!mLink.canDropNodes() || Clock::now() >= join_deadline) break;
  }
  // Startup reports: every welcomed node says whether it can render.
  const auto start_deadline = after(mOpt.first_frame_timeout_s * 1000.0);
  auto waiting = [&] {
    std::set<sync::PeerId> peers;
    for (uint32_t t = 0; t < mTiles->size(); ++t) {
      const TileTable::Slot& s = mTiles->slot(t);
      if (s.state == State::kJoining && !s.started) peers.insert(s.peer);
    }
    return peers;
  };
  for (bool first = true; first || (!waiting().empty() && Clock::now() < start_deadline);
       first = false) {
    if (mLink.canDropNodes() && waiting().empty()) break;
    sync::LinkEvents events = mLink.collect(
        0, waiting(), std::chrono::milliseconds(int64_t(mOpt.first_frame_timeout_s * 1000.0)),
        start_deadline);
    absorb(events);
    if (!mLink.canDropNodes()) break;
  }
  for (uint32_t t = 0; t < mTiles->size(); ++t) {
    TileTable::Slot& s = mTiles->slot(t);
    if (s.state != State::kJoining) continue;
    if (!s.started) {
      loseTile(t, "no startup report within the first-frame timeout");
      continue;
    }
    mTiles->setLive(t);
    s.reported = false;  // its first frame gets the cold-cache timeout
  }
  if (mStopCode != 0 && !mLink.canDropNodes()) {
    std::fprintf(stderr, "tessera-master: the wall cannot start; stopping every node\n");
    mLink.quit(uint32_t(mStopCode), "the wall cannot start");
    return false;
  }
  if (const auto why = policyViolation()) {
    std::fprintf(stderr, "tessera-master: the wall cannot start: %s\n", why->c_str());
    mStopCode = kExitStart;
    mLink.quit(uint32_t(mStopCode), *why);
    return false;
  }
  std::printf("tessera-master: %s transport; %zu of %zu tiles have a node\n", mLink.transport(),
              mTiles->driven(), mTiles->size());
  std::fflush(stdout);
  return true;
}

int Master::run() {
  mStopCode = 0;
  if (!start()) return mStopCode ? mStopCode : kExitStart;
  const bool deterministic = mOpt.frames > 0;
  if (!mOpt.movie.empty() || !mOpt.frames_dir.empty()) mFilm = std::make_unique<Film>(mOpt);
  const auto session_start = Clock::now();
  const size_t tiles = mTiles->size();
  for (uint64_t f = 0;; ++f) {
    const auto frame_start = Clock::now();
    {  // what arrived since the last frame: joins, late reports of joining nodes
      sync::LinkEvents events = mLink.poll(Clock::now());
      absorb(events);
    }
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
    if (const int sig = cli::stopSignal(); sig && !last) {
      std::printf("tessera-master: %s: ending the session with frame %llu\n",
                  sig == SIGINT ? "SIGINT" : "SIGTERM", (unsigned long long)(f + 1));
      std::fflush(stdout);
      last = true;
    }
    // After the script and the console: a remote leader's camera wins.
    if (mParticipants)
      mParticipants->beforeFrame(
          mGraph, f + 1, std::chrono::duration<double>(Clock::now() - session_start).count());
    // What the console and the sites measured and selected goes into the database.
    if (mAnnotations) mAnnotations->sync(mGraph);
    if (last && !mOpt.screenshot.empty()) shots.push_back(mOpt.screenshot);
    for (const std::string& s : shots) {
      scene::Command c;
      c.mutable_screenshot()->set_path(s);
      mGraph.addCommand(c);
    }

    mFrame = f + 1;
    cluster::FrameMessage message_out;
    const scene::Frame taken = mGraph.takeFrame(mFrame, uint64_t(t * 1e6));
    message_out.set_frame(sync::serializeFrame(taken));
    message_out.set_read_back(!shots.empty() || mFilm);
    if (mWallRelativeDepth) {
      message_out.add_relative_depth_range(mWallRelativeDepth->x);
      message_out.add_relative_depth_range(mWallRelativeDepth->y);
    }
    if (mParticipants) {
      std::vector<std::string> media;
      mParticipants->takeMedia(media);
      for (std::string& m : media) message_out.add_media(std::move(m));
    }
    const size_t frame_bytes = message_out.frame().size();
    mLink.publish(message_out);
    if (mParticipants) mParticipants->afterFrame(mGraph, message_out.frame());
    const double sync_ms = msSince(frame_start);
    double present_ms = 0;
    if (mConsole) {  // the console renders while the nodes do
      const auto p = Clock::now();
      mConsole->video(mGraph, message_out.media());
      mConsole->draw(mGraph, sync::SceneChanges::of(taken));
      if (last && !mOpt.console_screenshot.empty()) mConsole->save(mOpt.console_screenshot);
      present_ms = msSince(p);
    }

    // Collect: every live tile's report, up to the deadline.
    const auto collect_start = Clock::now();
    std::set<sync::PeerId> awaited;
    bool first = false;
    for (uint32_t i = 0; i < tiles; ++i) {
      if (mTiles->slot(i).state != State::kLive) continue;
      awaited.insert(mTiles->slot(i).peer);
      first |= !mTiles->slot(i).reported;
    }
    const double timeout_ms = first ? mOpt.first_frame_timeout_s * 1000.0 : nodeTimeoutMs();
    // The timeout is how long a node may be silent: a node at work says so now and then
    // (NodeReport{working}), so a frame whose cost jumps (a see-through ensemble, a cold chunk)
    // is slow, not hung. It is waited for up to ten timeouts, and a frame that must be complete
    // (deterministic runs, screenshots) up to the first-frame timeout.
    const bool complete = message_out.read_back() || (mOpt.frames > 0 && !mOpt.console);
    const auto quiet = std::chrono::microseconds(int64_t(timeout_ms * 1000.0));
    const double first_ms = mOpt.first_frame_timeout_s * 1000.0;
    sync::LinkEvents events = mLink.collect(
        mFrame, awaited, quiet,
        after(complete ? std::max(timeout_ms, first_ms) : std::min(10.0 * timeout_ms, first_ms)));
    std::vector<std::optional<cluster::NodeReport>> reports(tiles);
    std::vector<std::pair<sync::PeerId, cluster::NodeReport>> others;
    for (auto& [peer, report] : events.reports) {
      const auto tile = mTiles->tileOf(peer);
      if (!tile || report.working() || report.frame() != mFrame ||
          report.status().code() != cluster::NODE_OK) {
        others.emplace_back(peer, std::move(report));
        continue;
      }
      TileTable::Slot& slot = mTiles->slot(*tile);
      if (slot.state == State::kJoining && report.frame() > slot.welcome_frame)
        mTiles->setLive(*tile);
      // Nodes are not trusted for sizes: pixels only when asked, exactly the tile's.
      const config::Tile& tc = mTiles->tile(*tile);
      const size_t expected =
          message_out.read_back() ? size_t(tc.pixel_width()) * tc.pixel_height() * 4 : 0;
      if (report.rgba().size() != expected) {
        loseTile(*tile, "protocol error: " + std::to_string(report.rgba().size()) +
                            " bytes of pixels for a frame that asked for " +
                            std::to_string(expected));
        continue;
      }
      slot.reported = true;
      reports[*tile] = std::move(report);
    }
    events.reports = std::move(others);
    std::set<sync::PeerId> gone = events.gone;
    absorb(events);
    for (uint32_t i = 0; i < tiles; ++i) {
      const TileTable::Slot& slot = mTiles->slot(i);
      if (slot.state != State::kLive || !awaited.count(slot.peer) || reports[i]) continue;
      const bool closed = gone.count(slot.peer) || !mLink.connected(slot.peer);
      char why[160];
      std::snprintf(
          why, sizeof why,
          closed ? "dead: its connection closed" : "hung: connected, but no report within %.0f ms",
          timeout_ms);
      loseTile(i, why);
    }
    double slowest = 0;
    std::vector<glm::vec2> tile_ranges;
    for (const auto& r : reports) {
      if (!r) continue;
      slowest = std::max(slowest, r->stats().render_ms());
      tile_ranges.emplace_back(r->stats().relative_depth_lo(), r->stats().relative_depth_hi());
    }
    // The next frame maps the same depth differences to the same colours on every tile.
    mWallRelativeDepth = render::wallRange(tile_ranges);
    if (slowest > 0) {
      mRenderMs.push_back(slowest);
      if (mRenderMs.size() > 15) mRenderMs.erase(mRenderMs.begin());
    }
    const double collect_ms = msSince(collect_start);

    if (mStopCode == 0) {
      if (const auto why = policyViolation()) {
        mStopCode = kExitPolicyStop;
        mStopReason = *why;
      }
    }
    if (mStopCode != 0) {
      std::fprintf(stderr, "tessera-master: frame %llu: stopping the wall: %s\n",
                   (unsigned long long)mFrame, mStopReason.c_str());
      mLink.quit(uint32_t(mStopCode), mStopReason);
      if (mParticipants) mParticipants->end("the wall stopped: " + mStopReason);
      return mStopCode;
    }
    const auto swap_start = Clock::now();
    mLink.swap(mFrame);
    mSwapUnixMs = std::chrono::duration<double, std::milli>(
                      std::chrono::system_clock::now().time_since_epoch())
                      .count();
    const double barrier_ms = collect_ms + msSince(swap_start);

    if (!shots.empty() || mFilm) {
      std::vector<std::string> pixels(tiles);
      for (uint32_t i = 0; i < tiles; ++i)
        if (reports[i]) pixels[i] = std::move(*reports[i]->mutable_rgba());
      writeScreenshots(shots, mFrame, pixels);
    }
    if (mFilm && !mFilm->error.empty()) {
      std::fprintf(stderr, "tessera-master: frame %llu: stopping the wall: %s\n",
                   (unsigned long long)mFrame, mFilm->error.c_str());
      mLink.quit(uint32_t(kExitFilmFailed), mFilm->error);
      if (mParticipants) mParticipants->end("the wall stopped: " + mFilm->error);
      return kExitFilmFailed;
    }
    if (mCsv)
      writeStats(frame_start, mFrame, t, frame_bytes, sync_ms, barrier_ms, present_ms,
                 msSince(frame_start), reports);
    if (last) break;
    if (mOpt.max_fps > 0) {  // pace, handling joins meanwhile
      const auto next = frame_start + std::chrono::microseconds(int64_t(1e6 / mOpt.max_fps));
      while (Clock::now() < next) {
        sync::LinkEvents idle = mLink.poll(next);
        absorb(idle);
      }
    }
  }
  mLink.quit(0, "the session ended");
  if (mParticipants) mParticipants->end("the session ended");
  const sync::LinkCounters c = mLink.counters();
  std::printf(
      "tessera-master: %s link: sent %llu bytes in %llu messages, received %llu bytes in "
      "%llu messages, over %llu frames\n",
      mLink.transport(), (unsigned long long)c.bytes_sent, (unsigned long long)c.messages_sent,
      (unsigned long long)c.bytes_received, (unsigned long long)c.messages_received,
      (unsigned long long)mFrame);
  std::fflush(stdout);
  return mFilm ? finishFilm() : kExitOk;
}

void Master::film(const render::Image& wall) {
  Film& f = *mFilm;
  try {
    const render::Image picture =
        mOpt.movie_width > 0 ? render::resizeImage(wall, mOpt.movie_width, mOpt.movie_height)
                             : wall;
    if (!mOpt.movie.empty()) {
      if (!f.writer) {
        media::MovieSettings ms;
        ms.width = int(picture.width);
        ms.height = int(picture.height);
        ms.fps = mOpt.fps;
        f.writer = std::make_unique<media::MovieWriter>(mOpt.movie, ms);
      }
      f.writer->write(picture.rgba, int(picture.width), int(picture.height));
    }
    if (!mOpt.frames_dir.empty())
      render::writePng(render::framePngPath(mOpt.frames_dir, f.written).string(), picture);
    ++f.written;
    f.progress.update(f.written);
  } catch (const std::exception& e) {  // VideoError, RenderError: the disk, the encoder
    f.error = (mOpt.movie.empty() ? "--frames-dir " + mOpt.frames_dir : "--movie " + mOpt.movie) +
              ": " + e.what();
  }
}

int Master::finishFilm() {
  Film& f = *mFilm;
  f.progress.finish();
  // A frame whose wall picture failed was said when it did; the movie would lack it.
  if (f.written != mFrame) {
    std::fprintf(stderr,
                 "tessera-master: %s: %zu of %llu frames have a picture; no movie written\n",
                 mOpt.movie.empty() ? mOpt.frames_dir.c_str() : mOpt.movie.c_str(), f.written,
                 (unsigned long long)mFrame);
    return kExitFilmFailed;
  }
  if (mFrame < uint64_t(mOpt.frames))
    std::printf("tessera-master: the session ended at frame %llu of the path's %d\n",
                (unsigned long long)mFrame, mOpt.frames);
  if (f.writer) {
    try {
      f.writer->finish();
    } catch (const media::VideoError& e) {
      std::fprintf(stderr, "tessera-master: --movie %s: %s\n", mOpt.movie.c_str(), e.what());
      return kExitFilmFailed;
    }
    std::printf("tessera-master: wrote %s (%zu frames at %g fps, %s)\n", mOpt.movie.c_str(),
                f.written, mOpt.fps, f.writer->encoder().c_str());
  }
  if (!mOpt.frames_dir.empty() && f.written > 0)
    std::printf("tessera-master: wrote %s/frame-000000.png .. %s\n", mOpt.frames_dir.c_str(),
                render::framePngPath(mOpt.frames_dir, f.written - 1).filename().c_str());
  std::fflush(stdout);
  return kExitOk;
}

void Master::writeScreenshots(const std::vector<std::string>& paths, uint64_t frame,
                              const std::vector<std::string>& pixels) {
  std::vector<render::Image> images(pixels.size());
  for (size_t i = 0; i < pixels.size(); ++i) {
    const config::Tile& tile = mTiles->tile(uint32_t(i));
    if (pixels[i].empty()) {
      images[i] = render::lostTileImage(tile.pixel_width(), tile.pixel_height());
      continue;
    }
    images[i].width = tile.pixel_width();
    images[i].height = tile.pixel_height();
    images[i].rgba.assign(pixels[i].begin(), pixels[i].end());
  }
  // What the room sees: with projectors, their pictures recomposed on the screen through the
  // warps the wall names (a file that went bad since the start is said, no picture written).
  render::Image wall;
  try {
    // Foveal insets: each slot's picture arrives weighted by its node (render/inset.h); the wall
    // adds the insets' light to the context's.
    // A stereo wall: its left eye (each eye is written beside it).
    wall = mWall.insets_size() == 0 && !mWall.stereo()
               ? render::assembleWallMosaic(mWall, images)
               : render::assembleInsetWall(mWall, images, mGraph.settings().inset());
  } catch (const render::RenderError& e) {
    std::fprintf(stderr, "tessera-master: frame %llu: no screenshot: %s\n",
                 (unsigned long long)frame, e.what());
    return;
  }
  if (mFilm) film(wall);
  for (const std::string& p : paths) {
    try {
      if (fs::path(p).has_parent_path()) fs::create_directories(fs::path(p).parent_path());
      render::writePng(p, wall);
      std::printf("tessera-master: frame %llu: wrote %s (%ux%u); camera %s\n",
                  (unsigned long long)frame, p.c_str(), wall.width, wall.height,
                  cameraArgument(mGraph.camera()).c_str());
      // When the nodes were told to show it (system clock): what glass-to-glass measurements
      // (tests/collab/video_site_test.cpp, bench/video.cpp) compare burned-in clocks with.
      std::printf("tessera-master: frame %llu: swapped at unix ms %.1f\n",
                  (unsigned long long)frame, mSwapUnixMs);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "tessera-master: frame %llu: screenshot %s: %s\n",
                   (unsigned long long)frame, p.c_str(), e.what());
    }
    writeInsetPictures(p, frame, images);
    if (mWall.stereo()) writeEyePictures(p, frame, images);
    if (render::hasProjectors(mWall)) writeProjectorFrames(p, frame, images);
  }
  std::fflush(stdout);
}

void Master::writeProjectorFrames(const std::string& path, uint64_t frame,
                                  const std::vector<render::Image>& pictures) {
  // What each projector shows (its nodes' read-backs), side by side: PATH-projectors.png.
  const std::string file = render::projectorFramesPath(path);
  try {
    const render::Image frames = render::assembleProjectorFrames(mWall, pictures);
    render::writePng(file, frames);
    std::printf("tessera-master: frame %llu: wrote %s (%ux%u); the projectors' pictures\n",
                (unsigned long long)frame, file.c_str(), frames.width, frames.height);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tessera-master: frame %llu: screenshot %s: %s\n",
                 (unsigned long long)frame, file.c_str(), e.what());
  }
}

void Master::writeEyePictures(const std::string& path, uint64_t frame,
                              const std::vector<render::Image>& slots) {
  // A stereo wall: each eye's wall beside the screenshot, PATH-left.png and PATH-right.png.
  for (int eye : {-1, 1}) {
    const std::string file = render::stereoPairPath(path, eye > 0);
    try {
      const render::Image picture =
          render::assembleWallEye(mWall, slots, mGraph.settings().inset(), eye);
      render::writePng(file, picture);
      std::printf("tessera-master: frame %llu: wrote %s (%ux%u); the %s eye\n",
                  (unsigned long long)frame, file.c_str(), picture.width, picture.height,
                  eye < 0 ? "left" : "right");
    } catch (const std::exception& e) {
      std::fprintf(stderr, "tessera-master: frame %llu: screenshot %s: %s\n",
                   (unsigned long long)frame, file.c_str(), e.what());
    }
  }
}

void Master::writeInsetPictures(const std::string& path, uint64_t frame,
                                const std::vector<render::Image>& slots) {
  // Each inset at its own density beside the screenshot: PATH-inset-NAME.png (stereo: an eye a
  // file), the context sampled up under it.
  for (int i = 0; i < mWall.insets_size(); ++i) {
    const config::Inset& in = mWall.insets(i);
    for (int eye : in.stereo() ? std::vector<int>{-1, 1} : std::vector<int>{0}) {
      const std::string file = render::insetPicturePath(path, in.name(), eye);
      try {
        const render::Image detail =
            render::insetDetail(mWall, slots, mGraph.settings().inset(), i, eye);
        render::writePng(file, detail);
        const render::InsetRect r = render::insetRect(mWall, i, mGraph.settings().inset());
        std::printf("tessera-master: frame %llu: wrote %s (%ux%u); inset %s at (%.6g, %.6g)\n",
                    (unsigned long long)frame, file.c_str(), detail.width, detail.height,
                    in.name().c_str(), 0.5 * (r.x0 + r.x1), 0.5 * (r.y0 + r.y1));
      } catch (const std::exception& e) {
        std::fprintf(stderr, "tessera-master: frame %llu: screenshot %s: %s\n",
                     (unsigned long long)frame, file.c_str(), e.what());
      }
    }
  }
}

void Master::writeStatsHeader() {
  *mCsv << "frame,time_s,rank,tile,frame_bytes,sync_ms,render_ms,barrier_ms,present_ms,"
           "frame_ms,settle_frames,points,nodes,resident_bytes,resident_disk_bytes,"
           "store_bytes,chunks_queued,state,start_s\n";
}

void Master::writeStats(Clock::time_point frame_start, uint64_t frame, double t, size_t frame_bytes,
                        double sync_ms, double barrier_ms, double present_ms, double frame_ms,
                        const std::vector<std::optional<cluster::NodeReport>>& reports) {
  std::ofstream& csv = *mCsv;
  // The frame's start on the steady clock (CLOCK_MONOTONIC, shared by every process of the
  // host): benchmarks put kills and restarts on the same time line.
  char start[32];
  std::snprintf(start, sizeof start, "%.6f",
                std::chrono::duration<double>(frame_start.time_since_epoch()).count());
  csv << frame << "," << t << ",0,master," << frame_bytes << "," << sync_ms << ",0," << barrier_ms
      << "," << present_ms << "," << frame_ms << ",0,0,0,0,0,0,0,live," << start << "\n";
  for (uint32_t i = 0; i < reports.size(); ++i) {
    const TileTable::Slot& slot = mTiles->slot(i);
    if (!reports[i]) {
      if (slot.state == State::kLive) continue;  // cannot happen: live tiles reported
      csv << frame << "," << t << ",0," << mTiles->name(i) << ",0,0,0,0,0,0,0,0,0,0,0,0,0,"
          << (slot.state == State::kJoining ? "joining" : "lost") << "," << start << "\n";
      continue;
    }
    const cluster::NodeFrameStats& s = reports[i]->stats();
    csv << frame << "," << t << "," << slot.peer << "," << mTiles->name(i) << ",0,0,"
        << s.render_ms() << "," << s.barrier_ms() << "," << s.present_ms() << ",0," << s.frames()
        << "," << s.points() << "," << s.nodes() << "," << s.resident_bytes() << ","
        << s.resident_disk_bytes() << "," << s.store_bytes() << "," << s.chunks_queued() << ",live,"
        << start << "\n";
  }
  csv.flush();
}

}  // namespace tessera::master
