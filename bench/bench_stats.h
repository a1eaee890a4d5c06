// Small statistics the benchmarks share: percentiles of samples, and a thread's CPU time.
#pragma once

#include <time.h>

#include <algorithm>
#include <vector>

namespace tessera::bench {

/// The q-quantile (0..1) of `v`, the sample at floor(q * n) of the sorted samples (the largest
/// for q = 1); 0 for no samples.
inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(q * double(v.size())))];
}

/// CPU seconds the calling thread has used (CLOCK_THREAD_CPUTIME_ID).
inline double threadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

}  // namespace tessera::bench
