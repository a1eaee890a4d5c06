// Voice: WAV files in and out, for machines without a sound device (tests, the demo)
// and for recording what a participant hears. Reads 16-bit PCM, mono or stereo, at any rate
// from 8 to 192 kHz (RIFF/WAVE, WAVE_FORMAT_PCM or WAVE_FORMAT_EXTENSIBLE with PCM); voice
// streams take it as 48 kHz mono (stereo mixed down, other rates resampled). Writes 16-bit PCM.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace tessera::media {

/// A WAV file that cannot be read or written; what() names the file and what is wrong with it
/// ("media::readWav(): talk.wav: 24-bit samples, expected 16-bit PCM").
struct WavError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct WavAudio {
  int rate = 0;                  ///< samples per second per channel
  int channels = 0;              ///< 1 or 2
  std::vector<int16_t> samples;  ///< interleaved
};

/// The largest WAV file read, bytes (about 1.5 hours of 48 kHz stereo).
constexpr size_t kMaxWavBytes = size_t(1) << 30;

/// Parses a whole WAV file held in memory; `name` is what errors call it. Throws WavError.
WavAudio parseWav(std::span<const uint8_t> bytes, const std::string& name);
/// Reads and parses a WAV file (a regular file, at most kMaxWavBytes). Throws WavError.
WavAudio readWav(const std::filesystem::path& path);
/// A WAV file as a voice stream: 48 kHz mono floats in [-1, 1]. Throws WavError.
std::vector<float> readVoiceWav(const std::filesystem::path& path);
/// The audio as 48 kHz mono floats (channels averaged, resampled).
std::vector<float> toVoice(const WavAudio& audio);

/// Band-limited resampling (windowed sinc, 32 taps at the lower rate's band edge, Blackman
/// window; Smith, "Digital Audio Resampling", bandlimited interpolation). Rates 8..192 kHz.
std::vector<float> resample(std::span<const float> in, int from_rate, int to_rate);

/// Writes 16-bit PCM (samples clamped to [-1, 1], rounded; never wrapped). `samples` is
/// interleaved when channels is 2. Throws WavError naming the file when it cannot be written.
void writeWav(const std::filesystem::path& path, std::span<const float> samples, int rate = 48000,
              int channels = 1);

}  // namespace tessera::media
