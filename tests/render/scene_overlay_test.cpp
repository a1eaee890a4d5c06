// The scene overlay (render/scene_overlay.h): sketches, avatars and annotations of a scene graph
// as overlay primitives, placed in double through their ancestors, hidden and faded with them;
// then drawn on the bunny: a sketch on the surface shows where its points project and is hidden
// behind the model, an avatar's head shows at its eye, and the 2x2 wall's tiles assembled show
// the same overlay pixels as one view of the whole wall.
//
// TESSERA_TEST_PICTURES=DIR writes the pictures (scene_overlay_*.png) there, to look at.
#include <tessera/render/scene_overlay.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <numbers>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <tessera/render/view_renderer.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/config.h>

#include "../support/bunny_store_test.h"
#include "../support/lasso_payload.h"

namespace tessera::render {
namespace {

using sync::SceneGraph;

const std::string kConfigs = TESSERA_CONFIG_DIR;

scene::Color color(double r, double g, double b) {
  scene::Color c;
  c.set_r(float(r));
  c.set_g(float(g));
  c.set_b(float(b));
  return c;
}

void setTransform(SceneGraph& g, SceneGraph::NodeId id, const glm::dmat4& m) {
  g.setTransform(id, std::span<const double>(glm::value_ptr(m), 16));
}

/// A SKETCH node through `points` (node frame), magenta by default.
SceneGraph::NodeId addSketch(SceneGraph& g, const std::vector<glm::dvec3>& points,
                             SceneGraph::NodeId parent = SceneGraph::kRoot, float width = 3.0f,
                             scene::Color c = color(1, 0, 1)) {
  const SceneGraph::NodeId id = g.add(scene::SceneNode::SKETCH, parent, "sketch");
  scene::SketchPayload s;
  for (const glm::dvec3& p : points) {
    s.add_points(float(p.x));
    s.add_points(float(p.y));
    s.add_points(float(p.z));
  }
  *s.mutable_color() = c;
  s.set_width(width);
  g.setPayload(id, s);
  return id;
}

/// An AVATAR node whose camera is at `eye` looking at `target` (y up): its transform is the
/// camera pose, columns right, up, back, eye.
SceneGraph::NodeId addAvatar(SceneGraph& g, const glm::dvec3& eye, const glm::dvec3& target,
                             float fovy, float aspect, float reach,
                             SceneGraph::NodeId parent = SceneGraph::kRoot) {
  const SceneGraph::NodeId id = g.add(scene::SceneNode::AVATAR, parent, "avatar-node");
  setTransform(g, id, glm::inverse(glm::lookAt(eye, target, glm::dvec3(0, 1, 0))));
  scene::AvatarPayload a;
  a.set_site("Pisa");
  *a.mutable_color() = color(0.15, 0.9, 0.35);
  a.set_fovy_deg(fovy);
  a.set_aspect(aspect);
  a.set_reach(reach);
  g.setPayload(id, a);
  return id;
}

// ---- The primitives (no GL).

TEST(SceneOverlay, SketchFarFromTheOriginKeepsMillimetres) {
  // A georeferenced site: the group puts the sketch 10^6 m out, where a float steps by 6 cm.
  SceneGraph g;
  const auto site = g.add(scene::SceneNode::GROUP);
  const glm::dvec3 offset(1234567.891, -2345678.123, 345.5);
  setTransform(g, site, glm::translate(glm::dmat4(1.0), offset));
  const std::vector<glm::dvec3> pts = {
      {0.001, 0.0, 0.0}, {0.002, 0.001, 0.0}, {0.004, 0.001, 0.003}};
  addSketch(g, pts, site);
  Overlay o;
  EXPECT_EQ(appendSceneOverlay(g, o), 1u);
  ASSERT_EQ(o.lines.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    const glm::dvec3 a = offset + glm::dvec3(glm::vec3(pts[i]));
    const glm::dvec3 b = offset + glm::dvec3(glm::vec3(pts[i + 1]));
    EXPECT_LT(glm::length(o.lines[i].a - a), 1e-8) << i;
    EXPECT_LT(glm::length(o.lines[i].b - b), 1e-8) << i;
    // Millimetre segments stay millimetres long.
    EXPECT_NEAR(glm::length(o.lines[i].b - o.lines[i].a), glm::length(pts[i + 1] - pts[i]), 1e-7);
  }
  // One round join at the interior vertex, the line's width and colour.
  ASSERT_EQ(o.points.size(), 1u);
  EXPECT_LT(glm::length(o.points[0].at - o.lines[0].b), 1e-12);
  EXPECT_FLOAT_EQ(o.points[0].size_px, 3.0f);
  EXPECT_EQ(o.lines[0].color, glm::u8vec4(255, 0, 255, 255));
}

TEST(SceneOverlay, TransformsComposeAncestorsFirst) {
  SceneGraph g;
  const auto outer = g.add(scene::SceneNode::GROUP);
  const auto inner = g.add(scene::SceneNode::GROUP, outer);
  const glm::dmat4 to = glm::translate(glm::dmat4(1.0), {10.0, 0.0, 0.0});
  const glm::dmat4 rot = glm::rotate(glm::dmat4(1.0), std::numbers::pi / 2, {0.0, 0.0, 1.0});
  setTransform(g, outer, to);
  setTransform(g, inner, rot);
  const auto s = addSketch(g, {{1, 0, 0}, {2, 0, 0}}, inner);
  setTransform(g, s, glm::scale(glm::dmat4(1.0), {2.0, 2.0, 2.0}));
  Overlay o;
  appendSceneOverlay(g, o);
  ASSERT_EQ(o.lines.size(), 1u);
  // world = outer * inner * own: (1,0,0) -> (2,0,0) -> (0,2,0) -> (10,2,0).
  EXPECT_LT(glm::length(o.lines[0].a - glm::dvec3(10, 2, 0)), 1e-12);
  EXPECT_LT(glm::length(o.lines[0].b - glm::dvec3(10, 4, 0)), 1e-12);
}

TEST(SceneOverlay, HiddenNodesAndAncestorsHide) {
  SceneGraph g;
  const auto top = g.add(scene::SceneNode::GROUP);
  const auto mid = g.add(scene::SceneNode::GROUP, top);
  const auto s = addSketch(g, {{0, 0, 0}, {1, 0, 0}}, mid);
  const auto a = addAvatar(g, {0, 0, 5}, {0, 0, 0}, 60, 1.5f, 1, mid);
  const auto n = g.add(scene::SceneNode::ANNOTATION, mid);
  scene::AnnotationPayload ap;
  ap.set_text("crack");
  g.setPayload(n, ap);
  auto drawn = [&] {
    Overlay o;
    const size_t k = appendSceneOverlay(g, o);
    EXPECT_EQ(k == 0, o.empty());
    return k;
  };
  EXPECT_EQ(drawn(), 3u);
  g.setVisible(top, false);  // a grandparent hides all
  EXPECT_EQ(drawn(), 0u);
  g.setVisible(top, true);
  g.setVisible(mid, false);
  EXPECT_EQ(drawn(), 0u);
  g.setVisible(mid, true);
  g.setVisible(s, false);
  g.setVisible(a, false);
  EXPECT_EQ(drawn(), 1u);
  g.setVisible(n, false);
  EXPECT_EQ(drawn(), 0u);
}

TEST(SceneOverlay, OpacityMultipliesDownTheTree) {
  SceneGraph g;
  const auto top = g.add(scene::SceneNode::GROUP);
  g.setOpacity(top, 0.5f);
  const auto s = addSketch(g, {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}}, top);
  g.setOpacity(s, 0.5f);
  const auto a = addAvatar(g, {0, 0, 5}, {0, 0, 0}, 60, 1.5f, 1, top);
  Overlay o;
  appendSceneOverlay(g, o);
  ASSERT_FALSE(o.lines.empty());
  EXPECT_EQ(o.lines[0].color.a, 64);  // 255 * 0.25
  EXPECT_EQ(o.lines[0].color.r, 255);
  EXPECT_EQ(o.points[0].color.a, 64);  // the join
  // The avatar at 0.5: its lines, head and label (text and box) fade alike.
  ASSERT_EQ(o.labels.size(), 1u);
  EXPECT_EQ(o.labels[0].color.a, 128);
  EXPECT_EQ(o.labels[0].background.a, 100);  // 200 * 0.5
  EXPECT_EQ(o.lines.back().color.a, 128);
  EXPECT_EQ(o.points.back().color.a, 128);
  // Opacity 0 anywhere up the tree: nothing at all.
  g.setOpacity(a, 0.0f);
  g.setOpacity(s, 0.0f);
  Overlay none;
  EXPECT_EQ(appendSceneOverlay(g, none), 0u);
  EXPECT_TRUE(none.empty());
}

TEST(SceneOverlay, AvatarFrustumCornersAreAnalytic) {
  SceneGraph g;
  const glm::dvec3 eye(3.0, 1.5, 4.0), target(0.5, 0.25, -1.0);
  const float fovy = 50.0f, aspect = 1.6f, reach = 2.5f;
  addAvatar(g, eye, target, fovy, aspect, reach);
  Overlay o;
  appendSceneOverlay(g, o);
  // 4 edges from the eye and the far rectangle's 4.
  ASSERT_EQ(o.lines.size(), 8u);
  const glm::dvec3 fwd = glm::normalize(target - eye);
  const glm::dvec3 right = glm::normalize(glm::cross(fwd, glm::dvec3(0, 1, 0)));
  const glm::dvec3 up = glm::cross(right, fwd);
  const double h = reach * std::tan(double(fovy) * std::numbers::pi / 360.0), w = h * aspect;
  const glm::dvec3 centre = eye + fwd * double(reach);
  std::vector<glm::dvec3> corners = {centre - right * w - up * h, centre + right * w - up * h,
                                     centre + right * w + up * h, centre - right * w + up * h};
  for (const glm::dvec3& c : corners) {
    int from_eye = 0, on_rect = 0;
    for (const OverlayLine& l : o.lines) {
      if (glm::length(l.a - eye) < 1e-9 && glm::length(l.b - c) < 1e-9) ++from_eye;
      if (glm::length(l.a - c) < 1e-9 || glm::length(l.b - c) < 1e-9) ++on_rect;
    }
    EXPECT_EQ(from_eye, 1);
    EXPECT_EQ(on_rect, 3);  // the edge from the eye and two sides of the far face
  }
  // Each far side is the rectangle's width or height.
  EXPECT_NEAR(glm::length(corners[1] - corners[0]), 2 * w, 1e-9);
  // The head: a dark disc and the coloured dot on it, at the eye; the name above it.
  ASSERT_EQ(o.points.size(), 2u);
  EXPECT_LT(glm::length(o.points[0].at - eye), 1e-9);
  EXPECT_LT(glm::length(o.points[1].at - eye), 1e-9);
  EXPECT_GT(o.points[0].size_px, o.points[1].size_px);
  EXPECT_LT(o.points[0].color.r, 40);
  EXPECT_EQ(o.points[1].color, glm::u8vec4(38, 230, 89, 255));
  ASSERT_EQ(o.labels.size(), 1u);
  EXPECT_EQ(o.labels[0].text, "Pisa");
  EXPECT_LT(glm::length(o.labels[0].at - eye), 1e-9);
  EXPECT_LT(o.labels[0].offset_px.y, -7.0f);  // above the head
  EXPECT_EQ(o.labels[0].align, glm::vec2(0.5f, 1.0f));
}

/// A VIDEO_INSET node of `source` under `parent`: a world quad (w x h metres) or, with `screen`,
/// pinned at (x, y) of the screen, `screen_width` of it wide (height from the picture).
SceneGraph::NodeId addInset(SceneGraph& g, uint32_t source, SceneGraph::NodeId parent, float w,
                            float h, bool screen = false, float x = 0, float y = 0,
                            float screen_width = 0) {
  const SceneGraph::NodeId id = g.add(scene::SceneNode::VIDEO_INSET, parent, "video");
  scene::VideoInsetPayload v;
  v.set_source(source);
  v.set_width(w);
  v.set_height(h);
  v.set_screen(screen);
  v.set_screen_x(x);
  v.set_screen_y(y);
  v.set_screen_width(screen_width);
  g.setPayload(id, v);
  return id;
}

TEST(SceneOverlay, VideoInsetsAreQuadsBesideAvatarsOrScreenRectsOfTheWall) {
  SceneGraph g;
  const glm::dvec3 eye(0.0, 0.0, 2.0);
  const SceneGraph::NodeId avatar = addAvatar(g, eye, glm::dvec3(0.0), 45.0f, 1.5f, 0.0f);
  const SceneGraph::NodeId beside = addInset(g, 1, avatar, 0.4f, 0.3f);
  setTransform(g, beside, glm::translate(glm::dmat4(1.0), glm::dvec3(0.5, 0.0, 0.0)));
  addInset(g, 2, SceneGraph::kRoot, 0.0f, 0.0f, true, 0.25f, 0.5f, 0.5f);
  SceneOverlayOptions o;
  // The wall: 2 x 1 m; this view is its right half, 400 x 200 pixels.
  o.screen_wall = glm::dvec4(0.0, 0.0, 2.0, 1.0);
  o.screen_view = glm::dvec4(1.0, 0.0, 2.0, 1.0);
  o.view_px = glm::dvec2(400.0, 200.0);
  const GlTexture* none = nullptr;
  o.video_texture = [&](uint32_t) { return none; };
  Overlay out;
  EXPECT_EQ(appendSceneOverlay(g, out, o), 3u);
  // Beside the avatar: its frame is the camera's (looking down -z from z = 2, x right).
  ASSERT_EQ(out.quads.size(), 1u);
  const auto& c = out.quads[0].corners;
  EXPECT_LT(glm::length(c[0] - glm::dvec3(0.3, 0.15, 2.0)), 1e-6);   // top-left (sizes are floats)
  EXPECT_LT(glm::length(c[2] - glm::dvec3(0.7, -0.15, 2.0)), 1e-6);  // bottom-right
  EXPECT_EQ(out.quads[0].texture, nullptr);
  EXPECT_EQ(out.quads[0].tint, glm::u8vec4(40, 40, 48, 220)) << "a dark quad until decoded";
  // Pinned: x 0.5 .. 1.5 m of the wall, y 0.5 .. 1.25 m (4:3 until a picture says otherwise),
  // in this view's pixels (y down): half of it left of the view, continuing on the other tile.
  ASSERT_EQ(out.rects.size(), 1u);
  EXPECT_NEAR(out.rects[0].min.x, -200.0f, 1e-3f);
  EXPECT_NEAR(out.rects[0].max.x, 200.0f, 1e-3f);
  EXPECT_NEAR(out.rects[0].min.y, -50.0f, 1e-3f);
  EXPECT_NEAR(out.rects[0].max.y, 100.0f, 1e-3f);
  // A site's own inset is left out of its own view.
  o.hide_site = "Pisa";
  Overlay own;
  g.setPayload(beside, [&] {
    scene::VideoInsetPayload v = g.node(beside).video_inset();
    v.set_stream("Pisa");
    return v;
  }());
  appendSceneOverlay(g, own, o);
  EXPECT_TRUE(own.quads.empty());
}

TEST(SceneOverlay, OnlyTheInsetsAViewShowsAreItsToDecode) {
  SceneGraph g;
  addInset(g, 1, SceneGraph::kRoot, 0.5f, 0.5f);  // at the origin, in view
  const SceneGraph::NodeId far = addInset(g, 2, SceneGraph::kRoot, 0.5f, 0.5f);
  setTransform(g, far, glm::translate(glm::dmat4(1.0), glm::dvec3(100.0, 0.0, 0.0)));
  addInset(g, 3, SceneGraph::kRoot, 0, 0, true, 0.6f, 0.1f, 0.3f);   // right half of the wall
  addInset(g, 4, SceneGraph::kRoot, 0, 0, true, 0.05f, 0.1f, 0.3f);  // left half
  ViewSetup view;
  view.view = glm::lookAt(glm::dvec3(0, 0, 5), glm::dvec3(0.0), glm::dvec3(0, 1, 0));
  view.projection = glm::perspective(glm::radians(60.0), 1.0, 0.1, 50.0);
  SceneOverlayOptions o;
  o.screen_wall = glm::dvec4(0.0, 0.0, 2.0, 1.0);
  o.screen_view = glm::dvec4(1.0, 0.0, 2.0, 1.0);  // this view: the right half
  o.view_px = glm::dvec2(400.0, 200.0);
  EXPECT_EQ(shownVideoSources(g, view, o), (std::set<uint32_t>{1, 3}));
  setTransform(g, far, glm::translate(glm::dmat4(1.0), glm::dvec3(1.0, 0.0, 0.0)));
  EXPECT_EQ(shownVideoSources(g, view, o), (std::set<uint32_t>{1, 2, 3}));
}

TEST(SceneOverlay, DegenerateAvatarsAndSketchesDrawNoFrustumOrZeroLengthLines) {
  const std::tuple<float, float, float> cases[] = {
      {0.0f, 1.5f, 2.0f}, {60.0f, 0.0f, 2.0f}, {60.0f, 1.5f, 0.0f}};
  for (const auto& [fovy, aspect, reach] : cases) {
    SceneGraph g;
    const auto a = addAvatar(g, {0, 0, 5}, {0, 0, 0}, fovy, aspect, reach);
    Overlay o;
    appendSceneOverlay(g, o);
    EXPECT_TRUE(o.lines.empty()) << fovy << " " << aspect << " " << reach;
    EXPECT_EQ(o.points.size(), 2u);  // the head stays
    // Without a site the label is the node's name; without either, none.
    scene::AvatarPayload p = g.node(a).avatar();
    p.clear_site();
    g.setPayload(a, p);
    Overlay named;
    appendSceneOverlay(g, named);
    ASSERT_EQ(named.labels.size(), 1u);
    EXPECT_EQ(named.labels[0].text, "avatar-node");
    g.setName(a, "");
    Overlay anonymous;
    appendSceneOverlay(g, anonymous);
    EXPECT_TRUE(anonymous.labels.empty());
  }
  SceneGraph g;
  // Repeated points (a pen held still) give no zero-length segment and no join of their own.
  addSketch(g, {{0, 0, 0}, {0, 0, 0}, {1, 0, 0}, {1, 0, 0}, {1, 1, 0}}, SceneGraph::kRoot, 0.0f);
  addSketch(g, {{5, 5, 5}});             // one point: a dot
  addSketch(g, {{7, 7, 7}, {7, 7, 7}});  // all the same: a dot
  Overlay o;
  EXPECT_EQ(appendSceneOverlay(g, o), 3u);
  ASSERT_EQ(o.lines.size(), 2u);
  for (const OverlayLine& l : o.lines) {
    EXPECT_GT(glm::length(l.b - l.a), 0.5);
    EXPECT_FLOAT_EQ(l.width_px, 2.0f);  // width 0: the default
  }
  ASSERT_EQ(o.points.size(), 3u);  // one join, two dots
  EXPECT_EQ(o.points[0].at, glm::dvec3(1, 0, 0));
  EXPECT_EQ(o.points[1].at, glm::dvec3(5, 5, 5));
  EXPECT_EQ(o.points[2].at, glm::dvec3(7, 7, 7));
}

TEST(SceneOverlay, AnnotationIsItsTextAndADotAtItsAnchor) {
  SceneGraph g;
  const auto grp = g.add(scene::SceneNode::GROUP);
  setTransform(g, grp, glm::translate(glm::dmat4(1.0), {0.0, 100.0, 0.0}));
  const auto n = g.add(scene::SceneNode::ANNOTATION, grp);
  scene::AnnotationPayload ap;
  ap.set_text("salt efflorescence");
  ap.mutable_anchor()->set_x(1.0);
  ap.mutable_anchor()->set_y(2.0);
  ap.mutable_anchor()->set_z(3.0);
  g.setPayload(n, ap);
  Overlay o;
  appendSceneOverlay(g, o);
  ASSERT_EQ(o.labels.size(), 1u);
  ASSERT_EQ(o.points.size(), 1u);
  EXPECT_EQ(o.labels[0].text, "salt efflorescence");
  EXPECT_EQ(o.labels[0].at, glm::dvec3(1, 102, 3));
  EXPECT_EQ(o.points[0].at, glm::dvec3(1, 102, 3));
}

TEST(SceneOverlay, MeasurementsAreLinesDotsAndALabelInAReadableUnit) {
  scene::MeasurementPayload m;
  m.set_type(scene::MeasurementPayload::DISTANCE);
  m.set_value(0.142);
  m.set_uncertainty(0.0003);
  EXPECT_EQ(measurementLabel(m), "14.2 cm \u00b1 0.3 mm");
  m.set_value(2315.0);
  m.set_uncertainty(0.5);
  EXPECT_EQ(measurementLabel(m), "2.315 km \u00b1 50 cm");
  m.set_value(0.0);
  m.set_uncertainty(0.0);
  EXPECT_EQ(measurementLabel(m), "0 mm \u00b1 0 mm");
  m.set_type(scene::MeasurementPayload::POLYLINE);
  m.set_value(2.3151);
  m.set_uncertainty(0.004);
  EXPECT_EQ(measurementLabel(m), "path 2.315 m \u00b1 4 mm");
  m.set_type(scene::MeasurementPayload::ANGLE);
  m.set_value(std::numbers::pi / 4);
  m.set_uncertainty(std::numbers::pi / 180 * 0.41);
  EXPECT_EQ(measurementLabel(m), "45.00\u00b0 \u00b1 0.41\u00b0");
  m.set_type(scene::MeasurementPayload::AREA);
  m.set_value(0.3);
  m.set_uncertainty(0.002);
  EXPECT_EQ(measurementLabel(m), "area 3000 cm\u00b2 \u00b1 20 cm\u00b2");
  m.set_value(12.5);
  EXPECT_EQ(measurementLabel(m), "area 12.5 m\u00b2 \u00b1 20 cm\u00b2");

  // An area of 4 points under a translated group: a closed loop of 4 lines, 4 dots, the label at
  // the centroid, all in double far from the origin.
  SceneGraph g;
  const auto grp = g.add(scene::SceneNode::GROUP);
  setTransform(g, grp, glm::translate(glm::dmat4(1.0), {500000.0, 5000000.0, 0.0}));
  const auto n = g.add(scene::SceneNode::MEASUREMENT, grp);
  scene::MeasurementPayload a;
  a.set_type(scene::MeasurementPayload::AREA);
  for (double v : {0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.001}) a.add_points(v);
  a.set_value(1.0);
  g.setPayload(n, a);
  Overlay o;
  EXPECT_EQ(appendSceneOverlay(g, o), 1u);
  ASSERT_EQ(o.lines.size(), 4u);
  ASSERT_EQ(o.points.size(), 4u);
  ASSERT_EQ(o.labels.size(), 1u);
  EXPECT_EQ(o.lines[3].b, glm::dvec3(500000.0, 5000000.0, 0.0)) << "closed";
  EXPECT_EQ(o.points[3].at, glm::dvec3(500000.0, 5000001.0, 0.001)) << "millimetres kept";
  EXPECT_EQ(o.labels[0].at, glm::dvec3(500000.5, 5000000.5, 0.00025));
  EXPECT_EQ(o.labels[0].text, "area 1 m\u00b2 \u00b1 0 mm\u00b2");
}

TEST(SceneOverlay, RebuildsOnlyWhenNodesChange) {
  SceneGraph g;
  const auto s = addSketch(g, {{0, 0, 0}, {1, 0, 0}});
  SceneOverlay so;
  EXPECT_EQ(so.update(g, sync::SceneChanges()).lines.size(), 1u);  // the first look builds
  EXPECT_NE(so.drawn(), nullptr);
  g.setVisible(s, false);
  sync::SceneChanges camera_only;
  camera_only.camera = true;
  EXPECT_EQ(so.update(g, camera_only).lines.size(), 1u);  // kept: no node changed
  sync::SceneChanges changed;
  changed.nodes = {s};
  EXPECT_TRUE(so.update(g, changed).empty());
  EXPECT_EQ(so.drawn(), nullptr);  // nothing to draw: the renderer skips the pass
  g.setVisible(s, true);
  EXPECT_EQ(so.update(g, sync::SceneChanges::all()).lines.size(), 1u);
}

// ---- Drawn on the bunny.

class SceneOverlayRenderTest : public test::BunnyStoreTest {};

const uint8_t* pixel(const Image& img, int x, int y) {
  return &img.rgba[(size_t(y) * img.width + size_t(x)) * 4];
}

bool isMagenta(const uint8_t* p) {
  return p[0] > 200 && p[1] < 80 && p[2] > 200;
}
bool isCyan(const uint8_t* p) {
  return p[0] < 80 && p[1] > 200 && p[2] > 200;
}
bool isAvatarGreen(const uint8_t* p) {
  return p[0] < 90 && p[1] > 190 && p[2] < 130;
}
bool isModel(const uint8_t* p) {  // the bunny's grey (no colours, no EDL)
  return p[0] > 60 && std::abs(p[0] - p[1]) < 12 && std::abs(p[1] - p[2]) < 12;
}

/// Where world point p lands in the view's image (x right, y down, pixel units).
glm::dvec2 project(const ViewSetup& v, const glm::dvec3& p) {
  const glm::dvec4 c = v.projection * v.view * glm::dvec4(p, 1.0);
  return {(c.x / c.w * 0.5 + 0.5) * v.width, (0.5 - c.y / c.w * 0.5) * v.height};
}

/// Whether `test` holds for a pixel within `r` pixels of (x, y).
template <class F>
bool nearby(const Image& img, double x, double y, int r, F test) {
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      const int px = int(std::floor(x)) + dx, py = int(std::floor(y)) + dy;
      if (px < 0 || py < 0 || px >= int(img.width) || py >= int(img.height)) continue;
      if (test(pixel(img, px, py))) return true;
    }
  }
  return false;
}

