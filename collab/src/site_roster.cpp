#include <tessera/collab/site_roster.h>

#include <algorithm>
#include <cstdio>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <tessera/collab/site_messages.h>
#include <tessera/sync/scene_edits.h>
#include <tessera/sync/transform.h>
#include <tessera/sync/viewer_head.h>

namespace tessera::collab {

namespace {

using NodeId = sync::SceneGraph::NodeId;

/// Eight colours told apart on a dark wall and by most colour-blind viewers (Okabe and Ito's
/// palette, then two more).
constexpr float kPalette[][3] = {
    {0.90f, 0.62f, 0.00f}, {0.34f, 0.71f, 0.91f}, {0.00f, 0.62f, 0.45f}, {0.94f, 0.89f, 0.26f},
    {0.00f, 0.45f, 0.70f}, {0.84f, 0.37f, 0.00f}, {0.80f, 0.47f, 0.65f}, {0.95f, 0.95f, 0.95f}};

/// A pose as the avatar shows it: eye, orientation (camera to world), distance to the target.
struct PoseState {
  glm::dvec3 eye{0.0};
  glm::dquat orientation{1.0, 0.0, 0.0, 0.0};
  double reach = 1.0;
  float fovy_deg = 45.0f, aspect = 1.0f;

  static PoseState of(const site::SitePose& p) {
    PoseState s;
    s.eye = {p.eye(0), p.eye(1), p.eye(2)};
    const glm::dvec3 target{p.target(0), p.target(1), p.target(2)};
    const glm::dmat4 frame = poseFrame(s.eye, target, {p.up(0), p.up(1), p.up(2)});
    s.orientation = glm::normalize(glm::quat_cast(glm::dmat3(frame)));
    s.reach = glm::length(target - s.eye);
    s.fovy_deg = p.fovy_deg();
    s.aspect = p.aspect();
    return s;
  }
  /// The avatar's node transform, in the rigid form (44 bytes a frame to every node and site,
  /// not 130: sync/transform.h).
  scene::Transform transform() const { return sync::rigidTransform(glm::quat(orientation), eye); }
  static PoseState mix(const PoseState& a, const PoseState& b, double s) {
    if (s >= 1.0) return b;
    PoseState r = b;
    r.eye = glm::mix(a.eye, b.eye, s);
    r.orientation = glm::normalize(glm::slerp(a.orientation, b.orientation, s));
    r.reach = glm::mix(a.reach, b.reach, s);
    return r;
  }
};

}  // namespace

struct SiteRoster::Site {
  SiteInfo info;
  scene::Color color;
  bool has_pose = false;
  uint64_t sequence = 0;
  PoseState from, to;  // the avatar moves from `from` at `start` to `to` over `duration`
  double start = 0, duration = 0, last_pose_at = 0, interval = 1.0 / 30.0;
  glm::dmat4 shown{0.0};
  NodeId layer = 0;              // its sketches' group (0: none yet)
  std::vector<NodeId> sketches;  // oldest first
  std::vector<NodeId> measurements;  // oldest first

