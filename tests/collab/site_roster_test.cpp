// The site messages' checks (collab/site_messages.h) and what the roster does with them to the
// master's scene (collab/site_roster.h): avatars that follow poses smoothly, sketches in a layer
// per site with undo and clear, follow-me through the scene's leader and camera, unique names.
// The scene graph is the real one; every effect is read back from a replica that applied the
// frames, as a node or a site would see it.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include <glm/glm.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <tessera/collab/site_messages.h>
#include <tessera/collab/site_roster.h>
#include <tessera/media/video_packet.h>
#include <tessera/media/voice_packet.h>
#include <tessera/sync/config.h>
#include <tessera/sync/scene_graph.h>
#include <tessera/sync/transform.h>
#include <tessera/sync/vec3.h>

namespace {

using namespace tessera;

site::ToMaster pose(uint64_t seq, glm::dvec3 eye, glm::dvec3 target, glm::dvec3 up = {0, 1, 0}) {
  site::ToMaster m;
  site::SitePose& p = *m.mutable_pose();
  p.set_sequence(seq);
  for (int k = 0; k < 3; ++k) {
    p.add_eye(eye[k]);
    p.add_target(target[k]);
    p.add_up(up[k]);
  }
  p.set_fovy_deg(45);
  p.set_aspect(1.5f);
  return m;
}

site::ToMaster stroke(std::initializer_list<double> xyz) {
  site::ToMaster m;
  for (double v : xyz) m.mutable_stroke()->add_points(v);
  m.mutable_stroke()->mutable_color()->set_r(1);
  m.mutable_stroke()->set_width(4);
  return m;
}

glm::dvec3 avatarEye(const sync::SceneGraph& g, uint32_t id) {
  return glm::dvec3(sync::transformMatrix(g.node(id).transform())[3]);
}

/// A replica kept up to date with the master's frames, as nodes and sites keep theirs.
struct Session {
  sync::SceneGraph master, replica;
  collab::SiteRoster roster;
  uint64_t frame = 0;
  void step(double now) {
    roster.animate(master, now);
    replica.apply(master.takeFrame(++frame, uint64_t(now * 1e6)));
  }
};

TEST(SiteMessages, RefusesNonFiniteDegenerateAndOversizedInput) {
  site::ToMaster ok = pose(1, {0, 0, 2}, {0, 0, 0});
  EXPECT_FALSE(collab::checkToMaster(ok));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(collab::checkToMaster(pose(1, {nan, 0, 2}, {0, 0, 0})).value_or(""),
            "pose.eye: numbers must be finite");
  EXPECT_EQ(collab::checkToMaster(pose(1, {0, 0, 0}, {0, 0, 0})).value_or(""),
            "pose: eye and target coincide");
  EXPECT_EQ(collab::checkToMaster(pose(1, {0, 0, 2}, {0, 0, 0}, {0, 0, 0})).value_or(""),
            "pose.up: up is zero");
  EXPECT_EQ(collab::checkToMaster(pose(1, {0, 0, 2}, {0, 0, 0}, {0, 0, 1})).value_or(""),
            "pose.up: up is along the view direction");
  EXPECT_TRUE(collab::checkToMaster(pose(1, {1e9, 0, 2}, {0, 0, 0})));
  site::ToMaster fov = ok;
  fov.mutable_pose()->set_fovy_deg(180);
  EXPECT_TRUE(collab::checkToMaster(fov));
  site::ToMaster two_eyes = ok;
  two_eyes.mutable_pose()->add_eye(1);
  EXPECT_TRUE(collab::checkToMaster(two_eyes));

  EXPECT_FALSE(collab::checkToMaster(stroke({0, 0, 0, 1, 1, 1})));
  EXPECT_TRUE(collab::checkToMaster(stroke({0, 0, 0})));        // one point
  EXPECT_TRUE(collab::checkToMaster(stroke({0, 0, 0, 1, 1})));  // not triples
  EXPECT_TRUE(collab::checkToMaster(stroke({0, 0, 0, 1, nan, 1})));
  site::ToMaster wide = stroke({0, 0, 0, 1, 1, 1});
  wide.mutable_stroke()->set_width(65);
  EXPECT_TRUE(collab::checkToMaster(wide));
  site::ToMaster colour = stroke({0, 0, 0, 1, 1, 1});
  colour.mutable_stroke()->mutable_color()->set_g(-0.1f);
  EXPECT_TRUE(collab::checkToMaster(colour));
  site::ToMaster many;
  for (int i = 0; i < 3 * (collab::kMaxStrokePoints + 1); ++i) many.mutable_stroke()->add_points(0);
  many.mutable_stroke()->set_width(1);
  EXPECT_TRUE(collab::checkToMaster(many));

  EXPECT_TRUE(collab::checkToMaster(site::ToMaster()));  // no kind
  site::ToMaster m;
  EXPECT_TRUE(collab::parseToMaster("\xff\xff\xff garbage", m));
  EXPECT_TRUE(collab::parseToMaster(std::string(collab::kMaxSiteMessageBytes + 1, '\0'), m));
}

TEST(SiteMessages, VideoIsAVideoPacketChecked) {
  media::VideoPacket p;
  p.width = 640;
  p.height = 480;
  p.payload.assign(media::kMaxVideoChunkBytes, 7);
  const std::vector<uint8_t> packet = media::encodeVideoPacket(p);
  site::ToMaster m;
  m.set_video(packet.data(), packet.size());
  site::ToMaster parsed;
  EXPECT_EQ(collab::parseToMaster(m.SerializeAsString(), parsed), std::nullopt);
  EXPECT_EQ(parsed.video(), m.video());
  m.set_video(packet.data(), packet.size() - 1);  // truncated
  auto why = collab::parseToMaster(m.SerializeAsString(), parsed);
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("video: video packet: payload size"), std::string::npos) << *why;
  std::string oversized(packet.begin(), packet.end());
  oversized.append(100, '\0');  // more than a packet may be, whatever its size field says
  m.set_video(oversized);
  why = collab::parseToMaster(m.SerializeAsString(), parsed);
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("more than the largest packet"), std::string::npos) << *why;
  m.set_video("");
  EXPECT_TRUE(collab::parseToMaster(m.SerializeAsString(), parsed));
}

