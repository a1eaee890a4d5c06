// A token bucket (rate limits of the site hub and the chunk server): `rate` tokens a second up
// to `capacity` (burst_s seconds' worth); takes may run it into debt, which later refills pay.
#pragma once

#include <algorithm>

namespace tessera::collab {

struct TokenBucket {
  double rate = 0, capacity = 0, level = 0, at = 0;  // at: seconds, steady clock
  void start(double r, double burst_s, double now) {
    rate = r;
    capacity = r * burst_s;
    level = capacity;
    at = now;
  }
  void refill(double now) {
    level = std::min(capacity, level + (now - at) * rate);
    at = now;
  }
  /// Takes `amount`; false when the bucket ran dry (the rate is exceeded).
  bool take(double amount, double now) {
    refill(now);
    level -= amount;
    return level >= 0.0;
  }
  /// Seconds until the bucket is out of debt (0 when it is not in debt).
  double wait(double now) {
    refill(now);
    return level >= 0.0 ? 0.0 : -level / rate;
  }
};

}  // namespace tessera::collab