void maybeWrite(const std::string& name, const Image& img) {
  if (const char* dir = std::getenv("TESSERA_TEST_PICTURES"))
    writePng(std::string(dir) + "/scene_overlay_" + name + ".png", img);
}

glm::dvec3 bunnyCentre(const lod::PointStore& s) {
  const auto& sum = s.summary();
  return sum.origin + 0.5 * (sum.bbox_min + sum.bbox_max);
}

/// The bunny's front surface along the image line y = y0 + slope (x - width / 2): the picked
/// world points of every 3rd pixel of the longest run of covered pixels.
std::vector<glm::dvec3> surfaceStroke(ViewRenderer& r, const Image& img, double y0, double slope) {
  std::vector<glm::dvec3> best, run;
  for (uint32_t x = 0; x < img.width; x += 3) {
    const double y = y0 + slope * (double(x) - img.width / 2.0);
    if (y < 0 || y >= img.height) continue;
    const auto hit = r.pick(x, uint32_t(y));
    // A jump in depth (a silhouette over what is behind) ends a run too.
    if (hit && (run.empty() || glm::length(hit->world - run.back()) < 0.006)) {
      run.push_back(hit->world);
    } else {
      if (run.size() > best.size()) best = run;
      run.clear();
      if (hit) run.push_back(hit->world);
    }
  }
  return run.size() > best.size() ? run : best;
}

