#include <tessera/lod/range_source.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <tessera/core/file_checks.h>

namespace tessera::lod {

FileRangeSource::FileRangeSource(const std::filesystem::path& path) : mName(path.string()) {
  std::string why;
  mFd = openRegularFile(path, why);  // a FIFO or device is refused, never waited on
  if (mFd < 0) throw RangeError(why.starts_with("not a") ? why : "cannot open: " + why);
  struct stat st {};
  if (::fstat(mFd, &st) != 0) {
    const int e = errno;
    ::close(mFd);
    throw RangeError(std::string("cannot stat: ") + std::strerror(e));
  }
  mSize = uint64_t(st.st_size);
}

FileRangeSource::~FileRangeSource() {
  if (mFd >= 0) ::close(mFd);
}

void FileRangeSource::readRange(uint64_t offset, void* dst, size_t n, std::stop_token) const {
  size_t done = 0;
  while (done < n) {
    const ssize_t got =
        ::pread(mFd, static_cast<uint8_t*>(dst) + done, n - done, off_t(offset + done));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) throw RangeError(got < 0 ? std::strerror(errno) : "end of file");
    done += size_t(got);
  }
}

}  // namespace tessera::lod
