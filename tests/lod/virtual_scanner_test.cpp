// The virtual scanner: points lie on the scanned surface within the noise, outputs load through
// the .conf reader with their grid cells, and the same seed gives the same scans.
#include <gtest/gtest.h>

#include <tessera/lod/mesh.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/virtual_scanner.h>

#include "../support/mesh_distance.h"
#include "../support/read_all.h"
#include "../support/temp_dir.h"

namespace tessera::lod {
namespace {

const std::string kData = TESSERA_DATA_DIR;

struct Distances {
  std::vector<double> d;
  uint64_t points = 0;
};

Distances scanAndMeasure(const Mesh& mesh, const test::MeshDistance& dist, const ScanOptions& o,
                         const std::filesystem::path& dir) {
  ScanResult r = scanMesh(mesh, dir, o);
  auto read = test::readAll(r.conf, 50000);
  EXPECT_EQ(read.points.size(), r.points);
  EXPECT_EQ(read.info.scans.size(), size_t(o.scanners));
  EXPECT_TRUE(read.info.attributes & kGridPosition);
  Distances out;
  out.points = read.points.size();
  for (size_t i = 0; i < read.points.size(); i += 41)
    out.d.push_back(dist.distance(read.points.positions[i]));
  return out;
}

class VirtualScanner : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sMesh = new Mesh(readMesh(kData + "/stanford-bunny/reconstruction/bun_zipper.ply"));
    sDist = new test::MeshDistance(sMesh->positions, sMesh->triangles, 0.004);
  }
  static void TearDownTestSuite() {
    delete sDist;
    delete sMesh;
  }
  static Mesh* sMesh;
  static test::MeshDistance* sDist;
};
Mesh* VirtualScanner::sMesh = nullptr;
test::MeshDistance* VirtualScanner::sDist = nullptr;

TEST_F(VirtualScanner, NoiselessPointsLieOnTheMesh) {
  test::TempDir dir;
  ScanOptions o;
  o.scanners = 4;
  o.columns = 256;
  o.rows = 200;
  o.quiet = true;
  Distances m = scanAndMeasure(*sMesh, *sDist, o, dir.path());
  EXPECT_GT(m.points, 20000u);
  double worst = *std::max_element(m.d.begin(), m.d.end());
  // ASCII %.9g and float ray casting: micrometres on a 15 cm model.
  EXPECT_LT(worst, 2e-6) << "max distance " << worst;
}

TEST_F(VirtualScanner, NoiseHasTheRequestedSpread) {
  test::TempDir dir;
  ScanOptions o;
  o.scanners = 3;
  o.columns = 200;
  o.rows = 160;
  o.noise_mm = 0.5;
  o.binary = true;
  o.quiet = true;
  Distances m = scanAndMeasure(*sMesh, *sDist, o, dir.path());
  // Range noise sigma along the ray: distance to the surface is |N(0, sigma)| * cos(incidence),
  // whose median is at most 0.674 sigma (0.34 mm) and, for mostly frontal rays, not far below.
  double med = test::median(m.d);
  EXPECT_GT(med, 0.10e-3) << med;
  EXPECT_LT(med, 0.34e-3) << med;
}

TEST_F(VirtualScanner, PanoramicScannersSeeTheInside) {
  test::TempDir dir;
  ScanOptions o;
  o.scanners = 2;
  o.columns = 360;
  o.rows = 150;
  o.panoramic = true;
  o.quiet = true;
  Distances m = scanAndMeasure(*sMesh, *sDist, o, dir.path());
  // From inside a closed-ish surface almost every ray hits something.
  EXPECT_GT(m.points, uint64_t(0.5 * 2 * 360 * 150));
  EXPECT_LT(*std::max_element(m.d.begin(), m.d.end()), 2e-6);
}

TEST_F(VirtualScanner, SameSeedSameScans) {
  test::TempDir a, b, c;
  ScanOptions o;
  o.scanners = 2;
  o.columns = 64;
  o.rows = 64;
  o.noise_mm = 1.0;
  o.quiet = true;
  scanMesh(*sMesh, a.path(), o);
  o.threads = 1;
  scanMesh(*sMesh, b.path(), o);
  o.seed = 2;
  scanMesh(*sMesh, c.path(), o);
  EXPECT_EQ(test::readBytes(a / "scan_001.ply"), test::readBytes(b / "scan_001.ply"));
  EXPECT_NE(test::readBytes(a / "scan_001.ply"), test::readBytes(c / "scan_001.ply"));
  EXPECT_EQ(test::readBytes(a / "scans.conf"), test::readBytes(b / "scans.conf"));
}

}  // namespace
}  // namespace tessera::lod
