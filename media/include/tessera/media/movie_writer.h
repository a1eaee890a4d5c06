// Movie files: RGBA pictures encoded with libavcodec and muxed into an MP4 with libavformat, for
// rendered camera paths (tessera-render --movie). H.264 through libx264 when this libavcodec has
// it (CRF quality, `medium` preset, every frame's quality alike: a file, not a stream), else the
// first of these it has: any other H.264 encoder, an HEVC encoder, MPEG-4 part 2 (at a bitrate
// for about 0.2 bits a pixel). Frames are numbered from 0 at a constant rate: frame i is shown
// from i / fps seconds for 1 / fps seconds, so n frames last n / fps seconds.
//
// The file is written to a temporary name beside the output and renamed when finish() succeeds;
// a writer destroyed unfinished (an error, a stop) removes it, so a failed movie never leaves a
// file that plays. Not thread-safe: one writer, one thread.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include <tessera/media/video_codec.h>

namespace tessera::media {

/// The largest movie side, pixels (H.264 level 6.2's 8192x4320 picture, and even).
constexpr int kMaxMovieSide = 8192;

struct MovieSettings {
  int width = 1280, height = 720;  ///< even, 16..kMaxMovieSide
  double fps = 30.0;               ///< frames a second, (0, 240]
  /// libx264's constant rate factor (0 lossless .. 51; 18 looks like the source). Other
  /// encoders take a bitrate instead.
  int crf = 18;
  /// Why the settings cannot be used ("movie settings: width 641 is not even"), or nullopt.
  std::optional<std::string> problem() const;
};

/// The encoder a movie gets from this libavcodec ("libx264", "libopenh264", "mpeg4", ...), or
/// an empty string when it has none of them.
std::string movieEncoderName();

class MovieWriter {
 public:
  /// Opens `path` (written as an MP4 whatever its extension) for pictures of the settings' size.
  /// Throws VideoError for unusable settings, naming the setting; when no encoder is found; and
  /// when the file cannot be created, naming it and why.
  MovieWriter(const std::string& path, const MovieSettings& settings);
  ~MovieWriter();
  MovieWriter(const MovieWriter&) = delete;
  MovieWriter& operator=(const MovieWriter&) = delete;

  /// Encodes the next frame: width * height * 4 bytes, RGBA, top row first. Throws VideoError
  /// for a picture of another size, or when encoding or writing fails (disk full).
  void write(std::span<const uint8_t> rgba, int width, int height);
  /// Drains the encoder, writes the MP4's index and renames the file to its path. Throws
  /// VideoError when that fails; the file is then removed.
  void finish();

  int frames() const { return mFrames; }
  /// The encoder this movie uses (movieEncoderName()).
  const std::string& encoder() const { return mEncoder; }

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
  std::string mPath, mTemp, mEncoder;
  int mFrames = 0;
  bool mDone = false;
};

}  // namespace tessera::media
