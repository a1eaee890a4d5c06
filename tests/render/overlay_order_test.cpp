// Overlays hide each other by depth as the scene hides them: an opaque video inset hides the
// strokes, dots and labels behind it and not those in front of it, and two insets hide each
// other in depth order whatever order they are drawn in.
#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/render/gl_context.h>
#include <tessera/render/gl_objects.h>
#include <tessera/render/image.h>
#include <tessera/render/overlay_pass.h>
#include <tessera/render/view_renderer.h>

namespace tessera::render {
namespace {

class OverlayOrder : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { sContext = GlContext::createHeadless().release(); }
  static void TearDownTestSuite() { delete sContext; }
  static GlContext* sContext;

  static ViewSetup view() {
    ViewSetup v;
    v.width = 320;
    v.height = 240;
    v.view = glm::lookAt(glm::dvec3(0, 0, 2), glm::dvec3(0), glm::dvec3(0, 1, 0));
    v.projection = glm::perspective(glm::radians(40.0), 320.0 / 240.0, 0.1, 10.0);
    v.eye_world = {0, 0, 2};
    return v;
  }
  /// A square inset of side 0.6 centred on the axis at depth `z`, flat `tint`.
  static OverlayQuad inset(double z, glm::u8vec4 tint) {
    OverlayQuad q;
    q.corners = {glm::dvec3(-0.3, 0.3, z), glm::dvec3(0.3, 0.3, z), glm::dvec3(0.3, -0.3, z),
                 glm::dvec3(-0.3, -0.3, z)};
    q.tint = tint;
    return q;
  }
  /// Pixels of `img` whose colour is `c` (within 8 levels per channel).
  static size_t count(const Image& img, glm::u8vec3 c) {
    size_t n = 0;
    for (size_t i = 0; i < img.rgba.size(); i += 4)
      n += std::abs(img.rgba[i] - c.r) <= 8 && std::abs(img.rgba[i + 1] - c.g) <= 8 &&
           std::abs(img.rgba[i + 2] - c.b) <= 8;
    return n;
  }
  static const uint8_t* at(const Image& img, int x, int y) {
    return &img.rgba[(size_t(y) * img.width + size_t(x)) * 4];
  }
};
GlContext* OverlayOrder::sContext = nullptr;

TEST_F(OverlayOrder, AnOpaqueInsetHidesWhatIsBehindItAndNotWhatIsInFront) {
  const ViewSetup v = view();
  ViewRenderer r(v.width, v.height);
  const glm::u8vec3 red{255, 0, 0}, green{0, 255, 0};
  // A red stroke across the view behind the inset (z = -0.5), a green one in front (z = 0.5).
  auto strokes = [&](bool with_inset) {
    Overlay o;
    if (with_inset) o.quads.push_back(inset(0.0, {40, 40, 200, 255}));
    o.lines.push_back({{-1.0, 0.1, -0.5}, {1.0, 0.1, -0.5}, {255, 0, 0, 255}, 4.0f});
    o.lines.push_back({{-1.0, -0.1, 0.5}, {1.0, -0.1, 0.5}, {0, 255, 0, 255}, 4.0f});
    OverlayLabel behind;
    behind.at = {0.0, 0.2, -0.5};
    behind.text = "behind";
    behind.color = {255, 0, 0, 255};
    behind.background = {255, 0, 0, 255};
    o.labels.push_back(behind);
    return r.render({}, v, RenderOptions{}, nullptr, &o);
  };
  const Image bare = strokes(false), covered = strokes(true);
  const size_t red_bare = count(bare, red), red_covered = count(covered, red);
  const size_t green_bare = count(bare, green), green_covered = count(covered, green);
  std::printf(
      "red (behind the inset): %zu pixels without it, %zu with; green (in front): %zu, %zu\n",
      red_bare, red_covered, green_bare, green_covered);
  // The inset covers the middle of the red stroke (about a third of its length) and the label
  // anchored behind it; the green stroke keeps every pixel.
  EXPECT_LT(red_covered, red_bare * 3 / 4) << "the stroke behind shows through the inset";
  EXPECT_GT(red_covered, red_bare / 10) << "the stroke beside the inset is gone";
  EXPECT_NEAR(double(green_covered), double(green_bare), 0.02 * double(green_bare));
  // Inside the inset's projection, on the red stroke's row: the inset's colour.
  const int cx = int(v.width / 2);
  for (int y = 0; y < int(v.height); ++y) {
    const uint8_t* p = at(covered, cx, y);
    EXPECT_FALSE(p[0] > 200 && p[1] < 60 && p[2] < 60) << "red at (" << cx << ", " << y << ")";
  }
}

TEST_F(OverlayOrder, InsetsHideEachOtherInDepthOrder) {
  const ViewSetup v = view();
  ViewRenderer r(v.width, v.height);
  const glm::u8vec4 near_tint{250, 200, 0, 255}, far_tint{0, 200, 250, 255};
  for (const bool near_first : {true, false}) {
    Overlay o;
    OverlayQuad near = inset(0.3, near_tint), far = inset(-0.3, far_tint);
    for (glm::dvec3& c : far.corners) c *= glm::dvec3(2.0, 2.0, 1.0);  // larger: shows around
    if (near_first) {
      o.quads = {near, far};
    } else {
      o.quads = {far, near};
    }
    const Image img = r.render({}, v, RenderOptions{}, nullptr, &o);
    const uint8_t* centre = at(img, int(v.width / 2), int(v.height / 2));
    EXPECT_EQ(glm::u8vec3(centre[0], centre[1], centre[2]), glm::u8vec3(near_tint))
        << (near_first ? "near first" : "far first");
  }
}

}  // namespace
}  // namespace tessera::render
