#include "byte_source.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

#include <tessera/core/file_checks.h>
#include <tessera/lod/point_reader.h>

namespace tessera::lod {

namespace {
constexpr size_t kChunk = size_t(4) << 20;  // 4 MiB reads: page-cache speed, small footprint
}

ByteSource ByteSource::openFile(const std::filesystem::path& path, const std::string& component) {
  ByteSource s;
  s.mName = path.string();
  std::string why;
  s.mFd = openRegularFile(path, why);  // a FIFO or device is refused, never waited on
  if (s.mFd < 0) {
    throw ReadError(component + ": " + s.mName +
                    (why.starts_with("not a") ? ": " : ": cannot open: ") + why);
  }
  struct stat st {};
  if (::fstat(s.mFd, &st) != 0) {
    throw ReadError(component + ": " + s.mName + ": cannot stat: " + std::strerror(errno));
  }
  s.mSize = uint64_t(st.st_size);
  s.mBuffer = ReadBuffer(kChunk);
  s.mWindow = s.mBuffer.data();
  ::posix_fadvise(s.mFd, 0, 0, POSIX_FADV_SEQUENTIAL);
  return s;
}

ByteSource ByteSource::fromMemory(std::span<const uint8_t> bytes, std::string name) {
  ByteSource s;
  s.mName = std::move(name);
  s.mSize = bytes.size();
  s.mWindow = bytes.data();
  s.mWindowSize = bytes.size();
  return s;
}

ByteSource::ByteSource(ByteSource&& o) noexcept {
  *this = std::move(o);
}

ByteSource& ByteSource::operator=(ByteSource&& o) noexcept {
  if (this == &o) return *this;
  if (mFd >= 0) ::close(mFd);
  mName = std::move(o.mName);
  mFd = std::exchange(o.mFd, -1);
  mSize = o.mSize;
  bool owns = o.mWindow == o.mBuffer.data() && !o.mBuffer.empty();
  mBuffer = std::move(o.mBuffer);
  mWindow = owns ? mBuffer.data() : o.mWindow;
  mWindowSize = o.mWindowSize;
  mWindowOffset = o.mWindowOffset;
  mPos = o.mPos;
  mLine = o.mLine;
  o.mWindow = nullptr;
  o.mWindowSize = 0;
  return *this;
}

ByteSource::~ByteSource() {
  if (mFd >= 0) ::close(mFd);
}

void ByteSource::refill(size_t want) {
  if (mFd < 0) return;  // memory: the window is everything
  // Move the unread tail to the front, grow if one request exceeds the buffer, then read.
  size_t rest = mWindowSize - mPos;
  if (want > mBuffer.size()) {
    ReadBuffer bigger(std::max(want, mBuffer.size() * 2));
    std::memcpy(bigger.data(), mBuffer.data() + mPos, rest);
    mBuffer.swap(bigger);
  } else if (mPos > 0) {
    std::memmove(mBuffer.data(), mBuffer.data() + mPos, rest);
  }
  mWindow = mBuffer.data();
  mWindowOffset += mPos;
  mPos = 0;
  mWindowSize = rest;
  while (mWindowSize < mBuffer.size()) {
    ssize_t got = ::pread(mFd, mBuffer.data() + mWindowSize, mBuffer.size() - mWindowSize,
                          off_t(mWindowOffset + mWindowSize));
    if (got < 0) {
      if (errno == EINTR) continue;
      throw ReadError("lod::ByteSource: " + mName + ": read error at byte " +
                      std::to_string(mWindowOffset + mWindowSize) + ": " + std::strerror(errno));
    }
    if (got == 0) break;
    mWindowSize += size_t(got);
    if (mWindowSize >= want) break;
  }
}

size_t ByteSource::ensure(size_t n) {
  if (mWindowSize - mPos < n) refill(n);
  return std::min(n, mWindowSize - mPos);
}

size_t ByteSource::read(void* dst, size_t n) {
  auto* out = static_cast<uint8_t*>(dst);
  size_t copied = 0;
  while (copied < n) {
    size_t avail = ensure(std::min(n - copied, kChunk));
    if (avail == 0) break;
    std::memcpy(out + copied, data(), avail);
    consume(avail);
    copied += avail;
  }
  return copied;
}

void ByteSource::seek(uint64_t off) {
  off = std::min(off, mSize);
  if (off >= mWindowOffset && off <= mWindowOffset + mWindowSize) {
    mPos = size_t(off - mWindowOffset);
    return;
  }
  mWindowOffset = off;
  mWindowSize = 0;
  mPos = 0;
}

size_t ByteSource::readAt(uint64_t off, void* dst, size_t n) const {
  if (off >= mSize) return 0;
  n = size_t(std::min<uint64_t>(n, mSize - off));
  if (mFd < 0) {
    std::memcpy(dst, mWindow + off, n);
    return n;
  }
  size_t done = 0;
  while (done < n) {
    ssize_t got = ::pread(mFd, static_cast<uint8_t*>(dst) + done, n - done, off_t(off + done));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) break;
    done += size_t(got);
  }
  return done;
}

bool ByteSource::readLine(std::string_view& line, size_t max_line) {
  size_t scanned = 0;
  for (;;) {
    size_t avail = mWindowSize - mPos;
    const uint8_t* start = mWindow + mPos;
    const void* nl =
        avail > scanned ? std::memchr(start + scanned, '\n', avail - scanned) : nullptr;
    if (nl) {
      size_t len = size_t(static_cast<const uint8_t*>(nl) - start);
      size_t eat = len + 1;
      if (len > 0 && start[len - 1] == '\r') --len;
      line = std::string_view(reinterpret_cast<const char*>(start), len);
      mPos += eat;
      ++mLine;
      return true;
    }
    scanned = avail;
    if (avail > max_line) {
      throw ReadError("lod::ByteSource: " + mName + ": line " + std::to_string(mLine + 1) +
                      " at byte " + std::to_string(offset()) + " is longer than " +
                      std::to_string(max_line) + " bytes");
    }
    if (offset() + avail >= mSize) {
      if (avail == 0) return false;
      size_t len = avail;
      if (start[len - 1] == '\r') --len;
      line = std::string_view(reinterpret_cast<const char*>(start), len);
      mPos += avail;
      ++mLine;
      return true;
    }
    refill(std::min<size_t>(max_line + 2, avail + kChunk));
  }
}

}  // namespace tessera::lod
