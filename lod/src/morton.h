// Morton (Z-order) codes by the magic-bits method: 3D with 21 bits per axis, 2D with 32.
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

/// Spreads the low 32 bits of v to every second bit (2D Morton codes).
inline uint64_t mortonSpread2(uint64_t v) {
  v &= 0xFFFFFFFFull;
  v = (v | v << 16) & 0x0000FFFF0000FFFFull;
  v = (v | v << 8) & 0x00FF00FF00FF00FFull;
  v = (v | v << 4) & 0x0F0F0F0F0F0F0F0Full;
  v = (v | v << 2) & 0x3333333333333333ull;
  v = (v | v << 1) & 0x5555555555555555ull;
  return v;
}

/// Inverse of mortonSpread2: gathers every second bit (starting at bit 0).
inline uint32_t mortonCompact2(uint64_t v) {
  v &= 0x5555555555555555ull;
  v = (v ^ (v >> 1)) & 0x3333333333333333ull;
  v = (v ^ (v >> 2)) & 0x0F0F0F0F0F0F0F0Full;
  v = (v ^ (v >> 4)) & 0x00FF00FF00FF00FFull;
  v = (v ^ (v >> 8)) & 0x0000FFFF0000FFFFull;
  v = (v ^ (v >> 16)) & 0x00000000FFFFFFFFull;
  return uint32_t(v);
}

}  // namespace tessera::lod
