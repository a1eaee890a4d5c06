// Measurement (annotate/measurement.h, interact/surface_pick.h) against analytic shapes and real
// data: exact areas of planar polygons, a spherical polygon's area by its spherical excess, a
// cylinder patch, the same sphere as a point store, the full-resolution pick against a brute
// force over every leaf sample of the Autzen LiDAR (georeferenced: millimetres hundreds of km
// from the origin) and the bunny mesh against its input triangles.
#include <tessera/annotate/lasso_selection.h>
#include <tessera/annotate/measurement.h>
#include <tessera/interact/measure_tool.h>
#include <tessera/interact/select_tool.h>
#include <tessera/interact/surface_pick.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/mesh.h>
#include <tessera/lod/mesh_builder.h>
#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/scene_overlay.h>
#include <tessera/sync/scene_edits.h>

#include "../support/temp_dir.h"

namespace tessera::annotate {
namespace {

namespace fs = std::filesystem;
const fs::path kData = TESSERA_DATA_DIR;

std::vector<SurfacePoint> exact(const std::vector<glm::dvec3>& ps) {
  std::vector<SurfacePoint> out;
  for (const glm::dvec3& p : ps) out.push_back({p, 0.0});
  return out;
}

double triangulatedArea(std::span<const glm::dvec3> loop, std::span<const glm::u32vec3> tris) {
  double a = 0.0;
  for (const glm::u32vec3& t : tris)
    a += 0.5 * glm::length(glm::cross(loop[t.y] - loop[t.x], loop[t.z] - loop[t.x]));
  return a;
}

/// The least area over every triangulation of the polygon i..j (exhaustive; small n only).
double bruteMinimum(std::span<const glm::dvec3> p, size_t i, size_t j) {
  if (j - i < 2) return 0.0;
  double best = std::numeric_limits<double>::infinity();
  for (size_t k = i + 1; k < j; ++k)
    best = std::min(best, bruteMinimum(p, i, k) + bruteMinimum(p, k, j) +
                              0.5 * glm::length(glm::cross(p[k] - p[i], p[j] - p[i])));
  return best;
}

TEST(Measure, DistanceAngleAndPolylineWithTheirUncertainties) {
  const SurfacePoint a{{0, 0, 0}, 0.001}, b{{3, 4, 0}, 0.002}, c{{3, 0, 0}, 0.0};
  const Measurement d = distance(a, b);
  EXPECT_DOUBLE_EQ(d.value, 5.0);
  EXPECT_DOUBLE_EQ(d.uncertainty, 0.003);
  const Measurement r = angle(a, c, b);
  EXPECT_NEAR(r.value, M_PI / 2, 1e-15);
  EXPECT_NEAR(r.uncertainty, 0.001 / 3 + 0.002 / 4, 1e-15);
  EXPECT_NEAR(angle(b, a, b).value, 0.0, 1e-15);
  EXPECT_NEAR(angle({{-1, 0, 0}, 0}, {{0, 0, 0}, 0}, {{1, 1e-9, 0}, 0}).value, M_PI - 1e-9, 1e-15);
  // A straight run: the inner point does not move the length to first order; a turn does.
  const std::vector<SurfacePoint> run = {{{0, 0, 0}, 0.01}, {{1, 0, 0}, 0.01}, {{2, 0, 0}, 0.01}};
  const Measurement l = polylineLength(run);
  EXPECT_DOUBLE_EQ(l.value, 2.0);
  EXPECT_NEAR(l.uncertainty, 0.02, 1e-15);
  const std::vector<SurfacePoint> turn = {{{0, 0, 0}, 0.0}, {{1, 0, 0}, 0.01}, {{1, 1, 0}, 0.0}};
  EXPECT_NEAR(polylineLength(turn).uncertainty, 0.01 * std::sqrt(2.0), 1e-15);
}

TEST(Measure, BadPointsAreRefusedNamingWhat) {
  const SurfacePoint ok{{0, 0, 0}, 0.0}, nan{{std::nan(""), 0, 0}, 0.0};
  EXPECT_THROW(distance(ok, nan), MeasureError);
  EXPECT_THROW(distance(ok, {{1, 0, 0}, -1.0}), MeasureError);
  EXPECT_THROW(distance(ok, {{1, 0, 0}, std::numeric_limits<double>::infinity()}), MeasureError);
  EXPECT_THROW(angle(ok, ok, {{1, 0, 0}, 0}), MeasureError);
  EXPECT_THROW(polylineLength(std::vector<SurfacePoint>{ok}), MeasureError);
  const std::vector<glm::dvec3> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW(minimumAreaTriangulation(two), MeasureError);
  std::vector<glm::dvec3> long_loop(kMaxAreaLoop + 1, glm::dvec3(0.0));
  try {
    minimumAreaTriangulation(long_loop);
    ADD_FAILURE() << "a loop over the limit";
  } catch (const MeasureError& e) {
    EXPECT_NE(std::string(e.what()).find("at most 1024"), std::string::npos) << e.what();
  }
  const auto flat = [](const glm::dvec3& p) -> std::optional<glm::dvec3> { return p; };
  EXPECT_THROW(surfaceArea(exact({{0, 0, 0}, {1, 0, 0}, {0, std::nan(""), 0}}), flat),
               MeasureError);
  EXPECT_THROW(surfaceArea(exact({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}), SurfaceProjector{}),
               MeasureError);
}

TEST(Measure, MinimumAreaTriangulationIsTheLeastOfAllTriangulations) {
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<glm::dvec3> loop;
    for (int i = 0; i < 8; ++i) loop.push_back({g(rng), g(rng), g(rng)});
    const auto tris = minimumAreaTriangulation(loop);
    ASSERT_EQ(tris.size(), loop.size() - 2);
    EXPECT_NEAR(triangulatedArea(loop, tris), bruteMinimum(loop, 0, loop.size() - 1), 1e-12);
  }
}

TEST(Measure, PlanarPolygonsConvexAndConcaveAreExact) {
  // An L in a tilted plane far from the origin (georeferenced): area 3 (a 2x2 square less 1x1).
  const glm::dvec3 o(512345.0, 5012345.0, 120.0);
  const glm::dvec3 u = glm::normalize(glm::dvec3(1, 1, 0)),
                   v = glm::normalize(glm::dvec3(-1, 1, 2));
  std::vector<glm::dvec3> ell;
  for (auto [x, y] :
       std::vector<std::pair<double, double>>{{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}})
    ell.push_back(o + x * u + y * v);
  const auto plane = [&](const glm::dvec3& p) -> std::optional<glm::dvec3> {
    const glm::dvec3 n = glm::normalize(glm::cross(u, v));
    return p - n * glm::dot(p - o, n);
  };
  const AreaMeasurement a = surfaceArea(exact(ell), plane);
  EXPECT_NEAR(a.value, 3.0, 1e-9);
  EXPECT_LT(a.uncertainty, 1e-9);
  // Picked points with 1 mm uncertainty: the perimeter (8 m) times 1 mm.
  std::vector<SurfacePoint> picked = exact(ell);
  for (SurfacePoint& p : picked) p.uncertainty = 0.001;
  EXPECT_NEAR(surfaceArea(picked, plane).uncertainty, 0.008, 1e-9);
}

/// The area of the spherical polygon through `loop` (on the sphere of `radius` about the
/// origin) bounded by great-circle arcs: R^2 (sum of its angles - (n - 2) pi) (Girard).
double sphericalPolygonArea(const std::vector<glm::dvec3>& loop, double radius) {
  const size_t n = loop.size();
  double sum = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const glm::dvec3 v = glm::normalize(loop[i]);
    const glm::dvec3 a = glm::normalize(loop[(i + n - 1) % n]),
                     b = glm::normalize(loop[(i + 1) % n]);
    const glm::dvec3 ta = glm::normalize(a - v * glm::dot(a, v)),
                     tb = glm::normalize(b - v * glm::dot(b, v));
    sum += std::acos(std::clamp(glm::dot(ta, tb), -1.0, 1.0));
  }
  return radius * radius * (sum - double(n - 2) * M_PI);
}