TEST(SiteMessages, VoiceIsAVoicePacketChecked) {
  media::VoiceSender sender(media::VoiceSettings{}, 1);
  std::vector<float> tone(960);
  for (size_t i = 0; i < tone.size(); ++i) tone[i] = 0.3f * float(std::sin(0.05 * double(i)));
  const std::vector<uint8_t> packet = *sender.send(tone);
  site::ToMaster m;
  m.set_voice(packet.data(), packet.size());
  site::ToMaster parsed;
  EXPECT_EQ(collab::parseToMaster(m.SerializeAsString(), parsed), std::nullopt);
  EXPECT_EQ(parsed.voice(), m.voice());
  m.set_voice(packet.data(), packet.size() - 1);  // truncated
  const auto why = collab::parseToMaster(m.SerializeAsString(), parsed);
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("voice: voice packet: payload size"), std::string::npos) << *why;
  m.set_voice("");
  EXPECT_TRUE(collab::parseToMaster(m.SerializeAsString(), parsed));
  // The roster has nothing to do with voice (the hub's bridge takes it): the scene is untouched.
  sync::SceneGraph graph;
  collab::SiteRoster roster;
  const uint32_t id = roster.join(graph, "talker", "key");
  const uint64_t version = graph.version();
  m.set_voice(packet.data(), packet.size());
  roster.apply(graph, id, m, 0.0);
  EXPECT_EQ(graph.version(), version);
}