TEST_F(SceneOverlayRenderTest, SketchOnTheSurfaceHiddenBehindItAvatarInFront) {
  auto store = lod::PointStore::open(*sDir / "b.tlod");
  const glm::dvec3 c = bunnyCentre(*store);
  const uint32_t w = 480, h = 360;
  ViewSetup v;
  v.eye_world = c + glm::dvec3(0.0, 0.0, 0.45);
  v.view = glm::lookAt(v.eye_world, c, glm::dvec3(0, 1, 0));
  v.projection = glm::perspective(glm::radians(35.0), double(w) / h, 0.01, 10.0);
  v.width = w;
  v.height = h;
  const ModelInstance m[] = {{store.get(), storeModel(*store)}};
  ViewRenderer r(w, h);
  RenderOptions opt;
  opt.pick_ids = true;
  const Image plain = r.renderSettled(m, v, opt);
  const std::vector<glm::dvec3> surface = surfaceStroke(r, plain, h / 2 + 20, -0.25);
  ASSERT_GT(surface.size(), 30u);
  // The avatar's eye halfway between the camera and a point of the bunny's body.
  const auto body = r.pick(w / 2 + 10, h / 2 + 45);
  ASSERT_TRUE(body);
  const glm::dvec3 avatar_eye = glm::mix(v.eye_world, body->world, 0.55);

  // The sketch under a group at the bunny's centre (node frame relative to it), a line behind
  // the bunny across the whole view, and an avatar between the eye and the bunny.
  SceneGraph g;
  const auto grp = g.add(scene::SceneNode::GROUP);
  setTransform(g, grp, glm::translate(glm::dmat4(1.0), c));
  std::vector<glm::dvec3> local;
  for (const glm::dvec3& p : surface) local.push_back(p - c);
  addSketch(g, local, grp);
  const double behind = -0.12;  // metres behind the centre: the bunny is in front of it
  // Across the ears and the gap between them and the back.
  const glm::dvec3 b0 = glm::dvec3(-0.3, 0.05, behind), b1 = glm::dvec3(0.3, 0.05, behind);
  addSketch(g, {b0, b1}, grp, 4.0f, color(0, 1, 1));
  // First the sketches alone (the avatar's glyph would cover parts of them), then with it.
  Overlay sketches;
  ASSERT_EQ(appendSceneOverlay(g, sketches), 2u);
  const Image img = r.renderSettled(m, v, opt, nullptr, &sketches);
  addAvatar(g, avatar_eye, c, 40.0f, 1.5f, 0.08f);
  Overlay overlay;
  ASSERT_EQ(appendSceneOverlay(g, overlay), 3u);
  const Image with_avatar = r.renderSettled(m, v, opt, nullptr, &overlay);
  maybeWrite("bunny", with_avatar);

  // The sketch's colour where its points project (vertices and midpoints), nearly everywhere:
  // a point of the surface is in front of its own samples by the overlay's depth bias.
  size_t shown = 0, samples = 0;
  for (size_t i = 0; i + 1 < surface.size(); ++i) {
    for (const double t : {0.0, 0.5}) {
      const glm::dvec2 at = project(v, glm::mix(surface[i], surface[i + 1], t));
      ++samples;
      shown += nearby(img, at.x, at.y, 0, isMagenta);
    }
  }
  EXPECT_GE(shown, samples * 95 / 100) << shown << " of " << samples;
  // Nowhere else: magenta lies within 2 px of the polyline.
  size_t magenta = 0, stray = 0;
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      if (!isMagenta(pixel(img, int(x), int(y)))) continue;
      ++magenta;
      bool on = false;
      for (size_t i = 0; i + 1 < surface.size() && !on; ++i) {
        const glm::dvec2 a = project(v, surface[i]), b = project(v, surface[i + 1]);
        const glm::dvec2 p(x + 0.5, y + 0.5);
        const double t = glm::clamp(glm::dot(p - a, b - a) / glm::dot(b - a, b - a), 0.0, 1.0);
        on = glm::length(p - (a + t * (b - a))) < 3.0;
      }
      stray += !on;
    }
  }
  EXPECT_GT(magenta, size_t(surface.size()) * 6);
  EXPECT_EQ(stray, 0u);

  // The line behind: cyan where the background shows, the model's grey where the bunny is.
  size_t hidden = 0, visible = 0;
  const glm::dvec2 p0 = project(v, c + b0), p1 = project(v, c + b1);
  for (int k = 0; k <= 200; ++k) {
    const glm::dvec2 at = glm::mix(p0, p1, k / 200.0);
    if (at.x < 3 || at.x >= w - 3) continue;
    const uint8_t* before = pixel(plain, int(at.x), int(at.y));
    const uint8_t* after = pixel(img, int(at.x), int(at.y));
    if (isModel(before)) {
      EXPECT_FALSE(isCyan(after)) << "at " << at.x << "," << at.y;
      EXPECT_TRUE(isModel(after)) << "at " << at.x << "," << at.y;
      ++hidden;
    } else if (!nearby(plain, at.x, at.y, 3,
                       [](const uint8_t* p) { return p[0] || p[1] || p[2]; })) {
      EXPECT_TRUE(isCyan(after)) << "at " << at.x << "," << at.y;
      ++visible;
    }
  }
  EXPECT_GT(hidden, 20u);
  EXPECT_GT(visible, 40u);

  // The avatar: its head's colour at the projected eye, over the model; a dark ring around it;
  // its name above.
  const glm::dvec2 head = project(v, avatar_eye);
  EXPECT_TRUE(isAvatarGreen(pixel(with_avatar, int(head.x), int(head.y))));
  EXPECT_TRUE(isModel(pixel(plain, int(head.x), int(head.y))));  // it is in front of the bunny
  for (const glm::dvec2 d : {glm::dvec2(9, 0), glm::dvec2(-9, 0), glm::dvec2(0, 9)}) {
    const uint8_t* ring = pixel(with_avatar, int(head.x + d.x), int(head.y + d.y));
    EXPECT_LT(ring[0] + ring[1] + ring[2], 3 * 30) << d.x << "," << d.y;
  }
  size_t label = 0;  // green text pixels in a box above the head
  for (int y = int(head.y) - 40; y < int(head.y) - 10; ++y)
    for (int x = int(head.x) - 30; x < int(head.x) + 30; ++x)
      label += isAvatarGreen(pixel(with_avatar, x, y));
  EXPECT_GT(label, 20u);
}

