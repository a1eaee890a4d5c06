// Voice end to end: a tone, a synthetic voice and espeak-ng speech through the real
// Opus encoder, a simulated network (seeded loss and jitter), the packet decoder, the adaptive
// jitter buffer and the playout clock. The received signal is put back at the sender's
// timestamps, aligned to the sent one by cross-correlation, and measured: SNR against the sent
// signal and against the clean path (no loss, no jitter), the share of concealed frames, and
// clicks (a sample step twice as large as any the sent signal takes).
#include <gtest/gtest.h>

#include <cstdio>

#include "../support/temp_dir.h"
#include "../support/voice_path.h"

namespace {

using namespace tessera;
using test::NetworkModel;
using test::runVoicePath;

struct Measured : test::PathQuality {
  float step = 0;  ///< largest sample step of what was played
  test::VoicePath path;
};

Measured measure(const std::vector<float>& x, const NetworkModel& net, const test::VoicePath& clean,
                 const test::VoicePathOptions& options = {}) {
  Measured m;
  m.path = runVoicePath(x, net, options);
  static_cast<test::PathQuality&>(m) = test::pathQuality(x, clean, m.path);
  m.step = test::maxStep(m.path.played);
  return m;
}

/// The first 0.3 s are left out of the SNR: the buffer is still learning the jitter.
constexpr size_t kSettle = size_t(0.3 * media::kVoiceRate);

void report(const char* what, double loss, const Measured& m) {
  const auto& s = m.path.stats;
  std::printf(
      "%-9s loss %4.1f%%: lag %d, SNR %5.1f dB (sent) %5.1f dB (clean path), concealed "
      "%5.2f%% (fec %llu), lost %zu, late %llu, inserted %llu, dropped %llu, dtx %llu, "
      "target %.1f ms, jitter %.1f ms, max step %.3f\n",
      what, loss * 100, m.lag, m.snr_sent, m.snr_clean, m.concealed * 100,
      (unsigned long long)s.fec, m.path.packets_lost, (unsigned long long)s.late,
      (unsigned long long)s.inserted, (unsigned long long)s.dropped, (unsigned long long)s.dtx,
      s.target_s * 1e3, s.jitter_s * 1e3, m.step);
}

struct Bounds {
  double snr_sent_clean;  ///< the codec alone (no loss, no jitter), against the sent signal
  bool speech;            ///< the lag is unambiguous (a tone's repeats every period)
};

/// SNR against the clean path at 0%, 5% and 10% loss with 10 ms mean jitter: what the codec's
/// FEC and PLC keep (a concealed frame is close to 0 dB on its own, so 5% of them cap the SNR
/// near 13 dB whatever the concealment).
constexpr double kSnrAgainstClean[3] = {15, 8, 6};
constexpr double kLosses[3] = {0.0, 0.05, 0.10};

void sweep(const char* what, const std::vector<float>& x, const Bounds& bounds) {
  const test::VoicePath clean = runVoicePath(x, NetworkModel{});
  // The codec alone: no frame concealed, the lag is the lookahead.
  EXPECT_EQ(clean.stats.concealed, 0u) << what;
  EXPECT_EQ(clean.stats.late, 0u) << what;
  const int clean_lag = test::bestLag(x, clean.in_sender_time, 2000);
  if (bounds.speech) {
    EXPECT_NEAR(clean_lag, clean.lookahead, 8) << what;
  }
  EXPECT_GE(test::snrDb(x, clean.in_sender_time, clean_lag, kSettle, x.size()),
            bounds.snr_sent_clean)
      << what;
  // The playout never steps further than twice the sent signal's largest step.
  const float click = 2 * test::maxStep(x);
  EXPECT_LE(test::maxStep(clean.played), click) << what << ": the clean path clicks";
  for (int i = 0; i < 3; ++i) {
    NetworkModel net;
    net.loss = kLosses[i];
    net.jitter_ms = 10;
    net.seed = 11 + uint32_t(i);
    const Measured m = measure(x, net, clean);
    report(what, kLosses[i], m);
    SCOPED_TRACE(std::string(what) + " at " + std::to_string(int(kLosses[i] * 100)) + "% loss");
    if (bounds.speech) {
      EXPECT_NEAR(m.lag, clean.lookahead, 8);
    }
    EXPECT_GE(m.snr_clean, kSnrAgainstClean[i]);
    EXPECT_LE(m.step, click) << "a click: a step no sent sample takes";
    // Every lost or late packet is concealed, and nothing else (DTX silence is not): a lost
    // talkspurt start or end may leave a frame of doubt each.
    const double missing = double(m.path.packets_lost + m.path.stats.late);
    EXPECT_LE(double(m.path.stats.concealed), 1.1 * missing + 2);
    EXPECT_GE(double(m.path.stats.concealed), 0.8 * double(m.path.packets_lost));
    // The target lets 97% of packets through: at most 3% late on top of the losses.
    EXPECT_LE(m.concealed, kLosses[i] + 0.04);
    if (kLosses[i] > 0) {
      EXPECT_GT(m.path.stats.fec, 0u) << "no frame came back from FEC";
    }
    // The buffer followed the jitter (10 ms mean, exponential: its 97th percentile is 35 ms),
    // plus a frame for FEC under loss.
    EXPECT_GT(m.path.stats.target_s, 0.020);
    EXPECT_LT(m.path.stats.target_s, kLosses[i] > 0 ? 0.075 : 0.055);
    EXPECT_EQ(m.path.packets_refused, 0u);
  }
}

TEST(VoicePath, ToneThroughLossAndJitter) {
  sweep("tone", test::tone(440, 6), Bounds{15, false});
}

TEST(VoicePath, SyntheticSpeechThroughLossAndJitter) {
  const std::vector<float> x = test::syntheticSpeech(8);
  sweep("synthetic", x, Bounds{6, true});
  // Its pauses are sent as DTX: far fewer packets than frames, and silence is not concealment.
  const test::VoicePath clean = runVoicePath(x, NetworkModel{});
  EXPECT_LT(double(clean.packets_sent), 0.85 * double(clean.frames_sent));
  EXPECT_GT(clean.stats.dtx, 20u);
}

TEST(VoicePath, EspeakSpeechThroughLossAndJitter) {
  test::TempDir dir;
  const auto speech = test::espeakSpeech(
      dir / "sentence.wav",
      "The north wall of the chapel shows the oldest layer of plaster, under the later paintings.");
  if (!speech) GTEST_SKIP() << "espeak-ng is not installed (apt-get install espeak-ng)";
  ASSERT_GT(speech->size(), size_t(2 * media::kVoiceRate));
  sweep("espeak", *speech, Bounds{7, true});
}

TEST(VoicePath, ClickMeasureSeesASplice) {
  // The click bound above can fail: a tone with 10 ms cut out steps far beyond it.
  std::vector<float> x = test::tone(440, 1);
  const float bound = 2 * test::maxStep(x);
  std::vector<float> spliced(x.begin(), x.begin() + 24000);
  spliced.insert(spliced.end(), x.begin() + 24000 + 480 + 37, x.end());
  EXPECT_GT(test::maxStep(spliced), bound);
}

TEST(VoicePath, TenMillisecondFrames) {
  const std::vector<float> x = test::syntheticSpeech(4, 3);
  test::VoicePathOptions options;
  options.codec.frame_ms = 10;
  const test::VoicePath clean = runVoicePath(x, NetworkModel{}, options);
  NetworkModel net;
  net.loss = 0.05;
  net.jitter_ms = 5;
  net.seed = 5;
  const Measured m = measure(x, net, clean, options);
  report("10 ms", 0.05, m);
  // (SILK's own delay differs by a few samples between modes: 2.5 ms is still one sub-frame.)
  EXPECT_NEAR(m.lag, clean.lookahead, 16);
  EXPECT_GE(m.snr_clean, kSnrAgainstClean[1]);
  for (const auto& f : m.path.history) ASSERT_EQ(f.samples, 480);
  EXPECT_GT(m.path.stats.fec, 0u);
}

TEST(VoicePath, CorruptTruncatedAndOversizedPacketsAreRefusedAndTheStreamGoesOn) {
  const std::vector<float> x = test::syntheticSpeech(5, 9);
  const test::VoicePath clean = runVoicePath(x, NetworkModel{});
  NetworkModel net;
  net.jitter_ms = 5;
  net.duplicate = 0.05;
  net.seed = 21;
  const Measured plain = measure(x, net, clean);
  report("plain", 0, plain);
  // Around every fifth packet: its truncations, an oversized copy, random bytes, a flipped
  // header byte; every packet still goes through once, intact.
  test::VoicePathOptions options;
  size_t garbage = 0;
  options.tamper = [&garbage](const std::vector<uint8_t>& packet, std::mt19937& rng) {
    std::vector<std::vector<uint8_t>> out{packet};
    if (rng() % 5 != 0) return out;
    out.emplace_back(packet.begin(), packet.begin() + ptrdiff_t(rng() % packet.size()));
    std::vector<uint8_t> big = packet;
    big.resize(media::kMaxVoicePacketBytes + 1 + rng() % 100, 0x55);
    out.push_back(big);
    std::vector<uint8_t> noise(rng() % 1400);
    for (auto& b : noise) b = uint8_t(rng());
    out.push_back(noise);
    std::vector<uint8_t> flipped = packet;
    flipped[rng() % media::kVoiceHeaderBytes] ^= uint8_t(1 + rng() % 255);
    out.push_back(flipped);
    garbage += 4;
    return out;
  };
  const Measured m = measure(x, net, clean, options);
  report("tampered", 0, m);
  EXPECT_GT(m.path.packets_refused, garbage / 2) << "the decoder took garbage";
  // A flipped sequence, timestamp or site byte can pass the checks: the buffer takes it as a
  // duplicate, a late or a far packet, or a frame at the wrong time, and goes on.
  EXPECT_GE(plain.snr_clean, 30);
  EXPECT_GE(m.snr_clean, 30);
  EXPECT_LE(m.step, 2 * test::maxStep(x));
  EXPECT_EQ(m.path.stats.resets, 0u);
}

}  // namespace