std::vector<glm::dvec3> latitudeLoop(double radius, double polar, int n) {
  std::vector<glm::dvec3> loop;
  for (int i = 0; i < n; ++i) {
    const double phi = 2.0 * M_PI * i / n;
    loop.push_back(radius * glm::dvec3(std::sin(polar) * std::cos(phi),
                                       std::sin(polar) * std::sin(phi), std::cos(polar)));
  }
  return loop;
}

TEST(Measure, ASphericalCapByItsSphericalExcess) {
  const double radius = 2.0, polar = M_PI / 3;
  const auto loop = latitudeLoop(radius, polar, 48);
  const auto sphere = [&](const glm::dvec3& p) -> std::optional<glm::dvec3> {
    return radius * glm::normalize(p);
  };
  const AreaMeasurement a = surfaceArea(exact(loop), sphere);
  const double reference = sphericalPolygonArea(loop, radius);
  EXPECT_NEAR(a.value, reference, a.uncertainty) << "levels " << a.levels;
  EXPECT_LT(a.uncertainty, 2e-3 * reference) << "the bound is tight enough to be useful";
  EXPECT_GT(a.uncertainty, 0.0) << "a curved surface is not measured exactly";
  // The flat spanning disc would be far off: the refinement brings it onto the sphere.
  const double disc = M_PI * std::pow(radius * std::sin(polar), 2);
  EXPECT_GT(reference - disc, 100 * a.uncertainty);
  // And 48 great-circle arcs come within 1% of the cap they approximate, 2 pi R^2 (1 - cos).
  EXPECT_NEAR(a.value, 2 * M_PI * radius * radius * (1 - std::cos(polar)), 0.01 * reference);
}

