// Export: LAS and LAZ records copied exactly (and our LAZ chunks equal to LASzip's own for the
// same records), cuts by box and planes against a brute-force count over the same records,
// other scans and stores converted with their colours and positions, PLY out in double, bad
// outputs refused with nothing left behind.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <algorithm>
#include <cstring>
#include <fstream>

#include <tessera/lod/point_export.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>

#include "../support/read_all.h"
#include "../support/temp_dir.h"
#include "reader_util.h"

namespace tessera::lod {
namespace {

using test::readAll;
using test::TempDir;

const std::string kData = TESSERA_DATA_DIR;
const std::string kLas = kData + "/lidar/autzen_trim.las";
const std::string kLaz = kData + "/lidar/autzen_trim.laz";

/// The point records of an uncompressed LAS file.
std::vector<uint8_t> records(const std::filesystem::path& las) {
  const auto f = test::readBytes(las);
  const uint32_t offset = detail::loadLE<uint32_t>(f.data() + 96);
  const uint16_t rl = detail::loadLE<uint16_t>(f.data() + 105);
  uint64_t n = detail::loadLE<uint32_t>(f.data() + 107);
  if (f[25] >= 4 && detail::loadLE<uint64_t>(f.data() + 247)) n = detail::loadLE<uint64_t>(f.data() + 247);
  return {f.begin() + offset, f.begin() + long(offset + n * rl)};
}

/// The chunks of a LAZ file: from after the chunk table offset to the chunk table.
std::vector<uint8_t> chunkBytes(const std::filesystem::path& laz) {
  const auto f = test::readBytes(laz);
  const uint32_t offset = detail::loadLE<uint32_t>(f.data() + 96);
  const int64_t table = detail::loadLE<int64_t>(f.data() + offset);
  return {f.begin() + offset + 8, f.begin() + table};
}

TEST(PointExport, LasAndLazRecordsAreCopiedExactlyAndOurChunksAreLaszips) {
  TempDir dir;
  ExportReport r = exportPoints(kLas, dir / "a.laz");
  EXPECT_EQ(r.read, 110000u);
  EXPECT_EQ(r.written, 110000u);
  EXPECT_NE(r.method.find("records copied"), std::string::npos) << r.method;
  // The same records coded by LASzip and by us: the same bytes, chunk table included.
  EXPECT_TRUE(chunkBytes(dir / "a.laz") == chunkBytes(kLaz));
  exportPoints(dir / "a.laz", dir / "b.las");
  EXPECT_TRUE(records(dir / "b.las") == records(kLas));
  // The VLRs (the CRS) travel too; the LASzip VLR only in the LAZ.
  const auto a = readAll(dir / "a.laz"), b = readAll(dir / "b.las"), in = readAll(kLas);
  EXPECT_EQ(a.info.format, Format::kLaz);
  EXPECT_EQ(b.info.format, Format::kLas);
  EXPECT_EQ(b.info.format_detail, in.info.format_detail);
  EXPECT_EQ(test::readBytes(dir / "b.las").size(), test::readBytes(kLas).size());
}

TEST(PointExport, ABoxAndPlanesKeepExactlyThePointsInsideInOrder) {
  TempDir dir;
  const glm::dvec3 lo(636500, 849000, 0), hi(637000, 849400, 450);
  const glm::dvec4 plane(1, -1, 0, 212450);  // x - y >= -212450: a diagonal cut
  ExportOptions o;
  o.box = std::make_pair(lo, hi);
  o.planes = {plane};
  const ExportReport r = exportPoints(kLaz, dir / "cut.las", o);
  // Brute force over the LAS twin's records with the header's scale and offset.
  const auto f = test::readBytes(kLas);
  glm::dvec3 scale, offset;
  for (int i = 0; i < 3; ++i) {
    scale[i] = detail::loadLE<double>(f.data() + 131 + 8 * i);
    offset[i] = detail::loadLE<double>(f.data() + 155 + 8 * i);
  }
  const auto all = records(kLas);
  std::vector<uint8_t> want;
  for (size_t i = 0; i < all.size(); i += 34) {
    glm::dvec3 p;
    for (int c = 0; c < 3; ++c) p[c] = detail::loadLE<int32_t>(&all[i + 4 * c]) * scale[c] + offset[c];
    const bool in = glm::all(glm::greaterThanEqual(p, lo)) && glm::all(glm::lessThanEqual(p, hi)) &&
                    glm::dot(glm::dvec3(plane), p) + plane.w >= 0;
    if (in) want.insert(want.end(), all.begin() + long(i), all.begin() + long(i + 34));
  }
  ASSERT_GT(want.size(), 34u * 1000);
  ASSERT_LT(want.size(), all.size() / 2);
  EXPECT_EQ(r.written * 34, want.size());
  EXPECT_TRUE(records(dir / "cut.las") == want);
  // The header's box is the kept points' box.
  const auto cut = readAll(dir / "cut.las");
  ASSERT_TRUE(cut.info.header_bbox.has_value());
  EXPECT_GE(cut.info.header_bbox->first.x, lo.x);
  EXPECT_LE(cut.info.header_bbox->second.z, hi.z);
}

TEST(PointExport, Las14RecordsWithExtraBytesRoundTripThroughLaz) {
  TempDir dir;
  const auto in = readAll(kLas);
  for (int format : {6, 7, 8}) {
    LasWriteOptions w;
    w.minor_version = 4;
    w.point_format = format;
    w.scale = glm::dvec3(0.01);
    w.extra_bytes = 4;
    const auto las = dir / ("f" + std::to_string(format) + ".las");
    writeLas(las, in.points, in.info.origin, w);
    exportPoints(las, dir / "x.laz");
    exportPoints(dir / "x.laz", dir / "y.las");
    EXPECT_TRUE(records(dir / "y.las") == records(las)) << "format " << format;
    const auto back = readAll(dir / "x.laz");
    EXPECT_NE(back.info.format_detail.find("layered"), std::string::npos);
    ASSERT_EQ(back.points.size(), in.points.size());
    for (size_t i = 0; i < in.points.size(); i += 97) {
      ASSERT_LT(glm::length(back.info.origin + back.points.positions[i] -
                            (in.info.origin + in.points.positions[i])),
                0.01)
          << i;
    }
  }
}

TEST(PointExport, ScansOfOtherFormatsBecomeLas14WithTheirColours) {
  TempDir dir;
  for (const std::string name : {"bunnyDouble.e57", "ColouredCubeFloat.e57"}) {
    const std::string e57 = kData + "/e57/" + name;
    const auto in = readAll(e57);
    const ExportReport r = exportPoints(e57, dir / "e.laz");
    EXPECT_EQ(r.written, in.points.size()) << name;
    const auto out = readAll(dir / "e.laz");
    ASSERT_EQ(out.points.size(), in.points.size()) << name;
    EXPECT_EQ(out.info.format_detail.substr(0, 16),
              in.info.attributes & kColor ? "LAZ 1.4 format 7" : "LAZ 1.4 format 6");
    for (size_t i = 0; i < in.points.size(); ++i) {
      const glm::dvec3 a = in.info.origin + in.points.positions[i];
      const glm::dvec3 b = out.info.origin + out.points.positions[i];
      const glm::dvec3 d = glm::abs(a - b);
      ASSERT_LE(std::max({d.x, d.y, d.z}), 0.5e-4 + 1e-12) << name << " point " << i;
      if (in.info.attributes & kColor) {
        ASSERT_EQ(out.points.colors[i], in.points.colors[i]) << i;
      }
    }
  }
}

TEST(PointExport, AStoreGivesEveryInputPointOnceWithItsColour) {
  TempDir dir;
  BuildOptions b;
  b.quiet = true;
  const BuildReport report = buildStore({kLas}, dir / "s.tlod", b);
  exportPoints(dir / "s.tlod", dir / "s.laz");
  const auto in = readAll(kLas), out = readAll(dir / "s.laz");
  ASSERT_EQ(out.points.size(), in.points.size());
  auto key = [](const glm::u8vec4& c) { return (uint32_t(c.r) << 16) | (uint32_t(c.g) << 8) | c.b; };
  std::vector<uint32_t> a, c;
  for (const auto& col : in.points.colors) a.push_back(key(col));
  for (const auto& col : out.points.colors) c.push_back(key(col));
  std::sort(a.begin(), a.end());
  std::sort(c.begin(), c.end());
  EXPECT_TRUE(a == c);
  // Round trip: the export builds into a store of the same points.
  const BuildReport again = buildStore({dir / "s.laz"}, dir / "again.tlod", b);
  EXPECT_EQ(again.points, in.points.size());
  EXPECT_EQ(again.skipped, 0u);
  ASSERT_TRUE(out.info.header_bbox && in.info.header_bbox);
  for (int k = 0; k < 3; ++k) {
    // Within what the store states of its own positions.
    EXPECT_NEAR(out.info.header_bbox->first[k], in.info.header_bbox->first[k], report.max_error);
    EXPECT_NEAR(out.info.header_bbox->second[k], in.info.header_bbox->second[k], report.max_error);
  }
}

TEST(PointExport, PlyOutKeepsDoublePositions) {
  TempDir dir;
  exportPoints(kLaz, dir / "a.ply");
  const auto in = readAll(kLas), out = readAll(dir / "a.ply");
  ASSERT_EQ(out.points.size(), in.points.size());
  for (size_t i = 0; i < in.points.size(); ++i) {
    const glm::dvec3 a = in.info.origin + in.points.positions[i];
    const glm::dvec3 b = out.info.origin + out.points.positions[i];
    ASSERT_LT(glm::length(a - b), 1e-6) << i;
    ASSERT_EQ(out.points.colors[i], in.points.colors[i]) << i;
  }
}

TEST(PointExport, OutputsItCannotWriteAreRefusedAndLeaveNothing) {
  TempDir dir;
  EXPECT_THROW(exportPoints(kLas, dir / "a.txt"), WriteError);
  // Waveform packets are not exported.
  const auto in = readAll(kLas);
  LasWriteOptions w;
  w.point_format = 4;
  writeLas(dir / "wave.las", in.points, in.info.origin, w);
  try {
    exportPoints(dir / "wave.las", dir / "wave.laz");
    ADD_FAILURE() << "a waveform file was exported";
  } catch (const WriteError& e) {
    EXPECT_NE(std::string(e.what()).find("waveform"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "wave.laz"));
  // A folder that cannot be written: the error names the file, no partial file stays.
  std::filesystem::create_directories(dir / "ro");
  ::chmod((dir / "ro").c_str(), 0555);
  if (::access((dir / "ro").c_str(), W_OK) != 0) {  // root writes anywhere: nothing to test
    EXPECT_THROW(exportPoints(kLas, dir / "ro" / "a.laz"), WriteError);
    EXPECT_TRUE(std::filesystem::is_empty(dir / "ro"));
  }
  ::chmod((dir / "ro").c_str(), 0755);
  // A coordinate beyond the LAS range at the scale asked for.
  ExportOptions tiny;
  tiny.scale = 1e-12;
  EXPECT_THROW(exportPoints(kData + "/e57/bunnyDouble.e57", dir / "t.las", tiny), WriteError);
  EXPECT_FALSE(std::filesystem::exists(dir / "t.las"));
}

}  // namespace
}  // namespace tessera::lod
