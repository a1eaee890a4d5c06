#include <tessera/media/voice_mixer.h>

#include <algorithm>
#include <cmath>
#include <string>

#include <tessera/media/voice_packet.h>
#include <tessera/core/check.h>

namespace tessera::media {

float softLimit(float x) {
  // y = x below the knee; above it y = k + (1 - k) tanh((|x| - k) / (1 - k)): slope 1 at the
  // knee on both sides, so the curve has no corner to hear, and it tends to 1.
  const float a = std::fabs(x);
  if (!(a > kLimiterKnee)) return std::isfinite(x) ? x : 0.0f;
  const float span = 1.0f - kLimiterKnee;
  const float y = kLimiterKnee + span * std::tanh((a - kLimiterKnee) / span);
  return std::copysign(std::min(y, 0.99997f), x);
}

VoiceMixer::VoiceMixer(size_t block_samples) : mTotal(block_samples, 0.0f) {
  TESSERA_CHECK(block_samples > 0, "media::VoiceMixer: a block has at least one sample");
}

void VoiceMixer::clear() {
  std::fill(mTotal.begin(), mTotal.end(), 0.0f);
  mSources.clear();
}

void VoiceMixer::add(uint32_t source, std::span<const float> pcm) {
  TESSERA_CHECK(pcm.size() == mTotal.size(),
                "media::VoiceMixer::add(): source " + std::to_string(source) + " gave " +
                    std::to_string(pcm.size()) + " samples, the block is " +
                    std::to_string(mTotal.size()));
  auto [it, fresh] = mSources.try_emplace(source, mTotal.size(), 0.0f);
  for (size_t i = 0; i < pcm.size(); ++i) {
    it->second[i] += pcm[i];
    mTotal[i] += pcm[i];
  }
}

void VoiceMixer::minus(uint32_t source, std::span<float> out) const {
  TESSERA_CHECK(out.size() == mTotal.size(), "media::VoiceMixer: the output is not one block");
  const auto own = mSources.find(source);
  for (size_t i = 0; i < out.size(); ++i) {
    const float own_i = own == mSources.end() ? 0.0f : own->second[i];
    out[i] = softLimit(mTotal[i] - own_i);
  }
}

void VoiceMixer::roomMix(std::span<float> out) const {
  minus(kWallSite, out);
}

void VoiceMixer::mixMinus(uint32_t site, std::span<float> out) const {
  minus(site, out);
}

}  // namespace tessera::media