TEST(Measure, ACylinderPatchIsArcLengthTimesHeight) {
  const double radius = 2.0, height = 3.0;
  std::vector<glm::dvec3> loop;
  auto at = [&](double phi, double z) {
    return glm::dvec3(radius * std::cos(phi), radius * std::sin(phi), z);
  };
  for (int i = 0; i < 24; ++i) loop.push_back(at(M_PI / 2 * i / 24, 0));
  for (int i = 0; i < 12; ++i) loop.push_back(at(M_PI / 2, height * i / 12));
  for (int i = 24; i > 0; --i) loop.push_back(at(M_PI / 2 * i / 24, height));
  for (int i = 12; i > 0; --i) loop.push_back(at(0, height * i / 12));
  const auto cylinder = [&](const glm::dvec3& p) -> std::optional<glm::dvec3> {
    const glm::dvec2 r(p.x, p.y);
    const glm::dvec2 on = radius * glm::normalize(r);
    return glm::dvec3(on, p.z);
  };
  const AreaMeasurement a = surfaceArea(exact(loop), cylinder);
  const double reference = radius * M_PI / 2 * height;
  EXPECT_NEAR(a.value, reference, a.uncertainty);
  EXPECT_LT(a.uncertainty, 2e-3 * reference);
}

TEST(Measure, MinEdgeStopsRefinementAtTheDataResolution) {
  const auto loop = latitudeLoop(1.0, M_PI / 4, 16);
  const auto sphere = [](const glm::dvec3& p) -> std::optional<glm::dvec3> {
    return glm::normalize(p);
  };
  AreaOptions o;
  o.min_edge = 10.0;  // longer than any edge: nothing is refined
  const AreaMeasurement a = surfaceArea(exact(loop), sphere, o);
  EXPECT_EQ(a.levels, 0);
  EXPECT_EQ(a.triangles.size(), loop.size() - 2);
  // A projector that finds no surface leaves midpoints flat and says so.
  const auto nowhere = [](const glm::dvec3&) -> std::optional<glm::dvec3> { return std::nullopt; };
  const AreaMeasurement b = surfaceArea(exact(loop), nowhere);
  EXPECT_GT(b.unprojected, 0u);
}

// ---- on stores ---------------------------------------------------------------------------

/// Points on the unit sphere (seeded), built into a store in `dir`.
fs::path sphereStore(const fs::path& dir, size_t n) {
  lod::PointBatch b;
  b.reset(0);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t i = 0; i < n; ++i)
    b.positions.push_back(glm::normalize(glm::dvec3(g(rng), g(rng), g(rng))));
  lod::writePly(dir / "sphere.ply", b, glm::dvec3(0.0));
  lod::BuildOptions o;
  o.quiet = true;
  lod::buildStore({dir / "sphere.ply"}, dir / "sphere.tlod", o);
  return dir / "sphere.tlod";
}

TEST(MeasureOnStores, TheCapOfAScannedSphereThroughItsPointStore) {
  test::TempDir dir;
  auto store = lod::PointStore::open(sphereStore(dir.path(), 400000));
  render::ModelInstance m;
  m.store = store.get();
  const SurfaceProjector project = interact::pointSurfaceProjector(m);
  const auto loop = latitudeLoop(1.0, M_PI / 4, 32);
  std::vector<SurfacePoint> picked;
  for (const glm::dvec3& p : loop) picked.push_back({*project(p), 0.0});
  AreaOptions o;
  o.min_edge = interact::dataResolution(m);
  const AreaMeasurement a = surfaceArea(picked, project, o);
  EXPECT_EQ(a.unprojected, 0u);
  const double reference = sphericalPolygonArea(loop, 1.0);
  // The plane fitted to a neighbourhood of radius r sits r^2 / (2R) inside the sphere at
  // most: the relative area error that adds is below 2 r^2 / R^2.
  double r = 0.0;  // the largest fitting radius the projector uses: 4 leaf spacings
  for (lod::NodeId id = 0; id < store->loadedNodes(); ++id)
    if (store->node(id).leaf()) r = std::max(r, 4.0 * double(store->node(id).spacing));
  EXPECT_NEAR(a.value, reference, a.uncertainty + 2 * r * r * reference)
      << a.levels << " levels, uncertainty " << a.uncertainty << ", r " << r;
  EXPECT_LT(a.uncertainty, 0.01 * reference);
}

