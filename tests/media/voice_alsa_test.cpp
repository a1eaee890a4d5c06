// Sound devices through ALSA (media/voice_alsa.h) on alsa-lib's "null" PCM, which exists
// without a sound card: capture gives silence and playback discards, both at any speed (it has
// no clock), so the session's clock paces them. An unknown device is refused by name.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <tessera/media/voice_alsa.h>
#include <tessera/media/voice_bridge.h>
#include <tessera/core/check.h>

namespace {

using namespace tessera::media;

constexpr int kFrame = 960;  // 20 ms

/// Skips the test when alsa-lib has no "null" PCM (an unusual alsa.conf).
#define SKIP_WITHOUT_NULL_PCM()                                                  \
  do {                                                                           \
    try {                                                                        \
      AlsaPcm probe("null", AlsaPcm::Direction::kPlayback, kFrame);              \
    } catch (const AlsaError& e) {                                               \
      GTEST_SKIP() << "alsa-lib's null PCM cannot be opened here: " << e.what(); \
    }                                                                            \
  } while (false)

TEST(VoiceAlsa, DeviceNamesAreTakenFromTheAudioArgument) {
  EXPECT_EQ(alsaDeviceOf("alsa:default"), std::optional<std::string>("default"));
  EXPECT_EQ(alsaDeviceOf("alsa:hw:0,0"), std::optional<std::string>("hw:0,0"));
  EXPECT_EQ(alsaDeviceOf("talk.wav"), std::nullopt);
  EXPECT_EQ(alsaDeviceOf(""), std::nullopt);
  EXPECT_THROW(alsaDeviceOf("alsa:"), AlsaError);
}

TEST(VoiceAlsa, NullCapturesSilenceAndPlays) {
  SKIP_WITHOUT_NULL_PCM();
  AlsaPcm capture("null", AlsaPcm::Direction::kCapture, kFrame);
  AlsaPcm playback("null", AlsaPcm::Direction::kPlayback, kFrame);
  EXPECT_NE(capture.describe().find("capture device 'null'"), std::string::npos);
  EXPECT_GT(capture.available(), 0u);
  std::vector<float> frame(kFrame, 1.0f);
  for (int i = 0; i < 50; ++i) {
    capture.read(frame);
    EXPECT_TRUE(std::all_of(frame.begin(), frame.end(), [](float v) { return v == 0.0f; }));
    playback.write(frame);
  }
  EXPECT_EQ(capture.xruns(), 0u);
  EXPECT_EQ(playback.xruns(), 0u);
  EXPECT_THROW(capture.write(frame), tessera::PreconditionError);
}

TEST(VoiceAlsa, FramesFlowAtTheSessionsPace) {
  SKIP_WITHOUT_NULL_PCM();
  AlsaMicrophone microphone("null", kFrame);
  AlsaSpeaker speaker("null", kFrame);
  uint64_t captured = 0, played = 0;
  double last = -1;
  bool increasing = true;
  // One second of a loop at 100 Hz: 50 frames of 20 ms, and the kAlsaMaxAhead_s (25 frames)
  // a device may run ahead of the clock.
  for (int tick = 0; tick <= 100; ++tick) {
    const double now = tick * 0.01;
    microphone.pump(now, [&](std::span<const float> f) {
      EXPECT_EQ(f.size(), size_t(kFrame));
      ++captured;
    });
    speaker.pump(now, [&](double at, std::span<float> f) {
      EXPECT_EQ(f.size(), size_t(kFrame));
      increasing = increasing && at >= last + 0.02 - 1e-9;
      last = at;
      std::fill(f.begin(), f.end(), 0.25f);
      ++played;
    });
    const uint64_t most = uint64_t(std::floor((now + kAlsaMaxAhead_s) * 50 + 1e-9));
    ASSERT_LE(captured, most) << "at " << now << " s";
    ASSERT_LE(played, most) << "at " << now << " s";
  }
  EXPECT_EQ(captured, 75u);
  EXPECT_EQ(captured, microphone.frames());
  EXPECT_EQ(played, 75u);
  EXPECT_TRUE(increasing) << "each frame plays after the one before";
}

TEST(VoiceAlsa, AnUnknownDeviceIsRefusedByName) {
  for (const auto direction : {AlsaPcm::Direction::kCapture, AlsaPcm::Direction::kPlayback}) {
    try {
      AlsaPcm pcm("nosuchdevice", direction, kFrame);
      ADD_FAILURE() << "nosuchdevice opened";
    } catch (const AlsaError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("media::AlsaPcm"), std::string::npos) << what;
      EXPECT_NE(what.find("'nosuchdevice'"), std::string::npos) << what;
      EXPECT_NE(what.find(direction == AlsaPcm::Direction::kCapture ? "capture" : "playback"),
                std::string::npos)
          << what;
    }
  }
  EXPECT_THROW(AlsaPcm("null", AlsaPcm::Direction::kCapture, 5000), AlsaError);
}

TEST(VoiceAlsa, LiveStationAndBridgeLeaveTheirSidesToTheDevice) {
  // A station with a live microphone and speaker sends and plays nothing on its own clock.
  VoiceStation station(VoiceSettings{}, std::vector<float>(48000, 0.5f));
  station.setLive(true, true);
  int sent = 0;
  station.advance(1.0, [&](std::vector<uint8_t>) { ++sent; });
  EXPECT_EQ(sent, 0);
  EXPECT_TRUE(station.speaker().empty());
  std::vector<float> frame(size_t(station.frameSamples()), 0.5f);
  for (int i = 0; i < 5; ++i) station.sendLive(frame, [&](std::vector<uint8_t>) { ++sent; });
  EXPECT_EQ(sent, 5);

  // A bridge with a live wall microphone sends a site what it heard (the first period), and
  // nothing once it has heard nothing more (silence is not sent).
  VoiceBridge bridge(VoiceSettings{}, {});
  bridge.join(1);
  bridge.hearWall(frame);
  std::vector<int> to_site;
  bridge.advance(0.02, [&](uint32_t, const std::vector<uint8_t>&) { to_site.push_back(1); });
  bridge.advance(0.04, [&](uint32_t, const std::vector<uint8_t>&) { to_site.push_back(2); });
  EXPECT_EQ(to_site, std::vector<int>{1});
  EXPECT_EQ(bridge.takeRoom().size(), 2 * frame.size());
  EXPECT_TRUE(bridge.room().empty());
}

}  // namespace
