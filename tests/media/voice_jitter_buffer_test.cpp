// The jitter buffer (media/voice_jitter_buffer.h) on a simulated clock with real Opus packets:
// in order, duplicated, reordered, lost, late, from a restarted sender, with garbage payloads;
// the target delay following the jitter up and down. Nothing sleeps: times are passed in.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <tessera/media/voice_jitter_buffer.h>

#include "../support/voice_path.h"

namespace {

using namespace tessera::media;
using Kind = PlayedFrame::Kind;

struct Sent {
  VoicePacket packet;
  double sent_s;  ///< when the frame was whole (its last sample captured)
};

std::vector<Sent> encode(const std::vector<float>& x, bool dtx = false, uint16_t seq = 100,
                         uint32_t ts = 5000) {
  VoiceSettings s;
  s.dtx = dtx;
  VoiceSender sender(s, 2, seq, ts);
  std::vector<Sent> out;
  for (size_t at = 0; at + 960 <= x.size(); at += 960) {
    if (auto bytes = sender.send(std::span<const float>(x).subspan(at, 960))) {
      VoicePacket p;
      EXPECT_EQ(decodeVoicePacket(*bytes, p), std::nullopt);
      out.push_back({p, double(at + 960) / kVoiceRate});
    }
  }
  return out;
}

struct Arrival {
  size_t index;  ///< into the sent packets
  double at;
};

/// Pushes the arrivals as the clock passes them and pulls 10 ms blocks until `end_s`.
std::vector<float> drive(JitterBuffer& buffer, const std::vector<Sent>& sent,
                         std::vector<Arrival> arrivals, double end_s) {
  std::stable_sort(arrivals.begin(), arrivals.end(),
                   [](const Arrival& a, const Arrival& b) { return a.at < b.at; });
  std::vector<float> out, block(480);
  size_t next = 0;
  for (int k = 0; k * 0.01 < end_s; ++k) {
    const double t = k * 0.01;
    for (; next < arrivals.size() && arrivals[next].at <= t; ++next)
      buffer.push(sent[arrivals[next].index].packet, arrivals[next].at);
    buffer.pull(t, block);
    out.insert(out.end(), block.begin(), block.end());
  }
  return out;
}

std::vector<Arrival> steady(const std::vector<Sent>& sent, double delay_s = 0.03) {
  std::vector<Arrival> a;
  for (size_t i = 0; i < sent.size(); ++i) a.push_back({i, sent[i].sent_s + delay_s});
  return a;
}

JitterBufferSettings recording() {
  JitterBufferSettings s;
  s.record = true;
  return s;
}

TEST(JitterBuffer, SilenceBeforeTheFirstPacket) {
  JitterBuffer b;
  std::vector<float> block(480, 1.0f);
  b.pull(0, block);
  for (float v : block) EXPECT_EQ(v, 0.0f);
  EXPECT_EQ(b.stats().frames(), 0u);
}

TEST(JitterBuffer, InOrderWithoutJitterPlaysEveryFrameAtTheMinimumDelay) {
  const auto sent = encode(tessera::test::tone(440, 2));
  JitterBuffer b(recording());
  drive(b, sent, steady(sent), 2.5);
  EXPECT_EQ(b.stats().decoded, sent.size());
  EXPECT_EQ(b.stats().concealed, 0u);
  EXPECT_EQ(b.stats().late, 0u);
  EXPECT_EQ(b.stats().inserted, 0u);
  EXPECT_NEAR(b.stats().target_s, JitterBufferSettings{}.min_delay_s, 1e-9);
  EXPECT_LT(b.stats().delay_s, b.stats().target_s + 0.02 + 1e-9);
  EXPECT_LT(b.stats().jitter_s, 1e-9);
  uint32_t expected = 5000;
  ASSERT_GE(b.history().size(), sent.size());
  for (size_t i = 0; i < b.history().size(); ++i) {
    const PlayedFrame& f = b.history()[i];
    // After the last packet the stream is silent: concealment until it is known why.
    EXPECT_EQ(f.kind, i < sent.size() ? Kind::kDecoded : Kind::kConcealed) << i;
    EXPECT_EQ(f.timestamp, expected);
    expected += 960;
  }
}

TEST(JitterBuffer, DuplicatesAreIgnored) {
  const auto sent = encode(tessera::test::tone(440, 1));
  JitterBuffer once, twice;
  const std::vector<float> a = drive(once, sent, steady(sent), 1.5);
  auto arrivals = steady(sent);
  for (size_t i = 0; i < sent.size(); ++i) {
    arrivals.push_back({i, sent[i].sent_s + 0.031});  // before it plays: held twice
    arrivals.push_back({i, sent[i].sent_s + 0.2});    // after it played
  }
  const std::vector<float> b = drive(twice, sent, arrivals, 1.5);
  EXPECT_EQ(a, b) << "a duplicate changed what was played";
  EXPECT_EQ(twice.stats().duplicates, 2 * sent.size());
  EXPECT_EQ(twice.stats().late, 0u);
}

TEST(JitterBuffer, ReorderingWithinTheDelayIsHarmless) {
  const auto sent = encode(tessera::test::tone(440, 3));
  auto arrivals = steady(sent);
  for (size_t i = 0; i + 1 < arrivals.size(); i += 2) arrivals[i].at += 0.025;  // after i + 1
  JitterBuffer b(recording());
  drive(b, sent, arrivals, 3.5);
  // The first swaps teach the buffer the jitter (a frame or two inserted, none concealed
  // after that); every frame then plays from its own packet, in order.
  EXPECT_LE(b.stats().concealed, 1u);
  EXPECT_GE(b.stats().decoded, sent.size() - 1);
  int64_t last = -1;
  for (const PlayedFrame& f : b.history())
    if (f.kind == Kind::kDecoded) {
      EXPECT_GT(int64_t(f.timestamp), last);
      last = f.timestamp;
    }
  EXPECT_GT(b.stats().target_s, 0.02);
}

TEST(JitterBuffer, ALostPacketComesBackFromTheNextPacketsFec) {
  const auto sent = encode(tessera::test::syntheticSpeech(3, 4));
  auto arrivals = steady(sent);
  // Lose 40 (41 carries its FEC); lose 60 and 61 (62 carries 61's FEC; 60 is concealed).
  arrivals.erase(arrivals.begin() + 61);
  arrivals.erase(arrivals.begin() + 60);
  arrivals.erase(arrivals.begin() + 40);
  JitterBufferSettings settings = recording();
  settings.min_delay_s = 0.030;  // room for the next packet from the start (see below)
  JitterBuffer b(settings);
  drive(b, sent, arrivals, 3.5);
  EXPECT_EQ(b.stats().concealed, 3u);
  EXPECT_EQ(b.stats().fec, 2u);
  EXPECT_EQ(b.stats().decoded, sent.size() - 3);
  std::map<uint32_t, Kind> kinds;
  for (const PlayedFrame& f : b.history()) kinds[f.timestamp] = f.kind;
  EXPECT_EQ(kinds[sent[40].packet.timestamp], Kind::kFec);
  EXPECT_EQ(kinds[sent[60].packet.timestamp], Kind::kConcealed);
  EXPECT_EQ(kinds[sent[61].packet.timestamp], Kind::kFec);
}

TEST(JitterBuffer, ALatePacketIsDroppedAndItsFrameConcealed) {
  const auto sent = encode(tessera::test::tone(440, 2));
  auto arrivals = steady(sent);
  arrivals[25].at += 0.5;
  JitterBufferSettings s = recording();
  s.max_delay_s = 0.05;  // so the one late packet cannot pull the target past it
  JitterBuffer b(s);
  drive(b, sent, arrivals, 2.5);
  EXPECT_EQ(b.stats().late, 1u);
  EXPECT_EQ(b.stats().concealed, 1u);
  EXPECT_EQ(b.stats().decoded, sent.size() - 1);
}

TEST(JitterBuffer, UnderLossTheDelayMakesRoomForFec) {
  // No jitter, 5% loss: the target alone would be the minimum delay, too short for the next
  // packet to be there when a frame is missing. With losses seen, a frame is added, and lost
  // frames come back from FEC.
  const auto sent = encode(tessera::test::syntheticSpeech(6, 12));
  std::mt19937 rng(4);
  std::vector<Arrival> arrivals;
  size_t lost = 0;
  for (size_t i = 0; i < sent.size(); ++i) {
    if (i > 10 && rng() % 20 == 0) {
      ++lost;
      continue;
    }
    arrivals.push_back({i, sent[i].sent_s + 0.03});
  }
  JitterBuffer b;
  drive(b, sent, arrivals, 6.5);
  EXPECT_EQ(b.stats().concealed, lost);
  EXPECT_GE(b.stats().fec, lost * 8 / 10);
  EXPECT_NEAR(b.stats().target_s, JitterBufferSettings{}.min_delay_s + 0.020, 1e-9);
}

TEST(JitterBuffer, TheTargetFollowsTheJitterUpAndDown) {
  // 24 s of synthetic speech (pauses every few syllables, sent as DTX): 4 s without jitter,
  // 10 s with 30 ms mean exponential jitter, 10 s without.
  const auto x = tessera::test::syntheticSpeech(24, 8);
  const auto sent = encode(x, true);
  std::mt19937 rng(5);
  std::exponential_distribution<double> jitter(1 / 0.030);
  std::vector<Arrival> arrivals;
  for (size_t i = 0; i < sent.size(); ++i) {
    const double t = sent[i].sent_s;
    arrivals.push_back({i, t + 0.02 + (t > 4 && t < 14 ? jitter(rng) : 0.0)});
  }
  JitterBuffer b;
  std::vector<float> block(480);
  double calm_target = 0, jittery_target = 0, final_target = 0, final_delay = 0;
  uint64_t concealed_before = 0, frames_before = 0;
  std::stable_sort(arrivals.begin(), arrivals.end(),
                   [](const Arrival& a, const Arrival& c) { return a.at < c.at; });
  size_t next = 0;
  for (double t = 0; t < 25; t += 0.01) {
    for (; next < arrivals.size() && arrivals[next].at <= t; ++next)
      b.push(sent[arrivals[next].index].packet, arrivals[next].at);
    b.pull(t, block);
    if (std::fabs(t - 4) < 0.005) calm_target = b.stats().target_s;
    if (std::fabs(t - 7) < 0.005) {
      concealed_before = b.stats().concealed;
      frames_before = b.stats().frames();
    }
    if (std::fabs(t - 14) < 0.005) {
      jittery_target = b.stats().target_s;
      const double share = double(b.stats().concealed - concealed_before) /
                           double(b.stats().frames() - frames_before);
      EXPECT_LT(share, 0.05) << "concealed in the jittery stretch, once adapted";
    }
  }
  final_target = b.stats().target_s;
  final_delay = b.stats().delay_s;
  std::printf(
      "target: calm %.1f ms, jittery %.1f ms, calm again %.1f ms (delay %.1f ms); "
      "inserted %llu, dropped %llu\n",
      calm_target * 1e3, jittery_target * 1e3, final_target * 1e3, final_delay * 1e3,
      (unsigned long long)b.stats().inserted, (unsigned long long)b.stats().dropped);
  EXPECT_LT(calm_target, 0.015);
  // 30 ms mean exponential: its 97th percentile is 105 ms.
  EXPECT_GT(jittery_target, 0.070);
  EXPECT_LT(jittery_target, 0.160);
  EXPECT_LT(final_target, 0.015);
  // The delay came down with it, in the pauses.
  EXPECT_LT(final_delay, final_target + 0.035);
  EXPECT_GT(b.stats().dropped, 3u);
}

TEST(JitterBuffer, ARestartedSenderIsFollowed) {
  const auto x = tessera::test::tone(440, 2);
  auto first = encode(x, false, 100, 5000);
  const auto second = encode(x, false, 7, 900000000);
  std::vector<Sent> sent = first;
  for (Sent s : second) {
    s.sent_s += 2.2;
    sent.push_back(s);
  }
  JitterBuffer b;
  drive(b, sent, steady(sent), 5);
  EXPECT_EQ(b.stats().resets, 1u);
  EXPECT_GE(b.stats().decoded, sent.size() - 8 - 1);
  EXPECT_EQ(b.stats().refused, 8u);  // the eighth in a row resets the stream, then plays
}

TEST(JitterBuffer, GarbagePayloadsAreConcealedAndTheStreamGoesOn) {
  const auto x = tessera::test::tone(440, 2);
  auto sent = encode(x);
  std::mt19937 rng(9);
  for (size_t i = 10; i < sent.size(); i += 10) {
    auto& p = sent[i].packet.payload;
    for (size_t k = 1; k < p.size(); ++k) p[k] = uint8_t(rng());  // keep the TOC
  }
  JitterBuffer b;
  const auto out = drive(b, sent, steady(sent), 2.5);
  EXPECT_EQ(b.stats().decoded, sent.size());
  for (float v : out) ASSERT_TRUE(std::isfinite(v));
}

TEST(JitterBuffer, FarPacketsAreRefusedAndTheBufferIsBounded) {
  const auto sent = encode(tessera::test::tone(440, 4));
  JitterBuffer b;
  // Every packet as sent, nothing played: the buffer holds at most max_packets.
  for (const Sent& s : sent) b.push(s.packet, s.sent_s);
  EXPECT_EQ(b.held(), JitterBufferSettings{}.max_packets);
  EXPECT_EQ(b.stats().refused, sent.size() - b.held());
  EXPECT_EQ(b.stats().resets, 0u);
  // A packet stamped far ahead of its arrival is refused.
  JitterBuffer c;
  VoicePacket p = sent[0].packet;
  c.push(p, 0.0);
  p.sequence += 1;
  p.timestamp += uint32_t(kVoiceRate);  // 1 s of audio later, arriving at once
  c.push(p, 0.0);
  EXPECT_EQ(c.stats().refused, 1u);
  EXPECT_EQ(c.held(), 1u);
}

TEST(JitterBuffer, Deterministic) {
  const auto sent = encode(tessera::test::syntheticSpeech(3, 2), true);
  std::mt19937 rng(1);
  std::vector<Arrival> arrivals;
  for (size_t i = 0; i < sent.size(); ++i)
    if (rng() % 10) arrivals.push_back({i, sent[i].sent_s + 0.02 * double(rng() % 100) / 100});
  JitterBuffer a, b;
  EXPECT_EQ(drive(a, sent, arrivals, 3.5), drive(b, sent, arrivals, 3.5));
}

}  // namespace
