// The scene graph's differential sync: frames hold only what changed, replicas that apply them
// (from the start, or from a snapshot) equal the master, and bad frames and bytes give a typed
// SyncError that names what is wrong and leaves the replica as it was.
#include <gtest/gtest.h>

#include <limits>

#include <google/protobuf/stubs/logging.h>
#include <google/protobuf/util/message_differencer.h>

#include <cmath>
#include <random>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include <tessera/core/check.h>
#include <tessera/sync/camera_state.h>
#include <tessera/sync/config.h>
#include <tessera/sync/scene_edits.h>
#include <tessera/sync/scene_graph.h>
#include <tessera/sync/transform.h>
#include <tessera/sync/vec3.h>
#include <tessera/sync/viewer_head.h>
#include <tessera/sync/wire.h>

namespace tessera::sync {
namespace {

using scene::SceneNode;
using NodeId = SceneGraph::NodeId;
using Code = SyncError::Code;

const std::string kConfigs = TESSERA_CONFIG_DIR;

config::Camera makeCamera(glm::dvec3 eye, glm::dvec3 target, glm::dvec3 up) {
  config::Camera c;
  c.mutable_eye()->set_x(eye.x);
  c.mutable_eye()->set_y(eye.y);
  c.mutable_eye()->set_z(eye.z);
  c.mutable_target()->set_x(target.x);
  c.mutable_target()->set_y(target.y);
  c.mutable_target()->set_z(target.z);
  c.mutable_up()->set_x(up.x);
  c.mutable_up()->set_y(up.y);
  c.mutable_up()->set_z(up.z);
  return c;
}

glm::dvec3 vec(const config::Vec3& v) {
  return {v.x(), v.y(), v.z()};
}

/// What differs between two graphs, for failure messages.
std::string differences(const SceneGraph& a, const SceneGraph& b) {
  std::string report;
  google::protobuf::util::MessageDifferencer differ;
  differ.ReportDifferencesToString(&report);
  scene::Snapshot sa = a.snapshot(), sb = b.snapshot();
  differ.Compare(sa, sb);
  return report;
}

/// The frame through its bytes, as a node receives it.
scene::Frame wire(const scene::Frame& frame) {
  return parseFrame(serializeFrame(frame));
}

/// The SyncError code and message `fn` throws (kParse and "" when it throws nothing).
std::pair<Code, std::string> errorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const SyncError& e) {
    return {e.code(), e.what()};
  }
  return {Code::kParse, ""};
}

// ---------------------------------------------------------------------------------------------
// Frames hold only what changed

TEST(SceneGraph, UnchangedFrameIsTinyAndKeepsTheVersion) {
  SceneGraph g;
  scene::Frame f = g.takeFrame(1, 16'667);
  EXPECT_EQ(f.version(), 0u);
  EXPECT_FALSE(f.has_camera());
  EXPECT_EQ(f.created_size() + f.changed_size() + f.deleted_size(), 0);
  EXPECT_LE(serializeFrame(f).size(), 12u);
  f = g.takeFrame(100'000, 1'666'683'333);  // 7.7 hours at 60 Hz
  EXPECT_LE(serializeFrame(f).size(), 16u);
}

TEST(SceneGraph, CreatedNodeSendsOnlyWhatDiffersFromTheDefaults) {
  SceneGraph g;
  const NodeId group = g.add(SceneNode::GROUP, SceneGraph::kRoot, "group");
  const NodeId model = g.add(SceneNode::MODEL, group);
  g.setOpacity(model, 0.5f);
  scene::ModelPayload payload;
  payload.set_store("/data/bunny.tlod");
  g.setPayload(model, payload);
  scene::Frame f = g.takeFrame(1, 0);
  EXPECT_EQ(f.version(), 1u);
  ASSERT_EQ(f.created_size(), 2);
  const SceneNode& c = f.created(1);
  EXPECT_EQ(c.id(), model);
  EXPECT_EQ(c.kind(), SceneNode::MODEL);
  EXPECT_EQ(c.parent(), group);
  EXPECT_EQ(c.opacity(), 0.5f);
  EXPECT_EQ(c.model().store(), "/data/bunny.tlod");
  EXPECT_FALSE(c.has_visible());
  EXPECT_FALSE(c.has_transform());
  EXPECT_FALSE(c.has_name());
  EXPECT_FALSE(f.created(0).has_parent());  // under the root, the default

  SceneGraph replica;
  replica.apply(wire(f));
  EXPECT_TRUE(replica == g) << differences(replica, g);
  EXPECT_EQ(replica.node(model).model().store(), "/data/bunny.tlod");
  EXPECT_EQ(replica.children(group), std::vector<NodeId>{model});
}

TEST(SceneGraph, ChangedNodeSendsOnlyChangedFields) {
  SceneGraph g;
  const NodeId a = g.add(SceneNode::MODEL);
  g.takeFrame(1, 0);
  g.setOpacity(a, 0.25f);
  g.setVisible(a, true);  // already visible: not a change
  scene::Frame f = g.takeFrame(2, 0);
  ASSERT_EQ(f.changed_size(), 1);
  const SceneNode& c = f.changed(0);
  EXPECT_EQ(c.id(), a);
  EXPECT_TRUE(c.has_opacity());
  EXPECT_FALSE(c.has_visible());
  EXPECT_FALSE(c.has_kind());
  EXPECT_FALSE(c.has_model());
  EXPECT_EQ(f.version(), 2u);

  // Set and set back within a frame: nothing to send, the version stays.
  g.setOpacity(a, 0.75f);
  g.setOpacity(a, 0.25f);
  EXPECT_TRUE(g.hasPendingChanges());
  f = g.takeFrame(3, 0);
  EXPECT_EQ(f.changed_size(), 0);
  EXPECT_EQ(f.version(), 2u);
}

// A whole node is one checked call: a refused value leaves nothing behind, not even a
// pending change.
TEST(SceneGraph, AddIsWholeOrNothing) {
  SceneGraph g;
  g.takeFrame(1, 0);
  scene::SketchPayload bad;
  for (float v : {0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f}) bad.add_points(v);
  bad.mutable_color()->set_r(2.0f);  // out of [0, 1]
  bad.set_width(4.0f);
  EXPECT_THROW(g.add(scene::SceneNode::SKETCH, SceneGraph::kRoot, "s", bad, "kyoto"),
               tessera::PreconditionError);
  EXPECT_EQ(g.size(), 0u);
  EXPECT_FALSE(g.hasPendingChanges());
  // A payload of another kind, an author too long, a NaN in the transform: refused the same way.
  EXPECT_THROW(g.add(scene::SceneNode::CLIP, SceneGraph::kRoot, "c", scene::SketchPayload(), ""),
               tessera::PreconditionError);
  EXPECT_THROW(g.add(scene::SceneNode::GROUP, SceneGraph::kRoot, "g", {}, std::string(65, 'a')),
               tessera::PreconditionError);
  std::vector<double> nan_matrix(16, 0.0);
  nan_matrix[0] = std::nan("");
  EXPECT_THROW(g.add(scene::SceneNode::GROUP, SceneGraph::kRoot, "g", {}, "", nan_matrix),
               tessera::PreconditionError);
  EXPECT_EQ(g.size(), 0u);
  EXPECT_FALSE(g.hasPendingChanges());

  bad.mutable_color()->set_r(1.0f);
  std::vector<double> moved = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0.5, 0, 0, 1};
  const auto id = g.add(scene::SceneNode::SKETCH, SceneGraph::kRoot, "s", bad, "kyoto", moved);
  EXPECT_EQ(g.node(id).name(), "s");
  EXPECT_EQ(g.node(id).author(), "kyoto");
  EXPECT_EQ(g.node(id).sketch().points_size(), 6);
  // One create in the frame carries all of it: a replica gets the whole node at once.
  const scene::Frame f = g.takeFrame(2, 0);
  ASSERT_EQ(f.created_size(), 1);
  EXPECT_EQ(f.created(0).author(), "kyoto");
  SceneGraph replica;
  replica.apply(g.snapshot());
  EXPECT_TRUE(replica == g);
}

