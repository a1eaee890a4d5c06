// A preview store from a scan's sample, then the whole cached store (scan_preview.h).
#include <tessera/lod/scan_preview.h>

#include <atomic>
#include <chrono>

#include <unistd.h>

#include <tessera/core/stopwatch.h>
#include <tessera/lod/store_cache.h>

namespace tessera::lod {

namespace fs = std::filesystem;

ScanPreview::ScanPreview(const fs::path& input, const std::string& who,
                         const SampleOptions& options, bool quiet)
    : mInput(input), mWho(who), mQuiet(quiet) {
  if (cachedStoreReady(input)) {
    mFinal = cachedStoreFor(input, who, quiet);
    mDone = true;
    return;
  }
  auto t = std::chrono::steady_clock::now();
  std::optional<ScanSample> sample = ScanSample::read(input, options, &mWhyNot);
  mSampleSeconds = msSince(t) / 1000.0;
  if (!sample) return;
  mHeaderBounds = sample->info().header_bbox;
  static std::atomic<uint64_t> counter{0};
  const fs::path preview = fs::temp_directory_path() /
                           ("tessera-preview-" + std::to_string(::getpid()) + "-" +
                            std::to_string(counter++) + "-" + input.stem().string() + ".tlod");
  t = std::chrono::steady_clock::now();
  mPreviewPoints = buildSampleStore(*sample, preview).points;
  mPreviewBuildSeconds = msSince(t) / 1000.0;
  mPreview = preview;
}

ScanPreview::~ScanPreview() {
  if (mBuild.joinable()) mBuild.join();
  if (!mPreview.empty()) {
    std::error_code ec;
    fs::remove(mPreview, ec);
  }
}

void ScanPreview::startBuild() {
  if (mDone || mBuild.joinable()) return;
  mBuild = std::thread([this] {
    // No exception leaves the thread: finalStore() rethrows it on the owner's thread.
    try {
      mFinal = cachedStoreFor(mInput, mWho, mQuiet);
    } catch (...) {
      mError = std::current_exception();
    }
    mDone = true;
  });
}

bool ScanPreview::finalReady() const {
  return mDone;
}

fs::path ScanPreview::finalStore() {
  if (mBuild.joinable()) mBuild.join();
  if (!mDone) {
    mFinal = cachedStoreFor(mInput, mWho, mQuiet);
    mDone = true;
  }
  if (mError) std::rethrow_exception(mError);
  return mFinal;
}

}  // namespace tessera::lod