TEST(MeasureOnStores, FullResolutionPickOnGeoreferencedLidarIsARealSampleNearestTheRay) {
  test::TempDir dir;
  const fs::path las = kData / "lidar/autzen_trim.las";
  lod::BuildOptions bo;
  bo.quiet = true;
  bo.leaf_max = 4096;      // several levels, so the pick must descend
  bo.exact_leaves = true;  // measurement grade (the default): the file's own 0.01 ft integers
  lod::buildStore({las}, dir.path() / "autzen.tlod", bo);
  auto store = lod::PointStore::open(dir.path() / "autzen.tlod");
  ASSERT_GT(store->summary().depth, 2u);
  render::ModelInstance m;
  m.store = store.get();
  m.model = render::storeModel(*store);
  // Every leaf sample, in world coordinates (the brute force's data).
  struct Sample {
    glm::dvec3 world;
    double spacing;
  };
  std::vector<Sample> all;
  std::vector<lod::NodeId> stack = {store->root()};
  while (!stack.empty()) {
    const lod::NodeId id = stack.back();
    stack.pop_back();
    const lod::NodeInfo info = store->node(id);
    if (!info.leaf()) {
      for (lod::NodeId c : store->children(id)) stack.push_back(c);
      continue;
    }
    const auto pts = store->loadChunk(id);
    for (const glm::vec3& p : pts->positions)
      all.push_back({glm::dvec3(m.model * glm::dvec4(pts->offset + glm::dvec3(p), 1.0)),
                     double(info.spacing)});
  }
  ASSERT_EQ(all.size(), store->summary().points);
  // The input points, straight from the file: the pick lands on one within the store's error.
  std::vector<glm::dvec3> input;
  {
    auto reader = lod::openPointReader(las);
    lod::PointBatch b;
    while (reader->next(b))
      for (const glm::dvec3& p : b.positions) input.push_back(reader->info().origin + p);
  }
  interact::PickOptions po;
  po.pixel_angle = 0.5e-3;
  po.radius_px = 3.0;
  po.max_chunks = 100000;
  std::mt19937 rng(3);
  int hits = 0;
  for (int trial = 0; trial < 40; ++trial) {
    // Looking down at a random sample from 300 feet above, slightly oblique.
    const glm::dvec3 target = all[rng() % all.size()].world;
    const glm::dvec3 eye = target + glm::dvec3(20.0, -35.0, 300.0);
    const glm::dvec3 ray = glm::normalize(target - eye);
    const auto pick = interact::pickSurface(std::span(&m, 1), eye, ray, po);
    ASSERT_TRUE(pick) << "trial " << trial;
    ++hits;
    // Brute force, the same rule over every leaf sample: the front-most within the cone, then
    // the nearest to the ray among those within two spacings behind it.
    double front = std::numeric_limits<double>::infinity(), slab = 0;
    for (const Sample& s : all) {
      const glm::dvec3 q = s.world - eye;
      const double t = glm::dot(q, ray);
      const double r = std::max(po.pixel_angle * po.radius_px * t, s.spacing);
      if (t > 0 && glm::dot(q, q) - t * t <= r * r && t < front) {
        front = t;
        slab = 2.0 * std::max(s.spacing, po.pixel_angle * t);
      }
    }
    double best_perp = std::numeric_limits<double>::infinity();
    glm::dvec3 best(0.0);
    for (const Sample& s : all) {
      const glm::dvec3 q = s.world - eye;
      const double t = glm::dot(q, ray);
      const double r = std::max(po.pixel_angle * po.radius_px * t, s.spacing);
      const double perp2 = std::max(glm::dot(q, q) - t * t, 0.0);
      if (t <= 0 || perp2 > r * r || t > front + slab) continue;
      const double perp_px = std::sqrt(perp2) / (po.pixel_angle * t);
      if (perp_px < best_perp) {
        best_perp = perp_px;
        best = s.world;
      }
    }
    EXPECT_EQ(pick->point.world, best) << "trial " << trial;
    // A real input point within the store's stated uncertainty (LAS scale 0.01 ft here).
    double nearest = std::numeric_limits<double>::infinity();
    for (const glm::dvec3& p : input)
      nearest = std::min(nearest, glm::length(p - pick->point.world));
    EXPECT_LE(nearest, pick->point.uncertainty);
    // The store keeps the file's integers (step 0.01 ft); the float positions a pick reads
    // round them by far less than a step.
    EXPECT_LE(nearest, 0.001) << "the file's own points";
  }
  EXPECT_EQ(hits, 40);
  // A ray into the sky from above the highest sample hits nothing.
  const auto top = std::max_element(all.begin(), all.end(), [](const Sample& a, const Sample& b) {
    return a.world.z < b.world.z;
  });
  EXPECT_FALSE(interact::pickSurface(std::span(&m, 1), top->world + glm::dvec3(0, 0, 10),
                                     glm::dvec3(0, 0, 1), po));
}

