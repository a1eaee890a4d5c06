// tessera-site's loop, a library class as the master's and the node's are: join the
// master's session over the site link (site_client.h), keep a replica of the scene, render it
// locally with the renderer and the scene path every node uses (render::SceneDrawList, the
// scene overlay: every avatar but its own, every sketch), and send its pose about 30 times a
// second. Stores it does not have come from the master's chunk server in byte ranges, as its own
// cut needs them, and stay in a disk cache between sessions (chunk_client.h). Headless it plays
// a script (site.proto SiteScript): camera moves, strokes placed on the
// model through the depth buffer, undo and clear, lead, follow, screenshots, goodbye.
#pragma once

#include <memory>
#include <string>

#include <tessera/collab/site_client.h>
#include <tessera/media/video_codec.h>
#include <tessera/site.pb.h>

namespace tessera::collab {

/// Exit codes of SiteSession::run().
constexpr int kSiteOk = 0;           ///< the script ended, or the master ended the session
constexpr int kSiteFailed = 1;       ///< bad script, no GL, a failure the message names
constexpr int kSiteRefused = 16;     ///< the master refused or dropped this site
constexpr int kSiteMasterLost = 17;  ///< no master, or it went silent

struct SiteSessionOptions {
  SiteClientOptions client;
  std::string script;         ///< a SiteScript JSON file ("" : stay still until the master quits)
  std::string out_dir = ".";  ///< screenshots and strokes.csv
  /// A window (one-button navigation, strokes with the right button, keys for lead, follow,
  /// undo, clear) of this size instead of headless; the script, if any, still plays.
  bool window = false;
  uint32_t window_width = 960, window_height = 640;
  bool render = true;  ///< false: poses and requests only (benchmarks of the master's cost)
  double join_timeout_s = 15.0;
  /// Stores: a store the scene names is opened from this host when the file is there, else
  /// through the master's chunk server (chunk_client.h) when the master announces one;
  /// `remote_stores` takes every store from the chunk server.
  bool remote_stores = false;
  std::string cache_dir;        ///< the chunks' disk cache ("" : none)
  double cache_mb = 4096;       ///< its bound over all stores, MB (least recently used go first)
  double chunk_timeout_s = 30;  ///< a chunk request unanswered for this long is sent again
  /// A chunk in flight that this many frames in a row did not want is given up (its request
  /// withdrawn from the chunk server); 0: every request waits for its answer
  /// (render::StreamerOptions::cancel_after_frames).
  uint32_t withdraw_after_frames = 2;
  /// Voice (the master runs --voice): its microphone, a WAV file sent from the
  /// welcome on, and what it hears (the wall's microphone and the other sites), written as WAV
  /// when the session ends; or "alsa:DEVICE", a sound device (voice_alsa.h). "" : none.
  std::string audio_in, audio_out;
  /// Video: "test" (the test pattern), a video file, or a V4L2 camera (/dev/videoN)
  /// sent from the welcome on as H.264 (video_codec.h); "" : none. Other sites' insets are
  /// decoded and drawn when they are in view.
  std::string video;
  media::VideoSettings video_settings;
};

/// A site script from a file, checked: fps in (0, 240], a view of 16..8192 pixels, fovy in
/// (0, 180), actions in frame order with valid cameras, strokes of 2.. points. Throws
/// sync::ConfigError "collab::loadSiteScript(): FILE: FIELD: what".
site::SiteScript loadSiteScript(const std::string& path);

class SiteSession {
 public:
  explicit SiteSession(SiteSessionOptions options);
  ~SiteSession();
  /// Joins, plays the script, leaves. Returns an exit code (kSite*); messages on stdout (joins,
  /// actions, screenshots) and stderr (failures).
  int run();

 private:
  int runSession();
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace tessera::collab
