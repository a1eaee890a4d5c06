// What the remote sites' requests do to the master's scene, apart from the transport
// (site_hub.h owns the sockets, keys and rates): participants join and leave, each one an AVATAR
// node that follows its poses smoothly, their strokes become SKETCH nodes in a layer per site,
// undo and clear, their measurements MEASUREMENT nodes in "measurements", and follow-me (the leader's pose moves the scene camera).
//
// Avatar motion: each pose is reached over the measured interval between poses (at most 100 ms),
// position linearly, orientation by slerp, starting at the previous frame (the pose arrived
// since), so the first frame after a pose already moves and 30 Hz poses look smooth at 60 Hz.
// Follow-me: when a site takes the lead the scene camera flies from where it was to the leader's
// pose over half a second (smoothstep), then follows the pose. Concurrent edits of one field:
// the last applied wins, and the node's author says who.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <tessera/site.pb.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::collab {

/// One site as the master knows it.
struct SiteInfo {
  std::string name, key;  ///< unique name; Z85 public key
  uint32_t participant = 0, avatar = 0;
  bool leader = false;
  uint64_t poses = 0, strokes = 0, measurements = 0;
};

class SiteRoster {
 public:
  static constexpr double kLeadBlendSeconds = 0.5;
  SiteRoster();
  ~SiteRoster();

  /// A new participant named `wanted` (checked: site_messages.h checkName), made unique
  /// ("Kyoto lab (2)"; "console" is the wall's): its participant id, colour and AVATAR node
  /// (hidden until its first pose). Returns the participant id.
  uint32_t join(sync::SceneGraph& graph, const std::string& wanted, const std::string& key);
  /// Its avatar goes and its lead ends; its sketches stay.
  void leave(sync::SceneGraph& graph, uint32_t participant);
  /// The wall the sites' heads are checked against (sync::headProblem()): a head behind one of
  /// its tiles is refused and said. Without one, every head is refused.
  void setWall(const config::WallConfig& wall) { mWall = wall; }
  /// A checked request (site_messages.h) other than hello and bye, at `now` (seconds).
  void apply(sync::SceneGraph& graph, uint32_t participant, const site::ToMaster& request,
             double now);
  /// Before a frame is taken: avatars where their poses are now; the leader's camera.
  void animate(sync::SceneGraph& graph, double now);

  bool contains(uint32_t participant) const;
  const SiteInfo& info(uint32_t participant) const;
  scene::Color color(uint32_t participant) const;
  std::vector<SiteInfo> sites() const;

 private:
  struct Site;
  std::map<uint32_t, Site> mSites;
  uint32_t mNext = 1;
  double mLastFrame = -1.0;
  // The hand-over of the view to a new leader: the scene camera blends from where it was to
  // the leader's over kLeadBlendSeconds.
  config::Camera mLeadFrom;
  double mLeadStart = -1.0;
  std::optional<config::WallConfig> mWall;
};

}  // namespace tessera::collab
