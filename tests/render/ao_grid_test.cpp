// The multi-view AO grid (render/ao_grid.h) on depth planes written from an analytic square:
// samples land in the cells of their surface points, views facing the surface outweigh grazing
// ones, the picture is shaded by the grid, the same adds give the same grid, bad use is refused.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/render/ao_grid.h>
#include <tessera/render/gl_context.h>

namespace tessera::render {
namespace {

class AoGridTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { sContext = GlContext::createHeadless().release(); }
  static void TearDownTestSuite() { delete sContext; }
  static GlContext* sContext;
};
GlContext* AoGridTest::sContext = nullptr;

constexpr uint32_t kSize = 256;

struct View {
  glm::dmat4 view{1.0}, projection{1.0};
};

/// A camera at `eye` looking at the origin (up +y, or +z when looking along y).
View lookingAtOrigin(const glm::dvec3& eye) {
  View v;
  const glm::dvec3 up = std::abs(glm::normalize(eye).y) > 0.9 ? glm::dvec3(0, 0, 1)
                                                                : glm::dvec3(0, 1, 0);
  v.view = glm::lookAt(eye, glm::dvec3(0.0), up);
  v.projection = glm::perspective(glm::radians(45.0), 1.0, 0.1, 100.0);
  return v;
}

/// `words` into a frame target's plane (immutable storage: copied from a buffer made with them).
void upload(const GlBuffer& plane, const std::vector<uint32_t>& words) {
  const GlBuffer staging(words.size() * 4, words.data());
  glCopyNamedBufferSubData(staging.name(), plane.name(), 0, 0, GLsizeiptr(words.size() * 4));
}

/// The target's depth: the square |x|, |y| < 0.5 on the plane z = 0, seen through `v`; the
/// visibility buffer: `value` where the square is, -1 elsewhere.
GlBuffer drawSquare(FrameTarget& target, const View& v, float value) {
  const glm::dmat4 clip_from_world = v.projection * v.view;
  const glm::dmat4 world_from_clip = glm::inverse(clip_from_world);
  std::vector<uint32_t> depth(target.pixels(), kEmptyDepth);
  std::vector<float> visibility(target.pixels(), -1.0f);
  for (uint32_t y = 0; y < kSize; ++y)
    for (uint32_t x = 0; x < kSize; ++x) {
      const glm::dvec2 ndc((x + 0.5) / kSize * 2.0 - 1.0, (y + 0.5) / kSize * 2.0 - 1.0);
      glm::dvec4 a = world_from_clip * glm::dvec4(ndc, -1.0, 1.0);
      glm::dvec4 b = world_from_clip * glm::dvec4(ndc, 1.0, 1.0);
      const glm::dvec3 pa = glm::dvec3(a) / a.w, pb = glm::dvec3(b) / b.w;
      if (pa.z == pb.z) continue;
      const double t = pa.z / (pa.z - pb.z);
      const glm::dvec3 hit = pa + t * (pb - pa);
      if (t < 0.0 || std::abs(hit.x) >= 0.5 || std::abs(hit.y) >= 0.5) continue;
      const glm::dvec4 clip = clip_from_world * glm::dvec4(hit, 1.0);
      depth[size_t(y) * kSize + x] = std::bit_cast<uint32_t>(float(clip.z / clip.w * 0.5 + 0.5));
      visibility[size_t(y) * kSize + x] = value;
    }
  upload(target.depth(), depth);
  return GlBuffer(visibility.size() * 4, visibility.data());
}

const glm::dvec3 kFacing(0.0, 0.0, 2.0);
// 10 degrees above the square's plane, 2 units away.
const glm::dvec3 kGrazing(0.0, -2.0 * std::cos(glm::radians(10.0)), 2.0 * std::sin(glm::radians(10.0)));

TEST_F(AoGridTest, ASingleViewsVisibilityIsTheGridsWhereItsSamplesLand) {
  FrameTarget target(kSize, kSize);
  AoGrid grid;
  grid.reset(glm::dvec3(0.0), 0.05);
  const View a = lookingAtOrigin(kFacing);
  const GlBuffer vis = drawSquare(target, a, 0.2f);
  grid.add(target, vis, a.projection, a.view, 2);
  EXPECT_GT(grid.cells(), 300u);  // the square's 20 x 20 cells (a few more where it straddles)
  EXPECT_LT(grid.cells(), 700u);
  for (const glm::dvec3& p : {glm::dvec3(0.0), glm::dvec3(0.3, -0.2, 0.0), glm::dvec3(-0.4, 0.4, 0)})
    EXPECT_NEAR(grid.at(p), 0.2f, 2e-3) << p.x << " " << p.y;
  EXPECT_EQ(grid.at(glm::dvec3(3.0, 0.0, 0.0)), -1.0f);  // no sample near
}

TEST_F(AoGridTest, ViewsFacingTheSurfaceOutweighGrazingViews) {
  FrameTarget target(kSize, kSize);
  AoGrid grid;
  grid.reset(glm::dvec3(0.0), 0.05);
  const View b = lookingAtOrigin(kGrazing);
  {
    const GlBuffer vis = drawSquare(target, b, 1.0f);
    grid.add(target, vis, b.projection, b.view, 2);
  }
  EXPECT_NEAR(grid.at(glm::dvec3(0.1, 0.1, 0.0)), 1.0f, 1e-3);
  const View a = lookingAtOrigin(kFacing);
  const GlBuffer vis = drawSquare(target, a, 0.2f);
  grid.add(target, vis, a.projection, a.view, 2);
  // The grazing view's samples (w_n = cos 80 degrees) barely move the facing view's value.
  const float both = grid.at(glm::dvec3(0.1, 0.1, 0.0));
  EXPECT_GT(both, 0.2f);
  EXPECT_LT(both, 0.26f);
  // Shaded from the grid: grey 200 times the grid's value where the square is, the rest as is.
  std::vector<uint32_t> grey(target.pixels(), 200u | 200u << 8 | 200u << 16 | 0xFF000000u);
  upload(target.image(), grey);
  grid.shade(target, a.projection, a.view, 1.0f);
  const Image img = target.readImage();
  const uint8_t centre = img.rgba[(size_t(kSize / 2) * kSize + kSize / 2) * 4];
  EXPECT_NEAR(centre, 200.0 * both, 4.0);
  EXPECT_EQ(img.rgba[0], 200);  // the corner shows no square: left as it was
}

TEST_F(AoGridTest, TheSameAddsGiveTheSameGridAndBadUseIsRefused) {
  FrameTarget target(kSize, kSize);
  const View a = lookingAtOrigin(kFacing), b = lookingAtOrigin(kGrazing);
  AoGrid grid;
  float first = 0.0f;
  for (int round = 0; round < 2; ++round) {
    grid.reset(glm::dvec3(0.0), 0.05);
    for (const View* v : {&a, &b}) {
      const GlBuffer vis = drawSquare(target, *v, v == &a ? 0.3f : 0.9f);
      grid.add(target, vis, v->projection, v->view, 1);
    }
    const float value = grid.at(glm::dvec3(-0.12, 0.07, 0.0));
    if (round == 0) first = value;
    EXPECT_EQ(value, first);
  }
  AoGrid fresh;
  const GlBuffer vis = drawSquare(target, a, 0.5f);
  EXPECT_THROW(fresh.add(target, vis, a.projection, a.view, 2), std::exception);  // not placed
  EXPECT_THROW(fresh.reset(glm::dvec3(0.0), std::nan("")), std::exception);
  EXPECT_THROW(fresh.reset(glm::dvec3(0.0), 0.0), std::exception);
  fresh.reset(glm::dvec3(0.0), 0.05);
  EXPECT_THROW(fresh.add(target, vis, a.projection, a.view, 0), std::exception);
  EXPECT_THROW(fresh.shade(target, a.projection, a.view, std::nanf("")), std::exception);
}

}  // namespace
}  // namespace tessera::render
