// The size bound of the chunk client's disk cache (chunk_client.h, tessera-site --cache-mb):
// the cache folder holds at most `limit` bytes of ranges over all its stores; when a write
// passes it, the least recently used range files go first, down to 90% of it (so a full cache
// is not trimmed at every write). Recency is each file's modification time: a read from the
// cache touches its file, so what a site looked at last survives between sessions, and a cache
// folder shared by several sites stays within the bound whichever of them writes.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <unordered_map>

namespace tessera::collab {

class ChunkCacheBudget {
 public:
  /// The range files already under `root` (every store's folder; "store.txt" and temporary
  /// files do not count), by their modification times. A missing or unreadable root: empty.
  ChunkCacheBudget(std::filesystem::path root, uint64_t limit_bytes);

  /// A range read from the cache: its file is touched (now the most recent).
  void used(const std::filesystem::path& file);
  /// A range file written: counted, then the least recently used others are removed while the
  /// total is above the limit (down to 90% of it). The file just written stays, even when it
  /// alone is larger than the limit.
  void added(const std::filesystem::path& file, uint64_t bytes);
  /// A range file removed by its owner (a copy that failed its checksum).
  void removed(const std::filesystem::path& file);

  uint64_t bytes() const;
  uint64_t limit() const { return mLimit; }
  /// Range files and bytes removed to keep the bound, since construction.
  uint64_t evictedFiles() const;
  uint64_t evictedBytes() const;

 private:
  struct Entry {
    uint64_t bytes = 0;
    uint64_t stamp = 0;  // recency: larger is more recent
  };
  void touch(const std::string& key, Entry& e);

  std::filesystem::path mRoot;
  uint64_t mLimit;
  mutable std::mutex mMutex;
  std::unordered_map<std::string, Entry> mFiles;
  std::map<uint64_t, std::string> mByStamp;  // oldest first (stamps are unique)
  uint64_t mBytes = 0, mNextStamp = 0, mEvictedFiles = 0, mEvictedBytes = 0;
};

}  // namespace tessera::collab
