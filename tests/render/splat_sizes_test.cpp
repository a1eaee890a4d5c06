#include <tessera/render/splat_sizes.h>

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace tessera::render {
namespace {

/// Scan lines on a tilted plane: `along` apart on each line, lines `across` apart.
std::vector<glm::vec3> scanLines(int lines, int per_line, float along, float across) {
  const glm::vec3 n = glm::normalize(glm::vec3(0.1f, 0.2f, 1.0f));
  const glm::vec3 a = glm::normalize(glm::cross(n, glm::vec3(1, 0, 0))), b = glm::cross(n, a);
  std::vector<glm::vec3> pts;
  for (int l = 0; l < lines; ++l)
    for (int i = 0; i < per_line; ++i) pts.push_back(float(i) * along * a + float(l) * across * b);
  return pts;
}

TEST(SplatSizes, ScanLinesGetTheDiscThatClosesTheirGaps) {
  // Lines 4 apart, points 1 apart on them: a cell is the 1 x 4 rectangle around its point, so
  // the disc that closes the surface has the rectangle's half-diagonal, sqrt(0.5^2 + 2^2).
  const std::vector<glm::vec3> pts = scanLines(30, 120, 1.0f, 4.0f);
  const double spacing = 1.5;
  const std::vector<uint8_t> codes = splatScales(pts, spacing);
  ASSERT_EQ(codes.size(), pts.size());
  const double expected = std::hypot(0.5, 2.0) / spacing;
  size_t inner = 0, right = 0;
  for (int l = 2; l < 28; ++l)
    for (int i = 4; i < 116; ++i) {
      const uint32_t rgba = uint32_t(codes[size_t(l) * 120 + i]) << 24;
      ++inner;
      right += std::abs(pointSplatScale(rgba) - expected) < 1.0 / 64.0;
    }
  EXPECT_EQ(right, inner) << "expected scale " << expected;
}

}  // namespace
}  // namespace tessera::render
