// Whole-range positional reads and writes on file descriptors, and a descriptor closed on scope
// exit: the temporary files and the output of the store builder and verifier.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

namespace tessera::lod {

/// An open file descriptor, closed when it goes out of scope. Throws StoreError naming the file
/// (and `what` it is for) when it cannot be opened.
class ScopedFd {
 public:
  ScopedFd(const std::filesystem::path& path, int flags, const char* what);
  ~ScopedFd();
  ScopedFd(const ScopedFd&) = delete;
  ScopedFd& operator=(const ScopedFd&) = delete;
  int get() const { return mFd; }
  const std::string& name() const { return mName; }

 private:
  int mFd = -1;
  std::string mName;
};

/// Direct I/O (O_DIRECT) moves whole multiples of this, from and to buffers aligned to it.
constexpr size_t kDirectAlign = 4096;

/// A byte buffer aligned to kDirectAlign, grown on demand (contents not kept).
class AlignedBytes {
 public:
  /// At least `n` bytes (rounded up to kDirectAlign).
  uint8_t* reserve(size_t n);
  uint8_t* data() const { return mData.get(); }

 private:
  struct Free {
    void operator()(uint8_t* p) const;
  };
  std::unique_ptr<uint8_t, Free> mData;
  size_t mSize = 0;
};

/// Opens `path` with `flags`, adding O_DIRECT when `direct` and the file system allows it
/// (tmpfs does not: then without). `direct` tells which it got.
std::unique_ptr<ScopedFd> openMaybeDirect(const std::filesystem::path& path, int flags,
                                          bool& direct, const char* what);

/// Appends bytes to a new file strictly in order through an aligned buffer, so it can bypass the
/// page cache (O_DIRECT) where `direct`: a build's output at 10^9 points is 6 GB the cache
/// cannot keep, and its buffered writeback costs the build more than writing it. finish()
/// writes the tail and truncates the file to the bytes appended.
class SequentialWriter {
 public:
  SequentialWriter(const std::filesystem::path& path, bool direct, const char* what);
  void append(const void* data, size_t n);
  uint64_t size() const { return mFlushed + mUsed; }
  void finish();
  /// Overwrites kDirectAlign bytes at offset 0 (a header written last); after finish().
  void writeFirstBlock(const void* data);
  const ScopedFd& file() const { return *mFile; }

 private:
  static constexpr size_t kBuffer = size_t(8) << 20;
  bool mDirect;
  std::unique_ptr<ScopedFd> mFile;
  AlignedBytes mBuf;  ///< direct: the bytes not yet written
  size_t mUsed = 0;
  uint64_t mFlushed = 0;
};

/// Reads exactly `n` bytes at `offset`; throws StoreError naming `name` otherwise.
void preadAll(int fd, void* data, size_t n, uint64_t offset, const std::string& name);
/// Writes exactly `n` bytes at `offset`; throws StoreError ("disk full?") otherwise.
void pwriteAll(int fd, const void* data, size_t n, uint64_t offset, const std::string& name);

}  // namespace tessera::lod
