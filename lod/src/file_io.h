// Whole-range positional reads and writes on file descriptors, and a descriptor closed on scope
// exit: the temporary files and the output of the store builder and verifier.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
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

/// Reads exactly `n` bytes at `offset`; throws StoreError naming `name` otherwise.
void preadAll(int fd, void* data, size_t n, uint64_t offset, const std::string& name);
/// Writes exactly `n` bytes at `offset`; throws StoreError ("disk full?") otherwise.
void pwriteAll(int fd, const void* data, size_t n, uint64_t offset, const std::string& name);

}  // namespace tessera::lod
