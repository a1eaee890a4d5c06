#include <tessera/core/progress.h>

#include <unistd.h>

#include <cstdio>

namespace tessera {

std::string humanCount(double n) {
  char buf[32];
  if (n >= 1e9) {
    std::snprintf(buf, sizeof buf, "%.2f G", n / 1e9);
  } else if (n >= 1e6) {
    std::snprintf(buf, sizeof buf, "%.2f M", n / 1e6);
  } else if (n >= 1e3) {
    std::snprintf(buf, sizeof buf, "%.1f k", n / 1e3);
  } else {
    std::snprintf(buf, sizeof buf, "%.0f ", n);
  }
  return buf;
}

Progress::Progress(std::string label, uint64_t total, std::string unit, bool quiet)
    : mLabel(std::move(label)),
      mUnit(std::move(unit)),
      mTotal(total),
      mQuiet(quiet),
      mTty(isatty(STDERR_FILENO) != 0),
      mStart(std::chrono::steady_clock::now()),
      mLastPrint(mStart) {}

Progress::~Progress() {
  finish();
}

double Progress::elapsedSeconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - mStart).count();
}

void Progress::update(uint64_t done) {
  mDone = done;
  if (mQuiet || mFinished) return;
  auto now = std::chrono::steady_clock::now();
  // A terminal gets ~10 redraws a second; a log file one line every 5 s.
  auto interval = mTty ? std::chrono::milliseconds(100) : std::chrono::milliseconds(5000);
  if (now - mLastPrint < interval) return;
  mLastPrint = now;
  print(false);
}

void Progress::finish() {
  if (mFinished) return;
  mFinished = true;
  if (!mQuiet) print(true);
}

void Progress::print(bool final_line) {
  double t = elapsedSeconds();
  double rate = t > 0 ? mDone / t : 0.0;
  std::string line = mLabel + ": ";
  char buf[160];
  if (mTotal > 0 && !final_line) {
    double frac = std::min(1.0, double(mDone) / double(mTotal));
    if (mTty) {
      const int width = 30;
      int filled = int(frac * width);
      line += "[" + std::string(filled, '#') + std::string(width - filled, '.') + "] ";
    }
    double eta = rate > 0 ? (mTotal - std::min(mDone, mTotal)) / rate : 0.0;
    std::snprintf(buf, sizeof buf, "%5.1f%% %s%s, %s%s/s, ETA %.0f s", frac * 100.0,
                  humanCount(double(mDone)).c_str(), mUnit.c_str(), humanCount(rate).c_str(),
                  mUnit.c_str(), eta);
  } else {
    std::snprintf(buf, sizeof buf, "%s%s in %.2f s, %s%s/s%s", humanCount(double(mDone)).c_str(),
                  mUnit.c_str(), t, humanCount(rate).c_str(), mUnit.c_str(),
                  final_line ? "" : " ...");
  }
  line += buf;
  if (mTty) {
    std::fprintf(stderr, "\r%-100s%s", line.c_str(), final_line ? "\n" : "");
  } else {
    std::fprintf(stderr, "%s\n", line.c_str());
  }
  std::fflush(stderr);
}

}  // namespace tessera