TEST_F(SceneOverlayRenderTest, TilesOfTheWallShowTheWholeWallsOverlay) {
  auto store = lod::PointStore::open(*sDir / "b.tlod");
  const glm::dvec3 c = bunnyCentre(*store);
  const config::WallConfig wall = sync::loadWallConfig(kConfigs + "/walls/2x2.json");
  // The scene camera looks down -z at the bunny from 0.5 m: camera space is the world shifted,
  // so a wall point (x, y, 0) is seen along eye + (x - 0.97, y - 0.55, -2).
  const glm::dvec3 eye = c + glm::dvec3(0.0, 0.0, 0.5);
  config::Camera cam;
  cam.mutable_eye()->set_x(eye.x);
  cam.mutable_eye()->set_y(eye.y);
  cam.mutable_eye()->set_z(eye.z);
  cam.mutable_target()->set_x(c.x);
  cam.mutable_target()->set_y(c.y);
  cam.mutable_target()->set_z(c.z);
  cam.mutable_up()->set_y(1.0);
  const glm::dvec3 wall_eye(wall.eye().x(), wall.eye().y(), wall.eye().z());
  auto along = [&](double wx, double wy, double distance) {
    return eye + (glm::dvec3(wx, wy, 0.0) - wall_eye) * (distance / wall_eye.z);
  };

  SceneGraph g;
  // In front of the bunny: a line over three tiles, crossing the vertical bezel at y = 0.6 and
  // the horizontal one at x = 0.86; through the bunny's centre plane (so partly hidden by it)
  // a stroke over all four tiles; and an avatar whose head straddles the edge of a lower tile.
  addSketch(g, {along(0.1, 0.2, 0.35), along(1.84, 1.0, 0.35)});
  addSketch(g, {along(0.7, 0.75, 0.5), along(1.0, 0.5, 0.5), along(1.25, 0.3, 0.5)},
            SceneGraph::kRoot, 5.0f, color(0, 1, 1));
  addAvatar(g, along(0.955, 0.35, 0.3), c + glm::dvec3(0.0, -0.02, 0.0), 40.0f, 1.5f, 0.1f);
  Overlay overlay;
  appendSceneOverlay(g, overlay);

  const ModelInstance m[] = {{store.get(), storeModel(*store)}};
  RenderOptions opt;
  const ViewSetup whole_view = wholeWallView(wall, cam);
  ViewRenderer whole_r(whole_view.width, whole_view.height);
  const Image whole = whole_r.renderSettled(m, whole_view, opt, nullptr, &overlay);
  std::vector<Image> tiles;
  for (const config::Tile& t : wall.tiles()) {
    const ViewSetup tv = tileView(wall, t, cam);
    ViewRenderer r(tv.width, tv.height);
    tiles.push_back(r.renderSettled(m, tv, opt, nullptr, &overlay));
  }
  const Image mosaic = assembleWallMosaic(wall, tiles);
  maybeWrite("wall_mosaic", mosaic);
  maybeWrite("wall_whole", whole);
  ASSERT_EQ(mosaic.width, whole.width);
  ASSERT_EQ(mosaic.height, whole.height);

  // Over every tile's pixels, each overlay-coloured pixel of one image has one within 1 px in
  // the other; and the lines reach into the tiles they cross.
  auto overlayPixel = [](const uint8_t* p) {
    return isMagenta(p) || isCyan(p) || isAvatarGreen(p);
  };
  size_t compared = 0, mismatched = 0;
  std::vector<size_t> per_tile(size_t(wall.tiles_size()), 0);
  for (int i = 0; i < wall.tiles_size(); ++i) {
    const config::Tile& t = wall.tiles(i);
    const glm::ivec2 o = tileOffsetInWhole(wall, t);
    for (int y = 0; y < int(t.pixel_height()); ++y) {
      for (int x = 0; x < int(t.pixel_width()); ++x) {
        const int wx = o.x + x, wy = o.y + y;
        const bool in_mosaic = overlayPixel(pixel(mosaic, wx, wy));
        const bool in_whole = overlayPixel(pixel(whole, wx, wy));
        if (!in_mosaic && !in_whole) continue;
        ++compared;
        per_tile[size_t(i)] += in_mosaic;
        if (in_mosaic == in_whole) continue;
        // Within 1 px (and inside this tile, so a bezel never counts).
        bool ok = false;
        for (int dy = -1; dy <= 1 && !ok; ++dy) {
          for (int dx = -1; dx <= 1 && !ok; ++dx) {
            if (x + dx < 0 || y + dy < 0 || x + dx >= int(t.pixel_width()) ||
                y + dy >= int(t.pixel_height()))
              continue;
            ok = overlayPixel(pixel(in_mosaic ? whole : mosaic, wx + dx, wy + dy));
          }
        }
        mismatched += !ok;
      }
    }
  }
  EXPECT_GT(compared, 3000u);
  EXPECT_EQ(mismatched, 0u) << "of " << compared;
  for (size_t i = 0; i < per_tile.size(); ++i) {
    if (wall.tiles(int(i)).name() == "tile-1-1") continue;  // the line misses the lower right
    EXPECT_GT(per_tile[i], 500u) << wall.tiles(int(i)).name();
  }
  // The avatar's head shows up to the tile's edge it straddles.
  const glm::dvec2 head = project(whole_view, along(0.955, 0.35, 0.3));
  EXPECT_TRUE(isAvatarGreen(pixel(mosaic, int(head.x) - 2, int(head.y))));
}

}  // namespace
}  // namespace tessera::render