TEST(SiteMessages, SnapsAreBoundedFiniteStrokesInAView) {
  auto snap = [](std::vector<double> fg, std::vector<double> bg, float heavy) {
    site::ToMaster m;
    site::SiteSnap& s = *m.mutable_snap();
    s.set_model(1);
    const glm::dmat4 id(1.0);
    for (int k = 0; k < 16; ++k) {
      s.add_view(id[k / 4][k % 4]);
      s.add_projection(id[k / 4][k % 4]);
    }
    s.set_width(640);
    s.set_height(480);
    for (double v : fg) s.add_foreground(v);
    for (double v : bg) s.add_background(v);
    s.set_heavy_width(heavy);
    return m;
  };
  auto why = [](const site::ToMaster& m) { return collab::checkToMaster(m).value_or(""); };
  EXPECT_EQ(why(snap({10, 10, 20, 20}, {30, 30}, 0)), "");
  EXPECT_EQ(why(snap({10, 10, 20, 20, 30, 10}, {}, 16)), "");  // the robust lasso
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(why(snap({10, nan}, {30, 30}, 0)),
            "snap.foreground: numbers must be finite, within 1e6");
  EXPECT_EQ(why(snap({10, 10}, {}, 0)).rfind("snap.background: needs 1..2048", 0), 0u);
  EXPECT_EQ(why(snap({10, 10, 20}, {1, 1}, 0)).rfind("snap.foreground: needs", 0), 0u);
  EXPECT_EQ(why(snap({10, 10, 20, 20}, {}, 16)).rfind("snap.foreground: needs 3..2048", 0), 0u);
  EXPECT_EQ(why(snap({10, 10, 20, 20, 30, 10}, {1, 1}, 16)).rfind("snap.background:", 0), 0u);
  EXPECT_EQ(why(snap({10, 10}, {1, 1}, 0.5f)).rfind("snap.heavy_width:", 0), 0u);
  EXPECT_EQ(why(snap({10, 10}, {1, 1}, 1e9f)).rfind("snap.heavy_width:", 0), 0u);
  EXPECT_EQ(why(snap(std::vector<double>(2 * 2049, 1.0), {1, 1}, 0)).rfind("snap.foreground:", 0),
            0u);
  site::ToMaster m = snap({10, 10}, {1, 1}, 0);
  m.mutable_snap()->set_width(8);
  EXPECT_EQ(why(m), "snap.width: 16..16384 pixels, got 8");
  m = snap({10, 10}, {1, 1}, 0);
  m.mutable_snap()->clear_projection();
  EXPECT_EQ(why(m), "snap.projection: needs 16 numbers, got 0");
  m = snap({10, 10}, {1, 1}, 0);
  m.mutable_snap()->set_model(0);
  EXPECT_EQ(why(m), "snap.model: must name a MODEL node (> 0)");
  // Two strokes of the largest size fit a message.
  m = snap(std::vector<double>(2 * 2048, 1234.5678), std::vector<double>(2 * 2048, 1234.5678), 0);
  EXPECT_LE(m.ByteSizeLong(), collab::kMaxSiteMessageBytes);
}

TEST(SiteMessages, NamesAreShortPrintableUtf8) {
  EXPECT_FALSE(collab::checkName("Kyoto lab", "name"));
  EXPECT_FALSE(collab::checkName("京都ラボ", "name"));
  EXPECT_TRUE(collab::checkName("", "name"));
  EXPECT_TRUE(collab::checkName(std::string(65, 'a'), "name"));
  EXPECT_TRUE(collab::checkName("tab\there", "name"));
  EXPECT_TRUE(collab::checkName("\xc0\xaf", "name"));      // overlong '/'
  EXPECT_TRUE(collab::checkName("\xed\xa0\x80", "name"));  // a surrogate
  EXPECT_TRUE(collab::checkName("cut \xe4\xba", "name"));  // truncated sequence
  EXPECT_TRUE(collab::checkName("\xc2\x85", "name"));      // C1 control (NEL)
}

