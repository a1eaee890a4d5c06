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
  const auto las = test::readBytes(kLas), laz = test::readBytes(kLaz);
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

/// Autzen's records (LAS 1.2 format 3) as LAS 1.4 records of `format` (6, 7 or 8) with `extra`
/// extra bytes, with the fields LAS 1.4 adds filled so every context of the coder is used:
/// four scanner channels in runs, returns up to 15, flags, scan angles, repeated and jumping
/// GPS times, NIR.
std::vector<uint8_t> las14Records(int format, uint16_t extra, uint64_t& count) {
  const auto las = test::readBytes(kLas);
  LasLayout l = layoutOf(las);
  count = l.count;
  const uint32_t base = format == 6 ? 30 : format == 7 ? 36 : 38;
  const uint32_t rl = base + extra;
  std::vector<uint8_t> out(count * rl);
  std::mt19937 rng(7);
  uint32_t channel = 0;
  for (uint64_t i = 0; i < count; ++i) {
    const uint8_t* s = las.data() + l.data_offset + i * l.record_length;
    uint8_t* d = out.data() + i * rl;
    std::memcpy(d, s, 14);  // x y z intensity
    if (rng() % 500 == 0) channel = rng() % 4;
    const uint32_t n = 1 + rng() % (i % 1000 < 500 ? 3 : 15), r = 1 + rng() % n;
    d[14] = uint8_t(r | (n << 4));
    d[15] = uint8_t((rng() % 16) * (rng() % 8 == 0) | (channel << 4) | ((s[14] >> 6) << 6));
    d[16] = uint8_t(s[15] & 31) + (i % 3000 < 10 ? 200 : 0);  // classes above 31 too
    d[17] = uint8_t(i / 700);
    const int16_t angle = int16_t(int8_t(s[16]) * 166 + (rng() % 3 == 0 ? int(rng() % 7) - 3 : 0));
    std::memcpy(d + 18, &angle, 2);
    std::memcpy(d + 20, s + 18, 2);  // point source
    double t = detail::loadLE<double>(s + 20);
    if (i % 5000 == 4999) t += 1e9;    // a jump beyond 32 bits of difference
    if (i % 7 == 3) t = detail::loadLE<double>(out.data() + (i - 1) * rl + 22);  // repeats
    std::memcpy(d + 22, &t, 8);
    if (format >= 7) std::memcpy(d + 30, s + 28, 6);
    if (format == 8) {
      const uint16_t nir = uint16_t(rng() % 4 == 0 ? rng() : i);
      std::memcpy(d + 36, &nir, 2);
    }
    for (uint16_t e = 0; e < extra; ++e) d[base + e] = uint8_t(e == 0 ? i / 100 : rng() % 3);
  }
  return out;
}

/// Encodes `records` in chunks of `chunk` points and decodes them back.
std::vector<uint8_t> roundTrip(const std::vector<uint8_t>& records, uint64_t count,
                               const std::vector<laz::Item>& items, bool layered,
                               uint64_t chunk, size_t* coded_bytes = nullptr) {
  const uint32_t rl = laz::recordSize(items);
  laz::ChunkEncoder enc(items, layered);
  laz::ChunkDecoder dec(items, layered);
  std::vector<uint8_t> back(records.size());
  size_t total = 0;
  for (uint64_t at = 0; at < count; at += chunk) {
    const uint64_t n = std::min(chunk, count - at);
    std::vector<uint8_t> coded;
    enc.encode(records.data() + at * rl, n, coded);
    EXPECT_EQ(dec.decode(coded, n, back.data() + at * rl), coded.size()) << "chunk at " << at;
    total += coded.size();
  }
  if (coded_bytes) *coded_bytes = total;
  return back;
}

TEST(LazCoder, PointwiseRoundTripsAutzenInEveryChunkSize) {
  const auto las = test::readBytes(kLas);
  LasLayout l = layoutOf(las);
  std::vector<uint8_t> records(las.begin() + long(l.data_offset),
                               las.begin() + long(l.data_offset + l.count * l.record_length));
  for (uint64_t chunk : {uint64_t(1), uint64_t(2), uint64_t(777), uint64_t(50000), l.count}) {
    // Tiny chunks (a coder set up per point) on the first points only.
    const uint64_t n = chunk < 10 ? 2000 : l.count;
    const std::vector<uint8_t> part(records.begin(), records.begin() + long(n * l.record_length));
    size_t coded = 0;
    const auto back = roundTrip(part, n, laz::itemsForFormat(3, 0), false, chunk, &coded);
    ASSERT_TRUE(back == part) << "chunks of " << chunk;
    if (chunk == 50000) {  // within a few percent of what LASzip made of the same records
      const size_t laszip = test::readBytes(kLaz).size() - l.data_offset;
      EXPECT_LT(double(coded), 1.03 * double(laszip)) << coded << " against " << laszip;
    }
  }
}

