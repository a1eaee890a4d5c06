// Ambient occlusion of range scans (lod/ambient_occlusion.h): analytic shapes scanned by
// perspective scanners in memory, and the ten Stanford bunny scans against the Embree reference.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <optional>
#include <tuple>

#include <glm/gtc/quaternion.hpp>

#include <tessera/core/symmetric_eigen.h>
#include <tessera/lod/ambient_occlusion.h>
#include <tessera/lod/mesh.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/store_builder.h>
#include <tessera/lod/store_format.h>

#include "../support/command.h"
#include "../support/temp_dir.h"

namespace tessera::lod {
namespace {

const std::string kData = TESSERA_DATA_DIR;

/// A rectangle: corner + s * u + t * v for s, t in [0, 1].
struct Rect {
  glm::dvec3 corner, u, v;
};

std::optional<double> hit(const Rect& r, const glm::dvec3& o, const glm::dvec3& d) {
  glm::dvec3 n = glm::cross(r.u, r.v);
  double den = glm::dot(n, d);
  if (std::abs(den) < 1e-12) return std::nullopt;
  double t = glm::dot(n, r.corner - o) / den;
  if (t <= 1e-9) return std::nullopt;
  glm::dvec3 q = o + t * d - r.corner;
  double s = glm::dot(q, r.u) / glm::dot(r.u, r.u), w = glm::dot(q, r.v) / glm::dot(r.v, r.v);
  if (s < 0 || s > 1 || w < 0 || w > 1) return std::nullopt;
  return t;
}

/// A perspective scanner at `eye` looking at `target` (its frame: -z forward, +y up), ray-cast
/// against `scene`: the test's own scanner, independent of the library.
GridScan scanRects(const std::string& name, const std::vector<Rect>& scene, glm::dvec3 eye,
                   glm::dvec3 target, uint32_t cols, uint32_t rows, double half_fov_deg) {
  glm::dvec3 back = glm::normalize(eye - target);
  glm::dvec3 hint = std::abs(back.y) > 0.95 ? glm::dvec3(0, 0, 1) : glm::dvec3(0, 1, 0);
  glm::dvec3 right = glm::normalize(glm::cross(hint, back));
  glm::dvec3 up = glm::cross(back, right);
  glm::dmat3 rot(right, up, back);
  GridScan g;
  g.name = name;
  g.pose.translation = eye;
  g.pose.rotation = glm::quat_cast(rot);
  g.columns = cols;
  g.rows = rows;
  const double th = std::tan(half_fov_deg * std::numbers::pi / 180.0);
  for (uint32_t r = 0; r < rows; ++r)
    for (uint32_t c = 0; c < cols; ++c) {
      glm::dvec3 ld = glm::normalize(glm::dvec3((2.0 * (c + 0.5) / cols - 1.0) * th,
                                                (1.0 - 2.0 * (r + 0.5) / rows) * th, -1.0));
      glm::dvec3 wd = rot * ld;
      double best = 1e30;
      for (const Rect& rc : scene)
        if (auto t = hit(rc, eye, wd)) best = std::min(best, *t);
      g.points.push_back(best < 1e30 ? glm::vec3(ld * best) : glm::vec3(NAN));
    }
  return g;
}

/// The point of `set` nearest `p` (registered frame).
size_t nearest(const ScanSet& set, const glm::dvec3& p) {
  size_t best = 0;
  for (size_t i = 1; i < set.size(); ++i)
    if (glm::length(set.positions[i] - p) < glm::length(set.positions[best] - p)) best = i;
  return best;
}

/// Eq. 1 with eq. 4's falloff for a point on a floor (normal +z) at distance s from an infinite
/// wall y = 0 (the floor lies at y > 0): numerical quadrature over the hemisphere. Directions
/// towards the wall meet it at distance s / -w_y.
double wedgeVisibility(double s, double t_max) {
  const int n = 800;
  double sum = 0, norm = 0;
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) {
      double theta = (a + 0.5) / n * std::numbers::pi / 2,
             phi = (b + 0.5) / n * 2 * std::numbers::pi;
      glm::dvec3 w(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                   std::cos(theta));
      double weight = std::cos(theta) * std::sin(theta);
      double v = 1.0;
      if (w.y < 0) {
        double x = std::clamp(s / -w.y / t_max, 0.0, 1.0);
        v = x * x * (3 - 2 * x);
      }
      sum += weight * v;
      norm += weight;
    }
  return sum / norm;
}

TEST(AmbientOcclusionTest, TheNormalIsTheSmallestEigenvectorOfTheCovariance) {
  // core/symmetric_eigen.h, shared with the surface pick: a rotated diagonal matrix R D R^T has
  // the column of R that belongs to D's smallest entry as that eigenvector.
  const glm::dmat3 r = glm::mat3_cast(glm::angleAxis(0.7, glm::normalize(glm::dvec3(1, 2, 3))));
  for (int smallest = 0; smallest < 3; ++smallest) {
    glm::dmat3 d(0.0);
    for (int k = 0; k < 3; ++k) d[k][k] = k == smallest ? 1e-4 : 2.0 + k;
    const glm::dvec3 e = tessera::smallestEigenvector(r * d * glm::transpose(r));
    EXPECT_NEAR(std::abs(glm::dot(e, r[smallest])), 1.0, 1e-12) << smallest;
    EXPECT_NEAR(glm::length(e), 1.0, 1e-12);
  }
}

TEST(AmbientOcclusionTest, AFlatPlaneIsOpen) {
  std::vector<Rect> floor = {{{-1, -1, 0}, {2, 0, 0}, {0, 2, 0}}};
  ScanSet set = makeScanSet({scanRects("plane", floor, {0.3, 0.4, 1.5}, {0, 0, 0}, 96, 96, 25)});
  AoOptions o;
  o.t_max = 0.2;
  o = resolveAoOptions(set, o);
  EXPECT_EQ(set.maps[0].projection, ScanProjection::kPerspective);
  EXPECT_LT(set.maps[0].fit_rms_px, 0.01);
  for (AoMethod m : {AoMethod::kSsao, AoMethod::kMvao, AoMethod::kGrid}) {
    std::vector<float> ao = computeAmbientOcclusion(set, m, o);
    for (float v : ao) ASSERT_GT(v, 0.99f);
  }
  std::vector<uint32_t> some = {0, uint32_t(set.size() / 2), uint32_t(set.size() - 1)};
  for (float v : referenceAo(set, some, 256, o)) EXPECT_GT(v, 0.999f);
}

/// Floor z = 0 (y in [0, 1]) and wall y = 0 (z in [0, 1]): a 90-degree concave corner along x,
/// scanned from the floor's side and from the wall's side.
struct Corner {
  ScanSet set;
  AoOptions o;
  Corner() {
    std::vector<Rect> scene = {{{-1, 0, 0}, {2, 0, 0}, {0, 1, 0}},
                               {{-1, 0, 0}, {2, 0, 0}, {0, 0, 1}}};
    set = makeScanSet({scanRects("a", scene, {0.1, 0.9, 0.5}, {0, 0.1, 0.1}, 160, 160, 35),
                       scanRects("b", scene, {-0.1, 0.5, 0.9}, {0, 0.1, 0.1}, 160, 160, 35)});
    o.t_max = 0.2;
    o.samples = 64;
    o.radius = 0;
    o = resolveAoOptions(set, o);
  }
};

TEST(AmbientOcclusionTest, ACornerGivesTheCosineWeightedWedgeAtTheCrease) {
  Corner c;
  // The analytic value is 1/2 on the crease (the wall hides half the cosine-weighted
  // hemisphere, and rho(0) = 0); a little above at the distance of the nearest points.
  const size_t i = nearest(c.set, {0, 0.01, 0});
  const double s = c.set.positions[i].y;
  const double analytic = wedgeVisibility(s, c.o.t_max);
  EXPECT_NEAR(wedgeVisibility(0.0, c.o.t_max), 0.5, 1e-6);
  ASSERT_LT(s, 0.02);
  std::vector<uint32_t> pts = {uint32_t(i)};
  const float ref = referenceAo(c.set, pts, 1024, c.o)[0];
  EXPECT_NEAR(ref, analytic, 0.03) << "s " << s;
  std::vector<float> ssao = computeAmbientOcclusion(c.set, AoMethod::kSsao, c.o);
  std::vector<float> mvao = computeAmbientOcclusion(c.set, AoMethod::kMvao, c.o);
  std::printf("corner: s %.4f analytic %.3f reference %.3f ssao %.3f mvao %.3f\n", s, analytic, ref,
              ssao[i], mvao[i]);
  // Where the screen-space estimate fails: its samples count the wall by the distance to the
  // sampled point, not along the ray, and the disk (r_s = t_max / 2) and the 5x5 blur reach
  // the open floor; at the crease it reads about 0.82 where the truth is 0.55 (measured:
  // ssao 0.818, mvao 0.818, reference 0.549, analytic 0.551). Both views agree, so the
  // integration cannot fix it.
  EXPECT_NEAR(ssao[i], analytic, 0.3);
  EXPECT_NEAR(mvao[i], analytic, 0.3);
  // Far from the crease (more than t_max) the floor is open; the crease is clearly darker.
  const size_t far = nearest(c.set, {0, 0.5, 0});
  EXPECT_GT(mvao[far], 0.98f);
  EXPECT_LT(mvao[i], mvao[far] - 0.1f);
}

TEST(AmbientOcclusionTest, BadParametersAreRefusedByName) {
  Corner c;
  for (double bad : {std::nan(""), -1.0, HUGE_VAL}) {
    AoOptions o;
    o.t_max = bad;
    try {
      resolveAoOptions(c.set, o);
      FAIL() << "accepted t_max " << bad;
    } catch (const AoError& e) {
      EXPECT_NE(std::string(e.what()).find("t_max"), std::string::npos) << e.what();
    }
  }
  AoOptions o;
  o.neighbours = 4;
  EXPECT_THROW(resolveAoOptions(c.set, o), AoError);
  o = {};
  o.samples = 0;
  EXPECT_THROW(resolveAoOptions(c.set, o), AoError);
  for (double bad : {std::nan(""), -0.1, 0.5}) {
    o = {};
    o.angle_bias = bad;
    EXPECT_THROW(resolveAoOptions(c.set, o), AoError) << bad;
  }
}

TEST(AmbientOcclusionTest, AThinFinSeenEdgeOnIsMissedByItsViewAndRecoveredByTheOthers) {
  // A floor and a thin vertical fin (x = 0, 0.3 high). From straight above the fin is an edge
  // of no width: that view's depth map has no occluder, its SSAO says the floor beside the fin
  // is open. Two side views see the fin's faces; the integration takes their AO.
  std::vector<Rect> scene = {{{-1, -1, 0}, {2, 0, 0}, {0, 2, 0}},
                             {{0, -1, 0}, {0, 2, 0}, {0, 0, 0.3}}};
  std::vector<GridScan> scans = {
      scanRects("top", scene, {0.001, 0.02, 2.0}, {0.001, 0, 0}, 200, 200, 20),
      scanRects("east", scene, {1.0, 0.1, 0.9}, {0.1, 0, 0}, 200, 200, 30),
      scanRects("west", scene, {-1.0, -0.1, 0.9}, {-0.1, 0, 0}, 200, 200, 30)};
  AoOptions o;
  o.t_max = 0.2;
  auto floorErrors = [&](ScanSet& set) {
    AoOptions r = resolveAoOptions(set, o);
    std::vector<uint32_t> pts;
    for (uint32_t i = 0; i < set.size(); ++i) {
      const glm::dvec3& p = set.positions[i];
      if (set.scan_of_point[i] == 0 && std::abs(p.z) < 1e-6 && std::abs(p.x) > 0.01 &&
          std::abs(p.x) < 0.05 && std::abs(p.y) < 0.5)
        pts.push_back(i);
    }
    std::vector<float> ref = referenceAo(set, pts, 256, r);
    std::vector<float> ssao = computeAmbientOcclusion(set, AoMethod::kSsao, r);
    std::vector<float> mvao = computeAmbientOcclusion(set, AoMethod::kMvao, r);
    double es = 0, em = 0, mean_ref = 0;
    for (size_t k = 0; k < pts.size(); ++k) {
      es += std::abs(ssao[pts[k]] - ref[k]);
      em += std::abs(mvao[pts[k]] - ref[k]);
      mean_ref += ref[k];
    }
    const double n = double(std::max<size_t>(1, pts.size()));
    std::printf("fin: %zu points, reference %.3f, ssao error %.3f, mvao error %.3f\n", pts.size(),
                mean_ref / n, es / n, em / n);
    return std::tuple{pts.size(), mean_ref / n, es / n, em / n};
  };
  ScanSet all = makeScanSet(scans);
  auto [n, ref, ssao_err, mvao_err] = floorErrors(all);
  ASSERT_GT(n, 20u);
  // Measured: reference 0.862, ssao error 0.138, mvao error 0.066.
  EXPECT_LT(ref, 0.9);       // the fin occludes the floor beside it
  EXPECT_GT(ssao_err, 0.1);  // the top view does not see it
  EXPECT_LT(mvao_err, 0.6 * ssao_err);
  // With the top view alone the fin is not in the data at all (the reference built from the
  // scans does not know it either): the multi-view value is the single one.
  ScanSet top = makeScanSet({scans[0]});
  auto [n1, ref1, ssao1, mvao1] = floorErrors(top);
  EXPECT_NEAR(mvao1, ssao1, 0.01);
}

struct Errors {
  double mean = 0, p95 = 0, bias = 0;
  size_t n = 0;
};

Errors errors(const std::vector<float>& ao, const std::vector<float>& ref,
              const std::vector<uint32_t>& pts, const std::vector<bool>& keep) {
  std::vector<double> e;
  Errors r;
  for (size_t k = 0; k < pts.size(); ++k)
    if (keep.empty() || keep[k]) {
      e.push_back(std::abs(double(ao[pts[k]]) - ref[k]));
      r.bias += double(ao[pts[k]]) - ref[k];
    }
  r.n = e.size();
  if (e.empty()) return r;
  for (double x : e) r.mean += x;
  r.mean /= double(e.size());
  r.bias /= double(e.size());
  std::sort(e.begin(), e.end());
  r.p95 = e[size_t(0.95 * double(e.size() - 1))];
  return r;
}

struct Bunny {
  ScanSet set;
  Mesh mesh;
  AoOptions o;
  Bunny()
      : set(loadScans(kData + "/stanford-bunny/scans/bun.conf")),
        mesh(readMesh(kData + "/stanford-bunny/reconstruction/bun_zipper.ply")),
        o(resolveAoOptions(set, {})) {}
};

TEST(AmbientOcclusionTest, TheDiscReferenceAgreesWithTheMeshReferenceOnTheBunny) {
  // Two independent references: the scans' own points as discs, and the zippered mesh made
  // from them. Where registered layers of different scans cross, a disc reference that stops
  // at every disc met from behind reads dark specks (measured 0.051 mean |discs - mesh|, mean
  // 0.938 against 0.986, 1.3% of the points 0.3 darker); passing through them and with discs
  // of 0.75 rad(p) it reads 0.0166, 0.9% (ao_reference.cpp). The mesh is the reference the
  // methods are measured against; the discs are the same geometry the scans are.
  Bunny b;
  std::vector<uint32_t> pts;
  for (uint32_t i = 0; i < b.set.size(); i += 64) pts.push_back(i);
  const std::vector<float> discs = referenceAo(b.set, pts, 256, b.o);
  const MeshAoReference mesh = meshReferenceAo(b.set, b.mesh, pts, 256, b.o);
  double diff = 0, mean_d = 0, mean_m = 0, far = 0;
  int dark = 0;
  for (size_t k = 0; k < pts.size(); ++k) {
    diff += std::abs(discs[k] - mesh.ao[k]);
    mean_d += discs[k];
    mean_m += mesh.ao[k];
    far += mesh.distance[k] > 0.001;  // a millimetre off the reconstruction
    dark += discs[k] < mesh.ao[k] - 0.3f;
  }
  const double n = double(pts.size());
  std::printf("discs %.4f mesh %.4f, |discs - mesh| %.4f, %d dark specks, %.0f far of %zu\n",
              mean_d / n, mean_m / n, diff / n, dark, far, pts.size());
  EXPECT_LT(diff / n, 0.025);
  EXPECT_NEAR(mean_d / n, mean_m / n, 0.02);
  EXPECT_LT(dark, int(0.011 * n));
  // The scans lie on their reconstruction: the projection onto it moves few points far.
  EXPECT_LT(far, 0.01 * n);
}

TEST(AmbientOcclusionTest, MultiViewIsCloserToTheReferenceThanSingleViewOnTheBunny) {
  Bunny b;
  ASSERT_EQ(b.set.maps.size(), 10u);
  for (auto& m : b.set.maps)
    std::printf("%s %ux%u %s fit %.2f px\n", m.name.c_str(), m.columns, m.rows,
                projectionName(m.projection), m.fit_rms_px);
  std::vector<uint32_t> pts;
  for (uint32_t i = 0; i < b.set.size(); i += 16) pts.push_back(i);
  const MeshAoReference mesh = meshReferenceAo(b.set, b.mesh, pts, 256, b.o);
  const std::vector<float>& ref = mesh.ao;
  for (auto& m : b.set.maps) computeBorders(m);
  std::vector<bool> grazing, border;
  for (uint32_t i : pts) {
    grazing.push_back(grazingPoint(b.set, i));
    border.push_back(borderPoint(b.set, i));
  }
  // Measured against the mesh reference (every 16th point, 256 rays; mean / p95 absolute error),
  // the same at 8, 16, 32 and 64 samples within 0.0002 mean, 0.001 p95:
  //   ssao       all 0.0167 / 0.059   border 0.0165   grazing 0.0127   bias -0.0090
  //   mvao 1x1   all 0.0160 / 0.056   border 0.0156   grazing 0.0129   bias -0.0100
  //   mvao 5x5   all 0.0159 / 0.051   border 0.0157   grazing 0.0131   bias -0.0099
  // MVAO wins on every point and near borders by 4-6% in mean and 14% at the 95th percentile
  // with 5x5 neighbours. The sample count hardly matters: the 5x5 Gaussian removes the
  // sampling noise, and what is left is mostly the estimator's bias (-0.009 of 0.0167),
  // which every view shares and no average of views removes.
  for (int samples : {8, 16, 32, 64}) {
    AoOptions o = b.o;
    o.samples = samples;
    for (size_t j = 0; j < b.set.maps.size(); ++j) computeSsao(b.set.maps[j], uint32_t(j), o);
    std::vector<float> ssao = ownSsao(b.set);
    Errors es = errors(ssao, ref, pts, {}), eg = errors(ssao, ref, pts, grazing),
           eb = errors(ssao, ref, pts, border);
    std::printf("samples %d ssao all %.4f/%.4f grazing %.4f/%.4f border %.4f/%.4f bias %.4f\n",
                samples, es.mean, es.p95, eg.mean, eg.p95, eb.mean, eb.p95, es.bias);
    for (int nb : {1, 3, 5}) {
      o.neighbours = nb;
      std::vector<float> mv = integrateMvao(b.set, o);
      Errors m = errors(mv, ref, pts, {}), mg = errors(mv, ref, pts, grazing),
             mb = errors(mv, ref, pts, border);
      std::printf("  mvao %dx%d all %.4f/%.4f grazing %.4f/%.4f border %.4f/%.4f bias %.4f\n", nb,
                  nb, m.mean, m.p95, mg.mean, mg.p95, mb.mean, mb.p95, m.bias);
      EXPECT_LT(m.mean, 0.97 * es.mean) << samples << " samples, " << nb << "x" << nb;
      EXPECT_LT(m.p95, (nb == 5 ? 0.9 : 0.97) * es.p95)
          << samples << " samples, " << nb << "x" << nb;
      EXPECT_LT(mb.mean, 0.97 * eb.mean)
          << samples << " samples, " << nb << "x" << nb << ", border";
    }
    std::vector<float> gv = gridMvao(b.set, o);
    Errors g = errors(gv, ref, pts, {});
    std::printf("  grid all %.4f/%.4f\n", g.mean, g.p95);
    EXPECT_LT(g.mean, es.mean) << samples << " samples, grid";
  }
}

TEST(AmbientOcclusionTest, OnTheBunnyGrazingPointsTakeTheHeadOnViewsValueAndGainNothing) {
  // Why MVAO does not beat SSAO on points their own scanner sees at more than 60 degrees:
  // the integration does take their value from the views that see them head-on (w_n, eq. 11:
  // the own scan's share of the weight is 0.09 on them, 0.35 on all points), but on the bunny
  // the grazing view's SSAO is not worse than the head-on views' (error 0.0127 against 0.0167
  // on all points: grazing points lie on convex silhouettes, open in every view), and the
  // head-on views carry the same dark bias as every view (the estimator's, -0.009). Measured:
  // grazing ssao 0.0127, mvao 1x1 0.0129.
  Bunny b;
  std::vector<uint32_t> pts;
  for (uint32_t i = 0; i < b.set.size(); i += 16) pts.push_back(i);
  const MeshAoReference mesh = meshReferenceAo(b.set, b.mesh, pts, 256, b.o);
  for (size_t j = 0; j < b.set.maps.size(); ++j) computeSsao(b.set.maps[j], uint32_t(j), b.o);
  for (auto& m : b.set.maps) computeBorders(m);
  std::vector<float> share;
  const std::vector<float> mv = integrateMvao(b.set, b.o, &share);
  const std::vector<float> ssao = ownSsao(b.set);
  std::vector<bool> grazing;
  double share_g = 0, share_all = 0;
  for (uint32_t i : pts) {
    grazing.push_back(grazingPoint(b.set, i));
    share_all += share[i];
    if (grazing.back()) share_g += share[i];
  }
  const Errors sg = errors(ssao, mesh.ao, pts, grazing), sa = errors(ssao, mesh.ao, pts, {});
  const Errors mg = errors(mv, mesh.ao, pts, grazing), ma = errors(mv, mesh.ao, pts, {});
  share_g /= double(sg.n);
  share_all /= double(pts.size());
  std::printf(
      "own share grazing %.3f all %.3f; grazing ssao %.4f mvao %.4f; all ssao %.4f "
      "(bias %.4f) mvao %.4f (bias %.4f)\n",
      share_g, share_all, sg.mean, mg.mean, sa.mean, sa.bias, ma.mean, ma.bias);
  ASSERT_GT(sg.n, 1000u);
  EXPECT_LT(share_g, 0.2);  // head-on views decide grazing points
  EXPECT_LT(share_g, 0.5 * share_all);
  EXPECT_LT(sg.mean, sa.mean);                             // the grazing view is not the problem
  EXPECT_NEAR(mg.mean, sg.mean, 0.1 * sg.mean);            // so there is nothing to gain
  EXPECT_LT(sa.bias, -0.4 * sa.mean);                      // a dark bias is most of the error ...
  EXPECT_NEAR(ma.bias, sa.bias, 0.3 * std::abs(sa.bias));  // ... and every view shares it
}

TEST(AmbientOcclusionTest, WithAnAngleBiasMultiViewWinsOnGrazingPointsToo) {
  // The dark bias every view shares comes from the elevation n . v of samples just above the
  // tangent plane (the normal's error, the scanner's noise): open points read 0.992. With the
  // angle bias 0.1 (AoOptions::angle_bias) they read 0.9975, the bias is gone, and what is left
  // differs between views, which the integration averages out. Measured (every 16th point,
  // mesh reference, 32 samples, mean error): ssao all 0.0105 grazing 0.0095 border 0.0127
  // (bias 0.0008), mvao 1x1 0.0094 / 0.0082 / 0.0106, mvao 5x5 0.0092 / 0.0082 / 0.0106.
  Bunny b;
  std::vector<uint32_t> pts;
  for (uint32_t i = 0; i < b.set.size(); i += 16) pts.push_back(i);
  const MeshAoReference mesh = meshReferenceAo(b.set, b.mesh, pts, 256, b.o);
  AoOptions o = b.o;
  o.angle_bias = 0.1;
  for (size_t j = 0; j < b.set.maps.size(); ++j) computeSsao(b.set.maps[j], uint32_t(j), o);
  for (auto& m : b.set.maps) computeBorders(m);
  std::vector<bool> grazing, border;
  for (uint32_t i : pts) {
    grazing.push_back(grazingPoint(b.set, i));
    border.push_back(borderPoint(b.set, i));
  }
  const std::vector<float> ssao = ownSsao(b.set);
  const Errors sa = errors(ssao, mesh.ao, pts, {}), sg = errors(ssao, mesh.ao, pts, grazing),
               sb = errors(ssao, mesh.ao, pts, border);
  std::printf("bias 0.1 ssao all %.4f grazing %.4f border %.4f (bias %.4f)\n", sa.mean, sg.mean,
              sb.mean, sa.bias);
  EXPECT_LT(std::abs(sa.bias), 0.003);
  for (int nb : {1, 5}) {
    o.neighbours = nb;
    const std::vector<float> mv = integrateMvao(b.set, o);
    const Errors ma = errors(mv, mesh.ao, pts, {}), mg = errors(mv, mesh.ao, pts, grazing),
                 mb = errors(mv, mesh.ao, pts, border);
    std::printf("  mvao %dx%d all %.4f grazing %.4f border %.4f\n", nb, nb, ma.mean, mg.mean,
                mb.mean);
    EXPECT_LT(ma.mean, 0.93 * sa.mean) << nb;
    EXPECT_LT(mg.mean, 0.95 * sg.mean) << nb;
    EXPECT_LT(mb.mean, 0.9 * sb.mean) << nb;
  }
}

/// FNV-1a 64 of a file: the fingerprint of a store built before the AO attribute existed.
uint64_t fnv1a(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  uint64_t h = 0xcbf29ce484222325ull;
  for (char c; in.get(c);) h = (h ^ uint8_t(c)) * 0x100000001b3ull;
  return h;
}

TEST(AmbientOcclusionStoreTest, AStoreWithoutItCarriesNoAoByte) {
  test::TempDir dir;
  BuildOptions b;
  b.quiet = true;
  const auto out = dir.path() / "plain.tlod";
  buildStore({kData + "/stanford-bunny/scans/bun.conf"}, out, b);
  auto store = PointStore::open(out);
  EXPECT_EQ(store->summary().version, store::kVersion);
  EXPECT_FALSE(store->summary().attributes & kAmbientOcclusion);
  EXPECT_TRUE(store->decodeChunk(store->root())->ambient_occlusion.empty());
}

TEST(AmbientOcclusionStoreTest, EveryPointCarriesItsByte) {
  test::TempDir dir;
  const std::string conf = kData + "/stanford-bunny/scans/bun.conf";
  ScanSet set = loadScans(conf);
  AoOptions o = resolveAoOptions(set, {});
  std::vector<float> ao = computeAmbientOcclusion(set, AoMethod::kMvao, o);
  std::vector<uint8_t> bytes;
  for (float v : ao) bytes.push_back(aoByte(v));
  BuildOptions b;
  b.quiet = true;
  b.ambient_occlusion = bytes;
  const auto out = dir.path() / "ao.tlod";
  buildStore({conf}, out, b);
  auto store = PointStore::open(out);
  EXPECT_EQ(store->summary().version, store::kVersion);
  ASSERT_TRUE(store->summary().attributes & kAmbientOcclusion);
  // Leaves hold every input point once: their bytes are the input's, as a multiset.
  std::vector<uint8_t> stored;
  std::vector<NodeId> todo = {store->root()};
  while (!todo.empty()) {
    NodeId id = todo.back();
    todo.pop_back();
    auto kids = store->children(id);
    todo.insert(todo.end(), kids.begin(), kids.end());
    if (!kids.empty()) continue;
    auto chunk = store->decodeChunk(id);
    ASSERT_EQ(chunk->ambient_occlusion.size(), chunk->size());
    stored.insert(stored.end(), chunk->ambient_occlusion.begin(), chunk->ambient_occlusion.end());
  }
  std::sort(stored.begin(), stored.end());
  std::sort(bytes.begin(), bytes.end());
  EXPECT_EQ(stored, bytes);
  // A count that does not match the inputs is refused before anything is written.
  bytes.pop_back();
  b.ambient_occlusion = bytes;
  EXPECT_THROW(buildStore({conf}, dir.path() / "short.tlod", b), ReadError);
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "short.tlod"));
}

