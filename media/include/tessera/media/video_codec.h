// Video insets: H.264 through libavcodec (libx264 to encode, FFmpeg's own decoder),
// RAII over the codec contexts, pictures as RGBA (converted with libswscale). No GL, no sockets:
// the sanitizer pass and the fuzzer link only this.
//
// Encoder settings, chosen for glass-to-glass latency and recovery rather than compression
// (README, "Video insets"):
//  - libx264 `tune=zerolatency`: no frame-level lookahead, no B-frames, sliced threads; one
//    picture in gives its access unit out at once (no encoder delay).
//  - `preset=ultrafast` (default) or `veryfast`: a 640x480 frame in a few ms of one core.
//  - CBR-ish: bitrate = maxrate = the cap, a VBV buffer of `vbv_s` seconds, so no frame is much
//    larger than the cap allows (a large frame would take longer to send than a frame period).
//  - periodic intra refresh (x264 `intra-refresh`) every `refresh_s` seconds: a column of intra
//    blocks sweeps the picture, so every frame is about the same size and a late joiner or a
//    decoder that lost a packet has a whole picture again within `refresh_s` (the first frame
//    of each sweep carries SPS/PPS and a recovery point SEI and is flagged key). Or, with
//    intra_refresh off, an IDR picture every `refresh_s` seconds (a short GOP).
//
// Neither type is thread-safe: one stream, one thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace tessera::media {

/// A codec failed to start or was given bad settings; what() names the setting or the call.
struct VideoError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// The largest picture either side takes, pixels each way (1080p and a bit: 2048x2048).
constexpr int kMaxVideoSide = 2048;

/// An RGBA picture, 8 bits per channel, top row first, no padding (width * 4 bytes a row).
struct VideoPicture {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;

  bool empty() const { return width == 0 || height == 0; }
  void resize(int w, int h) {
    width = w;
    height = h;
    rgba.assign(size_t(w) * size_t(h) * 4, 0);
  }
  uint8_t* pixel(int x, int y) { return rgba.data() + (size_t(y) * size_t(width) + size_t(x)) * 4; }
  const uint8_t* pixel(int x, int y) const {
    return rgba.data() + (size_t(y) * size_t(width) + size_t(x)) * 4;
  }
};

struct VideoSettings {
  int width = 640, height = 480;  ///< even, 16..kMaxVideoSide
  double fps = 30.0;              ///< (0, 120]
  int kbps = 1000;                ///< the bitrate cap, kbit/s, 50..50000
  bool intra_refresh = true;      ///< periodic intra refresh; false: IDR every refresh_s
  /// Intra refresh period or GOP length, seconds, (0, 10]. A receiver starting at a refresh has
  /// its first whole picture one period later (the sweep), so 0.5 s: a late joiner or a loss
  /// recovers within 0.5 to 1 s.
  double refresh_s = 0.5;
  double vbv_s = 0.25;               ///< VBV buffer, seconds of the cap, (0, 5]
  std::string preset = "ultrafast";  ///< x264 preset: ultrafast .. veryslow
  int threads = 1;  ///< encoder threads (1 leaves the other core to the rest of the site)

  /// Frames between refreshes (at least 2).
  int refreshFrames() const;
  /// Why the settings cannot be used ("video settings: width 641 is not even"), or nullopt.
  std::optional<std::string> problem() const;
};

/// One access unit (what the encoder makes of one picture): Annex B bytes.
struct EncodedVideo {
  std::vector<uint8_t> bytes;
  bool key = false;  ///< decodable from here: an IDR or the start of an intra refresh sweep
};

/// One stream's H.264 encoder. Move-only.
class VideoEncoder {
 public:
  /// Throws VideoError naming the setting out of range, or libx264 missing from libavcodec.
  explicit VideoEncoder(const VideoSettings& settings);
  ~VideoEncoder();
  VideoEncoder(VideoEncoder&&) noexcept;
  VideoEncoder& operator=(VideoEncoder&&) noexcept;

  /// Encodes one picture (scaled to the settings' size when it has another); with zerolatency
  /// its access unit comes out at once. Throws VideoError when libavcodec fails.
  EncodedVideo encode(const VideoPicture& picture);
  /// The next picture is coded as an IDR (a receiver asked to start over).
  void forceKey() { mForceKey = true; }

  const VideoSettings& settings() const { return mSettings; }

 private:
  struct Impl;
  VideoSettings mSettings;
  std::unique_ptr<Impl> m;
  bool mForceKey = false;
};

/// One stream's H.264 decoder (FFmpeg's h264, one thread, low delay: a picture out for each
/// access unit in). Survives any bytes: corrupt or truncated access units are refused or make
/// a picture FFmpeg flags corrupt, which is not taken; the last good picture stays. Move-only.
class VideoDecoder {
 public:
  VideoDecoder();  ///< throws VideoError when libavcodec has no H.264 decoder
  ~VideoDecoder();
  VideoDecoder(VideoDecoder&&) noexcept;
  VideoDecoder& operator=(VideoDecoder&&) noexcept;

  /// Decodes one access unit. Returns why it failed (libavcodec's error, a picture of a size
  /// outside 16..kMaxVideoSide, a corrupt picture), or nullopt: then `fresh` says whether a new
  /// good picture is in picture().
  std::optional<std::string> decode(std::span<const uint8_t> access_unit, bool& fresh);
  /// Forgets the reference pictures (a packet was lost): the next decodable access unit is a
  /// key. picture() stays.
  void reset();

  /// The last good picture (empty before the first).
  const VideoPicture& picture() const { return mPicture; }

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
  VideoPicture mPicture;
};

/// PSNR, dB, of `b` against `a` over the RGB channels of the rectangle (x, y, w, h) of both
/// (same size pictures); 99 for identical.
double videoPsnr(const VideoPicture& a, const VideoPicture& b, int x, int y, int w, int h);

}  // namespace tessera::media
