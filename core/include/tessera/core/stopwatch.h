// Wall-clock intervals for statistics and benchmarks (steady clock, never for correctness).
#pragma once

#include <chrono>

namespace tessera {

/// Milliseconds from `start` to now on the steady clock.
inline double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace tessera
