// The master's side of the remote sites (collab/): one CURVE ROUTER socket
// that sites join over the internet (collab/curve.h: only keys on the allow list get in), as
// master::Participants of the master's loop.
//
// Before each frame the hub drains what the sites sent, checks every message
// (site_messages.h) and rate (a token bucket per site for messages and bytes), and applies the
// requests to the master's scene, which then reaches every node and site as ordinary frames:
//   hello   the site is welcomed with its participant id, colour and the scene's snapshot;
//           an AVATAR node stands for it from then on
//   pose    the avatar moves there, smoothly: each pose is reached over the measured interval
//           between poses (at most 100 ms), position linearly and orientation by slerp; the
//           leader's pose also moves the scene camera
//   stroke  a SKETCH node (a 3D polyline the site placed on the model) in the site's layer, a
//           GROUP node "sketches/NAME"; undo removes its newest, clear all of its sketches
//   lead    the scene's leader becomes the site (Settings::leader); release gives the view back
//   note    an edit of the annotation database (site_notes.h): committed, applied to the
//           scene, and answered (ok, or refused with the reason: a stale revision, an unknown
//           item), so a site's note is acknowledged only once it is on disk
//   bye     the avatar goes (its sketches stay); a site silent for the timeout goes too
//   video   a chunk of the site's H.264 stream (video_packet.h), held to the video cap: the
//           first makes a VIDEO_INSET node (beside the avatar, or pinned to the screen), and
//           every chunk goes to the render nodes with the next frame (takeMedia) and to the
//           other sites at once; no video for video_timeout_s and the inset goes
// Concurrent edits of one field: the last applied wins, and the node's author says who.
//
// After each frame every welcomed site gets the frame; a site whose queue is full (it does not
// read fast enough) misses it and gets a snapshot with the next frame instead. Sends never
// block; a site that breaks the protocol or floods is disconnected with a message, and its
// later messages are discarded unread, so it costs the wall nothing beyond receiving them.
//
// Not thread-safe: the master's loop thread uses it (the ZAP handler has its own thread).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <tessera/collab/site_roster.h>
#include <tessera/master/master.h>

namespace tessera::collab {

struct SiteHubOptions {
  std::string endpoint = "tcp://*:7401";  ///< where sites connect
  std::string key_file;                   ///< the master's key pair (curve.h key file)
  std::string allow_list;                 ///< site public keys (curve.h allow list)
  double silent_timeout_s =
      10.0;  ///< no message for this long: the site is gone (a closed connection: at once)
  /// Token buckets per site: sustained rates, bursts of `burst_s` seconds' worth.
  double messages_per_s = 200.0, bytes_per_s = 4.0 * 1024 * 1024, burst_s = 2.0;
  int send_queue = 256;  ///< messages queued per site (ZMQ_SNDHWM) before it falls behind
  /// The chunk server's endpoint (chunk_server.h; tessera-master --chunks), "" for none: sites
  /// then need the stores themselves. It serves the stores the scene's models name now.
  std::string chunks_endpoint;
  double chunk_bytes_per_s = 100e6 / 8;  ///< per site (--chunk-rate, Mbit/s)
  double chunk_total_bytes_per_s = 0;    ///< all sites (--chunk-total-rate, Mbit/s); 0: none
  /// Voice (voice_bridge.h): the master mixes what sites say, sends each its
  /// mix-minus and plays every site in the wall room. The clock is the master's loop: mixing
  /// happens before each frame, 20 ms periods at a time.
  bool voice = false;
  /// The wall room's microphone: a WAV file or "alsa:DEVICE" (voice_alsa.h); "" : none.
  /// Needs voice.
  std::string audio_in;
  /// The wall room's speakers: a WAV file written at the end or "alsa:DEVICE"; needs voice.
  std::string audio_out;
  /// Video insets: each site's video is held to this many kbit/s (sustained, with a
  /// one-second burst); chunks over it are dropped and the master says so once a second. The
  /// stream recovers at its next intra refresh; the wall never waits for it.
  double video_cap_kbps = 4000;
  /// Where a site's inset goes: beside its avatar (false), or pinned to the screen (true) at
  /// (screen_x, screen_y), lower-left corner, screen_width wide, fractions of the wall (more
  /// insets to its right); its height follows the picture's aspect.
  bool video_screen = false;
  float screen_x = 0.72f, screen_y = 0.04f, screen_width = 0.24f;
  double video_timeout_s = 3.0;  ///< no video from a site for this long: its inset goes
  /// The wall the sites' heads are checked against (SiteRoster::setWall()); no tiles: none.
  config::WallConfig wall;
};

struct SiteHubCounters {
  uint64_t joined = 0, left = 0, dropped = 0, refused = 0;
  uint64_t messages_in = 0, bytes_in = 0, messages_out = 0, bytes_out = 0;
  uint64_t snapshots_resent = 0;  ///< snapshots sent to sites that fell behind
  uint64_t discarded = 0;         ///< messages of dropped sites, discarded unread
  uint64_t chunk_requests = 0, chunk_refused = 0, chunk_bytes_out = 0;  ///< the chunk server's
  uint64_t voice_in = 0, voice_out = 0;      ///< voice packets from and to sites
  uint64_t video_in = 0, video_dropped = 0;  ///< video chunks from sites; dropped over the cap
  uint64_t video_to_nodes = 0, video_to_sites = 0;  ///< video chunks forwarded
  uint64_t notes = 0;  ///< sites' annotation edits committed (refused ones are said)
};

class SiteHub final : public master::Participants {
 public:
  /// Reads the key pair and the allow list, starts the ZAP handler and binds the endpoint.
  /// Throws collab::KeyError (keys, list) or std::runtime_error (the endpoint) naming them.
  explicit SiteHub(SiteHubOptions options);
  ~SiteHub() override;

  /// The bound endpoint with its real port ("tcp://0.0.0.0:7401").
  std::string endpoint() const;
  /// The chunk server's bound endpoint, "" without one.
  std::string chunksEndpoint() const;

  void beforeFrame(sync::SceneGraph& graph, uint64_t frame, double session_s) override;
  void afterFrame(const sync::SceneGraph& graph, const std::string& bytes) override;
  void end(const std::string& reason) override;
  void takeMedia(std::vector<std::string>& out) override;

  std::vector<SiteInfo> sites() const;
  SiteHubCounters counters() const;

  /// The annotation database the sites' SiteNote edits go to (not owned; null: refused with
  /// a reason). Master::annotations().
  void setAnnotations(annotate::AnnotationScene* notes);

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace tessera::collab
