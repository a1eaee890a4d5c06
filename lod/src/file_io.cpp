#include "file_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include <tessera/lod/point_store.h>

namespace tessera::lod {

ScopedFd::ScopedFd(const std::filesystem::path& path, int flags, const char* what)
    : mName(path.string()) {
  mFd = ::open(path.c_str(), flags | O_CLOEXEC, 0644);
  if (mFd < 0) {
    throw StoreError(std::string("lod: cannot open ") + what + " " + mName + ": " +
                     std::strerror(errno));
  }
}

ScopedFd::~ScopedFd() {
  if (mFd >= 0) ::close(mFd);
}

void preadAll(int fd, void* data, size_t n, uint64_t offset, const std::string& name) {
  auto* p = static_cast<uint8_t*>(data);
  size_t done = 0;
  while (done < n) {
    ssize_t got =
        ::pread(fd, p + done, std::min<size_t>(n - done, size_t(1) << 30), off_t(offset + done));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) {
      throw StoreError("lod: reading " + name +
                       " failed: " + (got < 0 ? std::strerror(errno) : "end of file"));
    }
    done += size_t(got);
  }
}

void pwriteAll(int fd, const void* data, size_t n, uint64_t offset, const std::string& name) {
  const auto* p = static_cast<const uint8_t*>(data);
  size_t done = 0;
  while (done < n) {
    ssize_t put =
        ::pwrite(fd, p + done, std::min<size_t>(n - done, size_t(1) << 30), off_t(offset + done));
    if (put < 0 && errno == EINTR) continue;
    if (put <= 0) {
      throw StoreError("lod: writing " + name + " failed: " +
                       (put < 0 ? std::strerror(errno) : "no space") + " (disk full?)");
    }
    done += size_t(put);
  }
}

}  // namespace tessera::lod