TEST(MeasureOnStores, MeshPickHitsTheInputTriangleAndItsProjectorTheSurface) {
  test::TempDir dir;
  const fs::path ply = kData / "stanford-bunny/reconstruction/bun_zipper.ply";
  lod::MeshBuildOptions bo;
  bo.quiet = true;
  bo.patch_triangles = 1024;
  lod::buildMeshStore(std::vector<fs::path>{ply}, dir.path() / "b.tmesh", bo);
  auto store = lod::MeshStore::open(dir.path() / "b.tmesh");
  render::ModelInstance m;
  m.mesh = store.get();
  m.model = render::storeModel(*store);
  const lod::Mesh input = lod::readMesh(ply);
  auto corner = [&](const lod::Triangle& t, int k) { return input.origin + input.positions[t[k]]; };
  std::mt19937 rng(5);
  interact::PickOptions po;
  po.max_chunks = 100000;
  const double step = store->summary().step;
  for (int trial = 0; trial < 30; ++trial) {
    const lod::Triangle& t = input.triangles[rng() % input.triangles.size()];
    const glm::dvec3 c = (corner(t, 0) + corner(t, 1) + corner(t, 2)) / 3.0;
    const glm::dvec3 n =
        glm::normalize(glm::cross(corner(t, 1) - corner(t, 0), corner(t, 2) - corner(t, 0)));
    const glm::dvec3 eye = c + 0.3 * n;
    // Brute force over the input triangles: the nearest crossing of the same ray.
    double best = std::numeric_limits<double>::infinity();
    glm::dvec3 best_normal(0.0);
    for (const lod::Triangle& u : input.triangles) {
      const glm::dvec3 a = corner(u, 0), e1 = corner(u, 1) - a, e2 = corner(u, 2) - a;
      const glm::dvec3 pv = glm::cross(-n, e2);
      const double det = glm::dot(e1, pv);
      if (std::abs(det) < 1e-300) continue;
      const glm::dvec3 tv = eye - a;
      const double uu = glm::dot(tv, pv) / det, vv = glm::dot(-n, glm::cross(tv, e1)) / det;
      const double tt = glm::dot(e2, glm::cross(tv, e1)) / det;
      if (uu >= 0 && vv >= 0 && uu + vv <= 1 && tt > 0 && tt < best) {
        best = tt;
        best_normal = glm::normalize(glm::cross(e1, e2));
      }
    }
    const auto pick = interact::pickSurface(std::span(&m, 1), eye, -n, po);
    ASSERT_TRUE(pick);
    EXPECT_TRUE(pick->triangle);
    // The store's vertices sit on a grid of `step`: the hit moves by at most a few steps.
    EXPECT_NEAR(glm::length(pick->point.world - eye), best, 4 * step) << "trial " << trial;
    EXPECT_GT(glm::dot(pick->normal, best_normal), 0.9) << "the same triangle, or its neighbour";
    // The projector brings a point off the surface back onto it (here: onto the same spot).
    const auto on = interact::meshSurfaceProjector(m)(pick->point.world + 0.2 * step * n);
    ASSERT_TRUE(on);
    EXPECT_LT(glm::length(*on - pick->point.world), 2 * step);
  }
}

}  // namespace
}  // namespace tessera::annotate

