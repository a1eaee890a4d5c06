// Voice: what each participant hears, one block of samples at a time. The wall room
// hears every site (not its own microphone: that would feed back through the room's speakers);
// each site hears the wall's microphone and every other site, never itself ("mix-minus", as in
// broadcast and conference bridges). Sums are limited with a soft knee, so a loud moment bends
// smoothly under full scale instead of clipping, or wrapping around in 16-bit.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <vector>

namespace tessera::media {

/// Unity below kLimiterKnee; above it the level bends (tanh) towards 1, never reaching it.
/// Continuous, with a continuous slope, and odd: limits without clicks. |softLimit(x)| < 1.
constexpr float kLimiterKnee = 0.7f;
float softLimit(float x);

class VoiceMixer {
 public:
  /// Every source's block is `block_samples` long (a playout period, e.g. 480 = 10 ms).
  explicit VoiceMixer(size_t block_samples);

  /// Starts a new block: forgets the previous block's sources.
  void clear();
  /// Adds a source's block: kWallSite (0) is the wall room's microphone, others are sites.
  /// A source added twice in a block adds up. Precondition (TESSERA_CHECK): block_samples long.
  void add(uint32_t source, std::span<const float> pcm);
  /// The wall room's speakers: every site, limited. Precondition: out is block_samples long.
  void roomMix(std::span<float> out) const;
  /// What `site` hears: every source but itself (the wall's microphone included), limited.
  void mixMinus(uint32_t site, std::span<float> out) const;

  size_t blockSamples() const { return mTotal.size(); }
  /// The sources added to this block, by id.
  const std::map<uint32_t, std::vector<float>>& sources() const { return mSources; }

 private:
  void minus(uint32_t source, std::span<float> out) const;

  std::vector<float> mTotal;  ///< the sum of every source, unlimited
  std::map<uint32_t, std::vector<float>> mSources;
};

}  // namespace tessera::media
