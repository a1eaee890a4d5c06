// Wall layouts the cluster benchmarks share (bench/cluster_frames, bench/cluster_link).
#pragma once

#include <cstdint>
#include <sstream>
#include <string>

namespace tessera::bench {

/// A wall of k = 1, 2, 4 or 8 tiles in a grid (1x1, 2x1, 2x2, 4x2) covering `w` x `h` pixels at
/// 1 mm per pixel, no bezels, the eye 2 m in front of the centre; tiles named tile-COL-ROW.
inline std::string gridWallJson(int k, uint32_t w, uint32_t h) {
  const int cols = k == 1 ? 1 : k == 2 ? 2 : k == 4 ? 2 : 4, rows = k / cols;
  const uint32_t tw = w / uint32_t(cols), th = h / uint32_t(rows);
  std::ostringstream j;
  j << "{\"name\": \"" << cols << "x" << rows << " bench wall\", \"tiles\": [";
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      j << (r || c ? ", " : "") << "{\"name\": \"tile-" << c << "-" << r
        << "\", \"x\": " << c * tw * 1e-3 << ", \"y\": " << (rows - 1 - r) * th * 1e-3
        << ", \"width\": " << tw * 1e-3 << ", \"height\": " << th * 1e-3
        << ", \"pixelWidth\": " << tw << ", \"pixelHeight\": " << th << "}";
    }
  }
  j << "], \"eye\": {\"x\": " << cols * tw * 0.5e-3 << ", \"y\": " << rows * th * 0.5e-3
    << ", \"z\": 2.0}}";
  return j.str();
}

}  // namespace tessera::bench
