// Voice: Opus (RFC 6716, libopus from Debian) at 48 kHz mono, as the sites and the
// wall send it. RAII wrappers: the encoder applies the settings below once; the decoder decodes a
// packet, recovers a lost frame from the next packet's in-band FEC, or conceals a gap (PLC).
// Samples are floats in [-1, 1] (full scale); a frame is 10 or 20 ms (480 or 960 samples).
// Neither type is thread-safe: one stream, one thread (the audio thread).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <vector>

struct OpusEncoder;
struct OpusDecoder;

namespace tessera::media {

/// Every voice stream is 48 kHz mono: the rate Opus runs at internally, so no resampling in
/// the codec, and the device rate of almost every sound card.
constexpr int kVoiceRate = 48000;
/// The longest frame this code sends or accepts: 20 ms.
constexpr int kMaxVoiceFrameSamples = kVoiceRate / 50;
/// The largest Opus payload accepted: one frame's bound (RFC 6716 section 3.2.1: a frame is at
/// most 1275 bytes).
constexpr size_t kMaxOpusPayloadBytes = 1275;

/// A voice stream's codec failed to start or was given bad settings; what() names the setting.
struct VoiceError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct VoiceSettings {
  int frame_ms = 20;               ///< 20 (default) or 10: 10 ms halves the packetization delay
                                   ///< for twice the packets (and header bytes)
  int bitrate = 32000;             ///< bits/s, 6000..128000: 32 kb/s leaves SILK room for the FEC
                                   ///< copy at 10% expected loss and keeps full-band hybrid speech
  bool fec = true;                 ///< in-band FEC (OPUS_SET_INBAND_FEC): a low-rate copy of each
                                   ///< frame rides in the next packet (SILK/hybrid modes only)
  int expected_loss_percent = 10;  ///< OPUS_SET_PACKET_LOSS_PERC, 0..100: how much FEC to spend
  bool dtx = true;                 ///< discontinuous transmission: silence sends almost nothing
  int complexity = 9;              ///< 0..10, CPU against quality (bench/voice measures it)

  int frameSamples() const { return kVoiceRate * frame_ms / 1000; }
};

/// One stream's Opus encoder: OPUS_APPLICATION_VOIP, 48 kHz mono, OPUS_SIGNAL_VOICE, the
/// settings above. Move-only.
class VoiceEncoder {
 public:
  /// Throws VoiceError naming the setting that is out of range, or libopus's refusal.
  explicit VoiceEncoder(const VoiceSettings& settings);
  ~VoiceEncoder();
  VoiceEncoder(VoiceEncoder&&) noexcept;
  VoiceEncoder& operator=(VoiceEncoder&&) noexcept;

  /// Encodes one frame of frameSamples() samples into `payload` (resized to the packet).
  /// Returns false when DTX says the frame need not be sent (libopus returns <= 2 bytes for a
  /// frame of silence it will not code): the caller sends nothing, and the receiver plays
  /// comfort noise. Precondition (TESSERA_CHECK): pcm.size() == frameSamples().
  bool encode(std::span<const float> pcm, std::vector<uint8_t>& payload);

  int frameSamples() const { return mFrameSamples; }
  /// The codec's lookahead, samples at 48 kHz (OPUS_GET_LOOKAHEAD: 312 = 6.5 ms in VOIP mode):
  /// the decoder's output lags the encoder's input by this much.
  int lookahead() const;
  /// Changes the bitrate (bits/s, 6000..128000) or the expected loss (0..100) mid-stream.
  void setBitrate(int bitrate);
  void setExpectedLoss(int percent);

 private:
  struct Free {
    void operator()(OpusEncoder* e) const noexcept;
  };
  std::unique_ptr<OpusEncoder, Free> mEncoder;
  int mFrameSamples = 0;
};

/// One stream's Opus decoder, 48 kHz mono. Move-only. Every call writes exactly out.size()
/// samples, a whole number of 2.5 ms (120 samples), at most kMaxVoiceFrameSamples.
class VoiceDecoder {
 public:
  VoiceDecoder();  ///< throws VoiceError if libopus cannot make a decoder
  ~VoiceDecoder();
  VoiceDecoder(VoiceDecoder&&) noexcept;
  VoiceDecoder& operator=(VoiceDecoder&&) noexcept;

  /// Decodes `packet`, which must be one frame of out.size() samples (voice_packet.h checks
  /// it). Returns false when libopus refuses the packet's contents; `out` then holds concealment
  /// so the stream goes on.
  bool decode(std::span<const uint8_t> packet, std::span<float> out);
  /// Recovers the frame before `next_packet` from its in-band FEC (opus_decode with
  /// decode_fec = 1); out.size() is the lost frame's duration. A packet without FEC data yields
  /// concealment (libopus falls back to PLC). Returns false as decode() does.
  bool decodeFec(std::span<const uint8_t> next_packet, std::span<float> out);
  /// Conceals a gap (opus_decode with no data): extrapolated speech after a loss, comfort
  /// noise during DTX, fading to silence over a long gap.
  void conceal(std::span<float> out);

 private:
  struct Free {
    void operator()(OpusDecoder* d) const noexcept;
  };
  std::unique_ptr<OpusDecoder, Free> mDecoder;
};

}  // namespace tessera::media
