// The point chunk codec (lod/src/chunk_codec.h, byte_streams.h): exact cells on the input's
// lattice, lossy cells within their bound, every attribute kept, format 1 chunks of older stores
// still decoded, and damaged chunks refused without reading outside their bytes (run under
// ASan by the asan preset).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <random>
#include <tuple>

#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_store.h>

#include "byte_streams.h"
#include "chunk_codec.h"

namespace tessera::lod {
namespace {

const std::filesystem::path kData = TESSERA_DATA_DIR;
const std::filesystem::path kSeeds =
    std::filesystem::path(TESSERA_FUZZ_REGRESSIONS) / ".." / "seeds";
constexpr AttributeMask kAll = kColor | kIntensity | kScanIndex | kClassification;

/// Points on the lattice of `step` (local frame), spread over a terrain-like sheet in a box
/// whose minimum is not on the lattice, with attributes drawn at random.
std::vector<BuildPoint> latticePoints(size_t n, const glm::dvec3& box_min, double extent,
                                      double step, uint32_t seed, int flat_axis = 2) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<BuildPoint> pts(n);
  for (auto& p : pts) {
    glm::dvec3 r(u(rng), u(rng), u(rng));
    r[flat_axis] = 0.3 + 0.05 * std::sin(6.0 * r[(flat_axis + 1) % 3]) + 0.01 * u(rng);
    const glm::dvec3 world = box_min + r * extent;
    p.position = glm::round(world / step) * step;
    for (int a = 0; a < 3; ++a) {  // stay inside the box, on the lattice
      if (p.position[a] < box_min[a]) p.position[a] += step;
      if (p.position[a] > box_min[a] + extent) p.position[a] -= step;
    }
    p.rgb = glm::u8vec3(rng() & 255, 100 + (rng() & 7), rng() & 255);
    p.intensity = uint16_t(rng() & 4095);
    p.source = uint16_t(rng() % 3);
    p.classification = uint8_t(2 + rng() % 4);
    p.ao = 255;
  }
  return pts;
}

ChunkPoints roundTrip(std::vector<BuildPoint>& pts, const glm::dvec3& box_min, double extent,
                      double step, AttributeMask a, bool lattice, EncodedChunk* enc_out = nullptr) {
  EncodedChunk enc = encodeChunk(pts, box_min, extent, step, a, 3, lattice);
  ChunkPoints out;
  decodeChunk(enc.bytes, box_min, out, "test chunk");
  if (enc_out) *enc_out = std::move(enc);
  return out;
}

TEST(ChunkCodec, LatticeCellsAreTheInputsOwnIntegersBitForBit) {
  // A box whose minimum lies between lattice points, as octree cells do.
  const glm::dvec3 box_min(-12.3456789, 7.0000123, 101.99);
  const double step = 0.01, extent = 37.5;
  for (int axis = 0; axis < 3; ++axis) {
    auto pts = latticePoints(20000, box_min, extent, step, 7u + uint32_t(axis), axis);
    const auto in = pts;
    EncodedChunk enc;
    ChunkPoints out = roundTrip(pts, box_min, extent, step, kAll, true, &enc);
    ASSERT_EQ(out.size(), in.size());
    EXPECT_LE(enc.max_error, 1e-9);
    EXPECT_EQ(out.step, step);
    // The encoder reorders `pts` into the decoded order: compare point by point.
    for (size_t i = 0; i < out.size(); ++i) {
      const glm::dvec3 cell = glm::round((glm::dvec3(out.positions[i]) - out.grid) / out.step);
      const glm::dvec3 stored = out.offset + out.grid + cell * out.step;
      // The stored integer is the input's own: round(x / step) in the local frame.
      ASSERT_EQ(glm::round(stored / step), glm::round(pts[i].position / step)) << i;
      ASSERT_LE(glm::length(stored - pts[i].position), 1e-9) << i;
      ASSERT_EQ(out.colors[i], glm::u8vec4(pts[i].rgb, 255)) << i;
      ASSERT_EQ(out.intensities[i], pts[i].intensity);
      ASSERT_EQ(out.sources[i], pts[i].source);
      ASSERT_EQ(out.classifications[i], pts[i].classification);
    }
    // The same multiset of points as went in.
    auto key = [](const BuildPoint& p) {
      return std::tuple(p.position.x, p.position.y, p.position.z, p.intensity);
    };
    std::vector<std::tuple<double, double, double, uint16_t>> a, b;
    for (const auto& p : in) a.push_back(key(p));
    for (const auto& p : pts) b.push_back(key(p));
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    EXPECT_EQ(a, b);
  }
}

TEST(ChunkCodec, LossyCellsStayWithinHalfTheirStepDiagonal) {
  const glm::dvec3 box_min(3.25, -1.5, 0.0);
  auto pts = latticePoints(5000, box_min, 10.0, 1e-4, 3);
  const double step = 0.07;
  ChunkPoints out = roundTrip(pts, box_min, 10.0, step, kColor, false);
  ASSERT_EQ(out.size(), pts.size());
  EXPECT_EQ(out.grid, glm::dvec3(0.0));
  EXPECT_TRUE(out.intensities.empty());
  for (size_t i = 0; i < out.size(); ++i) {
    const glm::dvec3 stored = out.offset + glm::dvec3(out.positions[i]);
    ASSERT_LE(glm::length(stored - pts[i].position), step * std::sqrt(3.0) / 2.0 + 1e-5) << i;
  }
}

TEST(ChunkCodec, EdgeCasesRoundTrip) {
  const glm::dvec3 box_min(0.0);
  // No points; one point; every point the same (constant streams); ambient occlusion alone.
  for (size_t n : {size_t(0), size_t(1), size_t(300)}) {
    std::vector<BuildPoint> pts(n);
    for (size_t i = 0; i < n; ++i) {
      pts[i].position = glm::dvec3(1.0, 2.0, 3.0);
      pts[i].rgb = glm::u8vec3(9, 9, 9);
      pts[i].ao = uint8_t(i * 7);
    }
    ChunkPoints out = roundTrip(pts, box_min, 4.0, 0.5, kColor | kAmbientOcclusion, true);
    ASSERT_EQ(out.size(), n);
    for (size_t i = 0; i < n; ++i) {
      EXPECT_EQ(glm::dvec3(out.positions[i]), glm::dvec3(1.0, 2.0, 3.0));
      EXPECT_EQ(out.ambient_occlusion[i], pts[i].ao);
    }
  }
  // A node 2^30 steps wide: cells of 31 bits per axis still decode exactly.
  {
    const double step = 1.0, extent = double(1u << 30);
    std::vector<BuildPoint> pts(3);
    pts[0].position = glm::dvec3(0.0);
    pts[1].position = glm::dvec3(extent);
    pts[2].position = glm::dvec3(extent, 0.0, 12345.0);
    EncodedChunk enc;
    ChunkPoints out = roundTrip(pts, box_min, extent, step, 0, true, &enc);
    EXPECT_EQ(enc.step, step);
    for (size_t i = 0; i < 3; ++i) {
      const glm::dvec3 cell = glm::round((glm::dvec3(out.positions[i]) - out.grid) / out.step);
      EXPECT_EQ(cell, pts[i].position) << i;
    }
  }
}

TEST(ChunkCodec, ByteStreamsRoundTripEveryMode) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 40; ++trial) {
    const size_t n = size_t(rng() % 5000);
    std::vector<uint8_t> s(n);
    const int kind = trial % 4;
    for (auto& v : s)
      v = kind == 0   ? uint8_t(rng())  // flat: stored
          : kind == 1 ? uint8_t(std::min(255.0, std::abs(std::normal_distribution<>(0, 3)(rng))))
          : kind == 2 ? uint8_t(rng() % 2 ? 0 : rng())  // skewed, all symbols
                      : uint8_t(42);                    // constant
    for (int level : {0, 3}) {
      std::vector<uint8_t> packed;
      detail::packStream(s, packed, level);
      std::vector<uint8_t> back(n + 1, 0xEE);
      ASSERT_TRUE(detail::unpackStream(packed, n, back.data())) << trial;
      EXPECT_TRUE(std::equal(s.begin(), s.end(), back.begin())) << trial;
      EXPECT_EQ(back[n], 0xEE) << "wrote past the end";
      if (n > 100 && kind == 1) {
        EXPECT_LT(packed.size(), n / 2) << "no compression";
      }
      // One byte fewer is always refused.
      if (!packed.empty()) {
        EXPECT_FALSE(
            detail::unpackStream(std::span(packed).first(packed.size() - 1), n, back.data()));
      }
    }
  }
}

