// PLY reader: real Stanford data, every encoding and type, skipped properties, faces, triangle
// strips, and bad input (truncation, NaN, wrong magic, unknown types, faces it cannot read)
// giving errors that say where.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cmath>
#include <cstring>
#include <limits>

#include <tessera/lod/mesh.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_writer.h>

#include "../support/read_all.h"
#include "../support/temp_dir.h"

namespace tessera::lod {
namespace {

using test::readAll;
using test::readAllMemory;
using test::readErrorOf;

const std::string kData = TESSERA_DATA_DIR;

TEST(PlyReader, RealRangeScanHasDeclaredPointsAndGridCells) {
  auto r = readAll(kData + "/stanford-bunny/scans/bun000.ply", 4096);
  EXPECT_EQ(r.points.size(), 40256u);
  EXPECT_EQ(r.info.format_detail, "ascii 1.0");
  ASSERT_EQ(r.info.scans.size(), 1u);
  EXPECT_EQ(r.info.scans[0].grid_columns, 512u);
  EXPECT_EQ(r.info.scans[0].grid_rows, 400u);
  ASSERT_TRUE(r.points.attributes & kGridPosition);
  // Every vertex sits in exactly one grid cell; cells are unique.
  std::vector<bool> used(512 * 400, false);
  for (auto g : r.points.grid_positions) {
    ASSERT_LT(g.x, 512);
    ASSERT_LT(g.y, 400);
    size_t cell = size_t(g.y) * 512 + g.x;
    EXPECT_FALSE(used[cell]);
    used[cell] = true;
  }
  // First vertex of the file, as written.
  EXPECT_NEAR(r.points.positions[0].x, -0.06325, 1e-7);
  EXPECT_NEAR(r.points.positions[0].y, 0.0359793, 1e-7);
  EXPECT_NEAR(r.points.positions[0].z, 0.0420873, 1e-7);
}

TEST(PlyReader, RealMeshHasTrianglesAndScalarAttributes) {
  auto r = readAll(kData + "/stanford-bunny/reconstruction/bun_zipper.ply");
  EXPECT_EQ(r.points.size(), 35947u);
  EXPECT_EQ(r.points.triangles.size(), 69451u);
  EXPECT_TRUE(r.info.attributes & kConfidence);
  EXPECT_TRUE(r.info.attributes & kIntensity);
  EXPECT_NEAR(r.points.confidences[0], 0.850855f, 1e-6);
  for (const auto& t : r.points.triangles) {
    ASSERT_LT(t.x, 35947u);
    ASSERT_LT(t.y, 35947u);
    ASSERT_LT(t.z, 35947u);
  }
}

PointBatch sampleBatch(size_t n, AttributeMask mask) {
  PointBatch b;
  b.reset(mask);
  for (size_t i = 0; i < n; ++i) {
    b.positions.emplace_back(0.25 * double(i), -1.5 + 0.125 * double(i % 7), 1000.0 + double(i));
    if (mask & kNormal) b.normals.emplace_back(0.f, 0.6f, 0.8f);
    if (mask & kColor)
      b.colors.emplace_back(uint8_t(i * 3), uint8_t(255 - i), uint8_t(i * 7),
                            mask & kAlpha ? uint8_t(i) : 255);
    if (mask & kIntensity) b.intensities.push_back(float(i) * 0.5f);
    if (mask & kConfidence) b.confidences.push_back(1.0f / float(i + 1));
  }
  return b;
}

struct EncodingCase {
  PlyEncoding encoding;
  bool doubles;
  bool ushort_colors;
};

std::string encodingName(const ::testing::TestParamInfo<EncodingCase>& i) {
  static const char* const kEnc[] = {"ascii", "binary_le", "binary_be"};
  return std::string(kEnc[int(i.param.encoding)]) + (i.param.doubles ? "_double" : "_float") +
         (i.param.ushort_colors ? "_ushort" : "_uchar");
}

class PlyRoundTrip : public ::testing::TestWithParam<EncodingCase> {};

TEST_P(PlyRoundTrip, EveryAttributeSurvives) {
  test::TempDir dir;
  const auto c = GetParam();
  AttributeMask mask = kNormal | kColor | kAlpha | kIntensity | kConfidence;
  PointBatch in = sampleBatch(200, mask);
  in.triangles = {{0, 1, 2}, {3, 4, 5}};
  writePly(dir / "a.ply", in, glm::dvec3(0), {c.encoding, c.doubles, c.ushort_colors});
  auto r = readAll(dir / "a.ply", 64);
  ASSERT_EQ(r.points.size(), 200u);
  EXPECT_EQ(r.info.attributes, mask);
  for (size_t i = 0; i < 200; ++i) {
    ASSERT_NEAR(r.points.positions[i].x, in.positions[i].x, c.doubles ? 0 : 1e-4);
    ASSERT_NEAR(r.points.positions[i].z, in.positions[i].z, c.doubles ? 0 : 1e-4);
    ASSERT_EQ(r.points.colors[i], in.colors[i]) << i;
    ASSERT_FLOAT_EQ(r.points.normals[i].y, 0.6f);
    ASSERT_FLOAT_EQ(r.points.intensities[i], in.intensities[i]);
    ASSERT_NEAR(r.points.confidences[i], in.confidences[i], 1e-6);
  }
  ASSERT_EQ(r.points.triangles.size(), 2u);
  EXPECT_EQ(r.points.triangles[1], Triangle(3, 4, 5));
}

INSTANTIATE_TEST_SUITE_P(
    Encodings, PlyRoundTrip,
    ::testing::Values(EncodingCase{PlyEncoding::kAscii, false, false},
                      EncodingCase{PlyEncoding::kAscii, true, true},
                      EncodingCase{PlyEncoding::kBinaryLittleEndian, false, false},
                      EncodingCase{PlyEncoding::kBinaryLittleEndian, true, true},
                      EncodingCase{PlyEncoding::kBinaryBigEndian, false, true},
                      EncodingCase{PlyEncoding::kBinaryBigEndian, true, false}),
    encodingName);

// Hand-written big-endian bytes: independent of our writer.
TEST(PlyReader, BigEndianBytesDecodeIndependently) {
  std::string s =
      "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty double x\n"
      "property float y\nproperty short z\nproperty ushort red\nproperty ushort green\nproperty "
      "ushort blue\nend_header\n";
  const uint8_t rec[] = {0x40, 0x09, 0x21, 0xFB, 0x54, 0x44, 0x2D, 0x18,  // 3.141592653589793
                         0xC0, 0x20, 0x00, 0x00,                          // -2.5f
                         0xFF, 0xFE,                                      // -2
                         0xFF, 0xFF, 0x80, 0x00, 0x00, 0x00};             // 65535, 32768, 0
  s.append(reinterpret_cast<const char*>(rec), sizeof rec);
  auto r = readAllMemory(s, "be.ply");
  ASSERT_EQ(r.points.size(), 1u);
  EXPECT_DOUBLE_EQ(r.points.positions[0].x, 3.141592653589793);
  EXPECT_DOUBLE_EQ(r.points.positions[0].y, -2.5);
  EXPECT_DOUBLE_EQ(r.points.positions[0].z, -2.0);
  EXPECT_EQ(r.points.colors[0], glm::u8vec4(255, 128, 0, 255));
}

TEST(PlyReader, UnknownPropertiesAndElementsAreSkippedBySize) {
  std::string s =
      "ply\nformat binary_little_endian 1.0\ncomment odd layout\nelement camera 1\nproperty double "
      "a\n"
      "element vertex 2\nproperty uchar flags\nproperty float x\nproperty list uchar int tags\n"
      "property float y\nproperty double weird\nproperty float z\nproperty uchar red\nproperty "
      "uchar green\n"
      "property uchar blue\nelement edge 1\nproperty int v1\nproperty int v2\nend_header\n";
  auto put = [&](const void* p, size_t n) { s.append(static_cast<const char*>(p), n); };
  double cam = 9.0;
  put(&cam, 8);
  for (int v = 0; v < 2; ++v) {
    uint8_t flags = 7, ntags = uint8_t(v + 1), rgb[3] = {10, 20, uint8_t(30 + v)};
    float x = 1.f + float(v), y = 2.f, z = 3.f;
    double weird = 1e300;
    put(&flags, 1);
    put(&x, 4);
    put(&ntags, 1);
    for (int k = 0; k < ntags; ++k) {
      int32_t t = 42;
      put(&t, 4);
    }
    put(&y, 4);
    put(&weird, 8);
    put(&z, 4);
    put(rgb, 3);
  }
  int32_t edge[2] = {0, 1};
  put(edge, 8);
  auto r = readAllMemory(s, "odd.ply");
  ASSERT_EQ(r.points.size(), 2u);
  EXPECT_EQ(r.points.positions[1], glm::dvec3(2, 2, 3));
  EXPECT_EQ(r.points.colors[1], glm::u8vec4(10, 20, 31, 255));
}

TEST(PlyReader, PolygonsAreTriangulatedAsFans) {
  std::string s =
      "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float "
      "z\n"
      "element face 2\nproperty list uchar uint vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 2 2\n4 0 1 2 3\n3 2 3 4\n";
  auto r = readAllMemory(s, "quad.ply");
  ASSERT_EQ(r.points.triangles.size(), 3u);
  EXPECT_EQ(r.points.triangles[0], Triangle(0, 1, 2));
  EXPECT_EQ(r.points.triangles[1], Triangle(0, 2, 3));
  EXPECT_EQ(r.points.triangles[2], Triangle(2, 3, 4));
}

TEST(PlyReader, NonFiniteVerticesAreSkippedCountedAndFacesRemapped) {
  std::string s =
      "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float "
      "z\n"
      "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\nnan 0 0\n1 1 0\n0 inf 1\n2 2 2\n3 0 2 4\n3 0 1 2\n";
  auto r = readAllMemory(s, "nan.ply");
  EXPECT_EQ(r.points.size(), 3u);
  EXPECT_EQ(r.stats.skipped.at("non-finite coordinate"), 2u);
  EXPECT_EQ(r.stats.first_skip_at.at("non-finite coordinate"), "line 11");
  // Face 0 1 2 used a skipped vertex: dropped. Face 0 2 4 is renumbered to delivered indices.
  ASSERT_EQ(r.points.triangles.size(), 1u);
  EXPECT_EQ(r.points.triangles[0], Triangle(0, 1, 2));
  EXPECT_EQ(r.stats.skipped.at("face with an out-of-range or skipped vertex"), 1u);
}

TEST(PlyReader, BadHeadersNameTheProblem) {
  EXPECT_NE(
      readErrorOf([] { readAllMemory("plx\nformat ascii 1.0\n", "a.ply"); }).find("not a PLY file"),
      std::string::npos);
  EXPECT_NE(readErrorOf([] { readAllMemory("", "a.ply"); }).find("empty"), std::string::npos);
  std::string unknown = readErrorOf([] {
    readAllMemory("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n",
                  "t.ply");
  });
  EXPECT_NE(unknown.find("t.ply: line 4: unknown property type 'quad'"), std::string::npos)
      << unknown;
  EXPECT_NE(readErrorOf([] {
              readAllMemory("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", "h.ply");
            }).find("no end_header"),
            std::string::npos);
  EXPECT_NE(readErrorOf([] {
              readAllMemory(
                  "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
                  "xy.ply");
            }).find("lacks x, y or z"),
            std::string::npos);
  EXPECT_NE(readErrorOf([] {
              readAllMemory(
                  "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                  "property float z\nend_header\n1 2 zebra\n",
                  "v.ply");
            }).find("line 8: bad value 'zebra'"),
            std::string::npos);
}

TEST(PlyReader, ExtraValuesOnALineNameTheInstance) {
  std::string last = readErrorOf([] {
    readAllMemory(
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n1 2 3\n4 5 6 7\n",
        "extra.ply");
  });
  EXPECT_NE(last.find("line 9: more values than vertex 1 declares ('7' is extra)"),
            std::string::npos)
      << last;
}

TEST(PlyReader, HeaderCountLargerThanDataIsAnErrorWithOffset) {
  std::string s =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n";
  size_t header = s.size();
  s.append(std::string(24, '\0'));  // two vertices of three
  std::string msg = readErrorOf([&] { readAllMemory(s, "short.ply"); });
  EXPECT_NE(msg.find("short.ply: byte " + std::to_string(header + 24) +
                     ": file ends inside vertex 2 of 3"),
            std::string::npos)
      << msg;
}

// Real files cut at many offsets: an error (never a crash, never silently fewer points).
TEST(PlyReader, TruncatedRealFilesFailCleanly) {
  test::TempDir dir;
  for (const std::string name :
       {"/stanford-bunny/scans/bun000.ply", "/stanford-bunny/reconstruction/bun_zipper_res3.ply"}) {
    auto bytes = test::readBytes(kData + name);
    for (double frac : {0.0001, 0.001, 0.01, 0.3, 0.5, 0.9, 0.999}) {
      size_t cut = size_t(double(bytes.size()) * frac);
      std::vector<uint8_t> part(bytes.begin(), bytes.begin() + ptrdiff_t(cut));
      test::writeBytes(dir / "cut.ply", part);
      std::string msg = readErrorOf([&] { readAll(dir / "cut.ply"); });
      EXPECT_NE(msg.find("lod::readPly()"), std::string::npos)
          << name << " cut at " << cut << ": '" << msg << "'";
      EXPECT_NE(msg.find("cut.ply"), std::string::npos) << msg;
    }
  }
  // The binary case too.
  auto r = readAll(kData + "/stanford-bunny/reconstruction/bun_zipper_res3.ply");
  writePly(dir / "bin.ply", r.points, glm::dvec3(0));
  auto bytes = test::readBytes(dir / "bin.ply");
  std::string text(bytes.begin(), bytes.end());
  size_t data = text.find("end_header\n") + 11;
  for (size_t cut : {data + 5, bytes.size() / 2, bytes.size() - 1}) {
    test::writeBytes(dir / "cut.ply",
                     std::vector<uint8_t>(bytes.begin(), bytes.begin() + ptrdiff_t(cut)));
    std::string msg = readErrorOf([&] { readAll(dir / "cut.ply"); });
    EXPECT_NE(msg.find("byte "), std::string::npos) << cut << ": " << msg;
  }
}

TEST(PlyReader, MagicLineWithTrailingBlanksIsRead) {
  // Some exporters write "ply " or "ply\t"; before, "not a PLY file". From memory,
  // and from a file named .ply and not (detection by magic).
  const std::string body =
      "format ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n1 2 3\n4 5 6\n";
  for (const char* magic : {"ply \n", "ply\t\r\n", "ply   \n"}) {
    SCOPED_TRACE(magic);
    EXPECT_EQ(readAllMemory(magic + body, "a.ply").points.size(), 2u);
    test::TempDir dir;
    for (const char* name : {"a.ply", "a.dat"}) {
      test::writeText(dir / name, magic + body);
      auto r = openPointReader(dir / name);
      EXPECT_EQ(r->info().format, Format::kPly);
      EXPECT_EQ(readAll(*r).points.size(), 2u);
    }
  }
  // Still refused: another word after "ply", or no line end in the probe.
  for (const char* bad : {"ply x\nformat ascii 1.0\n", "plyx\nformat ascii 1.0\n"}) {
    const std::string msg = readErrorOf([&] { readAllMemory(bad, "a.ply"); });
    EXPECT_NE(msg.find("not a PLY file"), std::string::npos) << bad << ": " << msg;
  }
}

TEST(PlyReader, FifoAndDevicesAreRefusedNotWaitedOn) {
  test::TempDir dir;
  const auto fifo = dir / "f.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Before: open() blocked forever waiting for a writer.
  std::string msg = readErrorOf([&] { openPointReader(fifo); });
  EXPECT_NE(msg.find("f.ply: not a regular file (a FIFO"), std::string::npos) << msg;
  msg = readErrorOf([] { openPointReader("/dev/null"); });
  EXPECT_NE(msg.find("character device"), std::string::npos) << msg;
}

TEST(PlyReader, MissingFileIsAReadError) {
  std::string msg = readErrorOf([] { openPointReader("/nonexistent/x.ply"); });
  EXPECT_NE(msg.find("/nonexistent/x.ply: no such file"), std::string::npos) << msg;
}

}  // namespace
}  // namespace tessera::lod

