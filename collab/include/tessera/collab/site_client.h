// A site's end of the site link: a CURVE DEALER socket to the master's site hub
// (site_hub.h), the hello and welcome, the frames and snapshots that keep the site's replica of
// the scene, and the requests it sends. See site.proto for the session.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include <tessera/collab/curve.h>
#include <tessera/site.pb.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::collab {

/// The session cannot go on: the master refused or dropped this site, ended the session, or
/// went silent. what() says which and why.
struct SiteSessionEnded : std::runtime_error {
  enum class Why { kRefused, kDropped, kQuit, kMasterLost, kBadMessage };
  SiteSessionEnded(Why w, const std::string& what) : std::runtime_error(what), why(w) {}
  Why why;
};

struct SiteClientOptions {
  std::string master;              ///< "tcp://HOST:7401"
  std::string master_key;          ///< the master's public key, Z85
  KeyPair keys;                    ///< this site's
  std::string name;                ///< shown on its avatar
  double master_timeout_s = 30.0;  ///< nothing from the master for this long: it is lost (a wall
                                   ///< screenshot may take seconds)
  /// Called by receive() with each voice packet the master sends (its bytes, unchecked: see
  /// voice_packet.h); without it they are dropped.
  std::function<void(std::string_view)> voice;
  /// Called by receive() with each chunk of another site's video (unchecked: video_packet.h);
  /// without it they are dropped.
  std::function<void(std::string_view)> video;
  /// Called by receive() with the master's answer to each SiteNote; without it they are
  /// dropped.
  std::function<void(const site::SiteNoteAnswer&)> note;
};

class SiteClient {
 public:
  using Clock = std::chrono::steady_clock;
  explicit SiteClient(SiteClientOptions options);
  ~SiteClient();

  /// Says hello and waits for the welcome until `deadline`; `graph` becomes the snapshot's
  /// replica. Throws SiteSessionEnded (refused, no answer in time, a bad welcome).
  site::SiteWelcome join(sync::SceneGraph& graph, Clock::time_point deadline);

  /// Applies every frame and snapshot that arrived (waiting for the first until `deadline`) to
  /// `graph`, returning what changed. Throws SiteSessionEnded when the master ends the session,
  /// drops this site, is silent for the timeout or sends what does not apply.
  sync::SceneChanges receive(sync::SceneGraph& graph, Clock::time_point deadline);

  /// Sends a request (never blocks; a full queue drops it: poses are sent again anyway).
  void send(const site::ToMaster& message);

  uint64_t bytesSent() const;
  uint64_t bytesReceived() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace tessera::collab