// Generated names count up from the largest among the siblings, so a deletion never makes the
// next one repeat a name still in use.
TEST(SceneGraph, FreshNamesNeverRepeatAfterADeletion) {
  SceneGraph g;
  const auto layer = g.add(scene::SceneNode::GROUP, SceneGraph::kRoot, "sketches");
  EXPECT_EQ(tessera::sync::freshName(g, layer, "sketch"), "sketch 1");
  const auto a = g.add(scene::SceneNode::GROUP, layer, tessera::sync::freshName(g, layer, "sketch"));
  g.add(scene::SceneNode::GROUP, layer, tessera::sync::freshName(g, layer, "sketch"));
  g.add(scene::SceneNode::GROUP, layer, "sketchy 9");  // another prefix
  g.add(scene::SceneNode::GROUP, layer, "sketch 7b");  // not a number
  g.remove(a);  // "sketch 1": one child fewer, yet the next is not "sketch 2" again
  EXPECT_EQ(tessera::sync::freshName(g, layer, "sketch"), "sketch 3");
  g.add(scene::SceneNode::GROUP, layer, "sketch 99999999999999999999999");  // too long to count
  EXPECT_EQ(tessera::sync::freshName(g, layer, "sketch"), "sketch 3");
}

TEST(SceneGraph, RemovingAParentRemovesItsSubtree) {
  SceneGraph g;
  const NodeId root = g.add(SceneNode::GROUP);
  const NodeId child = g.add(SceneNode::GROUP, root);
  const NodeId leaf = g.add(SceneNode::SKETCH, child);
  const NodeId other = g.add(SceneNode::MODEL);
  SceneGraph replica;
  replica.apply(wire(g.takeFrame(1, 0)));
  g.remove(root);
  EXPECT_FALSE(g.contains(child));
  EXPECT_FALSE(g.contains(leaf));
  EXPECT_TRUE(g.contains(other));
  scene::Frame f = g.takeFrame(2, 0);
  EXPECT_EQ(std::vector<NodeId>(f.deleted().begin(), f.deleted().end()),
            (std::vector<NodeId>{root, child, leaf}));
  replica.apply(wire(f));
  EXPECT_TRUE(replica == g) << differences(replica, g);
  EXPECT_EQ(replica.ids(), std::vector<NodeId>{other});
  EXPECT_TRUE(replica.children(SceneGraph::kRoot) == std::vector<NodeId>{other});
}

TEST(SceneGraph, RecreatedIdsDiffAgainstTheOldNode) {
  SceneGraph g;
  g.create(7, SceneNode::MODEL, SceneGraph::kRoot, "seven");
  g.setOpacity(7, 0.5f);
  SceneGraph replica;
  replica.apply(wire(g.takeFrame(1, 0)));

  // Same kind: only what differs from the old node travels.
  g.remove(7);
  g.create(7, SceneNode::MODEL, SceneGraph::kRoot, "seven");
  scene::Frame f = g.takeFrame(2, 0);
  EXPECT_EQ(f.deleted_size(), 0);
  EXPECT_EQ(f.created_size(), 0);
  ASSERT_EQ(f.changed_size(), 1);
  EXPECT_TRUE(f.changed(0).has_opacity());  // back to 1
  replica.apply(wire(f));
  EXPECT_TRUE(replica == g) << differences(replica, g);

  // Another kind: a delete and a create in one frame.
  g.remove(7);
  g.create(7, SceneNode::ANNOTATION);
  f = g.takeFrame(3, 0);
  EXPECT_EQ(f.deleted_size(), 1);
  EXPECT_EQ(f.created_size(), 1);
  replica.apply(wire(f));
  EXPECT_TRUE(replica == g) << differences(replica, g);
  EXPECT_EQ(replica.node(7).kind(), SceneNode::ANNOTATION);

  // Created and removed within one frame: nothing at all.
  g.create(8, SceneNode::GROUP);
  g.remove(8);
  f = g.takeFrame(4, 0);
  EXPECT_EQ(f.version(), 3u);
  EXPECT_EQ(f.created_size() + f.deleted_size() + f.changed_size(), 0);
}

