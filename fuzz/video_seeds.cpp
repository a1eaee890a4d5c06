// Writes the video fuzzer's seed corpus (fuzz/run.sh seed_video) into the current folder: records
// as video_fuzzer.cpp reads them (2 bytes length, 1 byte flags, the packet) of real H.264 from the
// test pattern, small so the fuzzer mutates headers and slices rather than copying pixels:
//   refresh.rec  96x64, 10 fps, 64 kbit/s, intra refresh every 0.5 s: 12 access units
//   idr.rec      the same with an IDR every 0.5 s instead
//   chunked.rec  a key of 3 chunks sent out of order, shown, hidden and shown again
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <tessera/media/video_packet.h>
#include <tessera/media/video_pattern.h>

namespace {

using namespace tessera::media;

void record(std::ofstream& out, const std::vector<uint8_t>& packet, uint8_t flags) {
  const uint8_t head[3] = {uint8_t(packet.size()), uint8_t(packet.size() >> 8), flags};
  out.write(reinterpret_cast<const char*>(head), 3);
  out.write(reinterpret_cast<const char*>(packet.data()), std::streamsize(packet.size()));
}

std::vector<std::vector<uint8_t>> stream(bool intra_refresh, int frames) {
  VideoSettings s;
  s.width = 96;
  s.height = 64;
  s.fps = 10;
  s.kbps = 64;
  s.intra_refresh = intra_refresh;
  VideoSender sender(s, 1);
  std::vector<std::vector<uint8_t>> out;
  VideoPicture p;
  for (int f = 0; f < frames; ++f) {
    drawTestPattern(p, s.width, s.height, {uint32_t(f), uint32_t(1000 + 100 * f)});
    for (auto& b : sender.send(p)) out.push_back(std::move(b));
  }
  return out;
}

}  // namespace

int main() {
  for (const auto& [name, refresh] : {std::pair{"refresh.rec", true}, {"idr.rec", false}}) {
    std::ofstream out(name, std::ios::binary);
    for (const auto& b : stream(refresh, 12)) record(out, b, 0);
  }
  // One key access unit cut into 3 chunks by hand, sent 2, 0, 1; then hidden and shown.
  const auto units = stream(true, 2);
  VideoPacket key;
  if (decodeVideoPacket(units[0], key)) return 1;
  std::ofstream out("chunked.rec", std::ios::binary);
  const size_t third = key.payload.size() / 3 + 1;
  for (int c : {2, 0, 1}) {
    VideoPacket part = key;
    part.chunk = uint8_t(c);
    part.chunks = 3;
    const size_t from = size_t(c) * third, to = std::min(key.payload.size(), from + third);
    part.payload.assign(key.payload.begin() + long(from), key.payload.begin() + long(to));
    record(out, encodeVideoPacket(part), c == 2 ? 1 : 0);
  }
  record(out, units[1], 2);
  record(out, units[1], 1);
  std::printf("video_seeds: wrote refresh.rec, idr.rec, chunked.rec\n");
  return 0;
}
