// The LAZ fuzz body (laz_fuzzer.cpp), shared with the regression replay. Bytes that start with
// "LASF" are read as a LAZ file (format forced, see fuzz_reader.h); any other bytes are one
// chunk handed straight to the chunk decoder: the first byte picks the items (every point
// format the coder knows, pointwise and layered, and with bit 7 the older item versions), the
// next two the point count, the rest are the chunk. Only laz::CorruptData may come out of the
// chunk decoder, and it must never read outside the bytes it is given.
#pragma once

#include <cstring>
#include <vector>

#include "../lod/src/laz_items.h"
#include "fuzz_reader.h"

namespace tessera::fuzz {

inline int decodeLaz(const uint8_t* data, size_t size) {
  using namespace tessera::lod;
  if (size >= 4 && std::memcmp(data, "LASF", 4) == 0) {
    return readAll(data, size, Format::kLaz, "fuzz.laz");
  }
  if (size < 3) return 0;
  static constexpr int kFormats[] = {0, 1, 2, 3, 6, 7, 8};
  const int format = kFormats[(data[0] & 0x7F) % 7];
  const uint16_t extra = uint16_t(((data[0] & 0x7F) / 7) % 4);
  std::vector<laz::Item> items = laz::itemsForFormat(format, extra);
  if (data[0] & 0x80) {
    for (laz::Item& it : items) it.version = format >= 6 ? 4 : 1;
  }
  const uint64_t count = 1 + (uint64_t(data[1]) | (uint64_t(data[2]) << 8)) % 2000;
  // An exact copy: the sanitizer sees any read past the chunk's last byte.
  const std::vector<uint8_t> chunk(data + 3, data + size);
  laz::ChunkDecoder decoder(items, format >= 6);
  std::vector<uint8_t> out(count * decoder.recordSize());
  try {
    const size_t used = decoder.decode(chunk, count, out.data());
    require(used <= chunk.size(), "chunk decoder used more bytes than it had");
  } catch (const laz::CorruptData&) {
  }
  return 0;
}

}  // namespace tessera::fuzz
