// The voice packet (media/voice_packet.h): round trip, every field checked, every truncation
// and extension refused, random bytes never crash, and the sender's numbering with DTX.
#include <gtest/gtest.h>

#include <random>

#include <tessera/media/voice_packet.h>

#include "../support/voice_path.h"

namespace {

using namespace tessera::media;

std::vector<uint8_t> realPayload() {
  VoiceEncoder e{VoiceSettings{}};
  std::vector<uint8_t> p;
  const auto x = tessera::test::tone(440, 0.02);
  e.encode(x, p);
  return p;
}

std::string why(const std::vector<uint8_t>& bytes) {
  VoicePacket p;
  return decodeVoicePacket(bytes, p).value_or("");
}

TEST(VoicePacket, RoundTrip) {
  VoicePacket p;
  p.site = 0xBEEF;
  p.sequence = 65535;
  p.timestamp = 0xFFFFFC40u;
  p.talkspurt = true;
  p.payload = realPayload();
  const std::vector<uint8_t> bytes = encodeVoicePacket(p);
  ASSERT_EQ(bytes.size(), kVoiceHeaderBytes + p.payload.size());
  VoicePacket q;
  ASSERT_EQ(decodeVoicePacket(bytes, q), std::nullopt);
  EXPECT_EQ(q.site, p.site);
  EXPECT_EQ(q.sequence, p.sequence);
  EXPECT_EQ(q.timestamp, p.timestamp);
  EXPECT_TRUE(q.talkspurt);
  EXPECT_EQ(q.frame_samples, 960);
  EXPECT_EQ(q.payload, p.payload);
}

TEST(VoicePacket, EveryFieldIsChecked) {
  VoicePacket p;
  p.payload = realPayload();
  const std::vector<uint8_t> good = encodeVoicePacket(p);
  // Every truncation, and one byte more.
  for (size_t n = 0; n < good.size(); ++n)
    EXPECT_NE(why({good.begin(), good.begin() + ptrdiff_t(n)}), "") << n << " bytes";
  auto longer = good;
  longer.push_back(0);
  EXPECT_NE(why(longer).find("payload size"), std::string::npos) << why(longer);
  auto bad = good;
  bad[0] = 2;
  EXPECT_NE(why(bad).find("version 2, expected 1"), std::string::npos) << why(bad);
  bad = good;
  bad[1] = 0x80;
  EXPECT_NE(why(bad).find("reserved bits"), std::string::npos) << why(bad);
  bad = good;
  bad[6] = uint8_t(bad[6] + 1);
  EXPECT_NE(why(bad).find("payload size"), std::string::npos) << why(bad);
  // Oversized: a payload larger than any Opus frame, with a matching size field.
  std::vector<uint8_t> big(kMaxVoicePacketBytes + 1, 0);
  big[0] = kVoicePacketVersion;
  big[6] = uint8_t((big.size() - kVoiceHeaderBytes) & 255);
  big[7] = uint8_t((big.size() - kVoiceHeaderBytes) >> 8);
  EXPECT_NE(why(big).find("more than the largest packet"), std::string::npos) << why(big);
  // A 40 ms Opus packet (SILK NB, config 2) is well formed but not a frame this stream uses.
  bad = good;
  bad[kVoiceHeaderBytes] = uint8_t(2 << 3);
  EXPECT_NE(why(bad).find("1920 samples, expected 480 or 960"), std::string::npos) << why(bad);
  // Code 3 (arbitrary frame count) with a count of 0: malformed Opus framing.
  bad = good;
  bad[kVoiceHeaderBytes] = uint8_t((1 << 3) | 3);
  bad[kVoiceHeaderBytes + 1] = 0;
  EXPECT_NE(why(bad).find("malformed"), std::string::npos) << why(bad);
  // Code 1 (two frames of equal size) with an odd payload.
  bad = good;
  bad[kVoiceHeaderBytes] = uint8_t((1 << 3) | 1);
  if ((bad.size() - kVoiceHeaderBytes - 1) % 2 == 1) {
    EXPECT_NE(why(bad), "");
  }
  EXPECT_EQ(why(good), "");
}

TEST(VoicePacket, RandomBytesNeverCrashAndWhatPassesIsConsistent) {
  std::mt19937 rng(17);
  VoicePacket p;
  p.payload = realPayload();
  const std::vector<uint8_t> good = encodeVoicePacket(p);
  int accepted = 0;
  for (int i = 0; i < 20000; ++i) {
    std::vector<uint8_t> bytes;
    if (i % 2) {
      bytes.resize(rng() % 1400);
      for (auto& b : bytes) b = uint8_t(rng());
      if (bytes.size() > 8) bytes[0] = kVoicePacketVersion;
    } else {
      bytes = good;  // mutate a few bytes of a good packet
      for (int k = 0; k < 1 + int(rng() % 4); ++k) bytes[rng() % bytes.size()] ^= uint8_t(rng());
    }
    VoicePacket q;
    if (decodeVoicePacket(bytes, q)) continue;
    ++accepted;
    ASSERT_EQ(q.payload.size() + kVoiceHeaderBytes, bytes.size());
    ASSERT_TRUE(q.frame_samples == 480 || q.frame_samples == 960);
  }
  EXPECT_GT(accepted, 100);  // mutated headers and payloads that still parse
}

TEST(VoicePacket, SenderNumbersSentPacketsAndStampsEveryFrame) {
  VoiceSender sender(VoiceSettings{}, 4, 65534, 0xFFFFFFFFu - 959);
  const auto speech = tessera::test::tone(300, 0.1);
  const std::vector<float> silence(960, 0.0f);
  std::vector<VoicePacket> sent;
  uint32_t frames = 0;
  const auto send = [&](std::span<const float> pcm) {
    if (auto bytes = sender.send(pcm)) {
      VoicePacket q;
      ASSERT_EQ(decodeVoicePacket(*bytes, q), std::nullopt);
      sent.push_back(q);
      EXPECT_EQ(q.timestamp, uint32_t(0xFFFFFFFFu - 959 + frames * 960));
    }
    ++frames;
  };
  for (size_t at = 0; at + 960 <= speech.size(); at += 960) send({speech.data() + at, 960});
  size_t during_silence = 0;
  for (int i = 0; i < 40; ++i) {
    const size_t n = sent.size();
    send(silence);
    during_silence += sent.size() - n;
  }
  for (size_t at = 0; at + 960 <= speech.size(); at += 960) send({speech.data() + at, 960});
  EXPECT_LT(during_silence, 20u) << "DTX left little out";
  ASSERT_GE(sent.size(), 10u);
  int talkspurts = 0;
  for (size_t i = 1; i < sent.size(); ++i) {
    EXPECT_EQ(sent[i].sequence, uint16_t(sent[i - 1].sequence + 1)) << "a gap in sequence";
    EXPECT_EQ(sent[i].site, 4);
    // Marked exactly when frames were left out before it.
    EXPECT_EQ(sent[i].talkspurt, sent[i].timestamp != uint32_t(sent[i - 1].timestamp + 960)) << i;
    talkspurts += sent[i].talkspurt;
  }
  EXPECT_TRUE(sent[0].talkspurt);
  EXPECT_GE(talkspurts, 1);
}

}  // namespace
