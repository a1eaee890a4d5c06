// See-through rendering (stochastic point-based rendering, Tanaka et al. 2016) against its own
// theory: the paper's Figure 5 experiment (a white plane of uniformly random points parallel to
// the image, black background: mean intensity 255 alpha), the estimators, and determinism.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/spbr.h>
#include <tessera/render/view_renderer.h>

#include "../support/temp_dir.h"

namespace tessera::render {
namespace {

TEST(Spbr, OpacityFormulaAndItsInverseAgree) {
  for (double alpha : {0.05, 0.3, 0.5, 0.9, 0.99}) {
    const double s = 1e-4, S = 1e-2;
    const double n = spbrPointsFor(alpha, s, S);
    EXPECT_NEAR(spbrOpacity(n, s, S), alpha, 1e-12);
  }
  // Eq. 3: for small n, alpha ~ n s / S.
  EXPECT_NEAR(spbrOpacity(2.0, 1e-4, 1.0), 2e-4, 1e-7);
}

TEST(Spbr, NodeParametersKeepCopiesInDistinctEnsembles) {
  const uint32_t L = 64;
  double last_k = 0;
  for (double alpha : {0.1, 0.5, 0.8, 0.95, 0.999}) {
    const SpbrNodeParams p = spbrNodeParams(alpha, 1.0 / (0.01 * 0.01), 0.01, L, 0.5 * L);
    EXPECT_GT(p.k, last_k * 0.999);
    EXPECT_LE(p.k, 0.5 * L + 1e-9);
    EXPECT_GE(p.cross_section, std::numbers::pi * 1e-4 * (1 - 1e-12));
    // The realised opacity, eq. 1 with n = k n_raw / L points per S, in its Poisson limit.
    const double per_area = p.k * 1e4 / L;
    EXPECT_NEAR(1.0 - std::exp(-per_area * p.cross_section), alpha, 0.01 * alpha);
    last_k = p.k;
  }
  EXPECT_EQ(spbrNodeParams(1.0, 1e4, 0.01, L).k, double(L));  // opaque: every ensemble
  // Independent ensembles (k <= 1): the cross-section grows instead.
  const SpbrNodeParams sharp = spbrNodeParams(0.5, 1e4, 0.01, L, 8.0);
  const SpbrNodeParams independent = spbrNodeParams(0.5, 1e4, 0.01, L, 1.0);
  EXPECT_NEAR(independent.k, 1.0, 1e-9);
  EXPECT_NEAR(independent.cross_section / sharp.cross_section, 8.0, 1e-6);
}

TEST(Spbr, SphereDensityMeasuresAUniformPlane) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<glm::vec3> pts(200000);
  for (auto& p : pts) p = {u(rng), u(rng), 0.0f};
  const double expected = 200000.0;  // points per unit area
  EXPECT_NEAR(sphereDensity(pts, 0.01, 1000, 1), expected, 0.02 * expected);
  // Subsampled (the streamer's chunks): same density, wider spheres.
  EXPECT_NEAR(sphereDensity(pts, 0.01, 1000, 1, 20000), expected, 0.03 * expected);
}

TEST(Spbr, DensityRatiosEvenOutAJumpInsideANode) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<glm::vec3> pts;
  for (int i = 0; i < 40000; ++i) pts.push_back({0.5f * u(rng), u(rng), 0.0f});          // left
  for (int i = 0; i < 160000; ++i) pts.push_back({0.5f + 0.5f * u(rng), u(rng), 0.0f});  // 4x
  const double node = sphereDensity(pts, 0.01, 512, 2);
  const std::vector<float> r =
      densityRatios(pts, 0.01, glm::vec3(0.0f), glm::vec3(1.0f, 1.0f, 0.0f), node);
  double left = 0, right = 0;
  size_t nl = 0, nr = 0, border = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (pts[i].x < 0.02f || pts[i].y < 0.02f || pts[i].y > 0.98f || pts[i].x > 0.98f) {
      border += r[i] == 1.0f;  // near the node's faces: the node's own density
      continue;
    }
    if (pts[i].x < 0.45f) left += r[i], ++nl;
    if (pts[i].x > 0.55f) right += r[i], ++nr;
  }
  EXPECT_GT(border, 1000u);
  // k scales by the ratio: four times the points take a quarter of the copies each.
  EXPECT_NEAR((left / nl) / (right / nr), 4.0, 0.4);
}

