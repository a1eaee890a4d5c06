// Opus wrappers (media/voice_codec.h) with the real libopus: settings checked, a tone through
// the codec, DTX on silence, in-band FEC recovering a lost frame better than concealment, and
// decoding garbage without harm.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <tessera/media/voice_codec.h>

#include "../support/voice_path.h"

namespace {

using namespace tessera::media;
using tessera::test::bestLag;
using tessera::test::snrDb;
using tessera::test::syntheticSpeech;
using tessera::test::tone;

std::string refusal(const VoiceSettings& s) {
  try {
    VoiceEncoder e(s);
  } catch (const VoiceError& e) {
    return e.what();
  }
  return "";
}

TEST(VoiceCodec, SettingsOutOfRangeAreRefusedByName) {
  VoiceSettings s;
  s.frame_ms = 15;
  EXPECT_NE(refusal(s).find("frame_ms is 15, expected 10 or 20"), std::string::npos) << refusal(s);
  s = {};
  s.bitrate = 1000;
  EXPECT_NE(refusal(s).find("bitrate (bits/s) is 1000"), std::string::npos) << refusal(s);
  s = {};
  s.expected_loss_percent = 101;
  EXPECT_NE(refusal(s).find("expected_loss_percent"), std::string::npos);
  s = {};
  s.complexity = -1;
  EXPECT_NE(refusal(s).find("complexity"), std::string::npos);
  EXPECT_EQ(refusal(VoiceSettings{}), "");
  VoiceEncoder e{VoiceSettings{}};
  EXPECT_THROW(e.setBitrate(500000), VoiceError);
  EXPECT_THROW(e.setExpectedLoss(-3), VoiceError);
}

/// Encodes `x` frame by frame (every frame, DTX off) and returns the packets.
std::vector<std::vector<uint8_t>> encodeAll(const std::vector<float>& x, VoiceSettings s) {
  VoiceEncoder e(s);
  std::vector<std::vector<uint8_t>> packets;
  const size_t n = size_t(e.frameSamples());
  for (size_t at = 0; at + n <= x.size(); at += n) {
    std::vector<uint8_t> p;
    e.encode(std::span<const float>(x).subspan(at, n), p);
    packets.push_back(p);
  }
  return packets;
}

TEST(VoiceCodec, ToneRoundTripIsDelayedByTheLookahead) {
  for (int frame_ms : {20, 10}) {
    VoiceSettings s;
    s.frame_ms = frame_ms;
    s.dtx = false;
    const std::vector<float> x = tone(440, 2);
    const auto packets = encodeAll(x, s);
    VoiceDecoder d;
    std::vector<float> y;
    std::vector<float> frame(size_t(s.frameSamples()));
    for (const auto& p : packets) {
      EXPECT_LE(p.size(), size_t(s.bitrate / 8 * frame_ms / 1000 * 2)) << "far over the bitrate";
      ASSERT_TRUE(d.decode(p, frame));
      y.insert(y.end(), frame.begin(), frame.end());
    }
    EXPECT_EQ(VoiceEncoder(s).lookahead(), 312);  // 6.5 ms at 48 kHz (VOIP)
    // A tone's correlation peaks once per period (109 samples), so look near the lookahead
    // only: the codec's delay is the lookahead give or take SILK's resampler (a few samples).
    int best = 0;
    double best_snr = -1e9;
    for (int lag = 312 - 40; lag <= 312 + 40; ++lag) {
      const double snr = snrDb(x, y, lag, 4800, x.size() - 4800);
      if (snr > best_snr) best_snr = snr, best = lag;
    }
    EXPECT_NEAR(best, 312, 16) << frame_ms << " ms frames";
    EXPECT_GT(best_snr, 15) << frame_ms << " ms frames";
  }
}

TEST(VoiceCodec, DtxLeavesSilenceOutAndSendsSpeech) {
  VoiceSettings s;
  VoiceEncoder e(s);
  std::vector<float> silence(960, 0.0f);
  std::vector<uint8_t> p;
  int sent = 0;
  for (int i = 0; i < 50; ++i) sent += e.encode(silence, p) ? 1 : 0;
  EXPECT_LT(sent, 25) << "DTX sent most frames of a second of silence";
  const std::vector<float> x = tone(300, 0.2);
  for (size_t at = 0; at + 960 <= x.size(); at += 960)
    EXPECT_TRUE(e.encode(std::span<const float>(x).subspan(at, 960), p));
  VoiceSettings off;
  off.dtx = false;
  VoiceEncoder continuous(off);
  for (int i = 0; i < 50; ++i) EXPECT_TRUE(continuous.encode(silence, p));
}

/// The error of frame `k` of the decoded stream when packet k is lost and replaced by
/// FEC from packet k+1 (fec = true) or by concealment, against decoding it normally.
double lostFrameSnr(const std::vector<std::vector<uint8_t>>& packets, size_t k, bool fec) {
  VoiceDecoder clean, lossy;
  std::vector<float> a(960), b(960);
  double snr = 0;
  for (size_t i = 0; i <= k + 1; ++i) {
    clean.decode(packets[i], a);
    if (i == k) {
      if (fec)
        lossy.decodeFec(packets[k + 1], b);
      else
        lossy.conceal(b);
    } else {
      lossy.decode(packets[i], b);
    }
    if (i == k) snr = snrDb(a, b, 0, 0, a.size());
  }
  return snr;
}

TEST(VoiceCodec, InBandFecRecoversALostFrameBetterThanConcealment) {
  const std::vector<float> x = syntheticSpeech(4, 5);
  VoiceSettings s;
  s.dtx = false;
  const auto packets = encodeAll(x, s);
  // Over the voiced frames (where the syllables are), FEC from the next packet beats PLC.
  double fec_sum = 0, plc_sum = 0;
  int frames = 0;
  for (size_t k = 10; k + 1 < packets.size(); k += 7) {
    double energy = 0;
    for (size_t i = k * 960; i < (k + 1) * 960; ++i) energy += double(x[i]) * x[i];
    if (energy / 960 < 1e-3) continue;
    fec_sum += lostFrameSnr(packets, k, true);
    plc_sum += lostFrameSnr(packets, k, false);
    ++frames;
  }
  ASSERT_GT(frames, 5);
  std::printf("lost voiced frames: FEC %.1f dB, PLC %.1f dB (mean of %d)\n", fec_sum / frames,
              plc_sum / frames, frames);
  EXPECT_GT(fec_sum / frames, plc_sum / frames + 3);
  EXPECT_GT(fec_sum / frames, 3);
  // Without FEC in the stream, "FEC" decoding is only concealment.
  s.fec = false;
  const auto plain = encodeAll(x, s);
  double none_sum = 0;
  frames = 0;
  for (size_t k = 10; k + 1 < plain.size(); k += 7) {
    double energy = 0;
    for (size_t i = k * 960; i < (k + 1) * 960; ++i) energy += double(x[i]) * x[i];
    if (energy / 960 < 1e-3) continue;
    none_sum += lostFrameSnr(plain, k, true);
    ++frames;
  }
  EXPECT_LT(none_sum / frames, fec_sum / frames - 3);
}

TEST(VoiceCodec, GarbageBehindAValidTocDecodesToSomethingBounded) {
  std::mt19937 rng(3);
  VoiceDecoder d;
  std::vector<float> out(960);
  int refused = 0;
  for (int i = 0; i < 2000; ++i) {
    std::vector<uint8_t> p(1 + rng() % 300);
    for (auto& b : p) b = uint8_t(rng());
    p[0] = uint8_t((p[0] & 0xF8) | 0);  // code 0: one frame; the config byte is random
    // Only 20 ms configurations fit `out`; the others are refused by voice_packet.h first.
    const int config = p[0] >> 3;
    const bool twenty = (config < 12 && config % 4 == 1) ||
                        (config >= 12 && config < 16 && config % 2 == 1) ||
                        (config >= 16 && config % 4 == 3);
    if (!twenty) continue;
    if (!d.decode(p, out)) ++refused;
    // (Float decoding is not clipped: garbage may be loud, the mixer's limiter bounds it.)
    for (float v : out) ASSERT_TRUE(std::isfinite(v));
  }
  d.conceal(out);
  for (float v : out) ASSERT_TRUE(std::isfinite(v));
  std::printf("garbage packets refused by libopus: %d\n", refused);
}

TEST(VoiceCodec, MovedFromCodecsStillWork) {
  VoiceEncoder a{VoiceSettings{}};
  VoiceEncoder b = std::move(a);
  std::vector<uint8_t> p;
  const std::vector<float> x = tone(500, 0.02);
  EXPECT_TRUE(b.encode(x, p));
  VoiceDecoder d;
  VoiceDecoder e = std::move(d);
  std::vector<float> out(960);
  EXPECT_TRUE(e.decode(p, out));
}

}  // namespace
