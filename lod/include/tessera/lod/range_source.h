// Where a point store's bytes come from ("chunks on demand"): a file on this host, or
// byte ranges fetched from elsewhere (collab/chunk_client.h: the master's chunk server, with a
// disk cache). PointStore reads everything through one: the header, the source table, each
// hierarchy page and each chunk payload is one read() of a byte range, and each is checked by
// its own CRC-32C in the store, so bytes that went wrong anywhere on the way (a link, a cache
// file) are refused, never decoded.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <stop_token>
#include <string>

namespace tessera::lod {

/// A read that failed (I/O error, a lost link, a timeout). what() says why, without the
/// source's name (PointStore adds it and what it was reading).
class RangeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A read given up because whoever asked for it no longer needs it (its stop token was
/// stopped: the chunk streamer's view moved on). Not a fault of the source or the store:
/// PointStore and MeshStore pass it on as it is, and the chunk may be asked for again.
class ReadCancelled : public RangeError {
 public:
  using RangeError::RangeError;
};

/// The bytes of one store, read by offset. Every method is thread-safe: the loader pool
/// (render/chunk_streamer.h) reads from several threads at once.
class RangeSource {
 public:
  virtual ~RangeSource() = default;
  /// The store's size, bytes; constant for the source's lifetime.
  virtual uint64_t size() const = 0;
  /// Copies the `n` bytes at `offset` to `dst`, which holds at least `n` bytes. Precondition:
  /// offset + n <= size() (PointStore checks). Blocks until done; throws RangeError. A source
  /// that waits on something slow (a link) gives up when `cancel` is stopped and throws
  /// ReadCancelled (what `dst` then holds is unspecified); a file's read ignores it.
  void read(uint64_t offset, void* dst, size_t n, std::stop_token cancel = {}) const {
    readRange(offset, dst, n, std::move(cancel));
  }
  /// The name messages use (the store's path, as the scene names it).
  virtual std::string name() const = 0;
  /// The bytes just read at [offset, offset + n) failed the store's checksum. A source that
  /// keeps a copy of them (a cache) drops it and returns true when reading them again may give
  /// other bytes; PointStore then reads them once more. Default: false (a file's bytes are what
  /// they are).
  virtual bool refetch(uint64_t offset, size_t n) const {
    (void)offset;
    (void)n;
    return false;
  }

 private:
  /// read(), by each kind of source.
  virtual void readRange(uint64_t offset, void* dst, size_t n, std::stop_token cancel) const = 0;
};

/// A regular file (pread, any number of threads). A FIFO or device is refused, never waited
/// on.
class FileRangeSource final : public RangeSource {
 public:
  /// Throws RangeError: "cannot open: No such file or directory", "not a regular file ...".
  explicit FileRangeSource(const std::filesystem::path& path);
  ~FileRangeSource() override;
  FileRangeSource(const FileRangeSource&) = delete;
  FileRangeSource& operator=(const FileRangeSource&) = delete;

  uint64_t size() const override { return mSize; }
  std::string name() const override { return mName; }

 private:
  void readRange(uint64_t offset, void* dst, size_t n, std::stop_token cancel) const override;

  std::string mName;
  int mFd = -1;
  uint64_t mSize = 0;
};

}  // namespace tessera::lod