TEST(Spbr, NormalsOfATiltedPlane) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const glm::vec3 n = glm::normalize(glm::vec3(0.3f, -0.2f, 1.0f));
  const glm::vec3 a = glm::normalize(glm::cross(n, glm::vec3(1, 0, 0))), b = glm::cross(n, a);
  std::vector<glm::vec3> pts(20000);
  for (auto& p : pts) p = u(rng) * a + u(rng) * b;
  const std::vector<uint32_t> packed = estimateNormals(pts, 0.03);
  size_t good = 0;
  for (uint32_t q : packed) {
    const glm::vec3 v(float(int32_t(q << 22) >> 22), float(int32_t(q << 12) >> 22),
                      float(int32_t(q << 2) >> 22));
    good += std::abs(glm::dot(glm::normalize(v), n)) > 0.999f;
  }
  EXPECT_GT(good, pts.size() * 99 / 100);
}

class SpbrRenderTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new test::TempDir();
    sContext = GlContext::createHeadless().release();
  }
  static void TearDownTestSuite() {
    delete sContext;
    delete sDir;
  }
  /// A white unit square of `n` uniformly random points at z = 0.
  static std::filesystem::path plane(size_t n) {
    const auto path = *sDir / ("plane-" + std::to_string(n) + ".tlod");
    if (std::filesystem::exists(path)) return path;
    lod::PointBatch b;
    b.reset(lod::kColor);
    std::mt19937_64 rng(n);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (size_t i = 0; i < n; ++i) {
      b.positions.push_back({u(rng), u(rng), 0.0});
      b.colors.push_back({255, 255, 255, 255});
    }
    lod::writePly(*sDir / "plane.ply", b, glm::dvec3(0.0));
    lod::BuildOptions o;
    o.quiet = true;
    lod::buildStore({*sDir / "plane.ply"}, path, o);
    return path;
  }
  /// Looking straight down at the plane's centre; the plane fills the 512x512 image.
  static ViewSetup topView() {
    config::Camera cam;
    cam.mutable_eye()->set_x(0.5);
    cam.mutable_eye()->set_y(0.5);
    cam.mutable_eye()->set_z(1.0);
    cam.mutable_target()->set_x(0.5);
    cam.mutable_target()->set_y(0.5);
    cam.mutable_up()->set_y(1);
    ViewSetup v;
    v.view = cameraView(cam);
    v.projection = glm::perspective(glm::radians(40.0), 1.0, 0.1, 10.0);
    v.width = v.height = 512;
    v.eye_world = {0.5, 0.5, 1.0};
    return v;
  }
  static double meanIntensity(const Image& img, double* stddev = nullptr) {
    double sum = 0, sum2 = 0;
    const size_t n = size_t(img.width) * img.height;
    for (size_t i = 0; i < n; ++i) {
      const double v = img.rgba[i * 4];
      sum += v;
      sum2 += v * v;
    }
    const double mean = sum / double(n);
    if (stddev) *stddev = std::sqrt(std::max(0.0, sum2 / double(n) - mean * mean));
    return mean;
  }
  static test::TempDir* sDir;
  static GlContext* sContext;
};
test::TempDir* SpbrRenderTest::sDir = nullptr;
GlContext* SpbrRenderTest::sContext = nullptr;

