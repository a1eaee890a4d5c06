// Samples of raw scans: the Autzen LAS and LAZ, generated LAZ with many chunks and binary PLY in
// both byte orders give every k-th record (or every k-th record of each chunk decoded) exactly as
// the whole file's reader gives those points, with the counts and bounds that implies; ASCII
// and text formats are refused with a reason; truncated and damaged files give the readers' own
// errors.
#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/scan_sample.h>

#include "../support/read_all.h"
#include "../support/temp_dir.h"

namespace tessera::lod {
namespace {

using test::readAll;
using test::readErrorOf;

const std::string kData = TESSERA_DATA_DIR;
const std::string kLas = kData + "/lidar/autzen_trim.las";
const std::string kLaz = kData + "/lidar/autzen_trim.laz";

ScanSample sampleOf(const std::filesystem::path& path, uint64_t points) {
  std::string why;
  auto s = ScanSample::read(path, {points}, &why);
  EXPECT_TRUE(s.has_value()) << why;
  if (!s) throw std::runtime_error(why);
  return std::move(*s);
}

/// Point `at` of `sample` equals point `of` of `full`, every attribute the reader gives.
void expectSamePoint(const PointBatch& sample, size_t at, const PointBatch& full, size_t of) {
  ASSERT_LT(of, full.size());
  EXPECT_EQ(sample.positions[at], full.positions[of]) << "sample " << at << ", point " << of;
  if (full.attributes & kColor) EXPECT_EQ(sample.colors[at], full.colors[of]);
  if (full.attributes & kIntensity) EXPECT_EQ(sample.intensities[at], full.intensities[of]);
  if (full.attributes & kClassification)
    EXPECT_EQ(sample.classifications[at], full.classifications[of]);
}

/// Every point of `sample` lies in the box of `full`'s points.
void expectInsideBounds(const PointBatch& sample, const PointBatch& full) {
  glm::dvec3 lo(1e300), hi(-1e300);
  for (const auto& p : full.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
  for (const auto& p : sample.positions) {
    EXPECT_TRUE(glm::all(glm::greaterThanEqual(p, lo)) && glm::all(glm::lessThanEqual(p, hi)));
  }
}

std::vector<uint8_t> bytesOf(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

void writeBytes(const std::filesystem::path& p, const std::vector<uint8_t>& b) {
  std::ofstream(p, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

PointBatch randomPoints(size_t n, uint32_t seed, bool color = true) {
  PointBatch b;
  b.reset(color ? kColor : 0u);
  b.resize(n);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-50.0, 50.0);
  for (size_t i = 0; i < n; ++i) {
    b.positions[i] = {u(rng), u(rng), 0.1 * u(rng)};
    if (color) b.colors[i] = glm::u8vec4(rng() & 255, rng() & 255, rng() & 255, 255);
  }
  return b;
}

TEST(ScanSampleTest, LasGivesEveryKthRecordAsTheReaderDoes) {
  const auto full = readAll(kLas);
  const ScanSample s = sampleOf(kLas, 10000);
  EXPECT_EQ(s.stride(), 11u);  // 110,000 records / 10,000 wanted
  EXPECT_EQ(s.points(), 10000u);
  EXPECT_EQ(s.info().declared_points, 110000u);
  EXPECT_EQ(s.info().format, Format::kLas);
  const auto got = readAll(*s.reader());
  ASSERT_EQ(got.points.size(), s.points());
  EXPECT_EQ(got.info.origin, full.info.origin);
  EXPECT_EQ(got.info.header_bbox, full.info.header_bbox);
  for (size_t i = 0; i < got.points.size(); ++i)
    expectSamePoint(got.points, i, full.points, i * s.stride());
  expectInsideBounds(got.points, full.points);
  // Spans that skip records read less than the file.
  EXPECT_LE(s.bytesRead(), std::filesystem::file_size(kLas));
}

TEST(ScanSampleTest, AStrideThatDoesNotDivideTheCountKeepsTheLastPartialStep) {
  const auto full = readAll(kLas);
  const ScanSample s = sampleOf(kLas, 7000);  // 110,000 / 7,000 = 15 (rounded down)
  EXPECT_EQ(s.stride(), 15u);
  EXPECT_EQ(s.points(), (110000u + 14u) / 15u);
  const auto got = readAll(*s.reader());
  ASSERT_EQ(got.points.size(), s.points());
  expectSamePoint(got.points, got.points.size() - 1, full.points, (s.points() - 1) * 15);
}

TEST(ScanSampleTest, AskingForMoreThanTheFileHoldsGivesEveryRecord) {
  const auto full = readAll(kLas);
  const ScanSample s = sampleOf(kLas, 1'000'000);
  EXPECT_EQ(s.stride(), 1u);
  const auto got = readAll(*s.reader());
  ASSERT_EQ(got.points.size(), full.points.size());
  for (size_t i = 0; i < got.points.size(); i += 997)
    expectSamePoint(got.points, i, full.points, i);
}

TEST(ScanSampleTest, LazGivesEveryKthRecordOfEachChunkDecoded) {
  // Autzen's LAZ has 3 chunks (50,000, 50,000, 10,000): all are decoded (at least 16 are).
  const auto full = readAll(kLas);  // the LAZ's twin: the same records
  const ScanSample s = sampleOf(kLaz, 10000);
  EXPECT_EQ(s.info().format, Format::kLaz);
  EXPECT_EQ(s.chunkCount(), 3u);
  EXPECT_EQ(s.chunks(), (std::vector<uint64_t>{0, 1, 2}));
  EXPECT_EQ(s.stride(), 11u);
  const uint64_t expected = (50000 + 10) / 11 * 2 + (10000 + 10) / 11;
  EXPECT_EQ(s.points(), expected);
  const auto got = readAll(*s.reader());
  ASSERT_EQ(got.points.size(), expected);
  size_t at = 0;
  for (uint64_t start : {0u, 50000u, 100000u}) {
    const uint64_t n = start == 100000u ? 10000u : 50000u;
    for (uint64_t i = 0; i < n; i += s.stride())
      expectSamePoint(got.points, at++, full.points, start + i);
  }
  EXPECT_EQ(got.info.origin, full.info.origin);
}

TEST(ScanSampleTest, LazWithManyChunksDecodesASpreadOfThem) {
  test::TempDir dir;
  const PointBatch b = randomPoints(1'000'000, 7);  // 20 chunks of 50,000
  LasWriteOptions o;
  o.laz = true;
  o.scale = glm::dvec3(0.001);
  writeLas(dir / "many.laz", b, glm::dvec3(1000.0, 2000.0, 30.0), o);
  const auto full = readAll(dir / "many.laz", 1 << 16);
  const ScanSample s = sampleOf(dir / "many.laz", 100000);
  EXPECT_EQ(s.chunkCount(), 20u);
  // Twice the wanted points need 4 chunks, but at least 16 are decoded: j * 20 / 16.
  std::vector<uint64_t> spread;
  for (uint64_t j = 0; j < 16; ++j) spread.push_back(j * 20 / 16);
  EXPECT_EQ(s.chunks(), spread);
  EXPECT_EQ(s.stride(), 8u);  // 800,000 decoded / 100,000 wanted
  EXPECT_EQ(s.points(), 16u * 6250u);
  const auto got = readAll(*s.reader(), 1 << 16);
  ASSERT_EQ(got.points.size(), s.points());
  size_t at = 0;
  for (uint64_t c : s.chunks())
    for (uint64_t i = 0; i < 50000; i += s.stride())
      expectSamePoint(got.points, at++, full.points, c * 50000 + i);
  EXPECT_LT(s.bytesRead(), std::filesystem::file_size(dir / "many.laz"));
}

TEST(ScanSampleTest, BinaryPlyInEitherByteOrderGivesEveryKthVertex) {
  test::TempDir dir;
  PointBatch b = randomPoints(50000, 3);
  b.triangles.push_back({0, 1, 2});  // a face element after the vertices is left out
  for (PlyEncoding e : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian}) {
    PlyWriteOptions o;
    o.encoding = e;
    const auto path = dir / "cloud.ply";
    writePly(path, b, glm::dvec3(0.0), o);
    const auto full = readAll(path);
    const ScanSample s = sampleOf(path, 4000);
    EXPECT_EQ(s.stride(), 12u);
    EXPECT_EQ(s.points(), (50000u + 11u) / 12u);
    EXPECT_EQ(s.extension(), ".ply");
    const auto got = readAll(*s.reader());
    ASSERT_EQ(got.points.size(), s.points());
    EXPECT_TRUE(got.points.triangles.empty());
    for (size_t i = 0; i < got.points.size(); ++i)
      expectSamePoint(got.points, i, full.points, i * s.stride());
  }
}

TEST(ScanSampleTest, FormatsWithoutFixedRecordsSayWhyTheyCannotBeSampled) {
  test::TempDir dir;
  const PointBatch b = randomPoints(1000, 5);
  PlyWriteOptions o;
  o.encoding = PlyEncoding::kAscii;
  writePly(dir / "ascii.ply", b, glm::dvec3(0.0), o);
  std::string why;
  EXPECT_FALSE(ScanSample::read(dir / "ascii.ply", {100}, &why).has_value());
  EXPECT_NE(why.find("ASCII PLY"), std::string::npos) << why;
  std::ofstream(dir / "points.xyz") << "1 2 3\n4 5 6\n";
  why.clear();
  EXPECT_FALSE(ScanSample::read(dir / "points.xyz", {100}, &why).has_value());
  EXPECT_NE(why.find("no fixed-size records"), std::string::npos) << why;
}

TEST(ScanSampleTest, TruncatedLasAndPlyGiveTheReadersErrors) {
  test::TempDir dir;
  std::vector<uint8_t> las = bytesOf(kLas);
  las.resize(las.size() - 1000);  // ends inside a record
  writeBytes(dir / "short.las", las);
  const std::string reader = readErrorOf([&] { readAll(dir / "short.las", 1 << 16); });
  const std::string sampler = readErrorOf([&] { sampleOf(dir / "short.las", 1000); });
  EXPECT_FALSE(reader.empty());
  EXPECT_EQ(sampler, reader);

  PlyWriteOptions o;
  writePly(dir / "cloud.ply", randomPoints(20000, 9, false), glm::dvec3(0.0), o);
  std::vector<uint8_t> ply = bytesOf(dir / "cloud.ply");
  ply.resize(ply.size() - 30);  // the last vertices cut
  writeBytes(dir / "short.ply", ply);
  const std::string ply_reader = readErrorOf([&] { readAll(dir / "short.ply", 1 << 16); });
  const std::string ply_sampler = readErrorOf([&] { sampleOf(dir / "short.ply", 1000); });
  EXPECT_FALSE(ply_reader.empty());
  EXPECT_EQ(ply_sampler, ply_reader);
}

TEST(ScanSampleTest, BadHeadersGiveTheReadersErrors) {
  test::TempDir dir;
  std::vector<uint8_t> las = bytesOf(kLas);
  las[105] = 3;  // a record length shorter than format 3 needs
  las[106] = 0;
  writeBytes(dir / "bad.las", las);
  const std::string sampler = readErrorOf([&] { sampleOf(dir / "bad.las", 1000); });
  EXPECT_NE(sampler.find("point record length 3 is shorter"), std::string::npos) << sampler;
  EXPECT_EQ(sampler, readErrorOf([&] { openPointReader(dir / "bad.las"); }));
  std::ofstream(dir / "bad.ply") << "ply\nformat binary_little_endian 1.0\nelement vertex 5\n";
  EXPECT_EQ(readErrorOf([&] { sampleOf(dir / "bad.ply", 10); }),
            readErrorOf([&] { openPointReader(dir / "bad.ply"); }));
}

TEST(ScanSampleTest, DamagedOrCutLazGivesTheChunkReadersErrorOrNoSample) {
  test::TempDir dir;
  std::vector<uint8_t> laz = bytesOf(kLaz);
  // Damage the middle of the second chunk: the sample decodes it, as the reader does.
  std::vector<uint8_t> damaged = laz;
  for (size_t i = 0; i < 64; ++i) damaged[damaged.size() / 2 + i] ^= 0x5A;
  writeBytes(dir / "damaged.laz", damaged);
  const std::string reader = readErrorOf([&] { readAll(dir / "damaged.laz", 1 << 16); });
  const std::string sampler = readErrorOf([&] { sampleOf(dir / "damaged.laz", 1000); });
  EXPECT_NE(reader.find("chunk 1 of 3"), std::string::npos) << reader;
  EXPECT_EQ(sampler, reader);
  // Cut short, the chunk table is gone: chunks are found only by decoding them in turn, so the
  // file is not sampled and says why (the build then reads it and reports where it ends).
  laz.resize(laz.size() * 3 / 4);
  writeBytes(dir / "cut.laz", laz);
  std::string why;
  EXPECT_FALSE(ScanSample::read(dir / "cut.laz", {1000}, &why).has_value());
  EXPECT_NE(why.find("chunks cannot be found"), std::string::npos) << why;
}

TEST(ScanSampleTest, ASampleBuildsAStoreOfItsPoints) {
  test::TempDir dir;
  const ScanSample s = sampleOf(kLas, 20000);
  const BuildReport r = buildSampleStore(s, dir / "sample.tlod", 2);
  EXPECT_EQ(r.points, s.points());
  auto store = PointStore::open(dir / "sample.tlod");
  EXPECT_EQ(store->summary().points, s.points());
  // Nothing but the store is left beside it.
  size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.path()))
    files += e.is_regular_file();
  EXPECT_EQ(files, 1u);
}

}  // namespace
}  // namespace tessera::lod