namespace tessera::annotate {
namespace {

// ---- the tool and its scene nodes --------------------------------------------------------

class MeasureToolTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new test::TempDir();
    lod::MeshBuildOptions bo;
    bo.quiet = true;
    bo.patch_triangles = 1024;
    lod::buildMeshStore(
        std::vector<fs::path>{kData / "stanford-bunny/reconstruction/bun_zipper.ply"},
        sDir->path() / "b.tmesh", bo);
  }
  static void TearDownTestSuite() {
    delete sDir;
    sDir = nullptr;
  }
  void SetUp() override {
    mStore = lod::MeshStore::open(sDir->path() / "b.tmesh");
    mModel.mesh = mStore.get();
    mModel.model = render::storeModel(*mStore);
    const lod::MeshSummary& s = mStore->summary();
    mCentre = s.origin + 0.5 * (s.bbox_min + s.bbox_max);
  }
  /// The pick along the ray from 0.5 m in front of the bunny (+z) through `offset` from its
  /// centre.
  interact::SurfacePick pickAt(glm::dvec2 offset) {
    const glm::dvec3 eye = mCentre + glm::dvec3(0, 0, 0.5);
    const glm::dvec3 target = mCentre + glm::dvec3(offset, 0.0);
    auto p = interact::pickSurface(std::span(&mModel, 1), eye, glm::normalize(target - eye));
    EXPECT_TRUE(p) << offset.x << "," << offset.y;
    return p.value_or(interact::SurfacePick{});
  }
  static inline test::TempDir* sDir = nullptr;
  std::unique_ptr<lod::MeshStore> mStore;
  render::ModelInstance mModel;
  glm::dvec3 mCentre{0.0};
};

// A clip plane (a CLIP node, ModelInstance::clip) makes what it cuts away unpickable:
// the ray through the cut front goes on to the inside of the back, and a plane that removes the
// whole model leaves nothing to pick.
TEST_F(MeasureToolTest, WhatAClipPlaneCutsAwayIsNotPicked) {
  const interact::SurfacePick front = pickAt({0.0, 0.0});
  const double cut_z = front.point.world.z - 0.005;
  const glm::dvec4 keep_behind(0.0, 0.0, -1.0, cut_z);  // keep z <= cut_z
  ASSERT_TRUE(mModel.clip.addGroup(std::span(&keep_behind, 1), false));
  const interact::SurfacePick behind = pickAt({0.0, 0.0});
  EXPECT_LE(behind.point.world.z, cut_z);
  EXPECT_GT(glm::length(behind.point.world - front.point.world), 0.005);
  // Inverted (keep z >= cut_z): the front is there again.
  mModel.clip = {};
  ASSERT_TRUE(mModel.clip.addGroup(std::span(&keep_behind, 1), true));
  EXPECT_LT(glm::length(pickAt({0.0, 0.0}).point.world - front.point.world), 1e-9);
  // Everything cut: nothing to pick.
  mModel.clip = {};
  const glm::dvec4 none(0.0, 0.0, -1.0, mCentre.z - 1.0);
  ASSERT_TRUE(mModel.clip.addGroup(std::span(&none, 1), false));
  const glm::dvec3 eye = mCentre + glm::dvec3(0, 0, 0.5);
  EXPECT_FALSE(interact::pickSurface(std::span(&mModel, 1), eye, glm::dvec3(0, 0, -1)));
}

TEST_F(MeasureToolTest, ADistanceEndsAtItsSecondPointAsANodeEveryTileDraws) {
  sync::SceneGraph g;
  interact::MeasureTool tool;
  EXPECT_FALSE(tool.add(pickAt({0, 0}), g, std::span(&mModel, 1), "console")) << "off";
  EXPECT_EQ(tool.cycle(), interact::MeasureTool::Mode::kDistance);
  const interact::SurfacePick a = pickAt({-0.02, 0.0}), b = pickAt({0.03, 0.01});
  EXPECT_FALSE(tool.add(a, g, std::span(&mModel, 1), "console"));
  EXPECT_EQ(tool.points().size(), 1u);
  const auto id = tool.add(b, g, std::span(&mModel, 1), "console");
  ASSERT_TRUE(id);
  EXPECT_TRUE(tool.points().empty());
  const scene::SceneNode& n = g.node(*id);
  EXPECT_EQ(n.kind(), scene::SceneNode::MEASUREMENT);
  EXPECT_EQ(n.author(), "console");
  EXPECT_EQ(n.name(), "distance 1");
  EXPECT_EQ(g.node(n.parent()).name(), "measurements");
  const scene::MeasurementPayload& m = n.measurement();
  EXPECT_EQ(m.type(), scene::MeasurementPayload::DISTANCE);
  ASSERT_EQ(m.points_size(), 6);
  EXPECT_EQ(glm::dvec3(m.points(0), m.points(1), m.points(2)), a.point.world);
  EXPECT_EQ(glm::dvec3(m.points(3), m.points(4), m.points(5)), b.point.world);
  EXPECT_DOUBLE_EQ(m.value(), glm::length(a.point.world - b.point.world));
  EXPECT_DOUBLE_EQ(m.uncertainty(), a.point.uncertainty + b.point.uncertainty);
  EXPECT_EQ(tool.lastLabel(), render::measurementLabel(m));
  // The node travels: a snapshot applied to another graph holds it unchanged.
  g.takeFrame(1, 0);
  sync::SceneGraph other;
  other.apply(g.snapshot());
  EXPECT_EQ(other.node(*id).measurement().SerializeAsString(), m.SerializeAsString());
}