namespace tessera::lod {
namespace {

// A range-grid cell larger than the reader's 64 KiB window, read from a file (not memory).
TEST(PlyReader, RangeGridCellLargerThanTheReadWindow) {
  test::TempDir dir;
  std::string s =
      "ply\nformat binary_little_endian 1.0\nobj_info num_cols 2\nobj_info num_rows 1\n"
      "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
      "element range_grid 2\nproperty list int int vertex_indices\nend_header\n";
  float xyz[3] = {1.f, 2.f, 3.f};
  s.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
  int32_t count = 20000, zero = 0, empty = 0;
  s.append(reinterpret_cast<const char*>(&empty), 4);  // cell 0: empty
  s.append(reinterpret_cast<const char*>(&count), 4);  // cell 1: 20000 x vertex 0
  for (int i = 0; i < count; ++i) s.append(reinterpret_cast<const char*>(&zero), 4);
  test::writeText(dir / "big.ply", s);
  auto r = test::readAll(dir / "big.ply");
  ASSERT_EQ(r.points.size(), 1u);
  EXPECT_EQ(r.points.grid_positions[0], glm::u16vec2(1, 0));
}

}  // namespace
}  // namespace tessera::lod

namespace tessera::lod {
namespace {

// A PLY of float x y z vertices and one element of int lists named `element`, its list property
// `vertex_indices` with `count_type` counts, written byte by byte here: independent of the
// reader and of writePly().
std::string plyWithLists(PlyEncoding encoding, const std::vector<glm::vec3>& vertices,
                         const std::string& element, const std::vector<std::vector<int32_t>>& lists,
                         const std::string& count_type = "int") {
  static const char* const kFormat[] = {"ascii", "binary_little_endian", "binary_big_endian"};
  std::string s = std::string("ply\nformat ") + kFormat[int(encoding)] + " 1.0\nelement vertex " +
                  std::to_string(vertices.size()) +
                  "\nproperty float x\nproperty float y\nproperty float z\nelement " + element +
                  " " + std::to_string(lists.size()) + "\nproperty list " + count_type +
                  " int vertex_indices\nend_header\n";
  auto put = [&](const void* p, size_t n) {
    std::string bytes(static_cast<const char*>(p), n);
    if (encoding == PlyEncoding::kBinaryBigEndian) std::reverse(bytes.begin(), bytes.end());
    s += bytes;
  };
  auto number = [&](auto v) {
    if (encoding == PlyEncoding::kAscii) {
      s += std::to_string(v) + " ";
    } else {
      put(&v, sizeof v);
    }
  };
  for (const glm::vec3& v : vertices) {
    for (int axis = 0; axis < 3; ++axis) number(v[axis]);
    if (encoding == PlyEncoding::kAscii) s += "\n";
  }
  for (const auto& list : lists) {
    if (count_type == "uchar") {
      number(uint8_t(list.size()));
    } else {
      number(int32_t(list.size()));
    }
    for (int32_t i : list) number(i);
    if (encoding == PlyEncoding::kAscii) s += "\n";
  }
  return s;
}

// Vertices 0..3 and 4..6 in the z = 0 plane: the strip's first triangle faces -z.
const std::vector<glm::vec3> kStripVertices = {{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {1, 1, 0},
                                               {3, 0, 0}, {3, 1, 0}, {4, 0, 0}};

double normalZ(const PointBatch& b, const Triangle& t) {
  return glm::cross(b.positions[t.y] - b.positions[t.x], b.positions[t.z] - b.positions[t.x]).z;
}

class PlyStrips : public ::testing::TestWithParam<PlyEncoding> {};

TEST_P(PlyStrips, StripsGiveTrianglesWithTheFirstOnesWinding) {
  for (const char* count_type : {"int", "uchar"}) {
    SCOPED_TRACE(count_type);
    auto r = readAllMemory(plyWithLists(GetParam(), kStripVertices, "tristrips",
                                        {{0, 1, 2, 3, -1, 4, 5, 6}}, count_type),
                           "strip.ply");
    ASSERT_EQ(r.points.size(), 7u);
    ASSERT_EQ(r.points.triangles.size(), 3u);
    EXPECT_EQ(r.points.triangles[0], Triangle(0, 1, 2));
    EXPECT_EQ(r.points.triangles[1], Triangle(2, 1, 3));  // odd: the first two swap
    EXPECT_EQ(r.points.triangles[2], Triangle(4, 5, 6));  // after -1 a new strip starts even
    for (const Triangle& t : r.points.triangles) EXPECT_LT(normalZ(r.points, t), 0.0);
    EXPECT_EQ(r.stats.triangles, 3u);
    EXPECT_TRUE(r.stats.skipped.empty());
    EXPECT_GE(r.info.declared_triangles, 3u);  // an upper bound: the header has no count
  }
}

// A 0xFFFFFFFF restart in an unsigned list, big-endian bytes written by hand.
TEST(PlyReader, UnsignedStripListsRestartAtAllOnes) {
  std::string s =
      "ply\nformat binary_big_endian 1.0\nelement vertex 6\nproperty uchar x\nproperty uchar "
      "y\nproperty uchar z\nelement tristrips 1\nproperty list ushort uint vertex_indices\n"
      "end_header\n";
  for (uint8_t i = 0; i < 6; ++i) s += std::string{char(i), char(i * i), char(1)};
  s += std::string("\x00\x07", 2);
  for (uint32_t i : {0u, 1u, 2u, 0xFFFFFFFFu, 3u, 4u, 5u})
    s += std::string{char(i >> 24), char(i >> 16), char(i >> 8), char(i)};
  auto r = readAllMemory(s, "be_strip.ply");
  ASSERT_EQ(r.points.triangles.size(), 2u);
  EXPECT_EQ(r.points.triangles[0], Triangle(0, 1, 2));
  EXPECT_EQ(r.points.triangles[1], Triangle(3, 4, 5));
}

TEST_P(PlyStrips, DegenerateTrianglesAndShortStripsAreSkippedAndCounted) {
  // 0 1 1 2 3: (0,1,1) and, odd, (1,1,2) repeat a vertex; (1,2,3) is even again. 5 6: too short.
  auto r = readAllMemory(
      plyWithLists(GetParam(), kStripVertices, "tristrips", {{0, 1, 1, 2, 3, -1, 5, 6}, {4}}),
      "degenerate.ply");
  ASSERT_EQ(r.points.triangles.size(), 1u);
  EXPECT_EQ(r.points.triangles[0], Triangle(1, 2, 3));
  EXPECT_EQ(r.stats.skipped.at("degenerate strip triangle (a vertex repeated)"), 2u);
  EXPECT_EQ(r.stats.first_skip_at.at("degenerate strip triangle (a vertex repeated)"),
            "tristrips 0, index 2");
  EXPECT_EQ(r.stats.skipped.at("strip with fewer than 3 vertices"), 2u);
  EXPECT_EQ(r.stats.first_skip_at.at("strip with fewer than 3 vertices"), "tristrips 0, index 6");
}

TEST_P(PlyStrips, TrianglesWithABadOrSkippedVertexAreSkippedAsFacesAre) {
  // Index 99 is out of range: the three triangles using it go, the rest of the strip stays, its
  // parity unchanged. Vertex 6 is not finite (skipped) and -7 is no vertex.
  std::vector<glm::vec3> vertices = kStripVertices;
  vertices[6].x = std::numeric_limits<float>::quiet_NaN();
  auto r = readAllMemory(
      plyWithLists(GetParam(), vertices, "tristrips", {{0, 1, 2, 99, 3, 4, 5, 6, -1, -7, 0, 1}}),
      "bad.ply");
  const std::string reason = "strip triangle with an out-of-range or skipped vertex";
  EXPECT_EQ(r.points.size(), 6u);
  ASSERT_EQ(r.points.triangles.size(), 2u);
  EXPECT_EQ(r.points.triangles[0], Triangle(0, 1, 2));
  EXPECT_EQ(r.points.triangles[1], Triangle(3, 4, 5));  // even: k = 4
  // (2,1,99), (2,99,3), (3,99,4), (5,4,6) and (-7,0,1).
  EXPECT_EQ(r.stats.skipped.at(reason), 5u);
  EXPECT_EQ(r.stats.first_skip_at.at(reason), "tristrips 0, index 3");
}

test::ReadResult readMemory(const std::string& bytes, const std::string& name, size_t batch_size) {
  auto reader = openPointReader(
      std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()), name);
  return readAll(*reader, batch_size);
}

TEST_P(PlyStrips, AGridAsStripsAndAsFacesGivesTheSameTriangles) {
  // A 30 x 20 grid: one strip per row of quads, b0 t0 b1 t1 ..., all in one list with -1
  // between rows (as Stanford's strip writer does). The faces list the triangles that strip
  // order makes, written by formula: (b_j, t_j, b_j+1) and (b_j+1, t_j, t_j+1).
  const int w = 30, h = 20;
  std::vector<glm::vec3> vertices;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) vertices.emplace_back(float(x), float(y), float(x * y) * 0.01f);
  std::vector<int32_t> strips;
  std::vector<std::vector<int32_t>> faces;
  for (int y = 0; y + 1 < h; ++y) {
    if (y > 0) strips.push_back(-1);
    for (int x = 0; x < w; ++x) {
      const int32_t b = y * w + x, t = (y + 1) * w + x;
      strips.push_back(b);
      strips.push_back(t);
      if (x + 1 < w) {
        faces.push_back({b, t, b + 1});
        faces.push_back({b + 1, t, t + 1});
      }
    }
  }
  const auto as_faces = readAllMemory(plyWithLists(GetParam(), vertices, "face", faces), "f.ply");
  ASSERT_EQ(as_faces.points.triangles.size(), size_t(2 * (w - 1) * (h - 1)));
  const std::string strip_bytes = plyWithLists(GetParam(), vertices, "tristrips", {strips});
  for (size_t batch : {size_t(7), size_t(1000)}) {  // 7: batches end inside the list
    SCOPED_TRACE(batch);
    const auto as_strips = readMemory(strip_bytes, "s.ply", batch);
    EXPECT_EQ(as_strips.points.triangles, as_faces.points.triangles);
    EXPECT_EQ(as_strips.stats.triangles, as_faces.stats.triangles);
    EXPECT_TRUE(as_strips.stats.skipped.empty());
  }
  // The mesh path reads them too (before, "no triangles (a point cloud, not a mesh)").
  test::TempDir dir;
  test::writeText(dir / "s.ply", strip_bytes);
  EXPECT_EQ(readMesh(dir / "s.ply").triangles, as_faces.points.triangles);
}

TEST_P(PlyStrips, AListLongerThanTheFileIsAnError) {
  std::string s = plyWithLists(GetParam(), kStripVertices, "tristrips", {{0, 1, 2, 3}});
  // Cut inside the list: the last index (and, in ASCII, the line end) are missing.
  s.resize(s.size() - (GetParam() == PlyEncoding::kAscii ? 3 : 2));
  const std::string msg = readErrorOf([&] { readAllMemory(s, "cut.ply"); });
  EXPECT_NE(msg.find("cut.ply: byte "), std::string::npos) << msg;
  EXPECT_NE(msg.find("file ends inside tristrips 0 of 1"), std::string::npos) << msg;
  // A length no file this size can hold is refused before reading on.
  std::string lying = plyWithLists(GetParam(), kStripVertices, "tristrips", {{0, 1, 2}});
  const uint32_t n = 1000000000;
  if (GetParam() == PlyEncoding::kAscii) {
    lying.replace(lying.rfind("3 0 1 2"), 1, std::to_string(n));
  } else {
    const bool be = GetParam() == PlyEncoding::kBinaryBigEndian;
    for (int k = 0; k < 4; ++k)
      lying[lying.size() - 16 + size_t(k)] = char(n >> (8 * (be ? 3 - k : k)));
  }
  const std::string lie = readErrorOf([&] { readAllMemory(lying, "lie.ply"); });
  EXPECT_NE(lie.find("lie.ply: byte " + std::to_string(lying.size()) +
                     ": file ends inside tristrips 0 of 1"),
            std::string::npos)
      << lie;
}

// An element that looks like faces but that the reader does not triangulate is named, not
// dropped (which would read the mesh as a point cloud with nothing said).
TEST(PlyReader, FacesItCannotReadAreNamedInTheError) {
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\n";
  const std::string verts = "0 0 0\n1 0 0\n0 1 0\n";
  for (const auto& [element, name] : std::vector<std::pair<std::string, std::string>>{
           {"element faces 1\nproperty list uchar int vertex_indices\n", "'faces' (1 instances)"},
           {"element face 1\nproperty list uchar int corners\n", "'face' (1 instances)"},
           {"element tristrips 1\nproperty list int int indices\n", "'tristrips' (1 instances)"},
           {"element quadstrip 1\nproperty int a\n", "'quadstrip' (1 instances)"},
           {"element polygon 1\nproperty list uchar int vertex_index\n",
            "'polygon' (1 instances)"}}) {
    SCOPED_TRACE(element);
    const std::string msg = readErrorOf(
        [&] { readAllMemory(head + element + "end_header\n" + verts + "3 0 1 2\n", "e.ply"); });
    EXPECT_NE(msg.find("e.ply: line 7: element " + name + " looks like faces but is not read"),
              std::string::npos)
        << msg;
    EXPECT_NE(msg.find("'tristrips'"), std::string::npos) << msg;
  }
  // An empty one loses nothing: read.
  EXPECT_EQ(readAllMemory(head + "element face 0\nend_header\n" + verts, "e.ply").points.size(),
            3u);
}

std::string plyEncodingName(const ::testing::TestParamInfo<PlyEncoding>& i) {
  static const char* const kEnc[] = {"ascii", "binary_le", "binary_be"};
  return kEnc[int(i.param)];
}

INSTANTIATE_TEST_SUITE_P(Encodings, PlyStrips,
                         ::testing::Values(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian,
                                           PlyEncoding::kBinaryBigEndian),
                         plyEncodingName);

}  // namespace
}  // namespace tessera::lod
