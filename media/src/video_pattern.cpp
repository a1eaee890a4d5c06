#include <tessera/media/video_pattern.h>

#include <chrono>
#include <cmath>
#include <vector>

#include <tessera/core/check.h>

namespace tessera::media {

namespace {

constexpr int kRows = 4, kColumns = 16;

uint8_t crc8(const uint8_t* p, int n) {
  // Initial value 0xFF and a final XOR: an all-black or all-white band never reads as a code.
  uint8_t c = 0xFF;
  for (int i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = uint8_t((c & 0x80) ? (c << 1) ^ 0x07 : c << 1);
  }
  return uint8_t(c ^ 0x55);
}

uint64_t pack(const PatternCode& code) {
  uint8_t b[7];
  const uint32_t f = code.frame & 0xFFFFFF;
  b[0] = uint8_t(f >> 16);
  b[1] = uint8_t(f >> 8);
  b[2] = uint8_t(f);
  for (int i = 0; i < 4; ++i) b[3 + i] = uint8_t(code.time_ms >> (24 - 8 * i));
  uint64_t bits = 0;
  for (uint8_t v : b) bits = (bits << 8) | v;
  return (bits << 8) | crc8(b, 7);
}

}  // namespace

uint32_t patternClockMs() {
  using namespace std::chrono;
  return uint32_t(
      uint64_t(duration_cast<milliseconds>(system_clock::now().time_since_epoch()).count()));
}

void drawTestPattern(VideoPicture& out, int width, int height, const PatternCode& code) {
  TESSERA_CHECK(width >= 32 && height >= 32, "media::drawTestPattern(): " + std::to_string(width) +
                                                 "x" + std::to_string(height) + ", at least 32x32");
  if (out.width != width || out.height != height) out.resize(width, height);
  const uint64_t bits = pack(code);
  const int band = height / 3;
  const int bar = int((code.frame * 8u) % uint32_t(width));
  const int t = int(code.frame & 0xFFFFFF);
  // The blue wave depends on x + y only: one table a picture, not a sine a pixel (the pattern
  // is drawn after its clock is read, so its cost counts in the measured latency).
  std::vector<uint8_t> wave(size_t(width + height));
  for (size_t i = 0; i < wave.size(); ++i)
    wave[i] = uint8_t(128 + 100 * std::sin(0.02 * double(i) + 0.1 * t));
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      uint8_t* p = out.pixel(x, y);
      if (y < band) {
        const int row = y * kRows / band, column = x * kColumns / width;
        const int bit = 63 - (row * kColumns + column);
        const uint8_t v = (bits >> bit) & 1 ? 255 : 0;
        p[0] = p[1] = p[2] = v;
      } else {
        // Smooth gradients that drift with the frame (H.264 codes them well; each frame
        // differs), and a vertical bar sweeping 8 pixels a frame.
        p[0] = uint8_t((x * 255 / width + 2 * t) & 0xFF);
        p[1] = uint8_t(((y - band) * 255 / (height - band) + t) & 0xFF);
        p[2] = wave[size_t(x + y)];
        if (x >= bar && x < bar + std::max(4, width / 40)) p[0] = p[1] = p[2] = 255;
      }
      p[3] = 255;
    }
  }
}

std::optional<PatternCode> readTestPattern(const uint8_t* rgba, int stride, int x0, int y0, int w,
                                           int h) {
  if (w < kColumns || h < 3 * kRows) return {};
  const double bw = double(w) / kColumns, bh = double(h) / 3.0 / kRows;
  uint64_t bits = 0;
  for (int row = 0; row < kRows; ++row) {
    for (int column = 0; column < kColumns; ++column) {
      // The block's middle third: far from the edges that scaling and the codec blur.
      const int xa = x0 + int(std::floor((column + 1.0 / 3.0) * bw));
      const int xb = x0 + std::max(int(std::ceil((column + 2.0 / 3.0) * bw)), xa - x0 + 1);
      const int ya = y0 + int(std::floor((row + 1.0 / 3.0) * bh));
      const int yb = y0 + std::max(int(std::ceil((row + 2.0 / 3.0) * bh)), ya - y0 + 1);
      double sum = 0;
      int n = 0;
      for (int y = ya; y < yb; ++y)
        for (int x = xa; x < xb; ++x) {
          const uint8_t* p = rgba + (size_t(y) * size_t(stride) + size_t(x)) * 4;
          sum += (double(p[0]) + p[1] + p[2]) / 3.0;
          ++n;
        }
      bits = (bits << 1) | (n > 0 && sum / n > 127.5 ? 1u : 0u);
    }
  }
  uint8_t b[7];
  for (int i = 0; i < 7; ++i) b[i] = uint8_t(bits >> (56 - 8 * i));
  if (crc8(b, 7) != uint8_t(bits)) return {};
  PatternCode code;
  code.frame = (uint32_t(b[0]) << 16) | (uint32_t(b[1]) << 8) | b[2];
  code.time_ms = (uint32_t(b[3]) << 24) | (uint32_t(b[4]) << 16) | (uint32_t(b[5]) << 8) | b[6];
  return code;
}

}  // namespace tessera::media
