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

/// How alike two pictures of one view are (a preview against its final picture, tests): a pixel
/// is covered when any of its RGB channels is above 16.
struct PictureLikeness {
  double pixel_iou = 1.0;        ///< IoU of the covered pixels (1 when neither covers any)
  double silhouette_iou = 1.0;   ///< IoU of the blocks holding a covered pixel: the outline
  double mean_difference = 0.0;  ///< mean |RGB difference| over pixels either covers, 0..255
};

/// Compares `a` and `b` with silhouette blocks of `block` x `block` pixels. Pixel IoU counts
/// every open pixel between a scan's points, where one picture shows the background and the
/// other a point; the silhouette IoU compares the outline. Precondition (TESSERA_CHECK): the
/// same size, rgba of width * height * 4 bytes, block >= 1. O(pixels).
PictureLikeness comparePictures(const Image& a, const Image& b, uint32_t block = 8);

/// Writes an 8-bit RGBA PNG. Throws RenderError naming the file on failure.
void writePng(const std::string& path, const Image& image);
/// Reads an 8-bit RGB or RGBA PNG (any libpng can expand: palette, grey, 16-bit are converted)
/// into RGBA, top row first. Throws RenderError naming the file on anything unreadable.
Image readPng(const std::string& path);

}  // namespace tessera::render
