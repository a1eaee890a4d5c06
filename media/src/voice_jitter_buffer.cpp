#include <tessera/media/voice_jitter_buffer.h>

#include <algorithm>
#include <cmath>

namespace tessera::media {
namespace {

constexpr double kRate = kVoiceRate;
/// Packets further than this from the playout point are refused; kResetAfter of them in a row
/// mean the sender started over (new timestamps), and the stream is reset to follow it.
constexpr int64_t kOutOfRange = 5 * kVoiceRate;
constexpr int kResetAfter = 8;
/// Timestamps remembered as played, to tell a duplicate from a late packet.
constexpr size_t kPlayedMemory = 64;
/// The share of the fastest transits left out of the base (see baseTransit()).
constexpr double kBaseQuantile = 0.01;
/// A packet whose transit is this much below the base came "before it was sent": its timestamp
/// is wrong (a genuine faster path moves the base by far less), and it is refused.
constexpr double kFutureTolerance_s = 0.5;
/// Losses at least this share of the window's packets: FEC is worth a frame of delay.
constexpr double kFecLossShare = 0.01;
/// Times within this of each other are equal (the playout clock's own rounding).
constexpr double kSlack_s = 1e-4;
/// How far over target by more than a frame the delay must be before a frame is skipped.
constexpr double kHysteresis_s = 0.002;

/// RTP-style extension of a wrapping counter to 64 bits, around the newest value seen
/// (RFC 3550 appendix A.1): the nearest 64-bit value with the same low bits.
int64_t extend32(uint32_t value, int64_t reference) {
  return reference + int32_t(value - uint32_t(reference));
}
int64_t extend16(uint16_t value, int64_t reference) {
  return reference + int16_t(uint16_t(value - uint16_t(reference)));
}

double rms(std::span<const float> x) {
  double sum = 0;
  for (float v : x) sum += double(v) * v;
  return x.empty() ? 0.0 : std::sqrt(sum / double(x.size()));
}

}  // namespace

JitterBuffer::JitterBuffer(JitterBufferSettings settings) : mSettings(settings) {
  mFrame.reserve(kMaxVoiceFrameSamples);
}

void JitterBuffer::reset() {
  JitterStats stats = mStats;
  std::vector<PlayedFrame> history = std::move(mHistory);
  const uint64_t output = mOutput;
  *this = JitterBuffer(mSettings);
  mStats = stats;
  mStats.resets += 1;
  mHistory = std::move(history);
  mOutput = output;
}

void JitterBuffer::push(const VoicePacket& packet, double arrival) {
  if (!mHaveStream) {
    mHaveStream = true;
    mMaxTimestamp = packet.timestamp;
    mMaxSequence = packet.sequence;
    mFirstArrival = arrival;
    mNext = mOrigin = mMaxTimestamp;
  }
  const int64_t ts = extend32(packet.timestamp, mMaxTimestamp);
  const int64_t seq = extend16(packet.sequence, mMaxSequence);
  const int64_t reference = mPlaying ? mNext : mMaxTimestamp;
  const bool from_the_future = !mTransits.empty() && arrival - double(ts - mOrigin) / kRate <
                                                         baseTransit() - kFutureTolerance_s;
  if (ts < reference - kOutOfRange || ts > reference + kOutOfRange || from_the_future ||
      packet.frame_samples <= 0 || packet.frame_samples > kMaxVoiceFrameSamples) {
    mStats.refused += 1;
    if (++mOutOfRange >= kResetAfter) {
      reset();
      push(packet, arrival);
    }
    return;
  }
  mOutOfRange = 0;

  bool measured = false;
  if (mPlaying && ts < mNext) {
    if (std::find(mPlayed.begin(), mPlayed.end(), ts) != mPlayed.end()) {
      mStats.duplicates += 1;
      return;
    }
    // A late packet measures the jitter too: leaving it out would keep the target below the
    // delays that made it late.
    updateJitter(ts, seq, arrival);
    measured = true;
    if (mGap != Gap::kNone && mQuiet && seq == mLastSequence + 1) {
      // The first packet after DTX silence, later than the silence's schedule: start the
      // talkspurt from it (the delay grows by what it was late; silence absorbs it).
      resolveGap(0);
      mNext = ts;
      mGap = Gap::kDtx;  // not continuous: the talkspurt's first packet is never skipped
    } else {
      mStats.late += 1;
      if (mGap == Gap::kUnknown) resolveGap(mLostInGap + int64_t(mGapFrames));
      return;
    }
  }
  if (mPackets.count(ts)) {
    mStats.duplicates += 1;
    return;
  }
  if (mPackets.size() >= mSettings.max_packets) {
    mStats.refused += 1;
    return;
  }
  mStats.received += 1;
  mMaxTimestamp = std::max(mMaxTimestamp, ts);
  mMaxSequence = std::max(mMaxSequence, seq);
  if (!measured) updateJitter(ts, seq, arrival);
  if (mGap == Gap::kUnknown) resolveGap(seq - mLastSequence - 1);
  mPackets.emplace(ts, Held{seq, packet.frame_samples, packet.payload});
}

void JitterBuffer::updateJitter(int64_t timestamp, int64_t sequence, double arrival) {
  // Transit against the first packet's timestamp, so the doubles stay small.
  const double transit = arrival - double(timestamp - mOrigin) / kRate;
  if (!mTransits.empty()) {
    // RFC 3550 section 6.4.1: D(i-1, i) = difference of transits; J += (|D| - J) / 16.
    const double d = std::fabs(transit - mLastTransit);
    mStats.jitter_s += (d - mStats.jitter_s) / 16.0;
  }
  mLastTransit = transit;
  mTransits.push_back(transit);
  mSequences.push_back(sequence);
  if (mTransits.size() > mSettings.window) {
    mTransits.pop_front();
    mSequences.pop_front();
  }
}

double JitterBuffer::transitQuantile(double q) const {
  std::vector<double> t(mTransits.begin(), mTransits.end());
  const size_t k = size_t(std::floor(q * double(t.size() - 1) + 0.5));
  std::nth_element(t.begin(), t.begin() + ptrdiff_t(k), t.end());
  return t[k];
}

double JitterBuffer::baseTransit() const {
  // The fastest packets' transit, taken as a low quantile rather than the minimum: one packet
  // with a wrong timestamp must not move the whole schedule.
  return mTransits.empty() ? 0.0 : transitQuantile(kBaseQuantile);
}

double JitterBuffer::lossShare() const {
  if (mSequences.size() < 2) return 0;
  const auto [lo, hi] = std::minmax_element(mSequences.begin(), mSequences.end());
  return 1.0 - double(mSequences.size()) / double(*hi - *lo + 1);
}

double JitterBuffer::targetDelay() const {
  if (mTransits.empty()) return mSettings.min_delay_s;
  double target = std::clamp(transitQuantile(mSettings.quantile) - baseTransit(),
                             mSettings.min_delay_s, mSettings.max_delay_s);
  // A lost frame comes back from the next packet's FEC only if that packet is here when the
  // frame is due: one frame more (the next packet's delay has the same quantile).
  if (lossShare() >= kFecLossShare) target += double(mFrameSamples) / kRate;
  return std::min(target, mSettings.max_delay_s);
}

double JitterBuffer::delayAt(double t) const {
  // How long before `t` the fastest packets would have brought frame mNext.
  return t - (double(mNext - mOrigin) / kRate + baseTransit());
}

void JitterBuffer::resolveGap(int64_t lost_packets) {
  // At most one concealed frame per lost packet: the rest of the gap was DTX silence.
  // (The first frames of a gap are taken as the lost ones: which they were is not known.)
  const uint64_t lost =
      std::min<uint64_t>(mGapFrames, uint64_t(std::max<int64_t>(0, lost_packets - mLostInGap)));
  mLostInGap += int64_t(lost);
  mStats.concealed += lost;
  mStats.dtx += mGapFrames - lost;
  // The gap's frames were recorded as concealed until it was known which were silence.
  for (size_t i = mHistory.size(), n = 0; i > 0 && n < mGapFrames - lost; --i) {
    if (mHistory[i - 1].kind != PlayedFrame::Kind::kConcealed) continue;
    mHistory[i - 1].kind = PlayedFrame::Kind::kDtx;
    ++n;
  }
  mGapFrames = 0;
  mGap = Gap::kNone;
}

void JitterBuffer::emit(PlayedFrame::Kind kind, int64_t timestamp, int samples) {
  mFrameAt = 0;
  mQuiet = rms(mFrame) < mSettings.silence_rms;
  if (mSettings.record)
    mHistory.push_back(PlayedFrame{kind, uint32_t(uint64_t(timestamp)), mOutput, samples});
}

void JitterBuffer::playFrame(double t) {
  using Kind = PlayedFrame::Kind;
  for (;;) {
    // Packets behind the playout point (only after the point moved past a misaligned one).
    while (!mPackets.empty() && mPackets.begin()->first < mNext) {
      mStats.late += 1;
      mPackets.erase(mPackets.begin());
    }
    const double target = targetDelay();
    const double delay = delayAt(t);
    mStats.target_s = target;
    mStats.delay_s = delay;
    mStats.loss_share = lossShare();
    const auto next = mPackets.begin();
    const bool present = next != mPackets.end() && next->first == mNext;
    const double frame_s = double(present ? next->second.frame_samples : mFrameSamples) / kRate;
    // A frame over target (and a little): after a frame is skipped the delay is still at or
    // over target, so skipping and inserting never alternate.
    const bool over = delay > target + frame_s + kHysteresis_s;

    if (present) {
      Held& held = next->second;
      const bool continuous = mGap == Gap::kNone;
      mFrame.resize(size_t(held.frame_samples));
      bool drop = delay > target + mSettings.shrink_in_speech_s;  // far over: even in speech
      bool decoded = false;
      if (!drop && over && mQuiet && continuous) {
        // Over target in silence: decode the frame (the decoder's state goes on) and skip it
        // if it is silence too.
        if (!mDecoder.decode(held.payload, mFrame)) mStats.decode_errors += 1;
        decoded = true;
        drop = rms(mFrame) < mSettings.silence_rms;
      }
      if (drop) {
        mStats.dropped += 1;
        mLastSequence = held.sequence;
        mLostInGap = 0;
        mNext += held.frame_samples;
        mPackets.erase(next);
        continue;
      }
      if (mQuiet && delay < target - kSlack_s) {
        // Silence before this packet: grow the delay by a frame of comfort noise.
        mDecoder.conceal(mFrame);
        mStats.inserted += 1;
        emit(Kind::kInserted, mNext, held.frame_samples);
        return;
      }
      if (mGap != Gap::kNone) resolveGap(held.sequence - mLastSequence - 1);
      if (!decoded && !mDecoder.decode(held.payload, mFrame)) mStats.decode_errors += 1;
      mStats.decoded += 1;
      mLastSequence = held.sequence;
      mLostInGap = 0;
      mFrameSamples = held.frame_samples;
      mPlayed.push_back(mNext);
      if (mPlayed.size() > kPlayedMemory) mPlayed.pop_front();
      emit(Kind::kDecoded, mNext, held.frame_samples);
      mNext += held.frame_samples;
      mPackets.erase(next);
      return;
    }

    // The frame at mNext is missing. Its length: the stream's frame, cut at the next packet
    // (whole 2.5 ms steps, what the decoder accepts).
    int samples = mFrameSamples;
    if (next != mPackets.end()) {
      const int64_t until = next->first - mNext;
      if (until < samples) samples = int(until / 120 * 120);
      if (samples == 0) {  // misaligned by less than 2.5 ms: play that packet now
        mNext = next->first;
        continue;
      }
    }
    mFrame.resize(size_t(samples));
    if (delay < target - kSlack_s) {
      // Underflow below target: wait for the packet with a concealed frame (grows the delay).
      mDecoder.conceal(mFrame);
      mStats.inserted += 1;
      emit(Kind::kInserted, mNext, samples);
      return;
    }
    // DTX when every packet between the last one played and the next one held is accounted
    // for by frames already concealed.
    const bool dtx =
        next != mPackets.end() && next->second.sequence - mLastSequence - 1 <= mLostInGap;
    if (over && mQuiet && (dtx || next == mPackets.end())) {
      // Skip a frame of silence: shrinks the delay.
      mStats.dropped += 1;
      mNext += samples;
      continue;
    }
    if (next == mPackets.end()) {
      // Nothing after it yet: loss or DTX, told when the next packet comes.
      mDecoder.conceal(mFrame);
      mGap = Gap::kUnknown;
      mGapFrames += 1;
      emit(Kind::kConcealed, mNext, samples);
    } else if (dtx) {
      mDecoder.conceal(mFrame);
      mGap = Gap::kDtx;
      mStats.dtx += 1;
      emit(Kind::kDtx, mNext, samples);
    } else {
      // A sequence gap: lost. FEC from the packet right after it (RFC 6716 section 2.1.7),
      // else concealment.
      mStats.concealed += 1;
      mLostInGap += 1;
      if (next->first == mNext + samples) {
        if (!mDecoder.decodeFec(next->second.payload, mFrame)) mStats.decode_errors += 1;
        mStats.fec += 1;
        emit(Kind::kFec, mNext, samples);
      } else {
        mDecoder.conceal(mFrame);
        emit(Kind::kConcealed, mNext, samples);
      }
    }
    mNext += samples;
    return;
  }
}

void JitterBuffer::pull(double now, std::span<float> out) {
  size_t k = 0;
  while (k < out.size()) {
    if (mFrameAt < mFrame.size()) {
      const size_t n = std::min(out.size() - k, mFrame.size() - mFrameAt);
      std::copy_n(mFrame.begin() + ptrdiff_t(mFrameAt), n, out.begin() + ptrdiff_t(k));
      mFrameAt += n;
      k += n;
      mOutput += n;
      continue;
    }
    const double t = now + double(k) / kRate;
    if (!mPlaying) {
      if (mPackets.empty() || t < mFirstArrival + targetDelay() - kSlack_s) {
        std::fill(out.begin() + ptrdiff_t(k), out.end(), 0.0f);
        mOutput += out.size() - k;
        return;
      }
      mPlaying = true;
      mNext = mPackets.begin()->first;
    }
    playFrame(t);
  }
}

}  // namespace tessera::media
