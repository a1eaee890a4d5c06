// The store builder's direct passes over uncompressed LAS records (lod/src/las_direct.cpp): a
// store built from LAS files is the store their LAZ twins make through the reader, byte for
// byte, on any number of threads and with out-of-core chunks; bad files fail as the reader does.
#include <gtest/gtest.h>

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