  PoseState current(double now) const {
    if (duration <= 0.0) return to;
    return PoseState::mix(from, to, std::clamp((now - start) / duration, 0.0, 1.0));
  }
};

SiteRoster::SiteRoster() = default;
SiteRoster::~SiteRoster() = default;

bool SiteRoster::contains(uint32_t participant) const {
  return mSites.count(participant) != 0;
}

const SiteInfo& SiteRoster::info(uint32_t participant) const {
  return mSites.at(participant).info;
}

scene::Color SiteRoster::color(uint32_t participant) const {
  return mSites.at(participant).color;
}

std::vector<SiteInfo> SiteRoster::sites() const {
  std::vector<SiteInfo> out;
  for (const auto& [id, s] : mSites) out.push_back(s.info);
  return out;
}

uint32_t SiteRoster::join(sync::SceneGraph& graph, const std::string& wanted,
                          const std::string& key) {
  auto taken = [&](const std::string& n) {
    if (n == "console") return true;
    for (const auto& [id, s] : mSites)
      if (s.info.name == n) return true;
    return false;
  };
  std::string name = wanted;
  for (int k = 2; taken(name); ++k) name = wanted.substr(0, 56) + " (" + std::to_string(k) + ")";
  const uint32_t id = mNext++;
  Site& s = mSites[id];
  s.info.name = name;
  s.info.key = key;
  s.info.participant = id;
  const float* c = kPalette[(id - 1) % std::size(kPalette)];
  s.color.set_r(c[0]);
  s.color.set_g(c[1]);
  s.color.set_b(c[2]);
  scene::AvatarPayload a;
  a.set_site(name);
  *a.mutable_color() = s.color;
  s.info.avatar = graph.add(scene::SceneNode::AVATAR, sync::SceneGraph::kRoot, "avatar: " + name,
                            std::move(a), name);
  graph.setVisible(s.info.avatar, false);  // until its first pose
  return id;
}

void SiteRoster::leave(sync::SceneGraph& graph, uint32_t participant) {
  auto it = mSites.find(participant);
  if (it == mSites.end()) return;
  const Site& s = it->second;
  if (s.info.avatar && graph.contains(s.info.avatar)) graph.remove(s.info.avatar);
  if (graph.settings().leader() == s.info.name) graph.setLeader("");
  mSites.erase(it);
}

void SiteRoster::apply(sync::SceneGraph& graph, uint32_t participant, const site::ToMaster& m,
                       double now) {
  auto it = mSites.find(participant);
  if (it == mSites.end()) return;
  Site& s = it->second;
  // Sketches the master removed meanwhile are forgotten.
  std::erase_if(s.sketches, [&](NodeId id) { return !graph.contains(id); });
  std::erase_if(s.measurements, [&](NodeId id) { return !graph.contains(id); });
  if (s.layer && !graph.contains(s.layer)) s.layer = 0;
  switch (m.kind_case()) {
    case site::ToMaster::kPose: {
      const site::SitePose& p = m.pose();
      if (s.has_pose && p.sequence() <= s.sequence) return;  // late or repeated
      const PoseState next = PoseState::of(p);
      if (s.has_pose) {
        s.interval = 0.8 * s.interval + 0.2 * std::clamp(now - s.last_pose_at, 0.0, 0.5);
        s.from = s.current(now);
      } else {
        s.from = next;
      }
      s.to = next;
      // It arrived at some time since the previous frame: the motion starts there, so the
      // first frame after it already moves.
      s.start = mLastFrame >= 0 ? std::min(now, mLastFrame) : now;
      s.duration = std::clamp(s.interval, 0.0, 0.1);
      s.last_pose_at = now;
      s.sequence = p.sequence();
      s.has_pose = true;
      s.info.poses++;
      return;
    }
    case site::ToMaster::kStroke: {
      const site::SiteStroke& st = m.stroke();
      if (s.sketches.size() >= kMaxSketchesPerSite) {
        std::printf(
            "tessera-master: sites: %s: stroke ignored: it has %zu sketches, the most a "
            "site may keep (undo or clear first)\n",
            s.info.name.c_str(), s.sketches.size());
        return;
      }
      if (!s.layer) s.layer = sync::layerGroup(graph, "sketches/" + s.info.name, s.info.name);
      std::vector<glm::dvec3> points;
      for (int i = 0; i + 2 < st.points_size(); i += 3)
        points.emplace_back(st.points(i), st.points(i + 1), st.points(i + 2));
      const NodeId id =
          sync::addSketch(graph, s.layer, s.info.name, points, st.color(), st.width());
      s.sketches.push_back(id);
      s.info.strokes++;
      return;
    }
    case site::ToMaster::kMeasure: {
      const site::SiteMeasure& me = m.measure();
      if (s.measurements.size() >= kMaxMeasurementsPerSite) {
        std::printf(
            "tessera-master: sites: %s: measurement ignored: it has %zu, the most a site may "
            "keep\n",
            s.info.name.c_str(), s.measurements.size());
        return;
      }
      std::vector<glm::dvec3> points;
      for (int i = 0; i + 2 < me.points_size(); i += 3)
        points.emplace_back(me.points(i), me.points(i + 1), me.points(i + 2));
      const NodeId layer = sync::layerGroup(graph, "measurements", s.info.name);
      try {
        s.measurements.push_back(sync::addMeasurement(graph, layer, s.info.name, me.type(),
                                                      points, me.value(), me.uncertainty()));
        s.info.measurements++;
      } catch (const std::exception& e) {  // checked already: the scene's own rule
        std::printf("tessera-master: sites: %s: measurement refused: %s\n", s.info.name.c_str(),
                    e.what());
      }
      return;
    }
    case site::ToMaster::kShading: {  // checked: the wall's lighting and filters, for everyone
      const site::SiteShading& sh = m.shading();
      if (sh.has_shading()) graph.setShading(sh.shading());
      if (sh.has_analysis()) graph.setAnalysis(sh.analysis());
      std::printf("tessera-master: sites: %s changed the shading\n", s.info.name.c_str());
      std::fflush(stdout);
      return;
    }
    case site::ToMaster::kHead: {  // checked alone; in front of every tile is the wall's check
      const auto why = mWall ? sync::headProblem(*mWall, m.head().head())
                             : std::optional<std::string>("the master knows no wall");
      if (why) {
        std::printf("tessera-master: sites: %s: head refused: head.head.%s\n", s.info.name.c_str(),
                    why->c_str());
      } else {
        graph.setHead(m.head().head());
        std::printf("tessera-master: sites: %s moved the viewer's head\n", s.info.name.c_str());
      }
      std::fflush(stdout);
      return;
    }
    case site::ToMaster::kUndo:
      if (!s.sketches.empty()) {
        graph.remove(s.sketches.back());
        s.sketches.pop_back();
      }
      return;
    case site::ToMaster::kClear:
      for (NodeId id : s.sketches) graph.remove(id);
      s.sketches.clear();
      return;
    case site::ToMaster::kLead:
      if (graph.settings().leader() != s.info.name) {
        graph.setLeader(s.info.name);
        mLeadFrom = graph.camera();
        mLeadStart = now;
        std::printf("tessera-master: sites: %s leads the view\n", s.info.name.c_str());
        std::fflush(stdout);
      }
      return;
    case site::ToMaster::kRelease:
      if (graph.settings().leader() == s.info.name) {
        graph.setLeader("");
        std::printf("tessera-master: sites: %s gave the view back\n", s.info.name.c_str());
        std::fflush(stdout);
      }
      return;
    default:
      return;
  }
}

void SiteRoster::animate(sync::SceneGraph& graph, double now) {
  for (auto& [id, s] : mSites) {
    s.info.leader = graph.settings().leader() == s.info.name;
    if (!s.has_pose || !graph.contains(s.info.avatar)) continue;
    const PoseState p = s.current(now);
    const scene::Transform pose = p.transform();
    const glm::dmat4 frame = sync::transformMatrix(pose);
    if (frame != s.shown) {
      graph.setTransform(s.info.avatar, pose);
      s.shown = frame;
    }
    const scene::AvatarPayload& old = graph.node(s.info.avatar).avatar();
    if (old.fovy_deg() != p.fovy_deg || old.aspect() != p.aspect || old.reach() != float(p.reach)) {
      scene::AvatarPayload a = old;
      a.set_fovy_deg(p.fovy_deg);
      a.set_aspect(p.aspect);
      a.set_reach(float(p.reach));
      graph.setPayload(s.info.avatar, a);
    }
    if (!graph.node(s.info.avatar).visible()) graph.setVisible(s.info.avatar, true);
    if (s.info.leader) {
      const glm::dvec3 f = -glm::dvec3(frame[2]), u = glm::dvec3(frame[1]);
      config::Camera c;
      auto set = [](config::Vec3* v, const glm::dvec3& x) {
        v->set_x(x.x);
        v->set_y(x.y);
        v->set_z(x.z);
      };
      set(c.mutable_eye(), p.eye);
      set(c.mutable_target(), p.eye + f * p.reach);
      set(c.mutable_up(), u);
      const double t =
          mLeadStart >= 0 ? std::clamp((now - mLeadStart) / kLeadBlendSeconds, 0.0, 1.0) : 1.0;
      graph.setCamera(t < 1.0 ? blendCameras(mLeadFrom, c, t * t * (3.0 - 2.0 * t)) : c);
    }
  }
  mLastFrame = now;
}

}  // namespace tessera::collab
