// A picture in memory (RGBA8, top row first) and what tools do with one: PNG files and the edge
// measure of the see-through tests and benches.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace tessera::render {

struct Image {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgba;  ///< width * height * 4, top row first
};

/// The 10-90% width, in pixels, of a vertical edge near `column` between a plateau on its left
/// and background on its right (the red channel's column means, linearly interpolated; plateau
/// and background levels from the middle halves of either side). O(width x height).
double edgeWidth(const Image& image, uint32_t column);

/// `image` at width x height, each new pixel the mean of the old pixels under it weighted by the
/// area they share (a box filter: fair both ways, exact when a size divides the other), in the
/// image's own values, alpha too. Precondition (TESSERA_CHECK): sizes > 0 and rgba of
/// width * height * 4 bytes. Cost: O(new pixels x old pixels each covers).
Image resizeImage(const Image& image, uint32_t width, uint32_t height);

/// Writes an 8-bit RGBA PNG. Throws RenderError naming the file on failure.
void writePng(const std::string& path, const Image& image);
/// Reads an 8-bit RGB or RGBA PNG (any libpng can expand: palette, grey, 16-bit are converted)
/// into RGBA, top row first. Throws RenderError naming the file on anything unreadable.
Image readPng(const std::string& path);

}  // namespace tessera::render