TEST(LazCoder, LayeredRoundTripsLas14FormatsWithChannelsAndExtraBytes) {
  for (int format : {6, 7, 8}) {
    for (uint16_t extra : {uint16_t(0), uint16_t(3)}) {
      uint64_t count = 0;
      const auto records = las14Records(format, extra, count);
      for (uint64_t chunk : {uint64_t(1), uint64_t(3), uint64_t(4096), uint64_t(50000)}) {
        const uint64_t n = chunk < 10 ? 1000 : count;
        const uint32_t rl = laz::recordSize(laz::itemsForFormat(format, extra));
        const std::vector<uint8_t> part(records.begin(), records.begin() + long(n * rl));
        const auto back = roundTrip(part, n, laz::itemsForFormat(format, extra), true, chunk);
        ASSERT_TRUE(back == part) << "format " << format << " extra " << extra << " chunks of "
                                  << chunk;
      }
    }
  }
}

TEST(LazCoder, PointwiseRoundTripsExtraBytesAndEveryLegacyFormat) {
  uint64_t count = 0;
  const auto las14 = las14Records(6, 0, count);
  for (int format : {0, 1, 2, 3}) {
    for (uint16_t extra : {uint16_t(0), uint16_t(5)}) {
      const auto items = laz::itemsForFormat(format, extra);
      const uint32_t rl = laz::recordSize(items);
      std::vector<uint8_t> records(count * rl);
      std::mt19937 rng(format * 10 + extra);
      for (uint64_t i = 0; i < count; ++i) {
        const uint8_t* s = las14.data() + i * 30;
        uint8_t* d = records.data() + i * rl;
        std::memcpy(d, s, 14);
        d[14] = uint8_t((s[14] & 7) | ((s[14] >> 4 & 7) << 3) | (s[15] & 0xC0));
        d[15] = s[16];
        d[16] = uint8_t(rng() % 181 - 90);
        d[17] = s[17];
        std::memcpy(d + 18, s + 20, 2);
        uint32_t at = 20;
        if (format == 1 || format == 3) {
          std::memcpy(d + at, s + 22, 8);
          at += 8;
        }
        if (format >= 2) {
          for (int c = 0; c < 3; ++c) {
            const uint16_t v = uint16_t(c == 0 ? rng() : i * (c + 1));
            std::memcpy(d + at + 2 * c, &v, 2);
          }
          at += 6;
        }
        for (uint16_t e = 0; e < extra; ++e) d[at + e] = uint8_t(rng() % (e + 2));
      }
      for (uint64_t chunk : {uint64_t(500), uint64_t(50000)}) {
        ASSERT_TRUE(roundTrip(records, count, items, false, chunk) == records)
            << "format " << format << " extra " << extra << " chunks of " << chunk;
      }
    }
  }
}

TEST(LazCoder, ChunkTablesRoundTripFixedAndVariable) {
  std::vector<uint32_t> points = {50000, 50000, 10000, 1, 77777};
  std::vector<uint64_t> bytes = {280000, 291234, 50000, 60, 400001};
  for (bool variable : {false, true}) {
    std::vector<uint8_t> coded;
    laz::encodeChunkTable(points, bytes, variable, coded);
    std::vector<uint32_t> p;
    std::vector<uint64_t> b;
    laz::decodeChunkTable(coded, uint32_t(bytes.size()), variable, p, b);
    EXPECT_EQ(b, bytes);
    if (variable) {
      EXPECT_EQ(p, points);
    }
  }
}

TEST(LazCoder, DamagedChunksThrowAndNeverReadOutsideTheirBytes) {
  const auto las = test::readBytes(kLas);
  LasLayout l = layoutOf(las);
  const uint64_t n = 3000;
  std::vector<uint8_t> records(las.begin() + long(l.data_offset),
                               las.begin() + long(l.data_offset + n * l.record_length));
  for (bool layered : {false, true}) {
    uint64_t count = 0;
    const auto recs = layered ? las14Records(7, 2, count) : records;
    const auto items = layered ? laz::itemsForFormat(7, 2) : laz::itemsForFormat(3, 0);
    std::vector<uint8_t> coded;
    laz::ChunkEncoder(items, layered).encode(recs.data(), n, coded);
    laz::ChunkDecoder dec(items, layered);
    std::vector<uint8_t> out(n * laz::recordSize(items));
    std::mt19937 rng(3);
    int thrown = 0;
    for (int trial = 0; trial < 300; ++trial) {
      auto bad = coded;
      if (trial % 3 == 0) {
        bad.resize(rng() % bad.size());  // cut short
      } else {
        for (int k = 0; k < 1 + trial % 5; ++k) bad[rng() % bad.size()] ^= uint8_t(1 + rng() % 255);
      }
      // A copy exactly as long as the damaged bytes: ASan sees any read beyond them.
      std::vector<uint8_t> exact(bad.begin(), bad.end());
      try {
        dec.decode(exact, n, out.data());
      } catch (const laz::CorruptData&) {
        ++thrown;
      }
    }
    EXPECT_GT(thrown, 100) << (layered ? "layered" : "pointwise");
  }
}
}  // namespace
}  // namespace tessera::lod
