// Stanford range scans: the .conf registers 10 real scans onto the published reconstruction.
#include <gtest/gtest.h>

#include <tessera/lod/mesh.h>
#include <tessera/lod/point_reader.h>

#include "../support/mesh_distance.h"

namespace tessera::lod {
namespace {

const std::string kData = TESSERA_DATA_DIR;

TEST(StanfordConf, RegistersTenScansOntoReconstruction) {
  auto reader = openPointReader(kData + "/stanford-bunny/scans/bun.conf");
  const SourceInfo& info = reader->info();
  ASSERT_EQ(info.scans.size(), 10u);
  EXPECT_EQ(info.declared_points, 362272u);
  EXPECT_TRUE(info.attributes & kScanIndex);
  EXPECT_TRUE(info.attributes & kGridPosition);
  for (const ScanInfo& s : info.scans) {
    EXPECT_EQ(s.grid_columns, 512u);
    EXPECT_EQ(s.grid_rows, 400u);
  }
  Mesh recon = readMesh(kData + "/stanford-bunny/reconstruction/bun_zipper.ply");
  test::MeshDistance dist(recon.positions, recon.triangles, 0.004);

  PointBatch batch;
  uint64_t total = 0;
  std::vector<uint64_t> per_scan(10, 0);
  std::vector<double> d;
  std::vector<std::vector<double>> d_scan(10);
  while (reader->next(batch)) {
    for (size_t i = 0; i < batch.size(); ++i) {
      uint16_t s = batch.scan_indices[i];
      ASSERT_LT(s, 10u);
      ++per_scan[s];
      const auto g = batch.grid_positions[i];
      ASSERT_LT(g.x, 512);
      ASSERT_LT(g.y, 400);
      if ((total + i) % 37 == 0) {
        double x = dist.distance(batch.positions[i]);
        d.push_back(x);
        d_scan[s].push_back(x);
      }
    }
    total += batch.size();
  }
  EXPECT_EQ(total, 362272u);
  EXPECT_EQ(reader->stats().skippedTotal(), 0u);
  for (size_t s = 0; s < 10; ++s) EXPECT_EQ(per_scan[s], info.scans[s].points);
  // Registered scan points lie about a millimetre from the merged surface; a wrong rotation
  // convention leaves whole scans centimetres away.
  double med = test::median(d);
  EXPECT_LT(med, 0.0015) << "median distance to bun_zipper.ply: " << med << " m";
  for (size_t s = 0; s < 10; ++s) {
    EXPECT_LT(test::median(d_scan[s]), 0.003) << "scan " << info.scans[s].name;
  }
  std::printf("median distance of registered scans to reconstruction: %.3f mm\n", med * 1000);
}

}  // namespace
}  // namespace tessera::lod
