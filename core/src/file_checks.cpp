#include <tessera/core/file_checks.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace tessera {

namespace {

std::string kindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "not a regular file (a directory)";
  if (S_ISFIFO(mode)) return "not a regular file (a FIFO: it would block)";
  if (S_ISSOCK(mode)) return "not a regular file (a socket)";
  if (S_ISCHR(mode)) return "not a regular file (a character device)";
  if (S_ISBLK(mode)) return "not a regular file (a block device)";
  return "not a regular file";
}

}  // namespace

int openRegularFile(const std::filesystem::path& path, std::string& why) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer, forever.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    why = std::strerror(errno);
    return -1;
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    why = ::fstat(fd, &st) != 0 ? std::string(std::strerror(errno)) : kindOf(st.st_mode);
    ::close(fd);
    return -1;
  }
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) (void)::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  return fd;
}

std::optional<std::string> notRegularFile(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return std::string(std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return kindOf(st.st_mode);
  return std::nullopt;
}

std::optional<std::filesystem::path> sameFileAs(const std::filesystem::path& output,
                                                std::span<const std::filesystem::path> inputs) {
  struct stat out {};
  if (::stat(output.c_str(), &out) != 0) return std::nullopt;
  for (const auto& in : inputs) {
    struct stat st {};
    if (::stat(in.c_str(), &st) == 0 && st.st_dev == out.st_dev && st.st_ino == out.st_ino)
      return in;
  }
  return std::nullopt;
}

std::string whyNotWritable(const std::filesystem::path& path, int error) {
  std::error_code ec;
  const std::filesystem::path folder = path.parent_path();
  if (!folder.empty() && !std::filesystem::exists(folder, ec))
    return "the folder " + folder.string() + " does not exist";
  if (!folder.empty() && !std::filesystem::is_directory(folder, ec))
    return folder.string() + " is not a folder";
  if (std::filesystem::is_directory(path, ec)) return "it is a folder";
  return std::strerror(error);
}

std::optional<std::string> notWritable(const std::filesystem::path& path) {
  std::error_code ec;
  if (path.empty()) return "no path";
  if (std::filesystem::exists(path, ec)) {
    if (std::filesystem::is_directory(path, ec)) return "it is a folder";
    if (access(path.c_str(), W_OK) != 0) return whyNotWritable(path, errno);
    return std::nullopt;
  }
  const std::filesystem::path folder =
      path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
  if (!std::filesystem::exists(folder, ec) || !std::filesystem::is_directory(folder, ec))
    return whyNotWritable(path, ENOENT);
  if (access(folder.c_str(), W_OK | X_OK) != 0)
    return "the folder " + folder.string() + " is not writable (" + std::strerror(errno) + ")";
  return std::nullopt;
}

}  // namespace tessera