TEST(SceneGraph, ReparentingMovesTheSubtree) {
  SceneGraph g;
  const NodeId a = g.add(SceneNode::GROUP), b = g.add(SceneNode::GROUP);
  const NodeId c = g.add(SceneNode::MODEL, a);
  SceneGraph replica;
  replica.apply(wire(g.takeFrame(1, 0)));
  g.setParent(a, b);
  scene::Frame f = g.takeFrame(2, 0);
  ASSERT_EQ(f.changed_size(), 1);
  EXPECT_EQ(f.changed(0).parent(), b);
  replica.apply(wire(f));
  EXPECT_TRUE(replica == g) << differences(replica, g);
  EXPECT_EQ(replica.children(b), std::vector<NodeId>{a});
  EXPECT_EQ(replica.children(a), std::vector<NodeId>{c});
  EXPECT_THROW(g.setParent(b, c), PreconditionError);  // c is below b
  EXPECT_THROW(g.setParent(b, b), PreconditionError);
}

TEST(SceneGraph, SnapshotLeavesPendingChangesOut) {
  SceneGraph g;
  const NodeId a = g.add(SceneNode::MODEL);
  g.takeFrame(1, 0);
  g.setOpacity(a, 0.5f);
  g.add(SceneNode::GROUP);
  g.remove(a);
  g.setCamera(makeCamera({1, 2, 3}, {0, 0, 0}, {0, 0, 1}));
  g.setShading(scene::SHADING_EDL);
  scene::Snapshot s = g.snapshot();
  EXPECT_EQ(s.version(), 1u);
  EXPECT_EQ(s.frame(), 1u);
  ASSERT_EQ(s.scene().nodes_size(), 1);
  EXPECT_EQ(s.scene().nodes(0).opacity(), 1.0f);
  EXPECT_EQ(s.scene().settings().shading(), scene::SHADING_COLOR);

  SceneGraph late;
  late.apply(parseSnapshot(serializeSnapshot(s)));
  late.apply(wire(g.takeFrame(2, 0)));
  EXPECT_TRUE(late == g) << differences(late, g);
}

TEST(SceneGraph, AnalysisSettingsReachEveryReplicaAndTurnOffAgain) {
  SceneGraph g;
  g.takeFrame(1, 0);
  SceneGraph replica;
  replica.apply(parseSnapshot(serializeSnapshot(g.snapshot())));
  scene::Analysis a;
  a.set_relative_depth_radius(24);
  a.set_contour_interval(0.5);
  a.mutable_contour_axis()->set_z(1.0);
  g.setAnalysis(a);
  replica.apply(wire(g.takeFrame(2, 0)));
  EXPECT_EQ(replica.settings().analysis().relative_depth_radius(), 24u);
  EXPECT_EQ(replica.settings().analysis().contour_interval(), 0.5);
  a.set_relative_depth_radius(0);  // off again: the message is replaced whole
  g.setAnalysis(a);
  replica.apply(wire(g.takeFrame(3, 0)));
  EXPECT_TRUE(replica == g) << differences(replica, g);
  EXPECT_EQ(replica.settings().analysis().relative_depth_radius(), 0u);
  a.set_contour_interval(-1.0);
  EXPECT_THROW(g.setAnalysis(a), tessera::PreconditionError);
}

scene::Head head(glm::dvec3 eye, glm::dvec3 right, double separation = 0.0) {
  scene::Head h;
  set(h.mutable_eye(), eye);
  set(h.mutable_right(), right);
  if (separation != 0.0) h.set_eye_separation(separation);
  return h;
}

// The viewer's head is a setting every replica gets with the next frame (and a late joiner with
// its snapshot); bad heads are refused by field: by the graph's precondition, by a replica
// applying a frame, by a scene file's checks, and against a wall by sync::headProblem().
TEST(SceneGraph, TheViewersHeadReachesReplicasAndBadHeadsAreRefusedByField) {
  SceneGraph g;
  g.takeFrame(1, 0);
  SceneGraph replica;
  replica.apply(parseSnapshot(serializeSnapshot(g.snapshot())));
  EXPECT_FALSE(replica.settings().has_head());
  g.setHead(head({0.3, 0.2, 1.2}, {0.94, 0, 0.34}, 0.07));
  replica.apply(wire(g.takeFrame(2, 0)));
  ASSERT_TRUE(replica.settings().has_head());
  EXPECT_EQ(replica.settings().head().eye().z(), 1.2);
  EXPECT_EQ(replica.settings().head().eye_separation(), 0.07);
  g.setHead(head({0.1, 0.2, 1.5}, {1, 0, 0}));  // replaced whole: its separation goes
  replica.apply(wire(g.takeFrame(3, 0)));
  EXPECT_FALSE(replica.settings().head().has_eye_separation());
  SceneGraph late;
  late.apply(parseSnapshot(serializeSnapshot(g.snapshot())));
  EXPECT_TRUE(late == g) << differences(late, g);

  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  auto refused = [&](const scene::Head& h, const std::string& says) {
    const auto why = SceneGraph::headProblem(h);
    ASSERT_TRUE(why) << says;
    EXPECT_NE(why->find(says), std::string::npos) << *why;
    EXPECT_THROW(g.setHead(h), tessera::PreconditionError) << says;
  };
  refused(head({nan, 0.2, 1}, {1, 0, 0}), "eye: needs finite x, y and z");
  refused(head({0, inf, 1}, {1, 0, 0}), "eye: needs finite");
  refused(head({0, 0.2, 1}, {0, 0, 0}), "right: the head's right axis must not be zero");
  refused(head({0, 0.2, 1}, {nan, 0, 0}), "right: needs finite");
  refused(head({0, 0.2, 1}, {1e300, 1e300, 0}), "right: the head's right axis must not be zero");
  refused(head({0, 0.2, 1}, {1, 0, 0}, 2.0), "eye_separation: must be in (0, 1] metres, got 2");
  refused(head({0, 0.2, 1}, {1, 0, 0}, -0.01), "eye_separation");
  scene::Head no_right = head({0, 0.2, 1}, {1, 0, 0});
  no_right.clear_right();
  refused(no_right, "right: needs finite x, y and z (the head's right axis), got none");
  // A replica refuses a frame carrying a NaN head and stays as it was.
  scene::Frame f;
  f.set_number(4);
  f.set_version(replica.version() + 1);
  *f.mutable_settings()->mutable_head() = head({0, nan, 1}, {1, 0, 0});
  const SceneGraph before = replica;
  try {
    replica.apply(f);
    ADD_FAILURE() << "a NaN head";
  } catch (const SyncError& e) {
    EXPECT_NE(std::string(e.what()).find("settings.head.eye: needs finite"), std::string::npos)
        << e.what();
  }
  EXPECT_TRUE(replica == before) << differences(replica, before);
  // A scene file's head passes the same checks.
  try {
    (void)parseSceneFile(R"({"camera": {"eye": {"z": 1}, "target": {}, "up": {"y": 1}},
        "settings": {"head": {"eye": {"x": 0, "y": 0, "z": 1}, "right": {}}}})",
                         "scene.json", "");
    ADD_FAILURE() << "a zero right axis";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("scene.json: scene: settings.head.right: the head's "
                                         "right axis must not be zero"),
              std::string::npos)
        << e.what();
  }
  // Against a wall: the head and both of its eyes in front of every tile.
  const config::WallConfig wall = loadWallConfig(kConfigs + "/walls/cave.json");
  EXPECT_FALSE(headProblem(wall, head(vec(wall.eye()), {1, 0, 0})));
  const auto behind = headProblem(wall, head(vec(wall.eye()) + glm::dvec3(0, -5, 0), {1, 0, 0}));
  ASSERT_TRUE(behind);
  EXPECT_NE(behind->find("eye: the head ("), std::string::npos) << *behind;
  EXPECT_NE(behind->find("is behind the plane of tiles["), std::string::npos) << *behind;
  // Its point inside the room, but an eye through the left wall at a wide separation.
  const config::WallConfig flat = loadWallConfig(kConfigs + "/walls/2x2.json");
  const auto eye_behind = headProblem(flat, head({1, 0.5, 0.02}, {0, 0, 1}, 0.065));
  ASSERT_TRUE(eye_behind);
  EXPECT_NE(eye_behind->find("its left eye"), std::string::npos) << *eye_behind;
  EXPECT_TRUE(headProblem(flat, head({1, 0.5, 1}, {0, 0, 0})));
}