namespace tessera::render {
namespace {

/// Even-odd point in polygon (the selection's rule), for the test's own reference.
bool inside(const std::vector<glm::dvec2>& poly, const glm::dvec2& p) {
  bool in = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const glm::dvec2 a = poly[i], b = poly[j];
    if ((a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y))
      in = !in;
  }
  return in;
}

double edgeDistance(const std::vector<glm::dvec2>& poly, const glm::dvec2& p) {
  double d = 1e300;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const glm::dvec2 a = poly[j], b = poly[i];
    const double t = glm::clamp(glm::dot(p - a, b - a) / glm::dot(b - a, b - a), 0.0, 1.0);
    d = std::min(d, glm::length(p - (a + t * (b - a))));
  }
  return d;
}

/// w x h views of the bunny from 0.45 m: the lasso's, from +z, and one `angle` radians aside
/// around y.
std::pair<ViewSetup, ViewSetup> lassoViewAndAside(const lod::PointStore& store, double angle,
                                                  uint32_t w, uint32_t h) {
  const glm::dvec3 c = bunnyCentre(store);
  auto from = [&](const glm::dvec3& eye) { return test::lookingAt(eye, c, w, h, 35.0, 0.05); };
  return {from(c + glm::dvec3(0.0, 0.0, 0.45)),
          from(c + 0.45 * glm::dvec3(std::sin(angle), 0.0, std::cos(angle)))};
}

