// Voice: the receiving end of one voice stream. Packets go in as they arrive (any
// order, late, twice); 48 kHz mono samples come out at the playout clock. The buffer holds
// packets long enough to absorb the network's jitter and no longer:
//
// - Jitter: every packet's transit (arrival - timestamp / 48 kHz) is kept for the last
//   `window` packets. The fastest of them (the 1st percentile, so one packet with a wrong
//   timestamp moves nothing) is the base; a packet's relative delay is its transit minus the
//   base, and the target playout delay is the `quantile` of the relative delays (the
//   delay that lets that share of packets arrive in time), clamped to [min_delay, max_delay].
//   This is WebRTC NetEq's relative-delay histogram in spirit (its "delay manager"); the RFC 3550
//   (section 6.4.1, A.8) interarrival jitter J += (|D| - J) / 16 is kept too, for the stats.
//   When the window's sequence numbers show losses (1% or more), the target grows by a frame so
//   the packet after a lost one is there in time to give its FEC.
// - Adaptation: the delay is changed where it cannot be heard. It grows when the next frame is
//   missing and the delay is below target (a concealed frame is played without advancing, so
//   the late packet can still play: NetEq's "expand"), and in silence (DTX gaps and quiet
//   frames); it shrinks by skipping frames of silence when it is more than a frame over target,
//   or any frame when it is more than `shrink_in_speech` over (after a jitter spike). A
//   talkspurt that starts after DTX is scheduled from its own arrival (per-talkspurt playout
//   adjustment, Ramjee et al. 1994, "Adaptive playout mechanisms for packetized audio
//   applications in wide-area networks"), so its first words are never dropped as late.
// - Losses: a missing frame whose next packet is here is recovered from that packet's in-band
//   FEC; otherwise it is concealed (Opus PLC). A sequence gap is a loss; a timestamp gap with no
//   sequence gap is DTX silence (comfort noise, not counted as concealed).
// - Packets older than the playout point are dropped (late); duplicates are ignored; a packet
//   far out of range is refused, and a run of them (a sender that restarted) resets the stream.
//
// Deterministic: the output depends only on the packets and the times passed in. Cost: one
// Opus decode per frame played and two selections over the window's transits. Not thread-safe:
// push() and pull() from one thread (the audio thread, or a queue feeding it).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <span>
#include <vector>

#include <tessera/media/voice_codec.h>
#include <tessera/media/voice_packet.h>

namespace tessera::media {

struct JitterBufferSettings {
  double min_delay_s = 0.010;         ///< the target never goes below this (scheduling slack)
  double max_delay_s = 0.400;         ///< nor above this (packets later than that are lost anyway)
  double quantile = 0.97;             ///< share of packets the target lets arrive in time
  size_t window = 250;                ///< packets the jitter is measured over (5 s at 20 ms)
  double shrink_in_speech_s = 0.080;  ///< over target by more than this: drop frames in speech
  size_t max_packets = 128;           ///< packets held at most (2.5 s at 20 ms); more are refused
  double silence_rms = 0.002;         ///< a decoded frame quieter than this (-54 dBFS) is silence
  bool record = false;                ///< keep history() (tests and benchmarks)
};

struct JitterStats {
  uint64_t received = 0;       ///< packets pushed and taken
  uint64_t decoded = 0;        ///< frames played from their own packet
  uint64_t concealed = 0;      ///< frames lost (or late) and played from FEC or PLC
  uint64_t fec = 0;            ///< of those, recovered from the next packet's FEC
  uint64_t dtx = 0;            ///< frames of DTX silence (comfort noise)
  uint64_t inserted = 0;       ///< frames played to grow the delay
  uint64_t dropped = 0;        ///< frames skipped to shrink the delay
  uint64_t late = 0;           ///< packets that came after their playout
  uint64_t duplicates = 0;     ///< packets already held or played
  uint64_t refused = 0;        ///< out of range or the buffer full
  uint64_t decode_errors = 0;  ///< packets libopus refused (concealed instead)
  uint64_t resets = 0;         ///< the stream started over (a sender restarted)
  double jitter_s = 0;         ///< RFC 3550 interarrival jitter, seconds
  double target_s = 0;         ///< the current target delay
  double delay_s = 0;          ///< the delay at the last frame played (against the fastest packet)
  double loss_share = 0;       ///< packets missing from the window's sequence numbers

