// LAS reader: the real Autzen LiDAR (counts, header box, colours), every point format and
// version, 8-bit colours in 16-bit fields, georeferenced precision and truncation.
#include <gtest/gtest.h>

#include <cstring>

#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_writer.h>

#include "../support/read_all.h"
#include "../support/temp_dir.h"

namespace tessera::lod {
namespace {

using test::readAll;
using test::readErrorOf;

const std::string kData = TESSERA_DATA_DIR;

TEST(LasReader, AutzenCountBoundsAndColours) {
  auto r = readAll(kData + "/lidar/autzen_trim.las", 8192);
  ASSERT_EQ(r.points.size(), 110000u);
  EXPECT_EQ(r.info.format_detail, "LAS 1.2 format 3");
  ASSERT_TRUE(r.info.header_bbox.has_value());
  glm::dvec3 lo(1e300), hi(-1e300);
  for (const auto& p : r.points.positions) {
    lo = glm::min(lo, r.info.origin + p);
    hi = glm::max(hi, r.info.origin + p);
  }
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(lo[c], r.info.header_bbox->first[c], 1e-3) << "axis " << c;
    EXPECT_NEAR(hi[c], r.info.header_bbox->second[c], 1e-3) << "axis " << c;
  }
  // Positions are local: small numbers, not hundreds of thousands of feet.
  for (const auto& p : r.points.positions) ASSERT_LT(glm::length(p), 2000.0);
  // Autzen stores 8-bit values (raw maximum 236) in the 16-bit fields: read as 16-bit colours
  // they would all be near-black (236 / 257 = 0). They must come out as stored.
  int max_c = 0;
  double mean = 0;
  for (const auto& c : r.points.colors) {
    max_c = std::max({max_c, int(c.r), int(c.g), int(c.b)});
    mean += (c.r + c.g + c.b) / 3.0;
  }
  mean /= double(r.points.size());
  EXPECT_EQ(max_c, 236);
  EXPECT_GT(mean, 40.0);
  EXPECT_EQ(readAll(kData + "/lidar/1.2-with-color.las").points.size(), 1065u);
}

PointBatch geoBatch(size_t n) {
  PointBatch b;
  b.reset(kColor | kIntensity | kClassification);
  for (size_t i = 0; i < n; ++i) {
    // Millimetre steps on top of local offsets (world adds a georeferenced origin).
    b.positions.emplace_back(0.001 * double(i), 12.345 + 0.001 * double(i % 97),
                             -3.5 + 0.002 * double(i % 13));
    b.colors.emplace_back(uint8_t(i), uint8_t(255 - i % 256), uint8_t(i * 5), 255);
    b.intensities.push_back(float(i * 11 % 65536));
    b.classifications.push_back(uint8_t(i % 19));
  }
  return b;
}

struct LasCase {
  int minor;
  int format;
  uint16_t extra;
};

class LasFormats : public ::testing::TestWithParam<LasCase> {};

TEST_P(LasFormats, RoundTripKeepsMillimetresAtGeoreferencedCoordinates) {
  test::TempDir dir;
  const auto c = GetParam();
  const glm::dvec3 origin(636001.76, 5848935.2, 406.26);  // UTM-like metres
  PointBatch in = geoBatch(3000);
  writeLas(dir / "g.las", in, origin, {c.minor, c.format, glm::dvec3(0.001), false, c.extra});
  auto r = readAll(dir / "g.las", 700);
  ASSERT_EQ(r.points.size(), in.size());
  bool rgb = c.format == 2 || c.format == 3 || c.format == 5 || c.format == 7 || c.format == 8 ||
             c.format == 10;
  EXPECT_EQ(bool(r.info.attributes & kColor), rgb);
  for (size_t i = 0; i < in.size(); ++i) {
    glm::dvec3 w = r.info.origin + r.points.positions[i];
    glm::dvec3 expect = origin + in.positions[i];
    ASSERT_NEAR(w.x, expect.x, 5e-4) << i;
    ASSERT_NEAR(w.y, expect.y, 5e-4) << i;
    ASSERT_NEAR(w.z, expect.z, 5e-4) << i;
    // Float local coordinates keep the millimetre (a float world coordinate would not).
    glm::vec3 local(r.points.positions[i]);
    ASSERT_NEAR(double(local.y) + r.info.origin.y, expect.y, 5e-4);
    ASSERT_EQ(r.points.intensities[i], in.intensities[i]);
    ASSERT_EQ(r.points.classifications[i], in.classifications[i]);
    if (rgb) {
      ASSERT_EQ(r.points.colors[i], in.colors[i]) << i;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(AllFormats, LasFormats,
                         ::testing::Values(LasCase{2, 0, 0}, LasCase{2, 1, 0}, LasCase{2, 2, 0},
                                           LasCase{2, 3, 0}, LasCase{3, 4, 0}, LasCase{3, 5, 0},
                                           LasCase{4, 6, 0}, LasCase{4, 7, 0}, LasCase{4, 8, 0},
                                           LasCase{4, 9, 0}, LasCase{4, 10, 0}, LasCase{2, 3, 5},
                                           LasCase{4, 7, 13}, LasCase{4, 3, 0}),
                         [](const ::testing::TestParamInfo<LasCase>& i) {
                           return "las1" + std::to_string(i.param.minor) + "_format" +
                                  std::to_string(i.param.format) + "_extra" +
                                  std::to_string(i.param.extra);
                         });

TEST(LasReader, EightBitColoursInSixteenBitFieldsAreDetected) {
  test::TempDir dir;
  PointBatch in = geoBatch(1000);
  writeLas(dir / "c8.las", in, glm::dvec3(0), {2, 3, glm::dvec3(0.001), true, 0});
  writeLas(dir / "c16.las", in, glm::dvec3(0), {2, 3, glm::dvec3(0.001), false, 0});
  auto a = readAll(dir / "c8.las"), b = readAll(dir / "c16.las");
  for (size_t i = 0; i < in.size(); ++i) {
    ASSERT_EQ(a.points.colors[i], in.colors[i]);
    ASSERT_EQ(b.points.colors[i], in.colors[i]);
  }
}

TEST(LasReader, BadHeadersAndTruncationSayWhere) {
  test::TempDir dir;
  auto bytes = test::readBytes(kData + "/lidar/autzen_trim.las");
  // Truncated at several offsets: inside the header, at the points, mid-record, last byte.
  for (size_t cut :
       {size_t(3), size_t(100), size_t(226), size_t(2000), bytes.size() / 3, bytes.size() - 1}) {
    test::writeBytes(dir / "cut.las",
                     std::vector<uint8_t>(bytes.begin(), bytes.begin() + ptrdiff_t(cut)));
    std::string msg = readErrorOf([&] { readAll(dir / "cut.las"); });
    EXPECT_NE(msg.find("cut.las"), std::string::npos) << cut << ": " << msg;
    EXPECT_NE(msg.find("byte"), std::string::npos) << cut << ": " << msg;
  }
  auto mutate = [&](size_t offset, uint8_t value) {
    auto b = bytes;
    b[offset] = value;
    test::writeBytes(dir / "bad.las", b);
    return readErrorOf([&] { readAll(dir / "bad.las"); });
  };
  EXPECT_NE(mutate(0, 'X').find("missing 'LASF'"), std::string::npos);
  EXPECT_NE(mutate(25, 9).find("unsupported LAS version 1.9"), std::string::npos);
  EXPECT_NE(mutate(104, 42).find("unknown point data format 42"), std::string::npos);
  EXPECT_NE(mutate(104, 0x83).find("marks LAZ compression but the file has no LASzip VLR"),
            std::string::npos);
  EXPECT_NE(mutate(105, 10).find("record length"), std::string::npos);
  // Header declaring more points than the data holds.
  auto b = bytes;
  uint32_t more = 110001;
  std::memcpy(b.data() + 107, &more, 4);
  test::writeBytes(dir / "more.las", b);
  std::string msg = readErrorOf([&] { readAll(dir / "more.las"); });
  EXPECT_NE(msg.find("file ends inside point record 110000 of 110001"), std::string::npos) << msg;
}

}  // namespace
}  // namespace tessera::lod
