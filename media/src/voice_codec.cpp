#include <tessera/media/voice_codec.h>

#include <opus.h>

#include <algorithm>
#include <string>

#include <tessera/core/check.h>

namespace tessera::media {
namespace {

void expectRange(int value, int lo, int hi, const char* what) {
  if (value < lo || value > hi)
    throw VoiceError("media::VoiceEncoder: " + std::string(what) + " is " + std::to_string(value) +
                     ", expected " + std::to_string(lo) + ".." + std::to_string(hi));
}

void expectOk(int rc, const char* what) {
  if (rc != OPUS_OK)
    throw VoiceError("media::VoiceEncoder: " + std::string(what) +
                     " failed: " + opus_strerror(rc));
}

bool wholeFrame(size_t samples) {
  return samples > 0 && samples <= size_t(kMaxVoiceFrameSamples) && samples % 120 == 0;
}

}  // namespace

void VoiceEncoder::Free::operator()(OpusEncoder* e) const noexcept {
  opus_encoder_destroy(e);
}
void VoiceDecoder::Free::operator()(OpusDecoder* d) const noexcept {
  opus_decoder_destroy(d);
}

VoiceEncoder::VoiceEncoder(const VoiceSettings& s) {
  if (s.frame_ms != 10 && s.frame_ms != 20)
    throw VoiceError("media::VoiceEncoder: frame_ms is " + std::to_string(s.frame_ms) +
                     ", expected 10 or 20");
  expectRange(s.bitrate, 6000, 128000, "bitrate (bits/s)");
  expectRange(s.expected_loss_percent, 0, 100, "expected_loss_percent");
  expectRange(s.complexity, 0, 10, "complexity");
  int rc = OPUS_OK;
  mEncoder.reset(opus_encoder_create(kVoiceRate, 1, OPUS_APPLICATION_VOIP, &rc));
  expectOk(rc, "opus_encoder_create");
  OpusEncoder* e = mEncoder.get();
  expectOk(opus_encoder_ctl(e, OPUS_SET_BITRATE(s.bitrate)), "OPUS_SET_BITRATE");
  // Voice: biases the mode decision towards SILK/hybrid, the modes that carry in-band FEC
  // (RFC 6716 section 2.1.7, LBRR frames); CELT-only packets have none.
  expectOk(opus_encoder_ctl(e, OPUS_SET_SIGNAL(OPUS_SIGNAL_VOICE)), "OPUS_SET_SIGNAL");
  expectOk(opus_encoder_ctl(e, OPUS_SET_INBAND_FEC(s.fec ? 1 : 0)), "OPUS_SET_INBAND_FEC");
  expectOk(opus_encoder_ctl(e, OPUS_SET_PACKET_LOSS_PERC(s.expected_loss_percent)),
           "OPUS_SET_PACKET_LOSS_PERC");
  expectOk(opus_encoder_ctl(e, OPUS_SET_DTX(s.dtx ? 1 : 0)), "OPUS_SET_DTX");
  expectOk(opus_encoder_ctl(e, OPUS_SET_COMPLEXITY(s.complexity)), "OPUS_SET_COMPLEXITY");
  mFrameSamples = s.frameSamples();
}

VoiceEncoder::~VoiceEncoder() = default;
VoiceEncoder::VoiceEncoder(VoiceEncoder&&) noexcept = default;
VoiceEncoder& VoiceEncoder::operator=(VoiceEncoder&&) noexcept = default;

bool VoiceEncoder::encode(std::span<const float> pcm, std::vector<uint8_t>& payload) {
  TESSERA_CHECK(pcm.size() == size_t(mFrameSamples),
                "media::VoiceEncoder::encode(): a frame is " + std::to_string(mFrameSamples) +
                    " samples, got " + std::to_string(pcm.size()));
  payload.resize(kMaxOpusPayloadBytes);
  const opus_int32 n = opus_encode_float(mEncoder.get(), pcm.data(), mFrameSamples, payload.data(),
                                         opus_int32(payload.size()));
  // Only API misuse makes opus_encode_float fail (the frame size and buffer are ours).
  TESSERA_CHECK(n > 0, std::string("media::VoiceEncoder::encode(): ") + opus_strerror(n));
  payload.resize(size_t(n));
  // "If the return value is 2 bytes or less, then the packet does not need to be transmitted
  // (DTX)" (opus.h, opus_encode).
  return n > 2;
}

int VoiceEncoder::lookahead() const {
  opus_int32 samples = 0;
  opus_encoder_ctl(mEncoder.get(), OPUS_GET_LOOKAHEAD(&samples));
  return int(samples);
}

void VoiceEncoder::setBitrate(int bitrate) {
  expectRange(bitrate, 6000, 128000, "bitrate (bits/s)");
  expectOk(opus_encoder_ctl(mEncoder.get(), OPUS_SET_BITRATE(bitrate)), "OPUS_SET_BITRATE");
}

void VoiceEncoder::setExpectedLoss(int percent) {
  expectRange(percent, 0, 100, "expected_loss_percent");
  expectOk(opus_encoder_ctl(mEncoder.get(), OPUS_SET_PACKET_LOSS_PERC(percent)),
           "OPUS_SET_PACKET_LOSS_PERC");
}

VoiceDecoder::VoiceDecoder() {
  int rc = OPUS_OK;
  mDecoder.reset(opus_decoder_create(kVoiceRate, 1, &rc));
  if (rc != OPUS_OK)
    throw VoiceError(std::string("media::VoiceDecoder: opus_decoder_create failed: ") +
                     opus_strerror(rc));
}

VoiceDecoder::~VoiceDecoder() = default;
VoiceDecoder::VoiceDecoder(VoiceDecoder&&) noexcept = default;
VoiceDecoder& VoiceDecoder::operator=(VoiceDecoder&&) noexcept = default;

bool VoiceDecoder::decode(std::span<const uint8_t> packet, std::span<float> out) {
  TESSERA_CHECK(wholeFrame(out.size()), "media::VoiceDecoder::decode(): bad frame size");
  TESSERA_CHECK(!packet.empty() && packet.size() <= kMaxOpusPayloadBytes,
                "media::VoiceDecoder::decode(): packet size out of range");
  const int n = opus_decode_float(mDecoder.get(), packet.data(), opus_int32(packet.size()),
                                  out.data(), int(out.size()), 0);
  if (n == int(out.size())) return true;
  conceal(out);
  return false;
}

bool VoiceDecoder::decodeFec(std::span<const uint8_t> next_packet, std::span<float> out) {
  TESSERA_CHECK(wholeFrame(out.size()), "media::VoiceDecoder::decodeFec(): bad frame size");
  TESSERA_CHECK(!next_packet.empty() && next_packet.size() <= kMaxOpusPayloadBytes,
                "media::VoiceDecoder::decodeFec(): packet size out of range");
  // With decode_fec = 1, frame_size must be exactly the missing duration (opus.h).
  const int n = opus_decode_float(mDecoder.get(), next_packet.data(),
                                  opus_int32(next_packet.size()), out.data(), int(out.size()), 1);
  if (n == int(out.size())) return true;
  conceal(out);
  return false;
}

void VoiceDecoder::conceal(std::span<float> out) {
  TESSERA_CHECK(wholeFrame(out.size()), "media::VoiceDecoder::conceal(): bad frame size");
  const int n = opus_decode_float(mDecoder.get(), nullptr, 0, out.data(), int(out.size()), 0);
  if (n != int(out.size())) std::fill(out.begin(), out.end(), 0.0f);
}

}  // namespace tessera::media
