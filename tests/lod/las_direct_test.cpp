// The store builder's direct passes over uncompressed LAS records (lod/src/las_direct.cpp): a
// store built from LAS files is the store their LAZ twins make through the reader, byte for
// byte, on any number of threads and with out-of-core chunks; bad files fail as the reader does.
#include <gtest/gtest.h>

#include <cstring>

#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/store_builder.h>

#include "../../lod/src/byte_source.h"
#include "../../lod/src/las_file.h"
#include "../support/temp_dir.h"

namespace tessera::lod {
namespace {

const std::string kData = TESSERA_DATA_DIR;
const std::vector<std::string> kLas = {kData + "/lidar/autzen_trim.las",
                                       kData + "/lidar/1.2-with-color.las"};

/// Copies a LAS file's records into a LAS (laz = false) or LAZ file at `out`.
void copyLas(const std::string& in, const std::filesystem::path& out, bool laz) {
  ByteSource src = ByteSource::openFile(in, "test");
  detail::LasFileWriter w(out, detail::readLasParts(src, "test"), laz, 1, "test");
  detail::forEachRecordBlock(in, 1, [&](const uint8_t* r, uint64_t n) { w.add(r, n); });
  w.commit();
}

TEST(LasDirect, LasInputsBuildTheStoreTheirLazTwinsBuild) {
  test::TempDir dir;
  std::vector<std::filesystem::path> las, laz;
  // Same file names in two folders: the stores' source tables are the same too.
  std::filesystem::create_directories(dir / "las");
  std::filesystem::create_directories(dir / "laz");
  for (const std::string& in : kLas) {
    const std::string name = std::filesystem::path(in).filename().string();
    las.push_back(dir / "las" / name);
    laz.push_back(dir / "laz" / name);
    copyLas(in, las.back(), false);
    copyLas(in, laz.back(), true);
  }
  ASSERT_EQ(openPointReader(laz[0])->info().format, Format::kLaz);
  ASSERT_EQ(openPointReader(las[0])->info().format, Format::kLas);
  BuildOptions o;
  o.quiet = true;
  o.chunk_points = 20000;  // many chunks: counting, distribution and upper levels all matter
  o.leaf_max = 400;
  for (int threads : {1, 2, 3}) {
    o.threads = threads;
    BuildReport r = buildStore(las, dir / "las.tlod", o);
    EXPECT_GT(r.chunks, 5u);
    buildStore(laz, dir / "laz.tlod", o);
    EXPECT_EQ(test::readBytes(dir / "las.tlod"), test::readBytes(dir / "laz.tlod"))
        << threads << " threads";
  }
  // Two inputs with different local origins: every point verifies against the LAS files.
  VerifyReport v = verifyStore(dir / "las.tlod", las, o);
  EXPECT_TRUE(v.ok()) << v.unmatched << " unmatched of " << v.input_points;
  EXPECT_EQ(v.input_points, 110000u + 1065u);
}

/// Overwrites the bounding box a LAS or LAZ header states (the records stay as they are).
void setHeaderBox(const std::filesystem::path& path, const glm::dvec3& lo, const glm::dvec3& hi) {
  std::vector<uint8_t> bytes = test::readBytes(path);
  for (int i = 0; i < 3; ++i) {
    std::memcpy(bytes.data() + 179 + 16 * i, &hi[i], 8);
    std::memcpy(bytes.data() + 187 + 16 * i, &lo[i], 8);
  }
  test::writeBytes(path, bytes);
}

// A LAZ read through its reader takes the bucketed route (the header's box is the cube, pass 1
// counts and writes buckets); its LAS twin is read in place. Every way a bucket group can go
// (one group, many, a chunk above the buckets merging several, a counting cell larger than the
// chunk size split in memory, groups too large for memory spilled to a file) builds the LAS
// twin's store byte for byte, and a header box that lies (too small, or far too large) sends
// the LAZ back to the raw route with the points' own box, as the LAS goes.
TEST(LasDirect, TheBucketedRouteBuildsTheLasTwinsStoreWhateverItsGroups) {
  test::TempDir dir;
  const std::filesystem::path las = dir / "a" / "autzen.las", laz = dir / "b" / "autzen.las";
  std::filesystem::create_directories(las.parent_path());
  std::filesystem::create_directories(laz.parent_path());
  copyLas(kLas[0], las, false);
  copyLas(kLas[0], laz, true);
  struct Case {
    const char* what;
    uint64_t chunk_points, memory_mb;
    int threads;
    int direct_io;  // the block file through the page cache (0) or around it (1)
  };
  const Case cases[] = {{"one chunk above the buckets", 1'000'000, 2048, 2, 0},
                        {"many groups", 20'000, 2048, 3, 1},
                        {"counting cells split in memory", 40, 2048, 2, -1},
                        {"groups spilled to a file", 3'000, 1, 2, 1}};
  auto same = [&](const Case& c, bool bucketed) {
    BuildOptions o;
    o.quiet = true;
    o.leaf_max = 400;
    o.chunk_points = c.chunk_points;
    o.memory_mb = c.memory_mb;
    o.threads = c.threads;
    o.direct_io = c.direct_io;
    const BuildReport from_las = buildStore({las}, dir / "las.tlod", o);
    const BuildReport from_laz = buildStore({laz}, dir / "laz.tlod", o);
    EXPECT_FALSE(from_las.bucketed) << c.what;
    EXPECT_EQ(from_laz.bucketed, bucketed) << c.what;
    EXPECT_EQ(from_las.chunks, from_laz.chunks) << c.what;
    EXPECT_EQ(test::readBytes(dir / "las.tlod"), test::readBytes(dir / "laz.tlod")) << c.what;
    const VerifyReport v = verifyStore(dir / "laz.tlod", {laz}, o);
    EXPECT_TRUE(v.ok()) << c.what << ": " << v.unmatched << " unmatched";
    return from_laz;
  };
  for (const Case& c : cases) {
    const BuildReport r = same(c, true);
    if (c.chunk_points == 40) {
      EXPECT_GT(r.chunks, 1000u) << "the counting cells were not split";
    }
  }

  const auto info = openPointReader(las)->info();
  ASSERT_TRUE(info.header_bbox);
  const auto [lo, hi] = *info.header_bbox;
  const glm::dvec3 mid = 0.5 * (lo + hi), half = 0.5 * (hi - lo);
  for (auto [what, scale] : {std::pair{"a header box holding half the points", 0.5},
                             std::pair{"a header box ten times too large", 10.0}}) {
    for (const auto& path : {las, laz}) setHeaderBox(path, mid - scale * half, mid + scale * half);
    same({what, 20'000, 2048, 2, 1}, false);
  }
}

TEST(LasDirect, ATruncatedLasFailsNamingTheFileAndTheRecord) {
  test::TempDir dir;
  std::vector<uint8_t> bytes = test::readBytes(kLas[0]);
  bytes.resize(bytes.size() - 100);  // the last record and part of the one before
  test::writeBytes(dir / "cut.las", bytes);
  BuildOptions o;
  o.quiet = true;
  try {
    buildStore({dir / "cut.las"}, dir / "cut.tlod", o);
    FAIL() << "a truncated LAS built";
  } catch (const ReadError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cut.las"), std::string::npos) << what;
    EXPECT_NE(what.find("file ends inside point record 109997 of 110000"), std::string::npos)
        << what;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "cut.tlod"));
}

}  // namespace
}  // namespace tessera::lod
