// The one view rule (sync/view.h): its edges, the command line's use of it, and agreement of
// every gate in sync: a camera the rule accepts loads from a scene file, encodes for the wire
// and decodes; a camera it refuses is refused by the file and
// by the encoder alike.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include <tessera/core/check.h>
#include <tessera/core/cli.h>
#include <tessera/sync/camera_state.h>
#include <tessera/sync/config.h>
#include <tessera/sync/vec3.h>
#include <tessera/sync/view.h>

namespace tessera::sync {
namespace {

std::string what(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up) {
  const auto p = viewProblem(eye, target, up);
  return p ? describe(*p, "camera") : "";
}

config::Camera camera(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up) {
  config::Camera c;
  set(c.mutable_eye(), eye);
  set(c.mutable_target(), target);
  set(c.mutable_up(), up);
  return c;
}

/// The scene file's answer: "" when it loads, else its error.
std::string sceneFileError(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up) {
  auto v = [](const glm::dvec3& x) {
    char s[160];
    std::snprintf(s, sizeof s, R"({"x": %.17g, "y": %.17g, "z": %.17g})", x.x, x.y, x.z);
    return std::string(s);
  };
  try {
    parseSceneFile(R"({"camera": {"eye": )" + v(eye) + R"(, "target": )" + v(target) +
                       R"(, "up": )" + v(up) + "}}",
                   "s.json");
    return "";
  } catch (const ConfigError& e) {
    return e.what();
  }
}

TEST(ViewRule, Edges) {
  EXPECT_EQ(what({0, 0, 5}, {0, 0, 0}, {0, 1, 0}), "");
  // Far from the origin (LiDAR coordinates), a 1 m view is still a view.
  EXPECT_EQ(what({636000, 848000, 500}, {636000, 848001, 500}, {0, 0, 1}), "");
  const double nan = std::nan(""), inf = INFINITY;
  EXPECT_EQ(what({nan, 0, 5}, {0, 0, 0}, {0, 1, 0}), "camera: numbers must be finite");
  EXPECT_EQ(what({0, 0, 5}, {0, inf, 0}, {0, 1, 0}), "camera: numbers must be finite");
  EXPECT_EQ(what({1, 2, 3}, {1, 2, 3}, {0, 1, 0}), "camera: eye and target coincide");
  // Rounding noise of the coordinates is no direction.
  EXPECT_EQ(what({1e6, 0, 0}, {1e6 + 1e-7, 0, 0}, {0, 1, 0}), "camera: eye and target coincide");
  // A view longer than a float holds cannot travel on the wire.
  EXPECT_EQ(what({-1e300, 0, 0}, {1e300, 0, 0}, {0, 1, 0}), "camera: eye and target coincide");
  EXPECT_EQ(what({0, 0, 5}, {0, 0, 0}, {0, 0, 0}), "camera.up: up is zero");
  EXPECT_EQ(what({0, 0, 5}, {0, 0, 0}, {0, 0, 2}), "camera.up: up is along the view direction");
  EXPECT_EQ(what({0, 0, 5}, {0, 0, 0}, {0, 0, -1}), "camera.up: up is along the view direction");
  EXPECT_EQ(what({0, 0, 5}, {0, 0, 0}, {1e-7, 0, 1}), "camera.up: up is along the view direction");
  EXPECT_EQ(what({0, 0, 5}, {0, 0, 0}, {1e-5, 0, 1}), "");
  EXPECT_EQ(describe(*viewProblem({0, 0, 5}, {0, 0, 0}, {0, 0, 0}), ""), "up: up is zero");
}

TEST(ViewRule, TheCommandLineSaysWhichOption) {
  EXPECT_NO_THROW(requireView({0, 0, 5}, {0, 0, 0}, {0, 1, 0}, "--camera"));
  try {
    requireView({0, 0, 5}, {0, 0, 0}, {0, 0, 2}, "--camera");
    ADD_FAILURE() << "no error";
  } catch (const cli::UsageError& e) {
    EXPECT_STREQ(e.what(), "--camera: up is along the view direction");
  }
  EXPECT_THROW(requireView({1, 2, 3}, {1, 2, 3}, {0, 1, 0}, "--eye"), cli::UsageError);
}

// The gates agree on cameras at and around every edge: near-parallel up vectors, views near
// rounding noise far from the origin, views near a float's range.
TEST(ViewRule, EveryGateAgrees) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), expo(-14.0, 14.0);
  int accepted = 0, refused = 0;
  for (int i = 0; i < 4000; ++i) {
    const double scale = std::pow(10.0, expo(rng));
    const glm::dvec3 eye = glm::dvec3(unit(rng), unit(rng), unit(rng)) * scale;
    glm::dvec3 dir(unit(rng), unit(rng), unit(rng));
    const double len = std::pow(10.0, expo(rng) * 3.0);  // 1e-42 .. 1e42
    const glm::dvec3 target = eye + dir * len;
    // up: along the view plus a part across it from 1e-9 to 1 of its length
    glm::dvec3 across = glm::cross(dir, glm::dvec3(unit(rng), unit(rng), unit(rng)));
    const double tilt = std::pow(10.0, -9.0 * (unit(rng) * 0.5 + 0.5));
    const glm::dvec3 up = (i % 5 == 0) ? glm::dvec3(0.0) : dir + across * tilt;
    const bool ok = !viewProblem(eye, target, up);
    (ok ? accepted : refused) += 1;
    const std::string file = sceneFileError(eye, target, up);
    EXPECT_EQ(ok, file.empty()) << file;
    if (ok) {
      // It goes on the wire and comes back.
      scene::CameraState state;
      ASSERT_NO_THROW(state = encodeCamera(camera(eye, target, up)));
      EXPECT_NO_THROW(decodeCamera(state));
    } else {
      EXPECT_THROW(encodeCamera(camera(eye, target, up)), PreconditionError);
    }
  }
  // The sweep crosses the rule's edges both ways.
  EXPECT_GT(accepted, 400);
  EXPECT_GT(refused, 400);
}

}  // namespace
}  // namespace tessera::sync
