// Video insets: the generated test pattern, whose pictures carry their own frame
// number and capture time, so a test or a benchmark reads them back from a wall screenshot
// (glass-to-glass latency, which frame the wall shows) and compares the inset with what was sent.
//
// The code: 64 bits = frame number (24 bits) | capture time (32 bits: milliseconds of the
// system clock, modulo 2^32) | CRC-8 of the 7 bytes before it (polynomial 0x07). Drawn in the top
// third of the picture as 4 rows of 16 blocks, most significant bit first, white for 1 and black
// for 0: at 640x480 a block is 40x40 pixels, so the code survives H.264 at low rates and an
// inset drawn at a quarter of its size (blocks of 10 pixels; only each block's middle third is
// read). Below the code: colour gradients and a bar that move with the frame number, so
// consecutive frames differ everywhere and a picture compared with the wrong frame scores low.
#pragma once

#include <cstdint>
#include <optional>

#include <tessera/media/video_codec.h>

namespace tessera::media {

struct PatternCode {
  uint32_t frame = 0;    ///< 24 bits
  uint32_t time_ms = 0;  ///< system clock, milliseconds modulo 2^32
};

/// The system clock in milliseconds modulo 2^32 (what the pattern burns in).
uint32_t patternClockMs();

/// Draws the pattern of `code` into `out` (resized to width x height, each at least 32).
void drawTestPattern(VideoPicture& out, int width, int height, const PatternCode& code);

/// Reads the code from the rectangle (x, y, w, h) of an RGBA image (`stride` pixels a row) where
/// a pattern picture is shown, scaled to that rectangle. nullopt when the checksum fails (not a
/// pattern, or a picture too damaged to read).
std::optional<PatternCode> readTestPattern(const uint8_t* rgba, int stride, int x, int y, int w,
                                           int h);

/// Milliseconds from `sent` to `shown`, both patternClockMs() values (modulo 2^32 arithmetic).
inline int64_t patternDelayMs(uint32_t sent, uint32_t shown) {
  return int64_t(int32_t(shown - sent));
}

}  // namespace tessera::media
