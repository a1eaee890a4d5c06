// The mixer (media/voice_mixer.h): the room hears the sites, each site hears everyone but
// itself, and loud sums bend under full scale without clipping, wrapping or clicks.
#include <gtest/gtest.h>

#include <cmath>

#include <tessera/media/voice_mixer.h>
#include <tessera/media/voice_packet.h>
#include <tessera/core/check.h>

#include "../support/voice_path.h"

namespace {

using namespace tessera::media;

TEST(VoiceMixer, RoomHearsTheSitesAndEachSiteEveryoneButItself) {
  VoiceMixer mixer(4);
  const std::vector<float> wall{0.1f, 0.1f, 0.1f, 0.1f};
  const std::vector<float> a{0.01f, 0.02f, 0.03f, 0.04f};
  const std::vector<float> b{-0.2f, 0.0f, 0.2f, 0.0f};
  mixer.add(kWallSite, wall);
  mixer.add(1, a);
  mixer.add(2, b);
  std::vector<float> out(4);
  mixer.roomMix(out);
  for (size_t i = 0; i < 4; ++i) EXPECT_FLOAT_EQ(out[i], a[i] + b[i]);
  mixer.mixMinus(1, out);
  for (size_t i = 0; i < 4; ++i) EXPECT_FLOAT_EQ(out[i], wall[i] + b[i]);
  mixer.mixMinus(2, out);
  for (size_t i = 0; i < 4; ++i) EXPECT_FLOAT_EQ(out[i], wall[i] + a[i]);
  mixer.mixMinus(9, out);  // a listener that said nothing hears everyone
  for (size_t i = 0; i < 4; ++i) EXPECT_FLOAT_EQ(out[i], wall[i] + a[i] + b[i]);
  mixer.clear();
  mixer.add(1, a);
  mixer.mixMinus(1, out);
  for (float v : out) EXPECT_EQ(v, 0.0f);
  EXPECT_THROW(mixer.add(2, std::vector<float>(5)), tessera::PreconditionError);
}

TEST(VoiceMixer, TheLimiterIsTransparentBelowTheKneeAndBoundedAbove) {
  for (float x = -kLimiterKnee; x <= kLimiterKnee; x += 0.01f) EXPECT_EQ(softLimit(x), x);
  float last = softLimit(-50);
  for (float x = -50; x <= 50; x += 0.001f) {
    const float y = softLimit(x);
    ASSERT_LT(std::fabs(y), 1.0f);
    ASSERT_GE(y, last) << "not monotonic at " << x;
    ASSERT_LT(y - last, 0.0011f) << "a step at " << x;
    last = y;
  }
  EXPECT_EQ(softLimit(NAN), 0.0f);
  EXPECT_LT(softLimit(INFINITY), 1.0f);
}

TEST(VoiceMixer, SixLoudSitesNeverWrapOrClick) {
  // Six sites speaking at 0.5 peak sum to 3: without the limiter 16-bit PCM would clip or
  // wrap. The mix stays under full scale, and its largest step stays within what the sum's
  // own largest step is.
  const size_t n = 48000;
  VoiceMixer mixer(n);
  float sum_step = 0;
  std::vector<float> sum(n, 0.0f);
  for (uint16_t site = 1; site <= 6; ++site) {
    const std::vector<float> x = tessera::test::syntheticSpeech(1, site);
    mixer.add(site, x);
    for (size_t i = 0; i < n; ++i) sum[i] += x[i];
  }
  sum_step = tessera::test::maxStep(sum);
  std::vector<float> room(n);
  mixer.roomMix(room);
  float peak = 0;
  for (float v : room) peak = std::max(peak, std::fabs(v));
  EXPECT_LT(peak, 1.0f);
  EXPECT_GT(peak, kLimiterKnee);  // it was loud enough to be limited
  EXPECT_LE(tessera::test::maxStep(room), sum_step);
}

}  // namespace
