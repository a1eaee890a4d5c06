// The E57 reader (lod/src/e57_reader.cpp) on the E57 files in ../shared/data/e57: the bunny as
// doubles lies on the Stanford reconstruction's surface (an independent copy of the same
// model), the coloured cube as floats on the unit cube's faces in its colours, a scan with no
// points and a file with no scans read empty, a page whose CRC-32C does not match is refused by
// page, and damaged copies are refused or read without a crash or a hang.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <random>
#include <set>

#include <tessera/lod/point_reader.h>

#include "../support/read_all.h"

namespace tessera::lod {
namespace {

const std::string kE57 = std::string(TESSERA_DATA_DIR) + "/e57/";

std::vector<uint8_t> bytesOf(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

TEST(E57Reader, TheBunnyLiesOnTheReconstructionsSurface) {
  const auto r = test::readAll(kE57 + "bunnyDouble.e57");
  EXPECT_EQ(r.info.format, Format::kE57);
  ASSERT_EQ(r.points.size(), 30571u);
  ASSERT_EQ(r.info.scans.size(), 1u);
  EXPECT_EQ(r.info.scans[0].name, "bunny");
  EXPECT_EQ(r.stats.skippedTotal(), 0u);
  // Nearest vertex of the reconstruction (35,947 vertices) through a 2 mm grid.
  const auto mesh = test::readAll(std::string(TESSERA_DATA_DIR) +
                                  "/stanford-bunny/reconstruction/bun_zipper.ply");
  const double cell = 0.002;
  std::map<std::array<int64_t, 3>, std::vector<glm::dvec3>> grid;
  auto key = [&](const glm::dvec3& p) {
    return std::array<int64_t, 3>{int64_t(std::floor(p.x / cell)), int64_t(std::floor(p.y / cell)),
                                  int64_t(std::floor(p.z / cell))};
  };
  for (const glm::dvec3& v : mesh.points.positions) grid[key(v)].push_back(v);
  std::vector<double> distances;
  for (size_t i = 0; i < r.points.size(); ++i) {
    const glm::dvec3 p = r.points.positions[i];
    const auto k = key(p);
    double best = 1e9;
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dz = -1; dz <= 1; ++dz)
          if (auto it = grid.find({k[0] + dx, k[1] + dy, k[2] + dz}); it != grid.end())
            for (const glm::dvec3& v : it->second) best = std::min(best, glm::length(p - v));
    distances.push_back(best);
  }
  std::sort(distances.begin(), distances.end());
  const double median = distances[distances.size() / 2];
  const double p99 = distances[distances.size() * 99 / 100];
  std::printf("bunny: nearest reconstruction vertex, median %.3g m, p99 %.3g m, max %.3g m\n",
              median, p99, distances.back());
  // The scan's points are the reconstruction's vertices to the PLY's float precision (a few
  // hundredths of them lie up to 3 mm off, on parts the two versions of the model differ in).
  EXPECT_LT(median, 2e-6);
  EXPECT_LT(p99, 1e-5);
  EXPECT_LT(distances.back(), 0.005);
}

TEST(E57Reader, TheColouredCubeIsOnItsFacesInItsColours) {
  const auto r = test::readAll(kE57 + "ColouredCubeFloat.e57");
  ASSERT_EQ(r.points.size(), 7680u);
  ASSERT_TRUE(r.points.attributes & kColor);
  std::set<uint32_t> colours;
  for (size_t i = 0; i < r.points.size(); ++i) {
    const glm::dvec3 p = r.points.positions[i];
    const double face = std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)});
    EXPECT_NEAR(face, 0.5, 1e-6) << "point " << i;
    const glm::u8vec4 c = r.points.colors[i];
    colours.insert(uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16);
  }
  EXPECT_GE(colours.size(), 3u);
}

TEST(E57Reader, EmptyScansAndFilesReadEmpty) {
  const auto zero = test::readAll(kE57 + "ZeroPoints.e57");
  EXPECT_EQ(zero.points.size(), 0u);
  EXPECT_EQ(zero.info.scans.size(), 1u);
  const auto none = test::readAll(kE57 + "empty.e57");
  EXPECT_EQ(none.points.size(), 0u);
  EXPECT_TRUE(none.info.scans.empty());
}

TEST(E57Reader, APageWithABadChecksumIsRefusedByPage) {
  try {
    test::readAll(kE57 + "bad-crc.e57");
    ADD_FAILURE() << "a page with a bad CRC was read";
  } catch (const ReadError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("bad-crc.e57"), std::string::npos) << what;
    EXPECT_NE(what.find("page 0"), std::string::npos) << what;
    EXPECT_NE(what.find("CRC-32C"), std::string::npos) << what;
  }
}

// Seeded damage (bytes overwritten, the file cut short) of real E57 files, read from memory:
// a ReadError naming the file or points read, never a crash or a hang. The page checksums
// catch most of it; what they cannot (a cut at a page boundary) the structure checks do.
TEST(E57Reader, DamagedCopiesAreRefusedOrReadWithoutACrash) {
  int refused = 0, read = 0;
  for (const char* name : {"bunnyDouble.e57", "ColouredCubeFloat.e57"}) {
    const std::vector<uint8_t> pristine = bytesOf(kE57 + name);
    for (uint32_t seed = 0; seed < 60; ++seed) {
      std::vector<uint8_t> bytes = pristine;
      std::mt19937 rng(seed);
      if (seed % 3 == 0) {
        bytes.resize(size_t(rng() % bytes.size()));
      } else {
        const size_t at = rng() % bytes.size();
        for (size_t i = 0; i < 16 && at + i < bytes.size(); ++i) bytes[at + i] = uint8_t(rng());
      }
      try {
        auto reader = openPointReader(std::span<const uint8_t>(bytes), name);
        PointBatch b;
        while (reader->next(b)) {
        }
        ++read;
      } catch (const ReadError& e) {
        EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
        ++refused;
      }
    }
  }
  std::printf("%d damaged copies refused, %d read\n", refused, read);
  EXPECT_GT(refused, 100);
}

}  // namespace
}  // namespace tessera::lod