TEST(ChunkCodec, FormatOneChunksOfOlderStoresStillDecode) {
  // The one-node version 2 store of 1.2-with-color.las (1065 points), its chunk as the fuzz
  // seed keeps it: the same points as the file, within the lossy bound it was written with.
  std::ifstream f(kSeeds / "chunk" / "format1-color.chunk", std::ios::binary);
  ASSERT_TRUE(f) << "missing seed";
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(f)), {});
  ASSERT_EQ(bytes[25], 0);  // format 1
  ChunkPoints out;
  decodeChunk(bytes, glm::dvec3(0.0), out, "format1-color.chunk");
  EXPECT_EQ(out.size(), 1065u);
  EXPECT_EQ(out.colors.size(), 1065u);
  EXPECT_EQ(out.intensities.size(), 1065u);
  EXPECT_EQ(out.grid, glm::dvec3(0.0));
  uint64_t colour_sum = 0;
  for (const auto& c : out.colors) colour_sum += c.r + c.g + c.b;
  EXPECT_GT(colour_sum, 0u);
  // Format 1 as stores of version 1-3 were written: every point and attribute comes back.
  const glm::dvec3 box_min(2.0);
  auto pts = latticePoints(4000, box_min, 8.0, 0.001, 21);
  EncodedChunk enc = encodeChunkFormat1(pts, box_min, 8.0, 0.004, kAll, 3);
  ASSERT_EQ(enc.bytes[25], 0);
  ChunkPoints back;
  decodeChunk(enc.bytes, box_min, back, "format 1");
  ASSERT_EQ(back.size(), pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    ASSERT_LE(glm::length(back.offset + glm::dvec3(back.positions[i]) - pts[i].position),
              0.004 * std::sqrt(3.0) / 2.0 + 1e-5);
    ASSERT_EQ(back.colors[i], glm::u8vec4(pts[i].rgb, 255));
    ASSERT_EQ(back.intensities[i], pts[i].intensity);
    ASSERT_EQ(back.classifications[i], pts[i].classification);
  }
}

