// Voice over the site link, without sockets: the two ends the site link carries
// voice packets between, each driven by a clock (seconds since it started) from its owner's loop.
//
// VoiceStation is a site's end: its microphone (samples, e.g. a WAV file; silence after them)
// cut into frames and sent as they become whole, and what the master sends it played out
// through a jitter buffer into its speaker (collected, e.g. written as WAV).
//
// VoiceBridge is the master's end: a jitter buffer per site; every frame period it mixes the
// sites' frames and the wall's microphone (voice_mixer.h): the wall room's speakers get every
// site, each site gets its mix-minus, encoded for it alone (one encoder per site: Opus keeps
// state per stream). A mix of digital silence is not encoded (no packets while nobody talks).
//
// Both are deterministic given the times and packets passed in. Not thread-safe.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <tessera/media/voice_codec.h>
#include <tessera/media/voice_jitter_buffer.h>
#include <tessera/media/voice_mixer.h>
#include <tessera/media/voice_packet.h>

namespace tessera::media {

/// Seconds of clock a station or bridge catches up at once; a longer stall (the loop that drives
/// it was busy) skips the rest, playing silence, rather than a burst of late audio.
constexpr double kVoiceMaxCatchUp_s = 0.5;

class VoiceStation {
 public:
  /// `microphone`: 48 kHz mono samples sent from clock 0 on (may be empty: a listener).
  VoiceStation(const VoiceSettings& codec, std::vector<float> microphone,
               const JitterBufferSettings& buffer = {});

  /// Advances the clock to `now`: every microphone frame whole by then goes to `send` as
  /// packet bytes (DTX leaves silent ones out), and the speaker plays every 10 ms block due.
  void advance(double now, const std::function<void(std::vector<uint8_t>)>& send);
  /// A packet from the master as received at `now`; returns why it is refused, if it is.
  std::optional<std::string> receive(std::span<const uint8_t> bytes, double now);

  /// A live microphone and speaker (voice_alsa.h) instead of samples: advance() then leaves
  /// that side to sendLive() and playLive(), which the device paces.
  void setLive(bool microphone, bool speaker);
  /// Sends one microphone frame (frameSamples() samples) as the device captured it.
  void sendLive(std::span<const float> frame,
                const std::function<void(std::vector<uint8_t>)>& send);
  /// Fills `out` with what plays at clock time `at` (when its first sample is heard).
  void playLive(double at, std::span<float> out) { mBuffer.pull(at, out); }
  int frameSamples() const { return mSender.frameSamples(); }

  const std::vector<float>& speaker() const { return mSpeaker; }
  const JitterStats& stats() const { return mBuffer.stats(); }
  /// True once the microphone's samples have all been sent.
  bool spoken() const { return mSent * size_t(mSender.frameSamples()) >= mMicrophone.size(); }

 private:
  VoiceSender mSender;
  JitterBuffer mBuffer;
  std::vector<float> mMicrophone, mSpeaker, mFrame;
  uint64_t mSent = 0;    ///< microphone frames handled
  uint64_t mPlayed = 0;  ///< speaker blocks played
  bool mLiveMicrophone = false, mLiveSpeaker = false;
};

class VoiceBridge {
 public:
  /// `wall_microphone`: the wall room's microphone, 48 kHz mono from clock 0 (may be empty).
  VoiceBridge(const VoiceSettings& codec, std::vector<float> wall_microphone,
              const JitterBufferSettings& buffer = {});

  /// A participant joins: it gets its mix-minus from the next period on.
  void join(uint32_t participant);
  void leave(uint32_t participant);
  /// A checked packet from `participant` (the link says who; the packet's site field is not
  /// trusted) at `now`. A participant that has not joined is ignored.
  void receive(uint32_t participant, const VoicePacket& packet, double now);
  /// Mixes every frame period due by `now`; each participant's mix-minus packets go to
  /// `send(participant, bytes)`.
  void advance(double now, const std::function<void(uint32_t, const std::vector<uint8_t>&)>& send);

  /// A live wall microphone (voice_alsa.h): its samples as captured, mixed from the next
  /// period on in place of the constructor's (at most kVoiceMaxCatchUp_s waits; older go).
  void hearWall(std::span<const float> samples);

  /// What the wall room's speakers played (every site mixed), from clock 0 (or since the last
  /// takeRoom()).
  const std::vector<float>& room() const { return mRoom; }
  /// What room() holds, handed over and cleared (a live speaker plays it).
  std::vector<float> takeRoom() { return std::exchange(mRoom, {}); }
  const JitterStats* stats(uint32_t participant) const;

 private:
  struct Participant {
    JitterBuffer in;
    VoiceSender out;
    std::vector<float> frame;
  };
  VoiceSettings mCodec;
  JitterBufferSettings mBufferSettings;
  VoiceMixer mMixer;
  std::map<uint32_t, Participant> mParticipants;
  std::vector<float> mWallMicrophone, mRoom, mMix;
  std::deque<float> mLiveWall;  ///< hearWall()'s samples not yet mixed
  bool mLive = false;           ///< hearWall() has been called
  uint64_t mPeriods = 0;        ///< frame periods mixed
};

}  // namespace tessera::media
