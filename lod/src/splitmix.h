// splitmix64 (Steele, Lea and Flood 2014): a stable hash of a key, so what is random in the data
// (scanner noise, mesh samples) depends only on seeds and indices, never on threads or order.
#pragma once

#include <cstdint>

namespace tessera::lod {

inline uint64_t splitmix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

}  // namespace tessera::lod
