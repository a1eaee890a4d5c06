#include "file_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <new>

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

uint8_t* AlignedBytes::reserve(size_t n) {
  n = (n + kDirectAlign - 1) / kDirectAlign * kDirectAlign;
  if (n > mSize) {
    mData.reset(static_cast<uint8_t*>(std::aligned_alloc(kDirectAlign, n)));
    if (!mData) throw std::bad_alloc();
    mSize = n;
  }
  return mData.get();
}

void AlignedBytes::Free::operator()(uint8_t* p) const { std::free(p); }

std::unique_ptr<ScopedFd> openMaybeDirect(const std::filesystem::path& path, int flags,
                                          bool& direct, const char* what) {
  if (direct) {
    try {
      return std::make_unique<ScopedFd>(path, flags | O_DIRECT, what);
    } catch (const StoreError&) {
      direct = false;  // a file system without direct I/O: through the cache
    }
  }
  return std::make_unique<ScopedFd>(path, flags, what);
}

SequentialWriter::SequentialWriter(const std::filesystem::path& path, bool direct,
                                   const char* what)
    : mDirect(direct) {
  mFile = openMaybeDirect(path, O_RDWR | O_CREAT | O_TRUNC, mDirect, what);
  mBuf.reserve(mDirect ? kBuffer : kDirectAlign);
}

void SequentialWriter::append(const void* data, size_t n) {
  if (!mDirect) {  // the page cache gathers the writes
    pwriteAll(mFile->get(), data, n, mFlushed, mFile->name());
    mFlushed += n;
    return;
  }
  const auto* p = static_cast<const uint8_t*>(data);
  while (n > 0) {
    const size_t take = std::min(n, kBuffer - mUsed);
    std::memcpy(mBuf.data() + mUsed, p, take);
    mUsed += take;
    p += take;
    n -= take;
    if (mUsed == kBuffer) {
      pwriteAll(mFile->get(), mBuf.data(), kBuffer, mFlushed, mFile->name());
      mFlushed += kBuffer;
      mUsed = 0;
    }
  }
}

void SequentialWriter::finish() {
  const uint64_t total = size();
  if (mUsed > 0) {
    const size_t padded = (mUsed + kDirectAlign - 1) / kDirectAlign * kDirectAlign;
    std::memset(mBuf.data() + mUsed, 0, padded - mUsed);
    pwriteAll(mFile->get(), mBuf.data(), padded, mFlushed, mFile->name());
  }
  if (::ftruncate(mFile->get(), off_t(total)) != 0)
    throw StoreError("lod: truncating " + mFile->name() + " failed: " + std::strerror(errno));
}

void SequentialWriter::writeFirstBlock(const void* data) {
  std::memcpy(mBuf.data(), data, kDirectAlign);
  pwriteAll(mFile->get(), mBuf.data(), kDirectAlign, 0, mFile->name());
}

}  // namespace tessera::lod
