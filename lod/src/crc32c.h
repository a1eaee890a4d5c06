// CRC-32C (Castagnoli): the per-chunk and per-page checksum of .tlod stores. Uses the SSE 4.2
// instruction when the CPU has it (about 10 GB/s), a table otherwise.
#pragma once

#include <cstddef>
#include <cstdint>

namespace tessera::lod {

uint32_t crc32c(const void* data, size_t size, uint32_t crc = 0);

}  // namespace tessera::lod
