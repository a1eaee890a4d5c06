// Picture measures and figure helpers the rendering benchmarks share (render_lod, edl, fill).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include <glm/glm.hpp>

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

/// PSNR of the RGB channels over the pixels where either image shows something other than
/// `background` (the model's pixels: a model small in the view would otherwise gain from the
/// empty pixels around it), dB; 99 for equal images or none covered.
inline double psnrCovered(const render::Image& a, const render::Image& b,
                          glm::u8vec3 background = {0, 0, 0}) {
  double se = 0;
  size_t n = 0;
  auto empty = [&](const render::Image& img, size_t i) {
    return img.rgba[i] == background.r && img.rgba[i + 1] == background.g &&
           img.rgba[i + 2] == background.b;
  };
  for (size_t i = 0; i < a.rgba.size(); i += 4) {
    if (empty(a, i) && empty(b, i)) continue;
    for (size_t c = 0; c < 3; ++c) {
      const double d = double(a.rgba[i + c]) - double(b.rgba[i + c]);
      se += d * d;
    }
    n += 3;
  }
  const double mse = n ? se / double(n) : 0.0;
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

/// A w x h window of `img` at (x, y), each pixel `zoom` x `zoom`.
inline render::Image crop(const render::Image& img, uint32_t x, uint32_t y, uint32_t w, uint32_t h,
                          uint32_t zoom) {
  render::Image c;
  c.width = w * zoom;
  c.height = h * zoom;
  c.rgba.resize(size_t(c.width) * c.height * 4);
  for (uint32_t j = 0; j < c.height; ++j)
    for (uint32_t i = 0; i < c.width; ++i)
      std::copy_n(&img.rgba[(size_t(y + j / zoom) * img.width + x + i / zoom) * 4], 4,
                  &c.rgba[(size_t(j) * c.width + i) * 4]);
  return c;
}

/// `cells` (all the same size) in a grid of `columns`, 4 px white gaps.
inline render::Image grid(const std::vector<render::Image>& cells, uint32_t columns) {
  const uint32_t gap = 4, w = cells[0].width, h = cells[0].height;
  const auto rows = uint32_t((cells.size() + columns - 1) / columns);
  render::Image g;
  g.width = columns * w + (columns - 1) * gap;
  g.height = rows * h + (rows - 1) * gap;
  g.rgba.assign(size_t(g.width) * g.height * 4, 255);
  for (size_t k = 0; k < cells.size(); ++k) {
    const uint32_t x0 = uint32_t(k % columns) * (w + gap), y0 = uint32_t(k / columns) * (h + gap);
    for (uint32_t y = 0; y < h; ++y)
      std::copy_n(&cells[k].rgba[size_t(y) * w * 4], w * 4,
                  &g.rgba[(size_t(y0 + y) * g.width + x0) * 4]);
  }
  return g;
}

}  // namespace tessera::bench
