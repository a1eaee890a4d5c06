// Picture measures the rendering benchmarks share (render_lod, edl).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdlib>

#include <tessera/render/image.h>

namespace tessera::bench {

/// PSNR of the RGB channels, dB (99 for equal images); with `box` > 1, of the images averaged
/// over box x box blocks first (what a viewer a few metres from the wall resolves: the scan's
/// sub-millimetre noise makes eye-dome lighting speckle pixel by pixel, which the raw PSNR
/// counts as error). Both images must have the same size.
inline double psnr(const render::Image& a, const render::Image& b, uint32_t box = 1) {
  double se = 0;
  size_t n = 0;
  for (uint32_t y = 0; y + box <= a.height; y += box)
    for (uint32_t x = 0; x + box <= a.width; x += box)
      for (int c = 0; c < 3; ++c) {
        double sa = 0, sb = 0;
        for (uint32_t dy = 0; dy < box; ++dy)
          for (uint32_t dx = 0; dx < box; ++dx) {
            const size_t i = (size_t(y + dy) * a.width + x + dx) * 4 + size_t(c);
            sa += a.rgba[i];
            sb += b.rgba[i];
          }
        const double d = (sa - sb) / double(box * box);
        se += d * d;
        ++n;
      }
  const double mse = se / double(n);
  return mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 99.0;
}

/// Mean absolute difference of the RGB channels over every pixel, grey levels (0..255): the
/// flicker measure when `a` and `b` are two frames of a small camera move.
inline double meanAbsChange(const render::Image& a, const render::Image& b) {
  uint64_t sum = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4)
    for (size_t c = 0; c < 3; ++c) sum += uint64_t(std::abs(int(a.rgba[i + c]) - b.rgba[i + c]));
  return double(sum) / double(a.rgba.size() / 4 * 3);
}

}  // namespace tessera::bench
