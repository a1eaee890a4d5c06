// Voice: one Opus frame on the wire, as a site or the wall sends it. Little-endian,
// a 12-byte header then the Opus packet (RFC 6716):
//
//   offset size  field
//   0      1     version (kVoicePacketVersion)
//   1      1     flags: bit 0 = first packet of a talkspurt (after DTX silence); the rest 0
//   2      2     site: the speaker (kWallSite = the wall room's microphone, else the site's
//                participant id)
//   4      2     sequence: +1 per packet sent, wrapping (RTP's sequence number, RFC 3550 5.1):
//                gaps are losses, while DTX silence advances the timestamp only
//   6      2     payload size, bytes: 1..kMaxOpusPayloadBytes and exactly the rest of the packet
//   8      4     timestamp: the frame's first sample, 48 kHz samples, wrapping (RTP timestamp)
//   12     n     the Opus packet: one frame of 10 or 20 ms
//
// decodeVoicePacket() checks every field and the Opus packet's own structure (TOC and frame
// lengths, opus_packet_parse) before anything else looks at it: bytes from outside never reach
// the decoder unchecked.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <tessera/media/voice_codec.h>

namespace tessera::media {

constexpr uint8_t kVoicePacketVersion = 1;
constexpr size_t kVoiceHeaderBytes = 12;
constexpr size_t kMaxVoicePacketBytes = kVoiceHeaderBytes + kMaxOpusPayloadBytes;
/// The wall room's microphone in `site` (sites are participants 1, 2, ...).
constexpr uint16_t kWallSite = 0;

struct VoicePacket {
  uint16_t site = kWallSite;
  uint16_t sequence = 0;
  uint32_t timestamp = 0;        ///< 48 kHz samples
  bool talkspurt = false;        ///< first packet after DTX silence
  int frame_samples = 0;         ///< 480 or 960, read from the Opus packet (filled by decode)
  std::vector<uint8_t> payload;  ///< the Opus packet
};

/// The packet's bytes. Precondition (TESSERA_CHECK): 1..kMaxOpusPayloadBytes of payload.
std::vector<uint8_t> encodeVoicePacket(const VoicePacket& packet);

/// Parses and checks one packet. Returns why it is refused ("voice packet: payload size 900
/// but 12 bytes follow the header"), or std::nullopt with `out` filled.
std::optional<std::string> decodeVoicePacket(std::span<const uint8_t> bytes, VoicePacket& out);

/// A stream's sending end: encodes 48 kHz mono frames, numbers and stamps them, and skips the
/// frames DTX does not send (the timestamp still advances, the sequence does not).
class VoiceSender {
 public:
  /// `first_sequence` and `first_timestamp` are random in a real stream (RFC 3550 5.1).
  VoiceSender(const VoiceSettings& settings, uint16_t site, uint16_t first_sequence = 0,
              uint32_t first_timestamp = 0);

  /// One frame of frameSamples() samples; returns the packet's bytes, or std::nullopt when
  /// DTX leaves the frame out.
  std::optional<std::vector<uint8_t>> send(std::span<const float> pcm);
  /// A frame not even encoded (the caller knows it is digital silence): as DTX, the timestamp
  /// advances and the next packet starts a talkspurt.
  void skip();

  int frameSamples() const { return mEncoder.frameSamples(); }
  VoiceEncoder& encoder() { return mEncoder; }

 private:
  VoiceEncoder mEncoder;
  VoicePacket mPacket;
  bool mSilent = true;  ///< the previous frame was not sent (the next one starts a talkspurt)
};

}  // namespace tessera::media