TEST_F(MeasureToolTest, AnglePathAndAreaOnTheBunnyWithBackspace) {
  sync::SceneGraph g;
  interact::MeasureTool tool;
  const std::span<const render::ModelInstance> models(&mModel, 1);
  tool.setMode(interact::MeasureTool::Mode::kAngle);
  tool.add(pickAt({-0.03, 0.0}), g, models, "site A");
  tool.add(pickAt({0.0, 0.0}), g, models, "site A");
  EXPECT_TRUE(tool.undoPoint());
  tool.add(pickAt({0.0, 0.008}), g, models, "site A");
  const auto angle_id = tool.add(pickAt({0.02, 0.0}), g, models, "site A");
  ASSERT_TRUE(angle_id);
  const auto& am = g.node(*angle_id).measurement();
  EXPECT_EQ(am.type(), scene::MeasurementPayload::ANGLE);
  EXPECT_GT(am.value(), 0.0);
  EXPECT_LT(am.value(), M_PI);

  tool.setMode(interact::MeasureTool::Mode::kPath);
  tool.add(pickAt({-0.02, -0.02}), g, models, "site A");
  EXPECT_FALSE(tool.finish(g, models, "site A")) << "a path needs 2 points";
  tool.add(pickAt({0.0, -0.01}), g, models, "site A");
  tool.add(pickAt({0.02, -0.02}), g, models, "site A");
  const auto path_id = tool.finish(g, models, "site A");
  ASSERT_TRUE(path_id);
  EXPECT_EQ(g.node(*path_id).measurement().points_size(), 9);

  // An area on the bunny's flank: a loop of 12 picks around its middle. Flat across its
  // chords it would be smaller: the surface bulges towards the viewer.
  tool.setMode(interact::MeasureTool::Mode::kArea);
  std::vector<SurfacePoint> loop;
  for (int i = 0; i < 12; ++i) {
    const double phi = 2 * M_PI * i / 12;
    const interact::SurfacePick p = pickAt({0.015 * std::cos(phi), 0.015 * std::sin(phi) - 0.01});
    loop.push_back(p.point);
    tool.add(p, g, models, "site A");
  }
  const auto area_id = tool.finish(g, models, "site A");
  ASSERT_TRUE(area_id);
  const auto& ar = g.node(*area_id).measurement();
  EXPECT_EQ(ar.type(), scene::MeasurementPayload::AREA);
  std::vector<glm::dvec3> world;
  for (const SurfacePoint& p : loop) world.push_back(p.world);
  const auto flat = minimumAreaTriangulation(world);
  const double spanning = triangulatedArea(world, flat);
  EXPECT_GE(ar.value(), spanning * 0.999);
  EXPECT_LT(ar.value(), spanning * 1.5) << "a patch of the bunny, not a crumpled one";
  EXPECT_GT(ar.uncertainty(), 0.0);
  EXPECT_LT(ar.uncertainty(), 0.2 * ar.value());
  EXPECT_EQ(g.children(g.node(*area_id).parent()).size(), 3u);
}

TEST(MeasurementNode, BadPayloadsAreRefusedNamingTheField) {
  sync::SceneGraph g;
  const auto layer = g.add(scene::SceneNode::GROUP);
  const std::vector<glm::dvec3> one = {{0, 0, 0}}, two = {{0, 0, 0}, {1, 0, 0}},
                                three = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  auto refused = [&](scene::MeasurementPayload::Type type, const std::vector<glm::dvec3>& pts,
                     double value, double unc, const std::string& field) {
    const size_t before = g.size();
    try {
      sync::addMeasurement(g, layer, "x", type, pts, value, unc);
      ADD_FAILURE() << field;
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
    EXPECT_EQ(g.size(), before) << "nothing left behind";
  };
  refused(scene::MeasurementPayload::DISTANCE, one, 1.0, 0.0, "measurement.points");
  refused(scene::MeasurementPayload::DISTANCE, three, 1.0, 0.0, "measurement.points");
  refused(scene::MeasurementPayload::ANGLE, two, 1.0, 0.0, "measurement.points");
  refused(scene::MeasurementPayload::AREA, two, 1.0, 0.0, "measurement.points");
  refused(scene::MeasurementPayload::DISTANCE, two, std::nan(""), 0.0, "measurement.value");
  refused(scene::MeasurementPayload::DISTANCE, two, 1.0, -1.0, "measurement.uncertainty");
  refused(scene::MeasurementPayload::DISTANCE, {{0, 0, 0}, {std::nan(""), 0, 0}}, 1.0, 0.0,
          "measurement.points");
  EXPECT_NO_THROW(
      sync::addMeasurement(g, layer, "x", scene::MeasurementPayload::AREA, three, 0.5, 0.01));
}

}  // namespace
}  // namespace tessera::annotate