// A selection lassoed in one view is tinted where its surface lies in another view too (the
// same points, seen from 25 degrees aside): every pixel whose surface point projects into the
// lasso (by the test's own point-in-polygon, away from the lasso's edge by the mask's
// resolution) is tinted, every other pixel is the plain picture's, background included.
TEST_F(SceneOverlayRenderTest, ASelectionIsTintedWhereItsSurfaceIsSeenFromAnyView) {
  auto store = lod::PointStore::open(*sDir / "b.tlod");
  const uint32_t w = 400, h = 300;
  const auto [lasso_view, other] = lassoViewAndAside(*store, 0.44, w, h);
  // A concave lasso (an L) over the bunny's body, in the lasso view's pixels (y down).
  const std::vector<glm::dvec2> px = {{150, 120}, {260, 120}, {260, 170},
                                      {200, 170}, {200, 230}, {150, 230}};
  SceneGraph g;
  const auto model = g.add(scene::SceneNode::MODEL);
  const auto sel = g.add(scene::SceneNode::SELECTION);
  g.setPayload(sel, test::lassoPayload(model, lasso_view, px));
  const std::vector<Highlight> highlights = sceneHighlights(g);
  ASSERT_EQ(highlights.size(), 1u);

  ModelInstance m[] = {{store.get(), storeModel(*store)}};
  m[0].node = model;  // the selection's model (SceneDrawList sets it)
  ViewRenderer r(w, h);
  for (const ViewSetup* v : {&lasso_view, &other}) {
    RenderOptions opt;
    opt.pick_ids = true;
    const Image plain = r.renderSettled(m, *v, opt);
    std::vector<std::optional<PickHit>> hits(size_t(w) * h);
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) hits[size_t(y) * w + x] = r.pick(x, y);
    opt.highlights = highlights;
    const Image tinted = r.renderSettled(m, *v, opt);
    maybeWrite(v == &lasso_view ? "selection_lasso_view" : "selection_other_view", tinted);
    size_t in = 0, out = 0, wrong = 0;
    for (uint32_t y = 0; y < h; ++y) {
      for (uint32_t x = 0; x < w; ++x) {
        const uint8_t *a = pixel(plain, int(x), int(y)), *b = pixel(tinted, int(x), int(y));
        const bool changed = a[0] != b[0] || a[1] != b[1] || a[2] != b[2];
        const auto& hit = hits[size_t(y) * w + x];
        if (!hit) {  // background: never tinted
          wrong += changed;
          continue;
        }
        const glm::dvec2 at = project(lasso_view, hit->world);
        if (edgeDistance(px, at) < 1.5) continue;  // the mask's cells: 0.4 px here
        const bool expect = inside(px, at);
        (expect ? in : out)++;
        if (changed != expect) ++wrong;
      }
    }
    EXPECT_GT(in, 4000u);
    EXPECT_GT(out, 4000u);
    EXPECT_EQ(wrong, 0u) << (v == &lasso_view ? "lasso view" : "other view");
  }
}

}  // namespace
}  // namespace tessera::render

