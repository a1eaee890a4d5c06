// The master's loop (master/): owns the scene graph, plays the script and the
// console's input into it, and drives the render nodes through a cluster link
// (sync/cluster_link.h), whichever its transport. Per frame:
//
//   joins      welcome each new node with the wall, its tile and a snapshot (late joiners and
//              nodes that come back are the same case)
//   publish    what changed (SceneGraph::takeFrame), asking for read-back on screenshot frames
//   collect    every live tile's report, until the node timeout; a tile that misses it is
//              dropped (dead: its connection closed; hung: connected but silent; protocol
//              error; failed: it said why), and the others go on
//   swap       the barrier's release: every node presents
//   screenshot the tiles' pixels assembled with bezels; a tile without a live node is drawn
//              as render::lostTileImage(), never left stale
//
// Failure policies from the wall config: a `critical` tile lost, or fewer live tiles than
// `minLiveTiles`, stops the wall with a message (exit code kPolicyStop).
#pragma once

#include <cstdint>
#include <fstream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/annotate/annotation_scene.h>
#include <tessera/master/script_player.h>
#include <tessera/master/tile_table.h>
#include <tessera/render/image.h>
#include <tessera/sync/cluster_link.h>
#include <tessera/sync/config.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::master {

class Console;

/// The session's other participants, outside the cluster (remote sites: collab/site_hub.h).
/// They change the scene before each frame is taken (avatars, sketches, the leader's camera)
/// and get every frame after; they never make the wall wait.
class Participants {
 public:
  virtual ~Participants() = default;
  /// Before frame `frame` is taken: apply what the participants asked for since the last one.
  /// `session_s`: seconds since the session started (real time).
  virtual void beforeFrame(sync::SceneGraph& graph, uint64_t frame, double session_s) = 0;
  /// After it was taken: `bytes` is its serialized scene::Frame.
  virtual void afterFrame(const sync::SceneGraph& graph, const std::string& bytes) = 0;
  /// The session ends (every participant is told why).
  virtual void end(const std::string& reason) = 0;
  /// Media for the render nodes with the frame being taken (video packets; checked
  /// by the participants): appended to `out`, which the master sends in the frame message.
  virtual void takeMedia(std::vector<std::string>& out) { (void)out; }
};

/// A reason to stop before rendering (bad config, nodes that cannot start): exit code 1.
struct StartError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Exit codes of Master::run().
constexpr int kExitOk = 0;
constexpr int kExitStart = 1;       ///< bad input, or the wall could not start
constexpr int kExitPolicyStop = 5;  ///< a critical tile or too many tiles lost mid-run
constexpr int kExitFilmFailed = 3;  ///< the movie or a frame's PNG could not be written

struct MasterOptions {
  std::string wall, scene, script, screenshot, stats, out_dir = ".";
  int frames = 0;      ///< > 0: deterministic run of this many frames (script time = f / fps)
  double fps = 60.0;   ///< script frames per second with `frames`
  double max_fps = 0;  ///< > 0: frames start at most this often (real time)
  bool console = false;
  uint32_t console_width = 960;
  std::string console_screenshot;  ///< with the console: what it shows at the last frame (PNG)
  /// The annotation database beside the scene (annotation_scene.h), opened or created; "" none.
  std::string annotations;
  /// A film of the script: `frames` becomes its frame count at `fps` (render::pathFrameCount()),
  /// every frame is settled and read back, and the wall's picture of each goes into the MP4
  /// `movie` (media/movie_writer.h) and/or the PNGs of `frames_dir` (render::framePngPath()),
  /// scaled to movie_width x movie_height when both are > 0 (render::resizeImage()).
  std::string movie, frames_dir;
  uint32_t movie_width = 0, movie_height = 0;
  double splat_scale = 2.0, gpu_budget_mb = 1024.0;
  /// A live node's report may be this late (ms) before its tile is dropped; 0: automatic, five
  /// times the slowest node's median render time over the last 15 frames, at least 1000 ms.
  double node_timeout_ms = 0;
  /// Before the first frame: how long to wait for a node per tile (seconds), and for each
  /// node's first rendered frame (cold caches).
  double join_wait_s = 10.0, first_frame_timeout_s = 120.0;
};