TEST(AmbientOcclusionStoreTest, AScanWithoutAGridIsProjectedOrRefusedByName) {
  test::TempDir dir;
  auto writePly = [&](const std::string& name, const std::vector<glm::vec3>& pts) {
    std::ofstream f(dir.path() / name);
    f << "ply\nformat ascii 1.0\nelement vertex " << pts.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    for (auto& p : pts) f << p.x << " " << p.y << " " << p.z << "\n";
  };
  std::vector<glm::vec3> plane, line;
  for (int r = 0; r < 30; ++r)
    for (int c = 0; c < 40; ++c) plane.emplace_back(c * 0.01f, r * 0.01f, 0.0f);
  for (int c = 0; c < 40; ++c) line.emplace_back(c * 0.01f, 0.0f, 0.0f);
  writePly("plain.ply", plane);
  writePly("line.ply", line);
  std::ofstream(dir.path() / "plane.conf") << "bmesh plain.ply 0 0 0 0 0 0 1\n";
  std::ofstream(dir.path() / "line.conf") << "bmesh line.ply 0 0 0 0 0 0 1\n";
  // No range grid: the points are projected along the scanner's view axis into one.
  ScanSet set = loadScans(dir.path() / "plane.conf");
  ASSERT_EQ(set.maps.size(), 1u);
  EXPECT_TRUE(set.maps[0].projected);
  AoOptions o = resolveAoOptions(set, {});
  for (float v : computeAmbientOcclusion(set, AoMethod::kMvao, o)) ASSERT_GT(v, 0.99f);
  RangeMapOptions no_projection;
  no_projection.allow_projection = false;
  EXPECT_THROW(loadScans(dir.path() / "plane.conf", no_projection), AoError);
  // Points on a line have no extent across the view: nothing to project into.
  try {
    loadScans(dir.path() / "line.conf");
    FAIL() << "a scan on a line cannot be projected";
  } catch (const AoError& e) {
    EXPECT_NE(std::string(e.what()).find("line.ply"), std::string::npos) << e.what();
  }
}