namespace tessera::render {
namespace {

// A VISIBLE selection (the lasso took only what its view showed) seen from 70 degrees aside:
// surfaces the lasso's view saw are tinted, surfaces it saw hidden behind nearer ones are not,
// though they project into the lasso (a THROUGH selection tints them). Which is which the test
// decides itself, from a full-resolution render of the lasso's view: each pixel's surface point
// against the depths around the pixel it projects to there, away from depth edges.
TEST_F(SceneOverlayRenderTest, AVisibleOnlySelectionIsTintedOnlyWhereTheLassoViewSawIt) {
  auto store = lod::PointStore::open(*sDir / "b.tlod");
  const uint32_t w = 400, h = 300;
  const auto [lasso_view, other] = lassoViewAndAside(*store, 1.22, w, h);
  // Over the whole bunny, so what its front hides lies inside the lasso too.
  const std::vector<glm::dvec2> px = {{60, 40}, {340, 40}, {340, 260}, {60, 260}};
  SceneGraph g;
  const auto model = g.add(scene::SceneNode::MODEL);
  const auto sel = g.add(scene::SceneNode::SELECTION);
  scene::SelectionPayload s = test::lassoPayload(model, lasso_view, px);
  s.set_visible_only(true);
  g.setPayload(sel, s);
  std::vector<Highlight> visible = sceneHighlights(g);
  ASSERT_EQ(visible.size(), 1u);
  ASSERT_TRUE(visible[0].visible_only);
  std::vector<Highlight> through = visible;
  through[0].visible_only = false;

  ModelInstance m[] = {{store.get(), storeModel(*store)}};
  m[0].node = model;
  ViewRenderer r(w, h);
  RenderOptions opt;
  opt.pick_ids = true;
  auto hitsOf = [&] {
    std::vector<std::optional<PickHit>> hits(size_t(w) * h);
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) hits[size_t(y) * w + x] = r.pick(x, y);
    return hits;
  };
  r.renderSettled(m, lasso_view, opt);
  const auto lasso_hits = hitsOf();
  auto eyeDepth = [&](const glm::dvec3& p) { return -(lasso_view.view * glm::dvec4(p, 1.0)).z; };
  const Image plain = r.renderSettled(m, other, opt);
  const auto hits = hitsOf();
  opt.highlights = visible;
  const Image tinted = r.renderSettled(m, other, opt);
  opt.highlights = through;
  const Image tinted_through = r.renderSettled(m, other, opt);
  maybeWrite("selection_visible_only", tinted);

