// Camera paths: the shipped paths load and fit their scenes, the camera passes through the
// keyframes smoothly and deterministically, actions come once each, bad files name the field.
#include <gtest/gtest.h>

#include <cmath>

#include <glm/glm.hpp>

#include <tessera/sync/camera_path.h>
#include <tessera/sync/config.h>

namespace tessera::sync {
namespace {

const std::string kConfigs = TESSERA_CONFIG_DIR;

glm::dvec3 vec(const config::Vec3& v) {
  return {v.x(), v.y(), v.z()};
}

std::string errorOf(const std::string& json) {
  try {
    parseCameraPath(json, "p.json");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

const char* kKeyframe = R"({"time": %g, "eye": {"x": %g, "y": 0, "z": 1}, "target": {"x": %g},
                            "up": {"y": 1}})";

std::string keyframe(double t, double eye_x, double target_x) {
  char buf[256];
  std::snprintf(buf, sizeof buf, kKeyframe, t, eye_x, target_x);
  return buf;
}

TEST(CameraPath, ShippedPathsLoadAndFitTheirScenes) {
  const auto bunny = loadCameraPath(kConfigs + "/paths/bunny-orbit.json");
  EXPECT_GE(bunny.keyframes_size(), 5);
  EXPECT_DOUBLE_EQ(pathDuration(bunny), 12.0);
  checkPathModels(bunny, SceneGraph::fromFile(loadSceneFile(kConfigs + "/scenes/bunny.json")),
                  "bunny-orbit.json");
  // The orbit keeps its distance to the bunny within 2 % between keyframes.
  const double radius =
      glm::length(vec(bunny.keyframes(0).eye()) - vec(bunny.keyframes(0).target()));
  for (double t = 0; t <= 12.0; t += 0.1) {
    const config::Camera c = cameraAt(bunny, t);
    EXPECT_NEAR(glm::length(vec(c.eye()) - vec(c.target())), radius, 0.02 * radius) << t;
  }
  const auto autzen = loadCameraPath(kConfigs + "/paths/autzen-flyover.json");
  checkPathModels(autzen, SceneGraph::fromFile(loadSceneFile(kConfigs + "/scenes/autzen.json")),
                  "autzen-flyover.json");
  EXPECT_THROW(
      checkPathModels(autzen, SceneGraph::fromFile(loadSceneFile(kConfigs + "/scenes/bunny.json")),
                      "a.json"),
      ConfigError);
}

TEST(CameraPath, PassesThroughKeyframesSmoothly) {
  const auto path = loadCameraPath(kConfigs + "/paths/autzen-flyover.json");
  for (const auto& k : path.keyframes()) {
    const config::Camera c = cameraAt(path, k.time());
    EXPECT_EQ(vec(c.eye()), vec(k.eye()));
    EXPECT_EQ(vec(c.target()), vec(k.target()));
  }
  // Before the start and after the end: the end keyframes.
  EXPECT_EQ(vec(cameraAt(path, -5).eye()), vec(path.keyframes(0).eye()));
  EXPECT_EQ(vec(cameraAt(path, 1e9).eye()), vec(path.keyframes(path.keyframes_size() - 1).eye()));
  // C1 at inner keyframes: velocities just before and just after agree.
  const double h = 1e-4;
  for (int i = 1; i + 1 < path.keyframes_size(); ++i) {
    const double t = path.keyframes(i).time();
    const glm::dvec3 before = (vec(cameraAt(path, t).eye()) - vec(cameraAt(path, t - h).eye())) / h;
    const glm::dvec3 after = (vec(cameraAt(path, t + h).eye()) - vec(cameraAt(path, t).eye())) / h;
    EXPECT_LT(glm::length(after - before), 1e-3 * glm::length(before) + 1e-3) << "keyframe " << i;
  }
  // Up: unit, orthogonal to the view. Deterministic to the bit.
  for (double t = 0; t < 20; t += 0.37) {
    const config::Camera c = cameraAt(path, t);
    const glm::dvec3 up = vec(c.up()), d = glm::normalize(vec(c.target()) - vec(c.eye()));
    EXPECT_NEAR(glm::length(up), 1.0, 1e-12);
    EXPECT_NEAR(glm::dot(up, d), 0.0, 1e-12);
    EXPECT_EQ(cameraAt(path, t).SerializeAsString(), c.SerializeAsString());
  }
}

TEST(CameraPath, TwoKeyframesMoveInAStraightLineAtConstantSpeed) {
  const auto path = parseCameraPath(
      R"({"keyframes": [)" + keyframe(0, 0, 0) + "," + keyframe(4, 8, 8) + "]}", "p.json");
  for (double t : {1.0, 2.0, 3.0}) EXPECT_NEAR(cameraAt(path, t).eye().x(), 2 * t, 1e-12);
}

TEST(CameraPath, ActionsComeOnceInConsecutiveIntervals) {
  const auto path = loadCameraPath(kConfigs + "/paths/bunny-orbit.json");
  size_t seen = 0;
  double t0 = -INFINITY;
  for (int frame = 0; frame <= 60 * 13; ++frame) {
    const double t1 = frame / 60.0;
    for (const auto& a : actionsIn(path, t0, t1)) {
      EXPECT_GT(a.time(), t0);
      EXPECT_LE(a.time(), t1);
      ++seen;
    }
    t0 = t1;
  }
  EXPECT_EQ(seen, size_t(path.actions_size()));
  const auto first = actionsIn(path, 2.9, 3.0);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(first[0].set_opacity().model(), "bunny scans");
  EXPECT_DOUBLE_EQ(first[0].set_opacity().opacity(), 0.5);
}

TEST(CameraPath, BadFilesNameTheField) {
  auto expectError = [](const std::string& json, const std::string& says) {
    const std::string e = errorOf(json);
    EXPECT_NE(e.find("sync::loadCameraPath(): p.json: " + says), std::string::npos)
        << "got: " << e << "\nwanted: " << says;
  };
  const std::string k0 = keyframe(0, 0, 1), k1 = keyframe(1, 0, 1);
  expectError("{", "not a valid CameraPath");
  expectError(R"({"keyframez": []})", "not a valid CameraPath");
  expectError("{}", "keyframes: a path needs at least one keyframe");
  expectError(R"({"keyframes": [)" + k1 + "," + k0 + "]}", "keyframes[1].time: 0");
  expectError(R"({"keyframes": [)" + k0 + "," + k0 + "]}", "keyframes[1].time");
  expectError(
      R"({"keyframes": [{"time": 0, "eye": {"x": 1}, "target": {"x": 1}, "up": {"y": 1}}]})",
      "keyframes[0]: eye and target coincide");
  expectError(R"({"closed": true, "keyframes": [)" + k0 + "," + k1 + "," + keyframe(2, 3, 1) + "]}",
              "closed: a closed path needs 3 keyframes or more");
  expectError(R"({"keyframes": [{"time": 0, "eye": {"z": 1}}]})",
              "keyframes[0]: needs eye, target and up");
  expectError(R"({"keyframes": [{"time": 0, "eye": {"z": 1}, "target": {}, "up": {"z": 2}}]})",
              "keyframes[0].up: up is along the view direction");
  const std::string one = R"({"keyframes": [)" + k0 + R"(], "actions": [)";
  expectError(one + R"({"time": 1}]})", "actions[0]: needs one of setOpacity");
  expectError(one + R"({"time": 1, "setShading": "phong"}]})",
              "actions[0].setShading: 'phong' is not one of color, edl");
  expectError(one + R"({"time": 1, "setAnalysis": {"aoSlices": 100}}]})",
              "actions[0].setAnalysis: settings.analysis.ao_slices: must be 1..64, got 100");
  expectError(one + R"({"time": 1, "setOpacity": {"model": "m", "opacity": 0}}]})",
              "actions[0].setOpacity.opacity: must be in (0, 1]");
  expectError(one + R"({"time": 1, "setVisible": {"visible": true}}]})",
              "actions[0].setVisible.model: names no model");
  expectError(one + R"({"time": 2, "screenshot": "a.png"}, {"time": 1, "screenshot": "b.png"}]})",
              "actions[1].time: actions must be in time order");
  expectError(one + R"({"time": 1, "screenshot": ""}]})", "actions[0].screenshot: needs a path");
  try {
    loadCameraPath("/nonexistent/path.json");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_STREQ(e.what(),
                 "sync::loadCameraPath(): /nonexistent/path.json: cannot open: No such file or "
                 "directory");
  }
}

}  // namespace
}  // namespace tessera::sync