TEST(AmbientOcclusionStoreTest, BuildWithAoCarriesItAndRefusesInputsWithoutScans) {
  test::TempDir dir;
  const std::string tool = TESSERA_LOD_TOOL;
  const std::string conf = kData + "/stanford-bunny/scans/bun.conf";
  const auto out = dir.path() / "bunny.tlod";
  test::CommandResult r =
      test::runCommand(tool + " build " + conf + " -o " + out.string() + " --ao --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("ambient occlusion: 10 scans, 362272 points"), std::string::npos) << r.out;
  auto store = PointStore::open(out);
  EXPECT_EQ(store->summary().version, store::kVersion);
  EXPECT_TRUE(store->summary().attributes & kAmbientOcclusion);
  // The same store byte for byte on one thread.
  const auto one = dir.path() / "one.tlod";
  r = test::runCommand(tool + " build " + conf + " -o " + one.string() +
                       " --ao --threads 1 --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(fnv1a(one), fnv1a(out));
  // Points without scans: refused as bad input (exit 1) by name, nothing written.
  const std::string las = kData + "/lidar/autzen_trim.las";
  r = test::runCommand(tool + " build " + las + " -o " + (dir.path() / "las.tlod").string() +
                       " --ao --quiet");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("autzen_trim.las"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("scans with poses"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "las.tlod"));
  // A mesh store cannot carry a point attribute: a command-line error.
  r = test::runCommand(tool + " build " + kData +
                       "/stanford-bunny/reconstruction/bun_zipper_res4.ply -o " +
                       (dir.path() / "m.tmesh").string() + " --ao --quiet");
  EXPECT_EQ(r.code, 2) << r.out;
}

}  // namespace
}  // namespace tessera::lod
