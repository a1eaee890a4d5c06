#include <tessera/media/voice_wav.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <numbers>

#include <tessera/media/voice_codec.h>
#include <tessera/core/file_checks.h>

#include "little_endian.h"

namespace tessera::media {
namespace {

constexpr int kMinRate = 8000;
constexpr int kMaxRate = 192000;

}  // namespace

WavAudio parseWav(std::span<const uint8_t> bytes, const std::string& name) {
  const auto fail = [&](const std::string& why) {
    return WavError("media::readWav(): " + name + ": " + why);
  };
  if (bytes.size() < 12 || std::memcmp(bytes.data(), "RIFF", 4) != 0 ||
      std::memcmp(bytes.data() + 8, "WAVE", 4) != 0)
    throw fail("not a WAV file (no RIFF/WAVE header)");
  WavAudio audio;
  bool have_format = false;
  size_t at = 12;
  while (at + 8 <= bytes.size()) {
    const uint8_t* chunk = bytes.data() + at;
    const size_t size = getLe32(chunk + 4);
    const size_t body = at + 8;
    const size_t left = bytes.size() - body;
    const std::string id(reinterpret_cast<const char*>(chunk), 4);
    if (id == "fmt ") {
      if (size < 16 || size > left)
        throw fail("the fmt chunk is " + std::to_string(size) +
                   " bytes, expected at least 16 within the file");
      const uint8_t* f = bytes.data() + body;
      uint16_t format = getLe16(f);
      if (format == 0xFFFE && size >= 40) format = getLe16(f + 24);  // EXTENSIBLE: sub-format
      const int channels = getLe16(f + 2);
      const uint32_t rate = getLe32(f + 4);
      const int block = getLe16(f + 12);
      const int bits = getLe16(f + 14);
      if (format != 1)
        throw fail("format " + std::to_string(format) +
                   ", expected PCM (1): compressed or "
                   "float WAV is not read (convert it to 16-bit PCM)");
      if (bits != 16) throw fail(std::to_string(bits) + "-bit samples, expected 16-bit PCM");
      if (channels != 1 && channels != 2)
        throw fail(std::to_string(channels) + " channels, expected mono or stereo");
      if (rate < uint32_t(kMinRate) || rate > uint32_t(kMaxRate))
        throw fail("sample rate " + std::to_string(rate) + " Hz, expected 8000..192000");
      if (block != channels * 2)
        throw fail("block align " + std::to_string(block) + ", expected " +
                   std::to_string(channels * 2) + " for " + std::to_string(channels) +
                   " channels of 16 bits");
      audio.rate = int(rate);
      audio.channels = channels;
      have_format = true;
    } else if (id == "data") {
      if (!have_format) throw fail("the data chunk comes before the fmt chunk");
      if (size > left)
        throw fail("truncated: the data chunk says " + std::to_string(size) + " bytes, " +
                   std::to_string(left) + " follow");
      const size_t frame = size_t(audio.channels) * 2;
      if (size % frame != 0)
        throw fail("the data chunk's " + std::to_string(size) +
                   " bytes are not whole sample frames of " + std::to_string(frame) + " bytes");
      audio.samples.resize(size / 2);
      for (size_t i = 0; i < audio.samples.size(); ++i)
        audio.samples[i] = int16_t(getLe16(bytes.data() + body + 2 * i));
      return audio;
    } else if (size > left) {
      throw fail("truncated: the '" + id + "' chunk says " + std::to_string(size) + " bytes, " +
                 std::to_string(left) + " follow");
    }
    at = body + size + (size & 1);  // chunks are padded to even sizes
  }
  throw fail(have_format ? "no data chunk" : "no fmt chunk");
}

WavAudio readWav(const std::filesystem::path& path) {
  std::string why;
  const int fd = openRegularFile(path, why);
  if (fd < 0) throw WavError("media::readWav(): " + path.string() + ": " + why);
  std::vector<uint8_t> bytes;
  uint8_t block[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, block, sizeof block);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const std::string error = std::strerror(errno);
      ::close(fd);
      throw WavError("media::readWav(): " + path.string() + ": " + error);
    }
    if (n == 0) break;
    if (bytes.size() + size_t(n) > kMaxWavBytes) {
      ::close(fd);
      throw WavError("media::readWav(): " + path.string() + ": larger than " +
                     std::to_string(kMaxWavBytes >> 20) + " MiB");
    }
    bytes.insert(bytes.end(), block, block + n);
  }
  ::close(fd);
  return parseWav(bytes, path.string());
}

