// 3D Morton (Z-order) codes with 21 bits per axis, by the magic-bits method.
#pragma once

#include <cstdint>

namespace tessera::lod {

/// Spreads the low 21 bits of v to every third bit.
inline uint64_t mortonSpread(uint64_t v) {
  v &= 0x1FFFFF;
  v = (v | v << 32) & 0x1F00000000FFFFull;
  v = (v | v << 16) & 0x1F0000FF0000FFull;
  v = (v | v << 8) & 0x100F00F00F00F00Full;
  v = (v | v << 4) & 0x10C30C30C30C30C3ull;
  v = (v | v << 2) & 0x1249249249249249ull;
  return v;
}

/// Inverse of mortonSpread: gathers every third bit (starting at bit 0) into the low 21 bits.
inline uint32_t mortonCompact(uint64_t v) {
  v &= 0x1249249249249249ull;
  v = (v ^ (v >> 2)) & 0x10C30C30C30C30C3ull;
  v = (v ^ (v >> 4)) & 0x100F00F00F00F00Full;
  v = (v ^ (v >> 8)) & 0x1F0000FF0000FFull;
  v = (v ^ (v >> 16)) & 0x1F00000000FFFFull;
  v = (v ^ (v >> 32)) & 0x1FFFFF;
  return uint32_t(v);
}

inline uint64_t mortonEncode(uint64_t x, uint64_t y, uint64_t z) {
  return mortonSpread(x) | mortonSpread(y) << 1 | mortonSpread(z) << 2;
}

}  // namespace tessera::lod