  /// Frames played since playout began (not counting the silence before it).
  uint64_t frames() const { return decoded + concealed + dtx + inserted; }
};

/// What the buffer played, frame by frame (with JitterBufferSettings::record).
struct PlayedFrame {
  enum class Kind { kDecoded, kFec, kConcealed, kDtx, kInserted };
  Kind kind;
  uint32_t timestamp;   ///< the sender's timestamp this frame stands for (kInserted: none)
  uint64_t output = 0;  ///< index of its first sample in the output (every sample pulled)
  int samples = 0;
};

class JitterBuffer {
 public:
  explicit JitterBuffer(JitterBufferSettings settings = {});

  /// A checked packet (decodeVoicePacket) that arrived at `arrival`, seconds on the receiver's
  /// clock (the same clock as pull()'s `now`). Any order; never throws on what a sender does.
  void push(const VoicePacket& packet, double arrival);
  /// Fills `out` with the next samples to play; `now` is when its first sample plays. Before the
  /// first packet and its target delay have passed, that is silence.
  void pull(double now, std::span<float> out);

  const JitterStats& stats() const { return mStats; }
  const std::vector<PlayedFrame>& history() const { return mHistory; }
  /// Packets held now.
  size_t held() const { return mPackets.size(); }

 private:
  struct Held {
    int64_t sequence;
    int frame_samples;
    std::vector<uint8_t> payload;
  };
  enum class Gap { kNone, kUnknown, kDtx };

  double transitQuantile(double q) const;
  double lossShare() const;
  double baseTransit() const;
  double targetDelay() const;
  double delayAt(double t) const;
  void updateJitter(int64_t timestamp, int64_t sequence, double arrival);
  void resolveGap(int64_t lost_packets);
  void reset();
  void playFrame(double t);
  void emit(PlayedFrame::Kind kind, int64_t timestamp, int samples);

  JitterBufferSettings mSettings;
  VoiceDecoder mDecoder;
  JitterStats mStats;
  std::map<int64_t, Held> mPackets;  ///< by extended timestamp
  std::deque<double> mTransits;      ///< arrival - timestamp / rate of the last `window` packets
  std::deque<int64_t> mSequences;    ///< their sequence numbers (the loss share)
  std::deque<int64_t> mPlayed;       ///< extended timestamps recently played from packets
  std::vector<float> mFrame;         ///< the frame being played out
  size_t mFrameAt = 0;               ///< samples of mFrame already given out
  std::vector<PlayedFrame> mHistory;

  bool mHaveStream = false;  ///< a packet has been taken (the extensions below are set)
  bool mPlaying = false;
  int64_t mMaxTimestamp = 0;  ///< extended (64-bit, unwrapped) timestamps and sequences
  int64_t mMaxSequence = 0;
  int64_t mOrigin = 0;  ///< the first packet's timestamp: transits are measured from it
  double mFirstArrival = 0;
  int64_t mNext = 0;           ///< extended timestamp of the next frame to play
  int64_t mLastSequence = -1;  ///< sequence of the last frame played from a packet
  int mFrameSamples = kMaxVoiceFrameSamples;
  Gap mGap = Gap::kNone;    ///< what the frames since the last packet played are
  uint64_t mGapFrames = 0;  ///< frames played since the gap began, not yet counted
  int64_t mLostInGap = 0;   ///< frames since the last packet played counted as lost
  bool mQuiet = true;       ///< the last frame played was silence
  double mLastTransit = 0;  ///< for the RFC 3550 estimate
  int mOutOfRange = 0;      ///< consecutive refused packets
  uint64_t mOutput = 0;     ///< samples pulled so far
};

}  // namespace tessera::media
