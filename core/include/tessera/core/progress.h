// Progress reporting for long work: a bar with rate and ETA when stderr is a terminal, plain
// log lines (at most one every few seconds) otherwise, nothing when quiet.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace tessera {

class Progress {
 public:
  /// `total` may be 0 when unknown (then no percentage or ETA is shown). `unit` names what is
  /// counted ("points"). Not thread-safe: update from one thread.
  Progress(std::string label, uint64_t total, std::string unit, bool quiet = false);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void add(uint64_t n) { update(mDone + n); }
  void update(uint64_t done);
  /// Prints the final line (done, elapsed, mean rate). Called by the destructor if not before.
  void finish();

  uint64_t done() const { return mDone; }
  double elapsedSeconds() const;

 private:
  void print(bool final_line);

  std::string mLabel;
  std::string mUnit;
  uint64_t mTotal;
  uint64_t mDone = 0;
  bool mQuiet;
  bool mTty;
  bool mFinished = false;
  std::chrono::steady_clock::time_point mStart;
  std::chrono::steady_clock::time_point mLastPrint;
};

/// "12.3 M" style short number.
std::string humanCount(double n);

}  // namespace tessera
