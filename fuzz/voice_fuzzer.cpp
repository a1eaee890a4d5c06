// libFuzzer target: voice packets from outside (media/voice_packet.h) as a site's or the
// wall's receiver takes them. The bytes are a sequence of records: 2 bytes little-endian length,
// 1 byte of arrival delay (units of 2 ms after the previous record's arrival), then that many
// bytes of packet. Each packet is checked (decodeVoicePacket); the ones that pass go into a jitter
// buffer (real Opus decoding, FEC and PLC), which is pulled at its 10 ms playout clock in between.
// A refusal is the only failure allowed: no crash, no exception, no precondition broken, no
// sample that is not a finite number.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include <tessera/media/voice_jitter_buffer.h>
#include <tessera/media/voice_packet.h>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace tessera::media;
  JitterBufferSettings settings;
  settings.max_packets = 32;
  JitterBuffer buffer(settings);
  std::vector<float> block(480);
  double arrival = 0, clock = 0;
  int records = 0;
  for (size_t at = 0; at + 3 <= size && records < 200; ++records) {
    const size_t n = std::min<size_t>(size - at - 3, data[at] | (size_t(data[at + 1]) << 8));
    arrival += 0.002 * data[at + 2];
    const std::span<const uint8_t> bytes(data + at + 3, n);
    at += 3 + n;
    VoicePacket packet;
    if (!decodeVoicePacket(bytes, packet)) buffer.push(packet, arrival);
    for (; clock <= arrival; clock += 0.01) {
      buffer.pull(clock, block);
      for (float v : block)
        if (!std::isfinite(v)) std::abort();
    }
  }
  for (int i = 0; i < 30; ++i, clock += 0.01) buffer.pull(clock, block);
  return 0;
}