TEST(SiteRoster, AvatarFollowsPosesSmoothlyAndLeavesWithItsSite) {
  Session s;
  const uint32_t a = s.roster.join(s.master, "Kyoto lab", "k1");
  s.step(0.0);
  const uint32_t avatar = s.roster.info(a).avatar;
  ASSERT_TRUE(s.replica.contains(avatar));
  EXPECT_FALSE(s.replica.node(avatar).visible()) << "no pose yet";
  EXPECT_EQ(s.replica.node(avatar).avatar().site(), "Kyoto lab");
  EXPECT_EQ(s.replica.node(avatar).author(), "Kyoto lab");

  // Poses 1/30 s apart; the wall at 60 Hz.
  s.roster.apply(s.master, a, pose(1, {0, 0, 2}, {0, 0, 0}), 0.01);
  s.step(1.0 / 60);
  EXPECT_TRUE(s.replica.node(avatar).visible());
  EXPECT_NEAR(glm::length(avatarEye(s.replica, avatar) - glm::dvec3(0, 0, 2)), 0.0, 1e-12);
  EXPECT_FLOAT_EQ(s.replica.node(avatar).avatar().reach(), 2.0f);
  // Frame of the avatar: right, up, back (the view negated), eye.
  const glm::dmat4 m = sync::transformMatrix(s.replica.node(avatar).transform());
  EXPECT_NEAR(m[2][2], 1.0, 1e-7) << "back = +z for a view down -z";

  double t = 1.0 / 60;
  s.roster.apply(s.master, a, pose(2, {1, 0, 2}, {1, 0, 0}), t + 0.005);
  std::vector<double> xs;
  for (int f = 0; f < 6; ++f) {
    t += 1.0 / 60;
    s.step(t);
    xs.push_back(avatarEye(s.replica, avatar).x);
  }
  EXPECT_GT(xs[0], 0.0) << "the first frame after a pose already moves";
  EXPECT_LT(xs[0], 1.0) << "... but does not jump";
  for (size_t i = 1; i < xs.size(); ++i) EXPECT_GE(xs[i], xs[i - 1]);
  EXPECT_DOUBLE_EQ(xs.back(), 1.0) << "reached within the pose interval";

  // An older pose (out of order) is ignored.
  s.roster.apply(s.master, a, pose(1, {5, 5, 5}, {0, 0, 0}), t);
  s.step(t += 0.05);
  EXPECT_DOUBLE_EQ(avatarEye(s.replica, avatar).x, 1.0);

  s.roster.leave(s.master, a);
  s.step(t += 0.05);
  EXPECT_FALSE(s.replica.contains(avatar));
  EXPECT_EQ(s.replica, s.master);
}

TEST(SiteRoster, StrokesAreSketchesInTheSitesLayerWithUndoAndClear) {
  Session s;
  const uint32_t a = s.roster.join(s.master, "Kyoto lab", "k1");
  const uint32_t b = s.roster.join(s.master, "Kyoto lab", "k2");
  EXPECT_EQ(s.roster.info(b).name, "Kyoto lab (2)") << "names are unique";
  // Georeferenced: millimetres at 10^6 m survive (float points relative to a double origin).
  s.roster.apply(s.master, a, stroke({636590.001, 847900.002, 100.003, 636590.5, 847900.25, 100.5}),
                 0);
  s.roster.apply(s.master, a, stroke({0, 0, 0, 1, 0, 0, 1, 1, 0}), 0);
  s.roster.apply(s.master, b, stroke({0, 0, 0, 0, 1, 0}), 0);
  s.step(0.0);
  const auto layer_a = s.replica.findByName("sketches/Kyoto lab");
  const auto layer_b = s.replica.findByName("sketches/Kyoto lab (2)");
  ASSERT_TRUE(layer_a && layer_b);
  std::vector<uint32_t> sketches = s.replica.children(*layer_a);
  ASSERT_EQ(sketches.size(), 2u);
  const scene::SceneNode& first = s.replica.node(sketches[0]);
  EXPECT_EQ(first.author(), "Kyoto lab");
  const glm::dvec3 t(sync::transformMatrix(first.transform())[3]);
  const auto& p = first.sketch().points();
  EXPECT_NEAR(t.x + p[3], 636590.5, 1e-3);
  EXPECT_NEAR(t.y + p[4], 847900.25, 1e-3);
  EXPECT_NEAR(t.x + p[0], 636590.001, 1e-6);

  s.roster.apply(s.master, a, site::ToMaster(), 0);  // nothing
  site::ToMaster undo;
  undo.mutable_undo();
  s.roster.apply(s.master, a, undo, 0);
  s.step(0.1);
  EXPECT_EQ(s.replica.children(*layer_a), std::vector<uint32_t>{sketches[0]}) << "the newest goes";
  // The master removed the other one itself: undo then has nothing of a's left, b's stay.
  s.master.remove(sketches[0]);
  s.roster.apply(s.master, a, undo, 0);
  site::ToMaster clear;
  clear.mutable_clear();
  s.step(0.2);
  EXPECT_TRUE(s.replica.children(*layer_a).empty());
  EXPECT_EQ(s.replica.children(*layer_b).size(), 1u);
  s.roster.apply(s.master, b, clear, 0);
  s.step(0.3);
  EXPECT_TRUE(s.replica.children(*layer_b).empty());
  // A site that leaves keeps its sketches in the scene (nothing else changes).
  s.roster.apply(s.master, b, stroke({0, 0, 0, 0, 1, 0}), 0);
  s.roster.leave(s.master, b);
  s.step(0.4);
  EXPECT_EQ(s.replica.children(*layer_b).size(), 1u);
}