TEST(ChunkCodec, DamagedChunksAreRefusedAndNeverReadOutsideTheirBytes) {
  const glm::dvec3 box_min(0.5);
  auto pts = latticePoints(3000, box_min, 20.0, 0.01, 5);
  EncodedChunk enc = encodeChunk(pts, box_min, 20.0, 0.01, kAll | kAmbientOcclusion, 3, true);
  const std::vector<uint8_t>& good = enc.bytes;
  size_t refused = 0, decoded = 0;
  auto attempt = [&](std::vector<uint8_t> b) {
    // An exact-size heap copy: ASan catches any read past it.
    auto heap = std::make_unique<uint8_t[]>(b.size());
    if (!b.empty()) std::memcpy(heap.get(), b.data(), b.size());
    ChunkPoints out;
    try {
      decodeChunk(std::span<const uint8_t>(heap.get(), b.size()), box_min, out, "damaged");
      ++decoded;
      ASSERT_EQ(out.positions.size(), out.colors.size());
      for (const auto& p : out.positions) ASSERT_TRUE(std::isfinite(p.x + p.y + p.z));
    } catch (const StoreError& e) {
      ++refused;
      EXPECT_NE(std::string(e.what()).find("damaged: corrupt chunk"), std::string::npos)
          << e.what();
    }
  };
  for (size_t len = 0; len < good.size(); len += 1 + len / 64) {
    attempt(std::vector<uint8_t>(good.begin(), good.begin() + ptrdiff_t(len)));
  }
  std::mt19937 rng(99);
  for (int i = 0; i < 3000; ++i) {
    auto b = good;
    const int flips = 1 + int(rng() % 3);
    for (int k = 0; k < flips; ++k) b[rng() % b.size()] ^= uint8_t(1u << (rng() % 8));
    attempt(b);
  }
  EXPECT_GT(refused, 2000u);  // truncations and most flips are caught by the stream checks
  EXPECT_GT(decoded + refused, 3000u);
}

}  // namespace
}  // namespace tessera::lod