  size_t seen = 0, hidden = 0, wrong = 0, through_missing = 0;
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      const auto& hit = hits[size_t(y) * w + x];
      if (!hit) continue;
      const glm::dvec2 at = project(lasso_view, hit->world);
      if (!inside(px, at) || edgeDistance(px, at) < 2.0) continue;
      // The lasso view's surface depths around the pixel the point lands on there.
      const double d = eyeDepth(hit->world);
      double nearest = 1e300, farthest = 0.0;
      bool complete = true;
      for (int dy = -3; dy <= 3; ++dy) {
        for (int dx = -3; dx <= 3; ++dx) {
          const int qx = int(std::floor(at.x)) + dx, qy = int(std::floor(at.y)) + dy;
          if (qx < 0 || qy < 0 || qx >= int(w) || qy >= int(h)) {
            complete = false;
            continue;
          }
          const auto& l = lasso_hits[size_t(qy) * w + size_t(qx)];
          if (!l) {
            complete = false;
            continue;
          }
          nearest = std::min(nearest, eyeDepth(l->world));
          farthest = std::max(farthest, eyeDepth(l->world));
        }
      }
      const uint8_t *a = pixel(plain, int(x), int(y)), *b = pixel(tinted, int(x), int(y)),
                    *t = pixel(tinted_through, int(x), int(y));
      const bool changed = std::memcmp(a, b, 3) != 0;
      through_missing += std::memcmp(a, t, 3) == 0;  // a THROUGH selection tints all of it
      if (complete && d <= nearest * 1.004) {        // no nearer surface around: seen
        ++seen;
        wrong += !changed;
      } else if (d > farthest * 1.03 + 0.005) {  // behind every surface around: hidden
        ++hidden;
        wrong += changed;
      }
    }
  }
  EXPECT_GT(seen, 1000u);
  EXPECT_GT(hidden, 1000u);
  EXPECT_EQ(through_missing, 0u);
  EXPECT_LE(wrong, (seen + hidden) / 500) << "seen " << seen << ", hidden " << hidden;
}

}  // namespace
}  // namespace tessera::render