// A site's shading keys change the wall's lighting and filters for everyone; a message with a
// filter out of range is refused by name before it reaches the scene.
TEST(SiteRoster, ASitesShadingKeysChangeTheWallsFilters) {
  Session s;
  const uint32_t a = s.roster.join(s.master, "A", "k1");
  site::ToMaster m;  // what G sends (interact::shadingEdit())
  m.mutable_shading()->mutable_analysis()->set_ao_strength(1.0f);
  m.mutable_shading()->set_shading(scene::SHADING_EDL);
  EXPECT_FALSE(collab::checkToMaster(m));
  s.roster.apply(s.master, a, m, 0.0);
  s.step(0.1);
  EXPECT_EQ(s.replica.settings().analysis().ao_strength(), 1.0f);
  EXPECT_EQ(s.replica.settings().shading(), scene::SHADING_EDL);
  site::ToMaster bad = m;
  bad.mutable_shading()->mutable_analysis()->set_ao_strength(std::nanf(""));
  const auto why = collab::checkToMaster(bad);
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("ao_strength"), std::string::npos) << *why;
  bad = m;
  bad.mutable_shading()->mutable_analysis()->set_ao_slices(1000);
  EXPECT_TRUE(collab::checkToMaster(bad));
  bad.Clear();
  bad.mutable_shading();
  EXPECT_TRUE(collab::checkToMaster(bad));  // names nothing
}

