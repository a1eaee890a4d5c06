#include <tessera/collab/chunk_cache.h>

#include <algorithm>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>

namespace tessera::collab {

namespace fs = std::filesystem;

namespace {

/// A range file's name: "OFFSET+LENGTH" (chunk_client.cpp), digits only around the '+'.
bool rangeFile(const std::string& name) {
  const size_t plus = name.find('+');
  if (plus == std::string::npos || plus == 0 || plus + 1 == name.size()) return false;
  return std::all_of(name.begin(), name.end(),
                     [](char c) { return c == '+' || (c >= '0' && c <= '9'); });
}

}  // namespace

ChunkCacheBudget::ChunkCacheBudget(fs::path root, uint64_t limit_bytes)
    : mRoot(std::move(root)), mLimit(limit_bytes) {
  // Oldest first by modification time (nanoseconds), then by name: stamps follow that order.
  std::vector<std::tuple<int64_t, std::string, uint64_t>> found;
  std::error_code ec;
  for (fs::recursive_directory_iterator
           it(mRoot, fs::directory_options::skip_permission_denied, ec),
       end;
       !ec && it != end; it.increment(ec)) {
    if (it.depth() != 1 || !rangeFile(it->path().filename().string())) continue;
    struct stat st {};
    if (::lstat(it->path().c_str(), &st) != 0 || !S_ISREG(st.st_mode)) continue;
    found.emplace_back(int64_t(st.st_mtim.tv_sec) * 1'000'000'000 + st.st_mtim.tv_nsec,
                       it->path().string(), uint64_t(st.st_size));
  }
  std::sort(found.begin(), found.end());
  for (const auto& [mtime, key, bytes] : found) {
    Entry& e = mFiles[key];
    e.bytes = bytes;
    e.stamp = mNextStamp++;
    mByStamp.emplace(e.stamp, key);
    mBytes += bytes;
  }
}

void ChunkCacheBudget::touch(const std::string& key, Entry& e) {
  mByStamp.erase(e.stamp);
  e.stamp = mNextStamp++;
  mByStamp.emplace(e.stamp, key);
}

void ChunkCacheBudget::used(const fs::path& file) {
  // The modification time carries recency to the next session (UTIME_NOW: no clock read here).
  const timespec now[2] = {{0, UTIME_OMIT}, {0, UTIME_NOW}};
  (void)::utimensat(AT_FDCWD, file.c_str(), now, AT_SYMLINK_NOFOLLOW);
  std::lock_guard lock(mMutex);
  const std::string key = file.string();
  auto it = mFiles.find(key);
  if (it != mFiles.end()) touch(key, it->second);
}

void ChunkCacheBudget::added(const fs::path& file, uint64_t bytes) {
  std::lock_guard lock(mMutex);
  const std::string key = file.string();
  auto [it, fresh] = mFiles.try_emplace(key);
  if (!fresh) {
    mBytes -= it->second.bytes;
    touch(key, it->second);
  } else {
    it->second.stamp = mNextStamp++;
    mByStamp.emplace(it->second.stamp, key);
  }
  it->second.bytes = bytes;
  mBytes += bytes;
  if (mBytes <= mLimit) return;
  const uint64_t target = mLimit / 10 * 9;
  for (auto old = mByStamp.begin(); mBytes > target && old != mByStamp.end();) {
    if (old->second == key) {
      ++old;
      continue;
    }
    std::error_code ec;
    fs::remove(old->second, ec);  // gone already (another site trimmed it): counted out anyway
    const auto entry = mFiles.find(old->second);
    mBytes -= entry->second.bytes;
    ++mEvictedFiles;
    mEvictedBytes += entry->second.bytes;
    mFiles.erase(entry);
    old = mByStamp.erase(old);
  }
}

void ChunkCacheBudget::removed(const fs::path& file) {
  std::lock_guard lock(mMutex);
  const std::string key = file.string();
  auto it = mFiles.find(key);
  if (it == mFiles.end()) return;
  mByStamp.erase(it->second.stamp);
  mBytes -= it->second.bytes;
  mFiles.erase(it);
}

uint64_t ChunkCacheBudget::bytes() const {
  std::lock_guard lock(mMutex);
  return mBytes;
}

uint64_t ChunkCacheBudget::evictedFiles() const {
  std::lock_guard lock(mMutex);
  return mEvictedFiles;
}

uint64_t ChunkCacheBudget::evictedBytes() const {
  std::lock_guard lock(mMutex);
  return mEvictedBytes;
}

}  // namespace tessera::collab
