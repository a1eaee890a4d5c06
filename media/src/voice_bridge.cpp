#include <tessera/media/voice_bridge.h>

#include <algorithm>
#include <cmath>

namespace tessera::media {
namespace {

/// The speaker's block: 10 ms, a usual sound card period.
constexpr size_t kSpeakerBlock = kVoiceRate / 100;

/// Frame `k` of `samples` (`n` long) into `frame`, zeros past the end.
void frameOf(const std::vector<float>& samples, uint64_t k, size_t n, std::vector<float>& frame) {
  frame.assign(n, 0.0f);
  const size_t at = size_t(k) * n;
  if (at < samples.size())
    std::copy_n(samples.begin() + ptrdiff_t(at), std::min(n, samples.size() - at), frame.begin());
}

/// How many periods of `period_s` are whole by `now`, after `done`; a stall longer than
/// kVoiceMaxCatchUp_s moves `done` on (those periods are skipped) and returns the rest.
uint64_t due(double now, double period_s, uint64_t& done, uint64_t& skipped) {
  const double whole = std::floor(now / period_s + 1e-9);
  const uint64_t total = whole > 0 ? uint64_t(whole) : 0;
  const uint64_t most = uint64_t(kVoiceMaxCatchUp_s / period_s);
  skipped = 0;
  if (total > done + most) {
    skipped = total - most - done;
    done = total - most;
  }
  return total > done ? total - done : 0;
}

bool silent(std::span<const float> x) {
  return std::all_of(x.begin(), x.end(), [](float v) { return v == 0.0f; });
}

}  // namespace

VoiceStation::VoiceStation(const VoiceSettings& codec, std::vector<float> microphone,
                           const JitterBufferSettings& buffer)
    : mSender(codec, kWallSite), mBuffer(buffer), mMicrophone(std::move(microphone)) {}

void VoiceStation::setLive(bool microphone, bool speaker) {
  mLiveMicrophone = microphone;
  mLiveSpeaker = speaker;
}

void VoiceStation::sendLive(std::span<const float> frame,
                            const std::function<void(std::vector<uint8_t>)>& send) {
  if (auto bytes = mSender.send(frame)) send(std::move(*bytes));
}

void VoiceStation::advance(double now, const std::function<void(std::vector<uint8_t>)>& send) {
  const size_t n = size_t(mSender.frameSamples());
  uint64_t skipped = 0;
  for (uint64_t k = mLiveMicrophone ? 0 : due(now, double(n) / kVoiceRate, mSent, skipped); k > 0;
       --k) {
    frameOf(mMicrophone, mSent++, n, mFrame);
    if (auto bytes = mSender.send(mFrame)) send(std::move(*bytes));
  }
  if (mLiveSpeaker) return;
  uint64_t left = due(now, double(kSpeakerBlock) / kVoiceRate, mPlayed, skipped);
  mSpeaker.resize(mSpeaker.size() + skipped * kSpeakerBlock, 0.0f);
  for (; left > 0; --left, ++mPlayed) {
    const size_t at = mSpeaker.size();
    mSpeaker.resize(at + kSpeakerBlock);
    mBuffer.pull(double(mPlayed * kSpeakerBlock) / kVoiceRate,
                 std::span<float>(mSpeaker).subspan(at, kSpeakerBlock));
  }
}

std::optional<std::string> VoiceStation::receive(std::span<const uint8_t> bytes, double now) {
  VoicePacket packet;
  if (auto why = decodeVoicePacket(bytes, packet)) return why;
  mBuffer.push(packet, now);
  return std::nullopt;
}

VoiceBridge::VoiceBridge(const VoiceSettings& codec, std::vector<float> wall_microphone,
                         const JitterBufferSettings& buffer)
    : mCodec(codec),
      mBufferSettings(buffer),
      mMixer(size_t(codec.frameSamples())),
      mWallMicrophone(std::move(wall_microphone)) {
  VoiceEncoder check(codec);  // the settings are refused here, not at the first join
}

void VoiceBridge::join(uint32_t participant) {
  mParticipants.try_emplace(
      participant, Participant{JitterBuffer(mBufferSettings), VoiceSender(mCodec, kWallSite), {}});
}

void VoiceBridge::leave(uint32_t participant) {
  mParticipants.erase(participant);
}

void VoiceBridge::receive(uint32_t participant, const VoicePacket& packet, double now) {
  auto it = mParticipants.find(participant);
  if (it != mParticipants.end()) it->second.in.push(packet, now);
}

void VoiceBridge::hearWall(std::span<const float> samples) {
  mLive = true;
  mLiveWall.insert(mLiveWall.end(), samples.begin(), samples.end());
  const size_t most = size_t(kVoiceMaxCatchUp_s * kVoiceRate);
  if (mLiveWall.size() > most)
    mLiveWall.erase(mLiveWall.begin(), mLiveWall.end() - ptrdiff_t(most));
}

const JitterStats* VoiceBridge::stats(uint32_t participant) const {
  auto it = mParticipants.find(participant);
  return it == mParticipants.end() ? nullptr : &it->second.in.stats();
}

void VoiceBridge::advance(double now,
                          const std::function<void(uint32_t, const std::vector<uint8_t>&)>& send) {
  const size_t n = mMixer.blockSamples();
  const double period_s = double(n) / kVoiceRate;
  uint64_t skipped = 0;
  uint64_t left = due(now, period_s, mPeriods, skipped);
  mRoom.resize(mRoom.size() + skipped * n, 0.0f);
  for (; left > 0; --left, ++mPeriods) {
    mMixer.clear();
    if (mLive) {  // what the device captured so far; silence when it is behind
      mMix.assign(n, 0.0f);
      const size_t have = std::min(n, mLiveWall.size());
      std::copy_n(mLiveWall.begin(), have, mMix.begin());
      mLiveWall.erase(mLiveWall.begin(), mLiveWall.begin() + ptrdiff_t(have));
    } else {
      frameOf(mWallMicrophone, mPeriods, n, mMix);
    }
    mMixer.add(kWallSite, mMix);
    const double t = double(mPeriods) * period_s;
    for (auto& [id, p] : mParticipants) {
      p.frame.resize(n);
      p.in.pull(t, p.frame);
      mMixer.add(id, p.frame);
    }
    const size_t at = mRoom.size();
    mRoom.resize(at + n);
    mMixer.roomMix(std::span<float>(mRoom).subspan(at, n));
    for (auto& [id, p] : mParticipants) {
      mMix.resize(n);
      mMixer.mixMinus(id, mMix);
      if (silent(mMix)) {
        p.out.skip();  // nobody else talks: nothing to encode or send
        continue;
      }
      if (auto bytes = p.out.send(mMix)) send(id, *bytes);
    }
  }
}

}  // namespace tessera::media
