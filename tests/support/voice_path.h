// Voice end to end without a sound device, for the tests and bench/voice: the test
// signals (a tone, a synthetic voice, espeak-ng speech), a simulated network (seeded loss,
// jitter, duplicates), the real sender -> packet bytes -> decodeVoicePacket -> jitter buffer ->
// playout clock path, and the measures (alignment by cross-correlation, SNR, clicks).
#pragma once

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <numbers>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <tessera/media/voice_codec.h>
#include <tessera/media/voice_jitter_buffer.h>
#include <tessera/media/voice_packet.h>
#include <tessera/media/voice_wav.h>

namespace tessera::test {

using media::kVoiceRate;

/// A sine of `hz`, `seconds` long, peak `amplitude` (full scale 1).
inline std::vector<float> tone(double hz, double seconds, float amplitude = 0.3f) {
  std::vector<float> x(size_t(seconds * kVoiceRate));
  for (size_t n = 0; n < x.size(); ++n)
    x[n] = amplitude * float(std::sin(2 * std::numbers::pi * hz * double(n) / kVoiceRate));
  return x;
}

/// A speech-like signal that needs no tool: a glottal pulse train (pitch gliding 95..190 Hz)
/// through three formant resonators (Peterson and Barney's vowel formants), shaped into
/// syllables of 120..260 ms with pauses of 250..600 ms after every few (so DTX has silence to
/// skip). Peak 0.5. Deterministic for a seed.
inline std::vector<float> syntheticSpeech(double seconds, uint32_t seed = 7) {
  static constexpr double kVowels[5][3] = {
      {730, 1090, 2440}, {270, 2290, 3010}, {300, 870, 2240}, {530, 1840, 2480}, {570, 840, 2410}};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<float> x(size_t(seconds * kVoiceRate), 0.0f);
  struct Resonator {
    double a1 = 0, a2 = 0, g = 0, y1 = 0, y2 = 0;
    void set(double f, double bw) {
      const double r = std::exp(-std::numbers::pi * bw / kVoiceRate);
      a1 = 2 * r * std::cos(2 * std::numbers::pi * f / kVoiceRate);
      a2 = -r * r;
      g = 1 - r;
    }
    double step(double in) {
      const double y = g * in + a1 * y1 + a2 * y2;
      y2 = y1;
      y1 = y;
      return y;
    }
  } formants[3];
  double phase = 0, glottal = 0;
  size_t n = size_t(0.2 * kVoiceRate);  // starts with a little silence
  int in_phrase = 0;
  while (n < x.size()) {
    const auto& v = kVowels[rng() % 5];
    for (int k = 0; k < 3; ++k) formants[k].set(v[k], 60 + 40 * k);
    const size_t length = size_t((0.12 + 0.14 * u(rng)) * kVoiceRate);
    const double f0_start = 95 + 95 * u(rng), f0_end = 95 + 95 * u(rng);
    for (size_t i = 0; i < length && n < x.size(); ++i, ++n) {
      const double s = double(i) / double(length);
      const double f0 = f0_start + (f0_end - f0_start) * s;
      phase += f0 / kVoiceRate;
      double pulse = 0;
      if (phase >= 1) {
        phase -= 1;
        pulse = 1;
      }
      glottal = 0.97 * glottal + pulse;  // spectral tilt of the glottal source
      double y = 0;
      for (auto& f : formants) y += f.step(glottal);
      const double envelope = std::sin(std::numbers::pi * s);  // the syllable's rise and fall
      x[n] = float(y * envelope);
    }
    if (++in_phrase >= 3 + int(rng() % 3)) {
      in_phrase = 0;
      n += size_t((0.25 + 0.35 * u(rng)) * kVoiceRate);
    }
  }
  float peak = 0;
  for (float v : x) peak = std::max(peak, std::fabs(v));
  if (peak > 0)
    for (float& v : x) v *= 0.5f / peak;
  return x;
}

/// A sentence spoken by espeak-ng (Debian espeak-ng), resampled to 48 kHz by media::readWav;
/// std::nullopt when espeak-ng is not installed.
inline std::optional<std::vector<float>> espeakSpeech(const std::filesystem::path& wav,
                                                      const std::string& sentence) {
  if (std::system("command -v espeak-ng >/dev/null 2>&1") != 0) return std::nullopt;
  const std::string command =
      "espeak-ng -w '" + wav.string() + "' '" + sentence + "' >/dev/null 2>&1";
  if (std::system(command.c_str()) != 0) return std::nullopt;
  return media::readVoiceWav(wav);
}

struct NetworkModel {
  double loss = 0;       ///< share of packets lost (independent)
  double jitter_ms = 0;  ///< mean extra delay, exponentially distributed (reorders packets)
  double base_ms = 20;   ///< the path's fixed delay
  double duplicate = 0;  ///< share of packets delivered twice
  uint32_t seed = 1;
};

struct VoicePathOptions {
  media::VoiceSettings codec;
  media::JitterBufferSettings buffer;
  double tick_s = 0.010;  ///< the playout device's period
  /// Called with each packet's bytes as sent; returns what the network carries instead (the
  /// packet, changed, or with garbage around it: tests of corrupt packets).
  std::function<std::vector<std::vector<uint8_t>>(const std::vector<uint8_t>&, std::mt19937&)>
      tamper;
};

struct VoicePath {
  std::vector<float> played;  ///< everything pulled, at the playout clock
  /// The played frames put back at the sender timestamps they stand for (inserted frames left
  /// out): the sent signal delayed by the codec's lookahead, where the path delivered it.
  std::vector<float> in_sender_time;
  media::JitterStats stats;
  std::vector<media::PlayedFrame> history;
  int lookahead = 0;
  size_t frames_sent = 0, packets_sent = 0, packets_lost = 0, packets_refused = 0;
  size_t payload_bytes = 0;
  std::vector<double> delays_s;  ///< the buffer's delay at every tick once playing
};

/// Sends `signal` through encoder -> network -> decodeVoicePacket -> jitter buffer, pulling
/// at the playout clock until everything has played. Sequence numbers and timestamps start just
/// below their wrap, so every run crosses it.
inline VoicePath runVoicePath(std::span<const float> signal, const NetworkModel& net,
                              const VoicePathOptions& options = {}) {
  constexpr uint16_t kFirstSequence = 65500;
  constexpr uint32_t kFirstTimestamp = 0xFFFF0000u;
  VoicePath out;
  media::VoiceSender sender(options.codec, 3, kFirstSequence, kFirstTimestamp);
  out.lookahead = sender.encoder().lookahead();
  const size_t frame = size_t(sender.frameSamples());
  std::vector<float> padded(signal.begin(), signal.end());
  padded.resize((padded.size() + frame - 1) / frame * frame + frame * 10, 0.0f);

  std::mt19937 rng(net.seed);
  std::uniform_real_distribution<double> u(0, 1);
  struct Arrival {
    double at;
    std::vector<uint8_t> bytes;
  };
  std::vector<Arrival> arrivals;
  for (size_t at = 0; at < padded.size(); at += frame) {
    out.frames_sent += 1;
    auto bytes = sender.send(std::span<const float>(padded).subspan(at, frame));
    if (!bytes) continue;
    out.packets_sent += 1;
    out.payload_bytes += bytes->size() - media::kVoiceHeaderBytes;
    const double sent = double(at + frame) / kVoiceRate;  // the frame is whole when captured
    std::vector<std::vector<uint8_t>> carried;
    if (options.tamper)
      carried = options.tamper(*bytes, rng);
    else
      carried.push_back(std::move(*bytes));
    for (const auto& packet : carried) {
      const int copies = u(rng) < net.duplicate ? 2 : 1;
      for (int c = 0; c < copies; ++c) {
        if (u(rng) < net.loss) {
          out.packets_lost += 1;
          continue;
        }
        const double jitter = net.jitter_ms > 0 ? -std::log(1 - u(rng)) * net.jitter_ms : 0;
        arrivals.push_back({sent + (net.base_ms + jitter) / 1000, packet});
      }
    }
  }
  std::stable_sort(arrivals.begin(), arrivals.end(),
                   [](const Arrival& a, const Arrival& b) { return a.at < b.at; });

  media::JitterBufferSettings buffer = options.buffer;
  buffer.record = true;
  media::JitterBuffer receiver(buffer);
  const size_t block = size_t(options.tick_s * kVoiceRate);
  const double end = double(padded.size()) / kVoiceRate + 1.0;
  size_t next = 0;
  std::vector<float> pcm(block);
  // The device's clock runs at its own phase against the sender's frames.
  for (double t = 0.0037; t < end; t += options.tick_s) {
    for (; next < arrivals.size() && arrivals[next].at <= t; ++next) {
      media::VoicePacket packet;
      if (media::decodeVoicePacket(arrivals[next].bytes, packet)) {
        out.packets_refused += 1;
        continue;
      }
      receiver.push(packet, arrivals[next].at);
    }
    receiver.pull(t, pcm);
    out.played.insert(out.played.end(), pcm.begin(), pcm.end());
    if (receiver.stats().frames() > 0) out.delays_s.push_back(receiver.stats().delay_s);
  }
  out.stats = receiver.stats();
  out.history = receiver.history();
  out.in_sender_time.assign(padded.size() + size_t(out.lookahead), 0.0f);
  for (const media::PlayedFrame& f : out.history) {
    if (f.kind == media::PlayedFrame::Kind::kInserted) continue;
    const size_t at = uint32_t(f.timestamp - kFirstTimestamp);
    for (int i = 0; i < f.samples; ++i)
      if (at + size_t(i) < out.in_sender_time.size() && f.output + size_t(i) < out.played.size())
        out.in_sender_time[at + size_t(i)] = out.played[f.output + size_t(i)];
  }
  return out;
}

/// The lag (samples, 0..max_lag) at which `y` best matches `x` (y[n + lag] ~ x[n]): the peak
/// of the cross-correlation, found on a 4x decimated copy and refined at full rate.
inline int bestLag(std::span<const float> x, std::span<const float> y, int max_lag) {
  const auto correlate = [](std::span<const float> a, std::span<const float> b, int lag) {
    double sum = 0;
    for (size_t n = 0; n < a.size() && n + size_t(lag) < b.size(); ++n)
      sum += double(a[n]) * b[n + size_t(lag)];
    return sum;
  };
  const auto decimate = [](std::span<const float> a) {
    std::vector<float> d(a.size() / 4);
    for (size_t i = 0; i < d.size(); ++i)
      d[i] = 0.25f * (a[4 * i] + a[4 * i + 1] + a[4 * i + 2] + a[4 * i + 3]);
    return d;
  };
  const std::vector<float> xd = decimate(x), yd = decimate(y);
  int coarse = 0;
  double best = -1e300;
  for (int lag = 0; lag <= max_lag / 4; ++lag) {
    const double c = correlate(xd, yd, lag);
    if (c > best) best = c, coarse = lag * 4;
  }
  int lag_best = coarse;
  best = -1e300;
  for (int lag = std::max(0, coarse - 8); lag <= std::min(max_lag, coarse + 8); ++lag) {
    const double c = correlate(x, y, lag);
    if (c > best) best = c, lag_best = lag;
  }
  return lag_best;
}

/// 10 log10(sum x^2 / sum (x - y[n + lag])^2) over x[from, to).
inline double snrDb(std::span<const float> x, std::span<const float> y, int lag, size_t from,
                    size_t to) {
  double signal = 0, noise = 0;
  for (size_t n = from; n < to && n < x.size() && n + size_t(lag) < y.size(); ++n) {
    const double e = double(x[n]) - y[n + size_t(lag)];
    signal += double(x[n]) * x[n];
    noise += e * e;
  }
  return 10 * std::log10(signal / std::max(noise, 1e-20));
}

/// The largest sample-to-sample step |x[n] - x[n-1]|: a click is a step the signal never takes.
inline float maxStep(std::span<const float> x) {
  float step = 0;
  for (size_t n = 1; n < x.size(); ++n) step = std::max(step, std::fabs(x[n] - x[n - 1]));
  return step;
}

/// How well `path` carried `x`, against the sent signal and against `clean` (the same codec
/// without loss or jitter): the received signal aligned by cross-correlation (`lag`, samples),
/// SNRs in dB over x[settle, end) (the buffer is still learning the jitter before), and the
/// shares of frames played that were concealed and that came from the next packet's FEC.
struct PathQuality {
  int lag = 0;
  double snr_sent = 0, snr_clean = 0, concealed = 0, fec = 0;
};

inline PathQuality pathQuality(std::span<const float> x, const VoicePath& clean,
                               const VoicePath& path, size_t settle = size_t(0.3 * kVoiceRate)) {
  PathQuality q;
  const auto& y = path.in_sender_time;
  q.lag = bestLag(x, y, 2000);
  q.snr_sent = snrDb(x, y, q.lag, settle, x.size());
  // The clean path at the same place: both are the sent signal delayed by the lookahead.
  const size_t l = size_t(clean.lookahead);
  q.snr_clean =
      snrDb(std::span<const float>(clean.in_sender_time).subspan(l), y, int(l), settle, x.size());
  const double frames = double(std::max<uint64_t>(1, path.stats.frames()));
  q.concealed = double(path.stats.concealed) / frames;
  q.fec = double(path.stats.fec) / frames;
  return q;
}

/// Power of `hz` in x[from, to) (Goertzel), per sample: who is heard in a mix of tones.
inline double power(std::span<const float> x, double hz, size_t from, size_t to) {
  const double w = 2 * std::numbers::pi * hz / kVoiceRate, c = 2 * std::cos(w);
  double s1 = 0, s2 = 0;
  to = std::min(to, x.size());
  for (size_t n = from; n < to; ++n) {
    const double s = x[n] + c * s1 - s2;
    s2 = s1;
    s1 = s;
  }
  const double n = double(to > from ? to - from : 1);
  return (s1 * s1 + s2 * s2 - c * s1 * s2) / (n * n);
}

inline double db(double p) {
  return 10 * std::log10(std::max(p, 1e-30));
}

/// A voice of its own pitch: a tone at `hz` (0.25 peak) that pauses for 0.4 s every 1.2 s (so
/// DTX and talkspurts happen).
inline std::vector<float> talking(double hz, double seconds) {
  std::vector<float> x = tone(hz, seconds, 0.25f);
  for (size_t n = 0; n < x.size(); ++n)
    if (std::fmod(double(n) / kVoiceRate, 1.2) > 0.8) x[n] = 0;
  return x;
}

}  // namespace tessera::test