// A site moves the viewer's head on the wall for everyone: the message's own checks refuse a
// NaN or a zero axis by field, the master's wall check one behind a tile; a refused head leaves
// the scene as it was.
TEST(SiteRoster, ASitesHeadMessageMovesTheViewersHeadOrIsRefused) {
  Session s;
  s.roster.setWall(sync::parseWallConfig(
      R"({"tiles": [{"name": "a", "width": 1.6, "height": 1.2, "pixelWidth": 64,
          "pixelHeight": 48}], "eye": {"x": 0.8, "y": 0.6, "z": 1.5}})",
      "wall.json", ""));
  const uint32_t a = s.roster.join(s.master, "A", "k1");
  site::ToMaster m;
  scene::Head& h = *m.mutable_head()->mutable_head();
  sync::set(h.mutable_eye(), {0.8, 0.6, 1.4});
  sync::set(h.mutable_right(), {0.94, 0.0, 0.34});
  h.set_eye_separation(0.06);
  EXPECT_FALSE(collab::checkToMaster(m));
  s.roster.apply(s.master, a, m, 0.0);
  s.step(0.1);
  ASSERT_TRUE(s.replica.settings().has_head());
  EXPECT_EQ(s.replica.settings().head().eye().x(), 0.8);
  EXPECT_EQ(s.replica.settings().head().eye_separation(), 0.06);

  site::ToMaster bad = m;
  bad.mutable_head()->mutable_head()->mutable_eye()->set_y(std::nan(""));
  EXPECT_EQ(collab::checkToMaster(bad).value_or("").rfind("head.head.eye: needs finite", 0), 0u)
      << collab::checkToMaster(bad).value_or("");
  bad = m;
  sync::set(bad.mutable_head()->mutable_head()->mutable_right(), {0, 0, 0});
  EXPECT_NE(collab::checkToMaster(bad).value_or("").find("head.head.right: the head's right axis"),
            std::string::npos);
  bad = m;
  bad.mutable_head()->mutable_head()->set_eye_separation(1.5);
  EXPECT_NE(collab::checkToMaster(bad).value_or("").find("eye_separation"), std::string::npos);
  bad.Clear();
  bad.mutable_head();
  EXPECT_TRUE(collab::checkToMaster(bad));  // no head in it
  // Behind the wall: passes the message's checks, refused by the master's wall check.
  bad = m;
  bad.mutable_head()->mutable_head()->mutable_eye()->set_z(-0.5);
  EXPECT_FALSE(collab::checkToMaster(bad));
  s.roster.apply(s.master, a, bad, 0.2);
  EXPECT_FALSE(s.master.hasPendingChanges());
  s.step(0.3);
  EXPECT_EQ(s.replica.settings().head().eye().z(), 1.4);
  // Without a wall to check against, a master refuses every head.
  Session bare;
  const uint32_t b = bare.roster.join(bare.master, "B", "k2");
  bare.step(0.0);
  bare.roster.apply(bare.master, b, m, 0.1);
  bare.step(0.2);
  EXPECT_FALSE(bare.replica.settings().has_head());
}

TEST(SiteRoster, TheLeadersPoseMovesTheSceneCameraUntilReleased) {
  Session s;
  const uint32_t a = s.roster.join(s.master, "A", "k1");
  const uint32_t b = s.roster.join(s.master, "B", "k2");
  s.roster.apply(s.master, a, pose(1, {0.3, 0.2, 1.0}, {0, 0.1, 0}), 0);
  s.roster.apply(s.master, b, pose(1, {-1, 0, 1}, {0, 0, 0}), 0);
  s.step(0.0);
  const config::Camera before = s.replica.camera();
  site::ToMaster lead;
  lead.mutable_lead();
  s.roster.apply(s.master, a, lead, 0.01);
  s.step(0.2);
  EXPECT_EQ(s.replica.settings().leader(), "A");
  // Half a second's hand-over: on the way from the wall's camera to A's pose, not a jump.
  const double mid = s.replica.camera().eye().x();
  EXPECT_GT(mid, before.eye().x() + 0.01);
  EXPECT_LT(mid, 0.3 - 0.01);
  s.step(0.6);
  const config::Camera c = s.replica.camera();
  EXPECT_NEAR(c.eye().x(), 0.3, 1e-9);
  EXPECT_NEAR(c.eye().z(), 1.0, 1e-9);
  // The view direction is the pose's (the camera is stored rounded: floats relative to the eye).
  const glm::dvec3 view = glm::normalize(glm::dvec3(
      c.target().x() - c.eye().x(), c.target().y() - c.eye().y(), c.target().z() - c.eye().z()));
  EXPECT_NEAR(glm::length(view - glm::normalize(glm::dvec3(-0.3, -0.1, -1.0))), 0, 1e-6);
  // B takes the lead: last writer wins.
  s.roster.apply(s.master, b, lead, 0.7);
  s.step(1.3);
  EXPECT_EQ(s.replica.settings().leader(), "B");
  EXPECT_NEAR(s.replica.camera().eye().x(), -1.0, 1e-9);
  // A's release does nothing now (it does not lead); B's gives the view back.
  site::ToMaster release;
  release.mutable_release();
  s.roster.apply(s.master, a, release, 1.4);
  s.step(1.5);
  EXPECT_EQ(s.replica.settings().leader(), "B");
  s.roster.leave(s.master, b);  // a leader that leaves gives the view back too
  s.step(1.6);
  EXPECT_EQ(s.replica.settings().leader(), "");
}

}  // namespace
