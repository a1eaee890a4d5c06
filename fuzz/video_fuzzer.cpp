// libFuzzer target: video packets from outside (media/video_packet.h) as a render node, the
// console or a site takes them. The bytes are a sequence of records: 2 bytes little-endian
// length, 1 byte of flags (bit 0: the stream is shown from this packet on, bit 1: not shown),
// then that many bytes of packet. Each packet is checked (decodeVideoPacket); the ones that pass
// go to a receiver (assembler, FFmpeg's H.264 decoder, the key and loss policy). A refusal or a
// decoding error is the only failure allowed: no crash, no exception, no precondition broken,
// and the picture is always either none or a whole RGBA picture of a size within the limits.
#include <cstdint>
#include <cstdlib>
#include <span>

#include <tessera/media/video_packet.h>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace tessera::media;
  VideoReceiver receiver;
  int records = 0;
  for (size_t at = 0; at + 3 <= size && records < 200; ++records) {
    const size_t n = std::min<size_t>(size - at - 3, data[at] | (size_t(data[at + 1]) << 8));
    const uint8_t flags = data[at + 2];
    if (flags & 1) receiver.setShown(true);
    if (flags & 2) receiver.setShown(false);
    const std::span<const uint8_t> bytes(data + at + 3, n);
    at += 3 + n;
    VideoPacket packet;
    if (decodeVideoPacket(bytes, packet)) continue;
    const uint64_t generation = receiver.generation();
    const bool changed = receiver.receive(packet);
    if (changed != (receiver.generation() != generation)) std::abort();
    const VideoPicture& p = receiver.picture();
    if (!p.empty() &&
        (p.width < 16 || p.height < 16 || p.width > kMaxVideoSide || p.height > kMaxVideoSide ||
         p.rgba.size() != size_t(p.width) * size_t(p.height) * 4))
      std::abort();
  }
  return 0;
}
