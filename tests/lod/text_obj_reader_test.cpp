// XYZ/PTS/TXT point lists and OBJ meshes.
#include <gtest/gtest.h>

#include <tessera/lod/point_reader.h>

#include "../support/read_all.h"

namespace tessera::lod {
namespace {

using test::readAllMemory;
using test::readErrorOf;

TEST(TextReader, ColumnLayouts) {
  auto r3 = readAllMemory("1 2 3\n4 5 6\n", "a.xyz");
  ASSERT_EQ(r3.points.size(), 2u);
  EXPECT_EQ(r3.info.attributes, 0u);
  EXPECT_EQ(r3.points.positions[1], glm::dvec3(4, 5, 6));

  auto r4 = readAllMemory("1,2,3,0.5\r\n4,5,6,0.25\r\n", "a.txt");
  ASSERT_EQ(r4.points.size(), 2u);
  EXPECT_EQ(r4.info.attributes, uint32_t(kIntensity));
  EXPECT_FLOAT_EQ(r4.points.intensities[1], 0.25f);

  auto r6 = readAllMemory("# comment\n1 2 3 255 128 0\n", "a.xyz");
  EXPECT_EQ(r6.info.attributes, uint32_t(kColor));
  EXPECT_EQ(r6.points.colors[0], glm::u8vec4(255, 128, 0, 255));

  // PTS: count line, then x y z intensity r g b.
  auto pts =
      readAllMemory("2\n636001.761 848935.201 406.26 -1200 10 20 30\n1 2 3 5 1 2 3\n", "scan.pts");
  ASSERT_EQ(pts.points.size(), 2u);
  EXPECT_TRUE(pts.info.has_declared_points);
  EXPECT_EQ(pts.info.declared_points, 2u);
  EXPECT_DOUBLE_EQ(pts.points.positions[0].x, 636001.761);
  EXPECT_FLOAT_EQ(pts.points.intensities[0], -1200.f);
  EXPECT_EQ(pts.points.colors[0], glm::u8vec4(10, 20, 30, 255));

  auto named = readAllMemory("X;Y;Z;Red;Green;Blue;extra\n1;2;3;4;5;6;7\n", "n.csv");
  EXPECT_EQ(named.info.attributes, uint32_t(kColor));
  EXPECT_EQ(named.points.colors[0], glm::u8vec4(4, 5, 6, 255));
}

TEST(TextReader, NonFiniteRowsAreSkippedAndCounted) {
  auto r = readAllMemory("1 2 3\nnan 2 3\n4 inf 6\n7 8 9\n", "n.xyz");
  EXPECT_EQ(r.points.size(), 2u);
  EXPECT_EQ(r.stats.skipped.at("non-finite coordinate"), 2u);
  EXPECT_EQ(r.stats.first_skip_at.at("non-finite coordinate"), "line 2");
}

TEST(TextReader, BadRowsNameTheLine) {
  EXPECT_NE(readErrorOf([] {
              readAllMemory("1 2 3\n1 2\n", "a.xyz");
            }).find("a.xyz: line 2: 2 values; expected 3"),
            std::string::npos);
  EXPECT_NE(readErrorOf([] {
              readAllMemory("1 2 3\n1 two 3\n", "a.xyz");
            }).find("line 2: value 2 is not a number: 'two'"),
            std::string::npos);
  EXPECT_NE(readErrorOf([] { readAllMemory("1 2 3 4 5\n", "a.xyz"); }).find("5 values per line"),
            std::string::npos);
  EXPECT_NE(readErrorOf([] {
              readAllMemory("3\n1 2 3\n", "a.pts");
            }).find("file ends after 1 points; the count line declares 3"),
            std::string::npos);
  EXPECT_NE(readErrorOf([] {
              readAllMemory("1\n1 2 3\n4 5 6\n", "a.pts");
            }).find("line 3: more points than the 1"),
            std::string::npos);
  EXPECT_NE(readErrorOf([] { readAllMemory("# only a comment\n", "a.xyz"); }).find("no points"),
            std::string::npos);
}

TEST(ObjReader, VerticesColoursAndPolygons) {
  auto r = readAllMemory(
      "# cube corner\nmtllib x.mtl\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 1 1 0 0 0 1\nv 0 1 0 0.5 0.5 "
      "0.5\n"
      "vn 0 0 1\nvt 0 0\nusemtl m\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4 -2 -1\n",
      "quad.obj");
  ASSERT_EQ(r.points.size(), 4u);
  EXPECT_TRUE(r.info.attributes & kColor);
  EXPECT_EQ(r.points.colors[0], glm::u8vec4(255, 0, 0, 255));
  EXPECT_EQ(r.points.colors[3], glm::u8vec4(128, 128, 128, 255));
  ASSERT_EQ(r.points.triangles.size(), 3u);
  EXPECT_EQ(r.points.triangles[1], Triangle(0, 2, 3));
  EXPECT_EQ(r.points.triangles[2], Triangle(0, 2, 3));
}

TEST(ObjReader, BadInput) {
  auto r =
      readAllMemory("v 0 0 0\nv nan 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\nf 1 3 4\nf 1 3 9\n", "n.obj");
  EXPECT_EQ(r.points.size(), 3u);
  ASSERT_EQ(r.points.triangles.size(), 1u);
  EXPECT_EQ(r.points.triangles[0], Triangle(0, 1, 2));
  EXPECT_EQ(r.stats.skipped.at("face with an out-of-range or skipped vertex"), 2u);
  EXPECT_NE(readErrorOf([] {
              readAllMemory("v 0 0 zero\n", "b.obj");
            }).find("b.obj: line 1: bad vertex value 'zero'"),
            std::string::npos);
  EXPECT_NE(readErrorOf([] {
              readAllMemory("v 0 0 0\nf 1 x 1\n", "b.obj");
            }).find("line 2: bad face index 'x'"),
            std::string::npos);
}

TEST(Detection, UnknownFormatsAreNamed) {
  EXPECT_NE(readErrorOf([] { readAllMemory("hello", "a.bin"); }).find("unknown point format"),
            std::string::npos);
  EXPECT_NE(readErrorOf([] { readAllMemory("hello", "a.las"); }).find("not a LAS file"),
            std::string::npos);
}

}  // namespace
}  // namespace tessera::lod
