// The gestures of Bettio et al. 2009, Figure 5, on a camera at (0, 0, 2) looking at the origin,
// with a flat "model" (the plane z = 0) under every pixel.
#include <tessera/interact/one_button_navigation.h>

#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

namespace {

using namespace tessera;
using interact::OneButtonNavigation;
using interact::PointerInput;

constexpr double kFovy = 0.8;
const glm::dvec2 kSize(800, 600);

config::Camera start() {
  config::Camera c;
  c.mutable_eye()->set_z(2.0);
  c.mutable_up()->set_y(1.0);
  return c;
}

glm::dvec3 eye(const config::Camera& c) {
  return {c.eye().x(), c.eye().y(), c.eye().z()};
}
glm::dvec3 look(const config::Camera& c) {
  return {c.target().x(), c.target().y(), c.target().z()};
}

struct Rig {
  OneButtonNavigation nav;
  config::Camera cam = start();

  glm::dmat4 clip() const {
    return glm::perspective(kFovy, kSize.x / kSize.y, 0.01, 100.0) *
           glm::lookAt(eye(cam), look(cam), glm::dvec3(cam.up().x(), cam.up().y(), cam.up().z()));
  }
  // The plane z = 0 under a pixel.
  std::optional<glm::dvec3> pick(glm::dvec2 px) const {
    const glm::dmat4 inv = glm::inverse(clip());
    const double nx = px.x / kSize.x * 2 - 1, ny = 1 - px.y / kSize.y * 2;
    glm::dvec4 a = inv * glm::dvec4(nx, ny, -1, 1), b = inv * glm::dvec4(nx, ny, 1, 1);
    const glm::dvec3 o = glm::dvec3(a) / a.w, d = glm::dvec3(b) / b.w - o;
    if (std::abs(d.z) < 1e-12 || -o.z / d.z < 0) return std::nullopt;
    return o + d * (-o.z / d.z);
  }
  std::optional<glm::dvec2> project(const glm::dvec3& w) const {
    const glm::dvec4 c = clip() * glm::dvec4(w, 1);
    if (c.w <= 0) return std::nullopt;
    return glm::dvec2((c.x / c.w * 0.5 + 0.5) * kSize.x, (0.5 - c.y / c.w * 0.5) * kSize.y);
  }
  void step(PointerInput in, double dt = 0.0) {
    in.size = kSize;
    cam = nav.update(
        cam, in, dt, kFovy, [this](glm::dvec2 p) { return pick(p); },
        [this](const glm::dvec3& w) { return project(w); });
  }
  void click(glm::dvec2 at) {
    step({at, true, true, false});
    step({at, false, false, true});
  }
  void drag(glm::dvec2 from, glm::dvec2 to) {
    step({from, true, true, false});
    for (int i = 1; i <= 10; ++i) step({from + (to - from) * (i / 10.0), true, false, false});
    step({to, false, false, true});
  }
};

TEST(OneButtonNavigation, ClickOnTheModelSetsATargetAndAMissClearsIt) {
  Rig r;
  r.click({500, 300});
  ASSERT_TRUE(r.nav.target());
  EXPECT_NEAR(r.nav.target()->z, 0.0, 1e-9);
  EXPECT_GT(r.nav.target()->x, 0.0);           // right of centre
  EXPECT_EQ(eye(r.cam), glm::dvec3(0, 0, 2));  // a click does not move the camera
  r.cam.mutable_eye()->set_z(-2);              // now the plane is behind: nothing under a pixel
  r.cam.mutable_target()->set_z(-3);
  r.click({400, 300});
  EXPECT_FALSE(r.nav.target());
}

TEST(OneButtonNavigation, DragWithATargetOrbitsIt) {
  Rig r;
  r.click({400, 300});  // the origin
  const glm::dvec3 t = *r.nav.target();
  r.drag({400, 300}, {600, 300});
  EXPECT_NEAR(glm::length(eye(r.cam) - t), 2.0, 1e-9);  // same distance from the target
  EXPECT_GT(std::abs(eye(r.cam).x), 0.5);               // but elsewhere around it
}

TEST(OneButtonNavigation, WithoutATargetHorizontalTurnsAndVerticalPans) {
  Rig turn;
  turn.drag({100, 300}, {300, 300});
  EXPECT_EQ(eye(turn.cam), glm::dvec3(0, 0, 2));  // the eye stays
  EXPECT_GT(std::abs(look(turn.cam).x), 0.1);     // the view turns
  Rig pan;
  pan.drag({300, 100}, {300, 300});
  EXPECT_NEAR(eye(pan.cam).x, 0.0, 1e-12);
  EXPECT_GT(eye(pan.cam).y, 0.1);  // dragging down moves the camera up (the scene follows)
  EXPECT_NEAR(eye(pan.cam).y, look(pan.cam).y, 1e-12);  // film-plane translation
}

TEST(OneButtonNavigation, RightBarMovesForwardAndClickOnTargetFlies) {
  Rig bar;
  bar.drag({790, 400}, {790, 300});  // up in the bar: forward
  EXPECT_LT(eye(bar.cam).z, 2.0);
  EXPECT_NEAR(eye(bar.cam).x, 0.0, 1e-12);

  Rig fly;
  fly.click({500, 350});
  const glm::dvec3 t = *fly.nav.target();
  fly.click({500, 350});  // on the target
  EXPECT_TRUE(fly.nav.flying());
  for (int i = 0; i < 10; ++i) fly.step({{500, 350}, false, false, false}, 0.1);
  EXPECT_FALSE(fly.nav.flying());
  EXPECT_NEAR(glm::length(look(fly.cam) - t), 0.0, 1e-9);  // looking at the target
  EXPECT_NEAR(glm::length(eye(fly.cam) - t), 0.5 * glm::length(glm::dvec3(0, 0, 2) - t), 1e-9);
}

TEST(OneButtonNavigation, WheelZooms) {
  Rig r;
  r.step({{400, 300}, false, false, false, 2.0});
  EXPECT_NEAR(eye(r.cam).z, 2.0 * 0.85 * 0.85, 1e-12);
}

}  // namespace
