#include <tessera/media/voice_packet.h>

#include <opus.h>

#include <tessera/core/check.h>

#include "little_endian.h"

namespace tessera::media {

std::vector<uint8_t> encodeVoicePacket(const VoicePacket& packet) {
  TESSERA_CHECK(!packet.payload.empty() && packet.payload.size() <= kMaxOpusPayloadBytes,
                "media::encodeVoicePacket(): the payload is " +
                    std::to_string(packet.payload.size()) + " bytes, expected 1..1275");
  std::vector<uint8_t> bytes(kVoiceHeaderBytes + packet.payload.size());
  bytes[0] = kVoicePacketVersion;
  bytes[1] = packet.talkspurt ? 1 : 0;
  putLe16(&bytes[2], packet.site);
  putLe16(&bytes[4], packet.sequence);
  putLe16(&bytes[6], uint16_t(packet.payload.size()));
  putLe32(&bytes[8], packet.timestamp);
  std::copy(packet.payload.begin(), packet.payload.end(), bytes.begin() + kVoiceHeaderBytes);
  return bytes;
}

std::optional<std::string> decodeVoicePacket(std::span<const uint8_t> bytes, VoicePacket& out) {
  const auto refuse = [](const std::string& why) { return "voice packet: " + why; };
  if (bytes.size() < kVoiceHeaderBytes + 1)
    return refuse(std::to_string(bytes.size()) + " bytes, shorter than the header and a TOC (" +
                  std::to_string(kVoiceHeaderBytes + 1) + ")");
  if (bytes.size() > kMaxVoicePacketBytes)
    return refuse(std::to_string(bytes.size()) + " bytes, more than the largest packet (" +
                  std::to_string(kMaxVoicePacketBytes) + ")");
  if (bytes[0] != kVoicePacketVersion)
    return refuse("version " + std::to_string(bytes[0]) + ", expected " +
                  std::to_string(kVoicePacketVersion));
  if ((bytes[1] & ~1u) != 0)
    return refuse("flags " + std::to_string(bytes[1]) + " set reserved bits (only bit 0 is used)");
  const size_t payload = getLe16(&bytes[6]);
  if (payload != bytes.size() - kVoiceHeaderBytes)
    return refuse("payload size " + std::to_string(payload) + " but " +
                  std::to_string(bytes.size() - kVoiceHeaderBytes) + " bytes follow the header");
  const uint8_t* opus = bytes.data() + kVoiceHeaderBytes;
  // The Opus packet's own framing (RFC 6716 section 3: TOC byte, frame count code, frame
  // lengths): libopus refuses a malformed one without decoding anything.
  unsigned char toc = 0;
  const unsigned char* frames[48];
  opus_int16 sizes[48];
  const int count = opus_packet_parse(opus, opus_int32(payload), &toc, frames, sizes, nullptr);
  if (count < 1)
    return refuse(std::string("the Opus packet is malformed (") +
                  (count < 0 ? opus_strerror(count) : "no frames") + ")");
  const int samples = opus_packet_get_nb_samples(opus, opus_int32(payload), kVoiceRate);
  if (samples != kVoiceRate / 100 && samples != kVoiceRate / 50)
    return refuse("the Opus packet lasts " + std::to_string(samples) +
                  " samples, expected 480 or 960 (10 or 20 ms)");
  out.site = getLe16(&bytes[2]);
  out.sequence = getLe16(&bytes[4]);
  out.timestamp = getLe32(&bytes[8]);
  out.talkspurt = (bytes[1] & 1) != 0;
  out.frame_samples = samples;
  out.payload.assign(opus, opus + payload);
  return std::nullopt;
}

VoiceSender::VoiceSender(const VoiceSettings& settings, uint16_t site, uint16_t first_sequence,
                         uint32_t first_timestamp)
    : mEncoder(settings) {
  mPacket.site = site;
  mPacket.sequence = first_sequence;
  mPacket.timestamp = first_timestamp;
}

std::optional<std::vector<uint8_t>> VoiceSender::send(std::span<const float> pcm) {
  const bool coded = mEncoder.encode(pcm, mPacket.payload);
  std::optional<std::vector<uint8_t>> bytes;
  if (coded) {
    mPacket.talkspurt = mSilent;
    bytes = encodeVoicePacket(mPacket);
    ++mPacket.sequence;
  }
  mSilent = !coded;
  mPacket.timestamp += uint32_t(mEncoder.frameSamples());
  return bytes;
}

void VoiceSender::skip() {
  mSilent = true;
  mPacket.timestamp += uint32_t(mEncoder.frameSamples());
}

}  // namespace tessera::media