std::vector<float> toVoice(const WavAudio& audio) {
  const size_t frames = audio.samples.size() / size_t(std::max(audio.channels, 1));
  std::vector<float> mono(frames);
  for (size_t i = 0; i < frames; ++i) {
    float sum = 0;
    for (int c = 0; c < audio.channels; ++c)
      sum += float(audio.samples[i * size_t(audio.channels) + size_t(c)]) / 32768.0f;
    mono[i] = sum / float(audio.channels);
  }
  return audio.rate == kVoiceRate ? mono : resample(mono, audio.rate, kVoiceRate);
}

std::vector<float> readVoiceWav(const std::filesystem::path& path) {
  return toVoice(readWav(path));
}

std::vector<float> resample(std::span<const float> in, int from_rate, int to_rate) {
  if (from_rate < kMinRate || from_rate > kMaxRate || to_rate < kMinRate || to_rate > kMaxRate)
    throw WavError("media::resample(): rates " + std::to_string(from_rate) + " -> " +
                   std::to_string(to_rate) + " Hz, expected 8000..192000");
  if (from_rate == to_rate) return {in.begin(), in.end()};
  // Cut-off at the lower rate's Nyquist frequency, in input samples' units (1 = input Nyquist).
  const double cutoff = std::min(1.0, double(to_rate) / double(from_rate)) * 0.95;
  const double half = 16.0 / cutoff;  // half the kernel, input samples
  const size_t out_size = size_t(double(in.size()) * to_rate / from_rate);
  std::vector<float> out(out_size);
  const ptrdiff_t n_in = ptrdiff_t(in.size());
  for (size_t n = 0; n < out_size; ++n) {
    const double x = double(n) * from_rate / to_rate;
    const ptrdiff_t lo = std::max<ptrdiff_t>(0, ptrdiff_t(std::ceil(x - half)));
    const ptrdiff_t hi = std::min<ptrdiff_t>(n_in - 1, ptrdiff_t(std::floor(x + half)));
    double sum = 0;
    for (ptrdiff_t k = lo; k <= hi; ++k) {
      const double d = x - double(k);
      const double arg = std::numbers::pi * cutoff * d;
      const double sinc = d == 0 ? 1.0 : std::sin(arg) / arg;
      const double w = 0.42 + 0.5 * std::cos(std::numbers::pi * d / half) +
                       0.08 * std::cos(2 * std::numbers::pi * d / half);  // Blackman
      sum += double(in[size_t(k)]) * cutoff * sinc * w;
    }
    out[n] = float(sum);
  }
  return out;
}

void writeWav(const std::filesystem::path& path, std::span<const float> samples, int rate,
              int channels) {
  if (channels != 1 && channels != 2)
    throw WavError("media::writeWav(): " + path.string() + ": " + std::to_string(channels) +
                   " channels, expected 1 or 2");
  if (rate < kMinRate || rate > kMaxRate)
    throw WavError("media::writeWav(): " + path.string() + ": rate " + std::to_string(rate) +
                   " Hz, expected 8000..192000");
  const uint64_t data = uint64_t(samples.size()) * 2;
  if (data + 36 > 0xFFFFFFFFu)
    throw WavError("media::writeWav(): " + path.string() + ": too long for a WAV file");
  std::vector<uint8_t> bytes(44 + data);
  uint8_t* p = bytes.data();
  std::memcpy(p, "RIFF", 4);
  putLe32(p + 4, uint32_t(36 + data));
  std::memcpy(p + 8, "WAVEfmt ", 8);
  putLe32(p + 16, 16);  // the fmt chunk's size
  putLe16(p + 20, 1);   // PCM
  putLe16(p + 22, uint16_t(channels));
  putLe32(p + 24, uint32_t(rate));
  putLe32(p + 28, uint32_t(rate * channels * 2));  // bytes per second
  putLe16(p + 32, uint16_t(channels * 2));         // block align
  putLe16(p + 34, 16);                             // bits per sample
  std::memcpy(p + 36, "data", 4);
  putLe32(p + 40, uint32_t(data));
  for (size_t i = 0; i < samples.size(); ++i) {
    const float v = std::isfinite(samples[i]) ? std::clamp(samples[i], -1.0f, 1.0f) : 0.0f;
    putLe16(p + 44 + 2 * i, uint16_t(int16_t(std::lround(v * 32767.0f))));
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out)
    throw WavError("media::writeWav(): " + path.string() + ": " + whyNotWritable(path, errno));
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!out.flush())
    throw WavError("media::writeWav(): " + path.string() + ": write failed (disk full?)");
}

}  // namespace tessera::media