namespace tessera::annotate {
namespace {

TEST_F(MeasureToolTest, ALassoBecomesASelectionNodeWithItsExactElementsAndItsLasso) {
  sync::SceneGraph g;
  const auto model = g.add(scene::SceneNode::MODEL);
  render::ViewSetup v;
  v.eye_world = mCentre + glm::dvec3(0, 0, 0.5);
  v.view = glm::lookAt(v.eye_world, mCentre, glm::dvec3(0, 1, 0));
  v.projection = glm::perspective(glm::radians(30.0), 4.0 / 3.0, 0.05, 5.0);
  v.width = 400;
  v.height = 300;
  const std::vector<glm::dvec2> box = {{170, 120}, {230, 120}, {230, 180}, {170, 180}};
  const interact::LassoSelectResult r =
      interact::selectWithLasso(g, mModel, model, v, box, "site B");
  ASSERT_NE(r.node, 0u);
  EXPECT_GT(r.count, 100u);
  EXPECT_EQ(r.corrupt, 0u);
  const scene::SceneNode& n = g.node(r.node);
  EXPECT_EQ(n.kind(), scene::SceneNode::SELECTION);
  EXPECT_EQ(n.author(), "site B");
  EXPECT_EQ(g.node(n.parent()).name(), "selections");
  const scene::SelectionPayload& s = n.selection();
  EXPECT_EQ(s.model(), model);
  EXPECT_EQ(s.count(), r.count);
  const std::string& bytes = s.elements();
  const Selection back = Selection::deserialize(
      std::span(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()));
  EXPECT_EQ(back.count(), r.count);
  // Every selected triangle's centroid is inside the box as the view shows it (the selection's
  // own rule), counted against a walk over the leaf triangles.
  const glm::dmat4 vp = v.projection * v.view * mModel.model;
  uint64_t inside = 0;
  std::vector<lod::NodeId> stack = {mStore->root()};
  while (!stack.empty()) {
    const lod::NodeId id = stack.back();
    stack.pop_back();
    if (!mStore->node(id).leaf()) {
      for (lod::NodeId c : mStore->children(id)) stack.push_back(c);
      continue;
    }
    const lod::MeshPatch p = mStore->readPatch(id);
    for (uint32_t t = 0; t < p.triangles(); ++t) {
      glm::dvec3 c(0.0);
      for (int k = 0; k < 3; ++k)
        c += (p.offset + glm::dvec3(p.positions[p.indices[3 * t + k]])) / 3.0;
      const glm::dvec4 q = vp * glm::dvec4(c, 1.0);
      const double x = (q.x / q.w * 0.5 + 0.5) * v.width, y = (0.5 - q.y / q.w * 0.5) * v.height;
      const bool in = q.w > 0 && x > 170 && x < 230 && y > 120 && y < 180;
      inside += in;
      EXPECT_EQ(back.contains(id, t), in) << "patch " << id << " triangle " << t;
    }
  }
  EXPECT_EQ(inside, r.count);
  // The lasso travels in the view's NDC with the view: the highlight's mask has it.
  ASSERT_EQ(s.lasso_size(), 8);
  EXPECT_DOUBLE_EQ(s.lasso(0), 170.0 / 400 * 2 - 1);
  EXPECT_DOUBLE_EQ(s.lasso(1), 1 - 120.0 / 300 * 2);
  const auto highlights = render::sceneHighlights(g);
  ASSERT_EQ(highlights.size(), 1u);
  size_t set = 0;
  for (uint32_t word : *highlights[0].mask) set += size_t(__builtin_popcount(word));
  const double share =
      double(set) / (double(render::kHighlightMaskSize) * render::kHighlightMaskSize);
  EXPECT_NEAR(share, (60.0 / 400) * (60.0 / 300), 0.002);
  // A lasso off the model selects nothing and makes nothing.
  const std::vector<glm::dvec2> empty_box = {{0, 0}, {10, 0}, {10, 10}};
  const size_t before = g.size();
  EXPECT_EQ(interact::selectWithLasso(g, mModel, model, v, empty_box, "site B").node, 0u);
  EXPECT_EQ(g.size(), before);
}

}  // namespace
}  // namespace tessera::annotate