class Master {
 public:
  Master(sync::MasterLink& link, MasterOptions options);
  ~Master();

  /// Loads and checks the wall, the scene and the script. Throws StartError / sync::ConfigError
  /// naming the file and field.
  void prepare();

  /// Opens the console window when asked (without a display it says so and goes on headless).
  void openConsole();

  /// Joins, the frame loop, the end. Returns an exit code (kExit*). Messages go to stdout
  /// (progress: joins, drops, screenshots) and stderr (failures).
  int run();

  const config::WallConfig& wall() const { return mWall; }
  /// The scene, after prepare().
  const sync::SceneGraph& scene() const { return mGraph; }

  /// The annotation database as part of the scene (after prepare(); null without
  /// --annotations). Sites' note requests go through it.
  annotate::AnnotationScene* annotations() { return mAnnotations.get(); }

  /// Remote participants that join the session (not owned; must outlive run()).
  void setParticipants(Participants* participants) { mParticipants = participants; }

 private:
  struct Pending;  // per-frame collection state
  struct Film;     // the movie and frames being written, with their progress bar
  /// The wall's picture of a filmed frame into the movie and the frames' folder (a failure to
  /// write is kept in the film, and stops the wall after the frame).
  void film(const render::Image& wall);
  /// After the last frame: the movie finished (its file appears), what was written said.
  /// Returns kExitOk, or kExitFilmFailed when a frame had no picture or the file failed.
  int finishFilm();
  bool start();
  void handleJoins(const sync::LinkEvents& events);
  void handleFaults(const sync::LinkEvents& events);
  /// Faults, joins and the reports that are not the current frame's: startup reports, failures,
  /// a joining node's first rendered frame (it is live from the next frame on).
  void absorb(sync::LinkEvents& events);
  void loseTile(uint32_t tile, const std::string& reason);
  std::optional<std::string> policyViolation() const;
  double nodeTimeoutMs() const;
  cluster::ClusterSetup setupFor(uint32_t tile) const;
  /// Each foveal inset at its own density beside the screenshot `path`
  /// (render::insetPicturePath()); `slots` are the pictures of render::wallSlots().
  /// Each eye of a stereo wall beside the screenshot `path` (render::stereoPairPath()).
  void writeEyePictures(const std::string& path, uint64_t frame,
                        const std::vector<render::Image>& slots);
  void writeInsetPictures(const std::string& path, uint64_t frame,
                          const std::vector<render::Image>& slots);
  /// What each projector shows beside the screenshot `path` (render::projectorFramesPath()),
  /// for a wall with projectors; `pictures` are the tiles' read-backs.
  void writeProjectorFrames(const std::string& path, uint64_t frame,
                            const std::vector<render::Image>& pictures);
  void writeScreenshots(const std::vector<std::string>& paths, uint64_t frame,
                        const std::vector<std::string>& pixels);
  void writeStatsHeader();
  void writeStats(sync::LinkClock::time_point frame_start, uint64_t frame, double t,
                  size_t frame_bytes, double sync_ms, double barrier_ms, double present_ms,
                  double frame_ms, const std::vector<std::optional<cluster::NodeReport>>& reports);
  std::string message(const std::string& text) const;

  sync::MasterLink& mLink;
  MasterOptions mOpt;
  config::WallConfig mWall;
  std::unique_ptr<TileTable> mTiles;
  sync::SceneGraph mGraph;
  std::optional<ScriptPlayer> mPlayer;
  std::unique_ptr<annotate::AnnotationScene> mAnnotations;
  std::unique_ptr<Console> mConsole;
  Participants* mParticipants = nullptr;
  std::unique_ptr<std::ofstream> mCsv;
  std::vector<double> mRenderMs;  // the slowest node's render time, last frames
  // The relative depth range the tiles' last reports agree on (render::wallRange()), sent with
  // the next frame.
  std::optional<glm::vec2> mWallRelativeDepth;
  std::unique_ptr<Film> mFilm;  // with --movie or --frames-dir
  uint64_t mFrame = 0;            // the last frame published
  double mSwapUnixMs = 0;         // the system clock at the last swap, milliseconds
  int mStopCode = 0;
  std::string mStopReason;
};

}  // namespace tessera::master