TEST(SceneGraph, FromFileMakesTheSceneFilesNodes) {
  SceneGraph g = SceneGraph::fromFile(loadSceneFile(kConfigs + "/scenes/bunny.json"));
  ASSERT_EQ(g.size(), 1u);
  const SceneNode& n = g.node(1);
  EXPECT_EQ(n.kind(), SceneNode::MODEL);
  EXPECT_EQ(n.name(), "bunny scans");
  EXPECT_TRUE(std::filesystem::path(n.model().store()).is_absolute());
  EXPECT_EQ(g.settings().shading(), scene::SHADING_EDL);
  EXPECT_NEAR(vec(g.camera().eye()).z, 0.38, 1e-12);
  EXPECT_EQ(g.findByName("bunny scans"), std::optional<NodeId>(1));
  // Nothing is pending: replicas start from the snapshot, as a joining node does.
  EXPECT_FALSE(g.hasPendingChanges());
  SceneGraph replica;
  replica.apply(parseSnapshot(serializeSnapshot(g.snapshot())));
  EXPECT_TRUE(replica == g) << differences(replica, g);
}

// ---------------------------------------------------------------------------------------------
// The camera's wire form

TEST(CameraState, GeoreferencedCameraSurvivesTheWireForm) {
  const glm::dvec3 eye(636590.123456, 847900.654321, 1400.5), target(636591.0, 849216.0, 463.25);
  config::Camera c = decodeCamera(encodeCamera(makeCamera(eye, target, {0, 0, 1})));
  EXPECT_EQ(vec(c.eye()), eye);                            // doubles, exact
  EXPECT_LT(glm::length(vec(c.target()) - target), 1e-4);  // 1.6 km away: float view, < 0.1 mm
  const glm::dvec3 up = vec(c.up()), d = glm::normalize(vec(c.target()) - vec(c.eye()));
  EXPECT_NEAR(glm::length(up), 1.0, 1e-12);
  EXPECT_NEAR(glm::dot(up, d), 0.0, 1e-7);
  EXPECT_GT(up.z, 0.8);
  // A rolled camera: up along the wall's x.
  c = decodeCamera(encodeCamera(makeCamera({0, 0, 1}, {0, 0, 0}, {1, 0, 0})));
  EXPECT_NEAR(c.up().x(), 1.0, 1e-7);
  // A camera looking straight down z keeps its up.
  c = decodeCamera(encodeCamera(makeCamera({0, 0, 5}, {0, 0, 0}, {0, 1, 0})));
  EXPECT_NEAR(c.up().y(), 1.0, 1e-7);
  EXPECT_THROW(encodeCamera(makeCamera({1, 1, 1}, {1, 1, 1}, {0, 0, 1})), PreconditionError);
  EXPECT_THROW(encodeCamera(makeCamera({0, 0, 0}, {0, 0, 1}, {0, 0, 1})), PreconditionError);
}

