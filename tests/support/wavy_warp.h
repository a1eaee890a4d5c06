// A projector's warp grid for tests (render/projector_pass.h): the picture kept inside its
// rectangle with a gentle wave across it, as a PFM's values. Header-only.
#pragma once

#include <cmath>
#include <cstdint>

#include <tessera/render/projector_pass.h>

namespace tessera::test {

/// A warp grid that keeps the picture inside its rectangle with a wave across it.
inline render::FloatImage wavyWarp(uint32_t w, uint32_t h, double phase) {
  render::FloatImage pfm;
  pfm.width = w;
  pfm.height = h;
  pfm.channels = 3;
  for (uint32_t j = 0; j < h; ++j)
    for (uint32_t i = 0; i < w; ++i) {
      const double s = double(i) / (w - 1), t = double(j) / (h - 1);
      pfm.values.push_back(float(0.02 + 0.96 * s + 0.015 * std::sin(6.0 * t + phase)));
      pfm.values.push_back(float(0.03 + 0.94 * t + 0.01 * std::sin(5.0 * s + phase)));
      pfm.values.push_back(0.0f);
    }
  return pfm;
}

}  // namespace tessera::test
