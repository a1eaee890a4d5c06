// An image item's picture as the wall shows it in an open note ("Information": items
// are text, numbers, images and links; the thesis' information model, chapter 5, shows a
// place's documents beside the model). The master decodes the item's image (its bytes in the
// database, or the file it names) and scales it to fit a small square, once per item revision;
// the scene carries the RGBA pixels to every tile and site (scene.proto AnnotationItem.picture),
// so no node or site decodes an image file from outside.
//
// Formats: whatever libavcodec decodes as a still picture, told by its first bytes: PNG, JPEG,
// BMP, GIF (its first frame), WebP, TIFF. Bounds: at most 64 MiB of input and 8192x8192 pixels
// decoded (a decompression bomb is refused before it allocates), scaled down by area averaging
// so text in a photographed document stays legible. Cost: one decode and one scale, a few
// milliseconds for a camera JPEG of 12 megapixels on this machine.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace tessera::annotate {

struct NotePicture {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgba;  ///< width * height * 4, top row first
};

/// The largest input read and the largest picture decoded.
constexpr size_t kMaxNoteImageBytes = size_t(64) << 20;
constexpr uint32_t kMaxNoteImageSide = 8192;

/// The image in `bytes` scaled to fit `max_px` x `max_px` (never enlarged; aspect kept; at least
/// 1 pixel a side). Throws std::runtime_error saying why ("not an image this build reads",
/// "a 40000x30000 picture: at most 8192 a side", the decoder's message) on anything else.
NotePicture decodeNotePicture(std::span<const uint8_t> bytes, uint32_t max_px);

/// The same for an image file; a relative `path` is taken from `base` (the database's folder).
/// The message names the file.
NotePicture readNotePicture(const std::filesystem::path& path, const std::filesystem::path& base,
                            uint32_t max_px);

}  // namespace tessera::annotate
