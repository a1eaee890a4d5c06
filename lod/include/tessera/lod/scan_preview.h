// A raw scan shown before its store is built: a preview store from an even sample of the scan
// (scan_sample.h), built in a fraction of the whole build's time, then the scan's cached store
// (store_cache.h), built after it or on a thread of its own. tessera-render --preview and its
// window draw the preview first and the whole store once it is there.
//
// The preview store lives in the temporary folder under a name of this process and is removed
// with the ScanPreview. A scan whose store is already cached, a .tlod, and a scan whose format
// cannot be sampled (whyNot()) have no preview: the whole store is the first picture.
#pragma once

#include <atomic>
#include <exception>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include <glm/glm.hpp>

#include <tessera/lod/scan_sample.h>

namespace tessera::lod {

class ScanPreview {
 public:
  /// Samples `input` and builds its preview store unless its store is cached already. `who`
  /// starts the cache's messages (store_cache.h); `quiet`: no build progress on stderr. Throws
  /// ReadError for a scan its reader refuses (as the whole build would), StoreError when the
  /// preview store cannot be written.
  ScanPreview(const std::filesystem::path& input, const std::string& who,
              const SampleOptions& options = {}, bool quiet = false);
  /// Waits for a build in flight, then removes the preview store.
  ~ScanPreview();
  ScanPreview(const ScanPreview&) = delete;
  ScanPreview& operator=(const ScanPreview&) = delete;

  /// Whether there is a preview store (else whyNot() says why, or the store was cached).
  bool hasPreview() const { return !mPreview.empty(); }
  /// The preview store's path; empty without one.
  const std::filesystem::path& previewPath() const { return mPreview; }
  /// Why the scan has no preview ("" when it has one or its store was cached).
  const std::string& whyNot() const { return mWhyNot; }
  /// The scan's bounds as its header states them (LAS, LAZ), file coordinates: what a camera is
  /// fitted to before the whole store exists. Nothing when the header has none.
  const std::optional<std::pair<glm::dvec3, glm::dvec3>>& headerBounds() const {
    return mHeaderBounds;
  }
  /// Points in the preview store, and the seconds sampling and building it took.
  uint64_t previewPoints() const { return mPreviewPoints; }
  double sampleSeconds() const { return mSampleSeconds; }
  double previewBuildSeconds() const { return mPreviewBuildSeconds; }

  /// Starts building the whole store on a thread of its own (once; later calls do nothing).
  /// Call from the thread that owns this object.
  void startBuild();
  /// Whether the whole store can be had without waiting (built, cached, or its build failed:
  /// finalStore() then throws).
  bool finalReady() const;
  /// The whole store's path, waiting for its build (building it on this thread when
  /// startBuild() was not called). Rethrows the build's error (ReadError, StoreError, ...).
  std::filesystem::path finalStore();

 private:
  std::filesystem::path mInput, mPreview, mFinal;
  std::string mWho, mWhyNot;
  bool mQuiet = false;
  std::optional<std::pair<glm::dvec3, glm::dvec3>> mHeaderBounds;
  uint64_t mPreviewPoints = 0;
  double mSampleSeconds = 0.0, mPreviewBuildSeconds = 0.0;
  std::thread mBuild;
  std::exception_ptr mError;
  std::atomic<bool> mDone{false};
};

}  // namespace tessera::lod