TEST(CameraState, FramesStayWithinTheByteBudget) {
  // A camera-only change at most 64 bytes; one opacity change adds at most 32.
  SceneGraph g;
  for (int i = 0; i < 20'000; ++i) g.add(SceneNode::MODEL);
  g.takeFrame(1, 0);
  const uint64_t number = 1'000'000, time_us = number * 16'667;  // 4.6 hours at 60 Hz
  g.setCamera(makeCamera({636590.1, 847900.2, 1400.3}, {636591.4, 849216.5, 463.6}, {0.1, 0, 1}));
  const size_t camera_only = serializeFrame(g.takeFrame(number, time_us)).size();
  EXPECT_LE(camera_only, 64u);
  g.setCamera(makeCamera({636592.1, 847901.2, 1401.3}, {636593.4, 849217.5, 464.6}, {0, 0.1, 1}));
  g.setOpacity(19'999, 0.5f);
  const size_t with_opacity = serializeFrame(g.takeFrame(number + 1, time_us + 16'667)).size();
  EXPECT_LE(with_opacity, camera_only + 32);
}

// ---------------------------------------------------------------------------------------------
// Bad frames, snapshots and bytes

class BadFrame : public ::testing::Test {
 protected:
  void SetUp() override {
    mMaster.create(1, SceneNode::GROUP);
    mMaster.create(2, SceneNode::GROUP, 1);
    mMaster.create(3, SceneNode::MODEL, 2);
    mReplica.apply(wire(mMaster.takeFrame(1, 0)));
    mBefore = mReplica;
  }

  /// A frame that follows the replica's version with one changed node.
  scene::Frame next() const {
    scene::Frame f;
    f.set_number(2);
    f.set_version(mReplica.version() + 1);
    return f;
  }

  /// Applies `f`, expects `code` and a message holding `says`, and the replica unchanged.
  void expectError(const scene::Frame& f, Code code, const std::string& says) {
    auto [got, what] = errorOf([&] { mReplica.apply(f); });
    EXPECT_EQ(int(got), int(code)) << what;
    EXPECT_NE(what.find(says), std::string::npos) << what;
    EXPECT_NE(what.find("sync::SceneGraph::apply(): frame 2"), std::string::npos) << what;
    EXPECT_TRUE(mReplica == mBefore) << differences(mReplica, mBefore);
  }

  SceneGraph mMaster, mReplica, mBefore;
};

TEST_F(BadFrame, VersionGap) {
  scene::Frame f = next();
  f.set_version(5);
  f.add_deleted(3);
  expectError(f, Code::kVersionGap, "brings version 5 but the replica is at version 1");
  f = next();  // no changes, yet a new version: a changing frame was lost
  expectError(f, Code::kVersionGap, "expects 1");
}

TEST_F(BadFrame, UnknownNodes) {
  scene::Frame f = next();
  f.add_changed()->set_id(42);
  f.mutable_changed(0)->set_opacity(0.5f);
  expectError(f, Code::kUnknownNode, "changed[0] (node 42): no such node");
  f = next();
  f.add_deleted(3);
  f.add_deleted(9);
  expectError(f, Code::kUnknownNode, "deleted[1] (node 9): no such node");
  f = next();
  f.add_deleted(3);
  f.add_changed()->set_id(3);
  f.mutable_changed(0)->set_visible(false);
  expectError(f, Code::kUnknownNode, "changed[0] (node 3)");
}

TEST_F(BadFrame, Duplicates) {
  scene::Frame f = next();
  SceneNode* c = f.add_created();
  c->set_id(2);
  c->set_kind(SceneNode::GROUP);
  expectError(f, Code::kDuplicateNode, "created[0] (node 2): already exists");
  f = next();
  f.add_deleted(3);
  f.add_deleted(3);
  expectError(f, Code::kDuplicateNode, "deleted[1] (node 3): listed twice");
}

TEST_F(BadFrame, ParentCycleAndMissingParents) {
  scene::Frame f = next();
  SceneNode* c = f.add_changed();
  c->set_id(1);
  c->set_parent(3);  // 3 is below 1
  expectError(f, Code::kParentCycle, "parents form a cycle");
  f = next();
  c = f.add_created();
  c->set_id(10);
  c->set_kind(SceneNode::GROUP);
  c->set_parent(11);
  expectError(f, Code::kBadParent, "node 10: parent 11 does not exist");
  f = next();
  f.add_deleted(2);  // leaves 3 without its parent
  expectError(f, Code::kBadParent, "node 3: parent 2 does not exist");
  f = next();
  c = f.add_created();  // two new nodes, each the other's parent
  c->set_id(10);
  c->set_kind(SceneNode::GROUP);
  c->set_parent(11);
  c = f.add_created();
  c->set_id(11);
  c->set_kind(SceneNode::GROUP);
  c->set_parent(10);
  expectError(f, Code::kParentCycle, "cycle");
}

TEST_F(BadFrame, BadFields) {
  auto withChange = [&](const std::function<void(SceneNode&)>& set) {
    scene::Frame f = next();
    SceneNode* c = f.add_changed();
    c->set_id(3);
    set(*c);
    return f;
  };
  expectError(withChange([](SceneNode& n) { n.set_opacity(1.5f); }), Code::kBadField,
              "changed[0] (node 3): opacity: 1.5 is not in [0, 1]");
  expectError(withChange([](SceneNode& n) { n.set_opacity(NAN); }), Code::kBadField, "opacity");
  expectError(withChange([](SceneNode& n) { n.mutable_transform()->add_m(1.0); }), Code::kBadField,
              "transform: needs 16 numbers");
  // The rigid form (sync/transform.h): sizes, both forms at once, numbers, a unit quaternion.
  auto rigid = [&](std::vector<double> t, std::vector<float> q, bool with_m = false) {
    return withChange([=](SceneNode& n) {
      scene::Transform* x = n.mutable_transform();
      for (double v : t) x->add_translation(v);
      for (float v : q) x->add_rotation(v);
      if (with_m)
        for (int i = 0; i < 16; ++i) x->add_m(i % 5 == 0 ? 1.0 : 0.0);
    });
  };
  expectError(rigid({1, 2}, {1, 0, 0, 0}), Code::kBadField,
              "changed[0] (node 3): transform: the rigid form needs a translation of 3 numbers and "
              "a rotation of 4, got 2 and 4");
  expectError(rigid({1, 2, 3}, {1, 0, 0}), Code::kBadField, "got 3 and 3");
  expectError(rigid({1, 2, 3}, {1, 0, 0, 0}, true), Code::kBadField,
              "16 numbers and the rigid form");
  expectError(rigid({1, NAN, 3}, {1, 0, 0, 0}), Code::kBadField, "translation must be finite");
  expectError(rigid({1, 2, -2e9}, {1, 0, 0, 0}), Code::kBadField, "beyond");
  expectError(rigid({1, 2, 3}, {1, 0, INFINITY, 0}), Code::kBadField, "rotation must be finite");
  expectError(rigid({1, 2, 3}, {0, 0, 0, 0}), Code::kBadField, "its length is 0");
  expectError(rigid({1, 2, 3}, {2, 0, 0, 0}), Code::kBadField, "unit quaternion");
  expectError(withChange([](SceneNode& n) { n.set_kind(SceneNode::SKETCH); }), Code::kBadField,
              "kind");
  expectError(withChange([](SceneNode& n) { n.mutable_sketch(); }), Code::kBadField,
              "payload: field 18 does not belong to kind MODEL");
  expectError(withChange([](SceneNode& n) { n.set_shading(scene::Shading(99)); }), Code::kBadField,
              "shading: unknown value 99");
  scene::Frame f = next();
  f.mutable_camera()->add_eye(1.0);
  expectError(f, Code::kBadField, "camera: camera.eye: needs 3 numbers, got 1");
  f = next();
  for (int i = 0; i < 3; ++i) f.mutable_camera()->add_view(0.0f);
  expectError(f, Code::kBadField, "eye and target coincide");
  f = next();
  f.mutable_settings()->set_spbr_ensembles(0);
  expectError(f, Code::kBadField, "settings.spbr_ensembles: must be 1..4096");
  f = next();
  f.mutable_settings()->set_points_per_pixel(std::numeric_limits<float>::infinity());
  expectError(f, Code::kBadField, "settings.points_per_pixel: must be finite and 0..1e6");
  f = next();
  f.mutable_settings()->mutable_analysis()->set_relative_depth_radius(1000);
  expectError(f, Code::kBadField, "settings.analysis.relative_depth_radius: must be 0..256 px");
  f = next();
  f.mutable_settings()->mutable_analysis()->set_contour_interval(
      std::numeric_limits<double>::quiet_NaN());
  expectError(f, Code::kBadField, "settings.analysis.contour_interval: must be finite");
  f = next();
  f.mutable_settings()->mutable_analysis()->set_relative_depth_lo(2.0f);
  f.mutable_settings()->mutable_analysis()->set_relative_depth_hi(1.0f);
  expectError(f, Code::kBadField, "relative_depth_lo must be below relative_depth_hi");
  f = next();
  f.mutable_settings()->mutable_analysis()->mutable_contour_axis()->set_z(
      std::numeric_limits<double>::infinity());
  expectError(f, Code::kBadField, "settings.analysis.contour_axis: must be finite");
  f = next();
  f.set_version(1);
  f.add_commands();
  expectError(f, Code::kBadField, "commands[0]: empty or unknown command");
  f = next();
  SceneNode* c = f.add_created();
  c->set_id(20);
  expectError(f, Code::kBadField, "created[0] (node 20): kind: missing or unknown");
  c->set_kind(SceneNode::Kind(77));
  expectError(f, Code::kBadField, "kind: missing or unknown");
}

// A CLIP node reaches a replica through a frame, its later change too, and every
// bad payload is refused with the field named, by the master's mutation and by a replica.
TEST(SceneGraph, ClipNodesSyncAndBadOnesAreRefusedByField) {
  SceneGraph master, replica;
  const NodeId model = master.add(SceneNode::MODEL);
  const NodeId clip = master.add(SceneNode::CLIP);
  scene::ClipPayload c;
  for (double v : {0.0, 0.0, -1.0, 0.25}) c.add_planes(v);  // keep z <= 0.25
  c.add_models(model);
  master.setPayload(clip, c);
  replica.apply(wire(master.takeFrame(1, 0)));
  ASSERT_TRUE(replica.contains(clip));
  EXPECT_EQ(replica.node(clip).kind(), SceneNode::CLIP);
  EXPECT_EQ(replica.node(clip).clip().planes_size(), 4);
  EXPECT_EQ(replica.node(clip).clip().models(0), model);
  // Turned into a box, then hidden: each change reaches the replica.
  scene::ClipPayload box;
  box.mutable_box_center()->set_x(1.0);
  box.mutable_box_half_extents()->set_x(0.5);
  box.mutable_box_half_extents()->set_y(0.5);
  box.mutable_box_half_extents()->set_z(2.0);
  box.set_invert(true);
  master.setPayload(clip, box);
  master.setVisible(clip, false);
  replica.apply(wire(master.takeFrame(2, 0)));
  EXPECT_TRUE(replica == master) << differences(replica, master);
  EXPECT_TRUE(replica.node(clip).clip().has_box_half_extents());
  EXPECT_FALSE(replica.node(clip).visible());

  auto refusal = [&](const std::function<void(scene::ClipPayload&)>& edit) {
    scene::ClipPayload bad = c;
    edit(bad);
    std::string master_says;
    try {
      master.setPayload(clip, bad);
    } catch (const PreconditionError& e) {
      master_says = e.what();
    }
    // The same payload from outside: a replica refuses the frame.
    scene::Frame f;
    f.set_number(3);
    f.set_version(replica.version() + 1);
    SceneNode* n = f.add_changed();
    n->set_id(clip);
    *n->mutable_clip() = bad;
    auto [code, what] = errorOf([&] { replica.apply(f); });
    EXPECT_EQ(int(code), int(Code::kBadField)) << what;
    // The master's mutation is refused with the same words (and where the check failed).
    const size_t field = what.find("clip.");
    EXPECT_NE(field, std::string::npos) << what;
    if (field != std::string::npos) {
      EXPECT_NE(master_says.find(what.substr(field)), std::string::npos) << master_says;
    }
    return what;
  };
  auto says = [](const std::string& what, const std::string& field) {
    return what.find(field) != std::string::npos;
  };
  EXPECT_PRED2(says, refusal([](auto& b) { b.add_planes(1.0); }), "clip.planes: needs a b c d");
  EXPECT_PRED2(says, refusal([](auto& b) { b.set_planes(2, NAN); }),
               "clip.planes: numbers must be finite");
  EXPECT_PRED2(says, refusal([](auto& b) { b.set_planes(2, 0.0); }),
               "clip.planes: plane 0 has a zero normal");
  EXPECT_PRED2(says, refusal([](auto& b) {
                 for (int i = 0; i < 24; ++i) b.add_planes(i % 4 == 0 ? 1.0 : 0.0);
               }),
               "clip.planes: at most 6 planes, got 7");
  EXPECT_PRED2(says, refusal([](auto& b) { b.mutable_box_half_extents()->set_x(1.0); }),
               "clip.planes: a clip node holds planes or a box, not both");
  EXPECT_PRED2(says, refusal([](auto& b) {
                 b.clear_planes();
                 b.mutable_box_half_extents()->set_x(1.0);
                 b.mutable_box_half_extents()->set_y(0.0);
                 b.mutable_box_half_extents()->set_z(1.0);
               }),
               "clip.box_half_extents: each must be > 0, got 0");
  EXPECT_PRED2(says, refusal([](auto& b) {
                 b.clear_planes();
                 b.mutable_box_center()->set_y(1.0);
               }),
               "clip.box_center: a box needs box_half_extents too");
  EXPECT_PRED2(says, refusal([](auto& b) {
                 b.clear_planes();
                 b.mutable_box_half_extents()->set_x(1.0);
                 b.mutable_box_center()->set_y(INFINITY);
               }),
               "clip.box_center: numbers must be finite");
  EXPECT_PRED2(says, refusal([](auto& b) { b.add_models(0); }), "clip.models: ids must name MODEL");
  EXPECT_PRED2(says, refusal([](auto& b) {
                 for (int i = 0; i < 65; ++i) b.add_models(1);
               }),
               "clip.models: at most 64");
  EXPECT_PRED2(says, refusal([](auto& b) { b.set_outline(-1.0f); }), "clip.outline");
  EXPECT_TRUE(replica == master) << differences(replica, master);
}

TEST(SceneGraphSnapshot, BadSnapshotsAreErrors) {
  SceneGraph g;
  g.create(1, SceneNode::GROUP);
  g.create(2, SceneNode::GROUP, 1);
  g.takeFrame(1, 0);
  const scene::Snapshot good = g.snapshot();
  SceneGraph replica;
  auto expect = [&](const scene::Snapshot& s, Code code, const std::string& says) {
    auto [got, what] = errorOf([&] { replica.apply(s); });
    EXPECT_EQ(int(got), int(code)) << what;
    EXPECT_NE(what.find(says), std::string::npos) << what;
    EXPECT_TRUE(replica == SceneGraph());
  };
  scene::Snapshot s = good;
  s.mutable_scene()->mutable_nodes(0)->set_parent(2);
  expect(s, Code::kParentCycle, "cycle");
  s = good;
  *s.mutable_scene()->add_nodes() = good.scene().nodes(0);
  expect(s, Code::kDuplicateNode, "scene.nodes[2] (node 1): listed twice");
  s = good;
  s.mutable_scene()->mutable_camera()->clear_roll();
  expect(s, Code::kBadField, "scene.camera: incomplete");
  s = good;
  s.mutable_scene()->mutable_nodes(1)->set_parent(5);
  expect(s, Code::kBadParent, "node 2: parent 5 does not exist");
  replica.apply(good);
  EXPECT_TRUE(replica == g);
}

TEST(Wire, GarbageAndTruncatedBytesAreErrorsNotCrashes) {
  google::protobuf::LogSilencer quiet;  // protobuf logs each invalid UTF-8 string it rejects
  SceneGraph g;
  for (int i = 0; i < 10; ++i) g.add(SceneNode::Kind(1 + i % 6), SceneGraph::kRoot, "n");
  g.setCamera(makeCamera({1, 2, 3}, {0, 0, 0}, {0, 0, 1}));
  scene::Command shot;
  shot.mutable_screenshot()->set_path("wall.png");
  g.addCommand(shot);
  const std::string bytes = serializeFrame(g.takeFrame(1, 5));
  const std::string snap = serializeSnapshot(g.snapshot());
  int parse_errors = 0;
  auto tryAll = [&](const std::string& b) {
    SceneGraph replica;
    try {
      replica.apply(parseFrame(b));
    } catch (const SyncError& e) {
      parse_errors += e.code() == Code::kParse;
    }
    try {
      SceneGraph r2;
      r2.apply(parseSnapshot(b));
    } catch (const SyncError&) {
    }
  };
  for (size_t n = 0; n < bytes.size(); ++n) tryAll(bytes.substr(0, n));
  for (size_t n = 0; n < snap.size(); ++n) tryAll(snap.substr(0, n));
  EXPECT_GT(parse_errors, 0);
  std::mt19937_64 rng(6);
  for (int i = 0; i < 2000; ++i) {
    std::string b = bytes;
    for (int k = 0; k < 1 + i % 4; ++k) b[rng() % b.size()] = char(rng());
    tryAll(b);
    std::string random(rng() % 64, '\0');
    for (char& ch : random) ch = char(rng());
    tryAll(random);
  }
  auto [code, what] = errorOf([] { parseFrame("\xff\xff\xff"); });
  EXPECT_EQ(int(code), int(Code::kParse));
  EXPECT_EQ(what, "sync::parseFrame(): 3 bytes are not a valid Frame (truncated or corrupt)");
}

// ---------------------------------------------------------------------------------------------
// The property test: random operations on a master; a replica from the start and one
// from a snapshot taken at a random point equal the master after every frame.

class RandomScene {
 public:
  explicit RandomScene(uint64_t seed) : mRng(seed) {}

  /// One random mutation of `g`.
  void mutate(SceneGraph& g) {
    const std::vector<NodeId> ids = g.ids();
    const int op = pick(100);
    if (ids.empty() || (op < 30 && ids.size() < 400)) return create(g, ids);
    const NodeId id = ids[pick(int(ids.size()))];
    if (op < 38) {
      mRemovedWithChildren += !g.children(id).empty();
      g.remove(id);
      mRemoved.push_back(id);
    } else if (op < 52) {
      g.setOpacity(id, float(pick(101)) / 100.0f);
    } else if (op < 58) {
      g.setVisible(id, pick(2) == 0);
    } else if (op < 64 && pick(3) == 0) {
      // A pose in the rigid form, as the avatars' (sync/transform.h).
      const glm::quat q = glm::normalize(glm::quat(float(pick(201)) - 99.5f, float(pick(201) - 100),
                                                   float(pick(201) - 100), float(pick(201) - 100)));
      g.setTransform(id, rigidTransform(q, {636590.0 + pick(2001) / 7.0, pick(2001) / 3.0, 0.25}));
    } else if (op < 64) {
      std::vector<double> m;
      if (pick(4) != 0) {
        for (int i = 0; i < 16; ++i) m.push_back(i % 5 == 0 ? 1.0 : double(pick(2001) - 1000) / 7);
        m[3] = m[7] = m[11] = 0.0;  // affine (SceneGraph refuses projective transforms)
        m[12] += 636590.0;          // georeferenced translation
      }
      g.setTransform(id, m);
    } else if (op < 67) {
      g.setName(id, "node " + std::to_string(pick(50)));
    } else if (op < 70) {
      g.setShading(id, scene::Shading(pick(3)));
    } else if (op < 73) {
      g.setLodPixels(id, float(pick(5)) * 0.5f);
    } else if (op < 78) {
      setPayload(g, id);
    } else if (op < 84) {
      reparent(g, id, ids);
    } else if (op < 94) {
      const glm::dvec3 eye(636000.0 + pick(1000), 848000.0 + pick(1000), 400.0 + pick(1000));
      g.setCamera(makeCamera(eye, eye + glm::dvec3(pick(9) - 4.0, pick(9) - 4.0, -1.0),
                             {pick(3) - 1.0, 0.5, 1.0}));
    } else {
      const int s = pick(4);
      if (s == 0) g.setBackground(float(pick(2)), 0.5f, float(pick(11)) / 10.0f);
      if (s == 1) g.setShading(pick(2) ? scene::SHADING_COLOR : scene::SHADING_EDL);
      if (s == 2) g.setLodPixels(float(1 + pick(4)));
      if (s == 3) g.setSpbrEnsembles(uint32_t(1 + pick(8)));
    }
  }

  int pick(int n) { return int(mRng() % uint64_t(n)); }

  int mRecreated = 0, mRemovedWithChildren = 0, mReparented = 0;

 private:
  void create(SceneGraph& g, const std::vector<NodeId>& ids) {
    const NodeId parent =
        ids.empty() || pick(4) == 0 ? SceneGraph::kRoot : ids[pick(int(ids.size()))];
    const auto kind = SceneGraph::Kind(1 + pick(6));
    if (!mRemoved.empty() && pick(2) == 0) {
      const size_t k = size_t(pick(int(mRemoved.size())));
      const NodeId id = mRemoved[k];
      mRemoved.erase(mRemoved.begin() + std::ptrdiff_t(k));
      if (!g.contains(id)) {
        g.create(id, kind, parent, "again");
        ++mRecreated;
        return;
      }
    }
    g.add(kind, parent, "n" + std::to_string(ids.size()));
  }

  void setPayload(SceneGraph& g, NodeId id) {
    switch (g.node(id).kind()) {
      case SceneNode::MODEL: {
        scene::ModelPayload p;
        p.set_store("/stores/" + std::to_string(pick(5)) + ".tlod");
        return g.setPayload(id, p);
      }
      case SceneNode::ANNOTATION: {
        scene::AnnotationPayload p;
        p.set_text("note " + std::to_string(pick(5)));
        p.mutable_anchor()->set_x(pick(10));
        return g.setPayload(id, p);
      }
      case SceneNode::SKETCH: {
        scene::SketchPayload p;
        for (int i = 0, n = 3 * pick(5); i < n; ++i) p.add_points(float(pick(100)) / 10.0f);
        p.set_width(float(pick(4)));
        return g.setPayload(id, p);
      }
      case SceneNode::AVATAR: {
        scene::AvatarPayload p;
        p.set_site("site " + std::to_string(pick(3)));
        p.mutable_color()->set_g(float(pick(2)));
        return g.setPayload(id, p);
      }
      case SceneNode::VIDEO_INSET: {
        scene::VideoInsetPayload p;
        p.set_stream("cam" + std::to_string(pick(3)));
        p.set_width(float(pick(3)));
        return g.setPayload(id, p);
      }
      default:
        return;
    }
  }

  void reparent(SceneGraph& g, NodeId id, const std::vector<NodeId>& ids) {
    NodeId parent = pick(5) == 0 ? SceneGraph::kRoot : ids[pick(int(ids.size()))];
    for (NodeId a = parent; a != SceneGraph::kRoot; a = g.node(a).parent()) {
      if (a == id) return;  // would make a cycle: the master's API refuses it
    }
    g.setParent(id, parent);
    ++mReparented;
  }

  std::mt19937_64 mRng;
  std::vector<NodeId> mRemoved;
};

class SceneGraphProperty : public ::testing::TestWithParam<uint64_t> {};

TEST_P(SceneGraphProperty, ReplicasEqualTheMasterAfterEveryFrame) {
  constexpr int kOperations = 10'000;
  RandomScene random(GetParam());
  SceneGraph master, from_start;
  std::optional<SceneGraph> from_snapshot;
  const int snapshot_at = kOperations / 4 + random.pick(kOperations / 2);
  uint64_t number = 0, frames = 0, version_bumps = 0;
  size_t max_nodes = 0;
  for (int op = 0; op < kOperations; ++op) {
    if (op == snapshot_at) {
      from_snapshot.emplace();
      from_snapshot->apply(parseSnapshot(serializeSnapshot(master.snapshot())));
    }
    random.mutate(master);
    max_nodes = std::max(max_nodes, master.size());
    if (random.pick(8) != 0 && op + 1 != kOperations) continue;
    const uint64_t version = master.version();
    ++number;
    const scene::Frame frame = wire(master.takeFrame(number, number * 16'667));
    version_bumps += master.version() != version;
    ++frames;
    from_start.apply(frame);
    ASSERT_TRUE(from_start == master) << "frame " << number << "\n"
                                      << differences(from_start, master);
    if (from_snapshot) {
      from_snapshot->apply(frame);
      ASSERT_TRUE(*from_snapshot == master) << "frame " << number << "\n"
                                            << differences(*from_snapshot, master);
    }
  }
  ASSERT_TRUE(from_snapshot.has_value());
  // The run exercised what it claims to.
  EXPECT_GT(frames, 1000u);
  EXPECT_GT(version_bumps, 900u);
  EXPECT_GT(random.mRecreated, 100);
  EXPECT_GT(random.mRemovedWithChildren, 50);
  EXPECT_GT(random.mReparented, 100);
  EXPECT_GT(max_nodes, 50u);
  std::printf(
      "property test, seed %llu: %llu frames, %d re-created ids, %d removed subtrees, up to %zu "
      "nodes\n",
      static_cast<unsigned long long>(GetParam()), static_cast<unsigned long long>(frames),
      random.mRecreated, random.mRemovedWithChildren, max_nodes);
}

INSTANTIATE_TEST_SUITE_P(Seeds, SceneGraphProperty, ::testing::Values(2024u, 7u, 99u));

}  // namespace
}  // namespace tessera::sync