// The paper's Figure 5, at n_raw = 10^6 and L = 64: mean intensity within 2.5% of 255 alpha.
TEST_F(SpbrRenderTest, WhitePlaneShowsTheRequestedOpacity) {
  auto store = lod::PointStore::open(plane(1'000'000));
  const ViewSetup v = topView();
  for (float alpha : {0.05f, 0.2f, 0.5f, 0.8f, 0.95f}) {
    ModelInstance inst{store.get(), storeModel(*store), alpha};
    RenderOptions opt;
    opt.spbr.ensembles = 64;
    opt.spbr.max_k = 1.0;  // independent ensembles: the noise is the binomial's
    ViewRenderer r(v.width, v.height);
    RenderStats st;
    const Image img = r.renderSettled({&inst, 1}, v, opt, &st);
    double sd = 0;
    const double mean = meanIntensity(img, &sd);
    // Independent ensembles: a pixel is the mean of 64 Bernoulli(alpha) draws.
    const double ideal = 255.0 * std::sqrt(alpha * (1.0 - alpha) / 64.0);
    std::printf(
        "alpha %.2f: mean %.2f (theory %.2f), stddev %.2f (independent ensembles: %.2f), "
        "%u ensembles, %.3g copies\n",
        alpha, mean, 255.0 * alpha, sd, ideal, st.ensembles, double(st.copies));
    EXPECT_EQ(st.ensembles, 64u);
    EXPECT_NEAR(mean, 255.0 * alpha, 0.025 * 255.0 * alpha) << "alpha " << alpha;
    EXPECT_LT(sd, 1.5 * ideal) << "ensembles are not independent at alpha " << alpha;
    // The paper's way (fixed cross-sections, copies for k > 1): the same mean, more noise.
    RenderOptions copies = opt;
    copies.spbr.max_k = 1e9;
    ViewRenderer rc(v.width, v.height);
    const double mean_copies = meanIntensity(rc.renderSettled({&inst, 1}, v, copies));
    std::printf("  with copies: mean %.2f\n", mean_copies);
    EXPECT_NEAR(mean_copies, 255.0 * alpha, 0.025 * 255.0 * alpha) << "alpha " << alpha;
  }
}

TEST_F(SpbrRenderTest, ProgressiveRefinementConvergesAndRestartsOnChange) {
  auto store = lod::PointStore::open(plane(1'000'000));
  ViewSetup v = topView();
  v.width = v.height = 128;
  ModelInstance inst{store.get(), storeModel(*store), 0.4f};
  RenderOptions opt;
  opt.spbr.ensembles = 4;
  opt.spbr.progressive_max = 32;
  opt.spbr.max_k = 1.0;  // independent ensembles: the noise falls as 1/sqrt(ensembles)
  ViewRenderer r(v.width, v.height);
  RenderStats st;
  const Image settled = r.renderSettled({&inst, 1}, v, opt, &st);
  EXPECT_EQ(st.ensembles, 32u);
  double sd32 = 0;
  meanIntensity(settled, &sd32);
  r.render({&inst, 1}, v, opt, &st);  // resting: nothing more to draw
  EXPECT_EQ(st.ensembles_drawn, 0u);
  v.view = glm::translate(v.view, glm::dvec3(0.01, 0, 0));  // moved: starts over at 4
  const Image moved = r.render({&inst, 1}, v, opt, &st);
  EXPECT_EQ(st.ensembles, 4u);
  double sd4 = 0;
  meanIntensity(moved, &sd4);
  EXPECT_LT(sd32, 0.5 * sd4) << "32 ensembles average out more noise than 4";
}

TEST_F(SpbrRenderTest, SameInputsGiveTheSamePixelsAndOpacityOneIsOpaque) {
  auto store = lod::PointStore::open(plane(1'000'000));
  ViewSetup v = topView();
  v.width = v.height = 128;
  ModelInstance inst{store.get(), storeModel(*store), 0.5f};
  RenderOptions opt;
  opt.spbr.ensembles = 8;
  ViewRenderer a(128, 128), b(128, 128);
  EXPECT_EQ(a.renderSettled({&inst, 1}, v, opt).rgba, b.renderSettled({&inst, 1}, v, opt).rgba);
  inst.opacity = 1.0f;
  RenderStats st;
  const Image opaque = a.renderSettled({&inst, 1}, v, opt, &st);
  EXPECT_EQ(st.ensembles, 0u);
  EXPECT_GT(meanIntensity(opaque), 254.0);
}

TEST_F(SpbrRenderTest, OpacitiesBeyondTheCopyBudgetAreRefusedWithOnesThatFit) {
  auto store = lod::PointStore::open(plane(1'000'000));
  const ViewSetup v = topView();
  ModelInstance inst{store.get(), storeModel(*store), 0.9f};
  RenderOptions opt;
  opt.spbr.max_copies_per_frame = 100000;
  ViewRenderer r(v.width, v.height);
  try {
    r.renderSettled({&inst, 1}, v, opt);
    FAIL() << "expected a refusal";
  } catch (const RenderError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("at opacity 0.9 fits at"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace tessera::render
