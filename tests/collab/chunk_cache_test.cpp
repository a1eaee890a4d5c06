// The chunk cache's bound (collab/chunk_cache.h) on real files: least recently used ranges go
// first, a read keeps a range, and the next session sees the folder as this one left it.
#include <tessera/collab/chunk_cache.h>

#include <fstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "../support/temp_dir.h"

namespace tessera::collab {
namespace {

namespace fs = std::filesystem;

/// A range file of `bytes` bytes in `store`'s folder under `root`.
fs::path writeRange(const fs::path& root, const std::string& store, uint64_t offset, size_t bytes) {
  fs::create_directories(root / store);
  const fs::path p = root / store / (std::to_string(offset) + "+" + std::to_string(bytes));
  std::ofstream(p, std::ios::binary) << std::string(bytes, 'x');
  return p;
}

uint64_t folderBytes(const fs::path& root) {
  uint64_t total = 0;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file() && e.path().filename() != "store.txt") total += e.file_size();
  return total;
}

TEST(ChunkCacheBudget, TheLeastRecentlyUsedRangesGoFirstAndTheBoundHolds) {
  test::TempDir dir;
  const fs::path root = dir.path() / "cache";
  fs::create_directories(root);
  ChunkCacheBudget budget(root, 10000);
  EXPECT_EQ(budget.bytes(), 0u);
  std::vector<fs::path> ranges;
  for (int i = 0; i < 4; ++i) {  // 4 x 2000 bytes over two stores: within the bound
    ranges.push_back(writeRange(root, i % 2 ? "a" : "b", uint64_t(i) * 2000, 2000));
    budget.added(ranges.back(), 2000);
  }
  EXPECT_EQ(budget.bytes(), 8000u);
  EXPECT_EQ(budget.evictedFiles(), 0u);
  budget.used(ranges[0]);  // the oldest read again: now the most recent
  // Two more: 12000 bytes, over the bound; trimmed to 90% (9000): the two least recently used
  // (ranges 1 and 2) go, range 0 stays for its read.
  for (int i = 4; i < 6; ++i) {
    ranges.push_back(writeRange(root, "a", uint64_t(i) * 2000, 2000));
    budget.added(ranges.back(), 2000);
  }
  EXPECT_EQ(budget.evictedFiles(), 2u);
  EXPECT_EQ(budget.evictedBytes(), 4000u);
  EXPECT_TRUE(fs::exists(ranges[0]));
  EXPECT_FALSE(fs::exists(ranges[1]));
  EXPECT_FALSE(fs::exists(ranges[2]));
  for (int i = 3; i < 6; ++i) EXPECT_TRUE(fs::exists(ranges[size_t(i)])) << i;
  EXPECT_EQ(budget.bytes(), 8000u);
  EXPECT_EQ(folderBytes(root), 8000u);

  // A range removed by its owner (failed its checksum) is counted out.
  fs::remove(ranges[3]);
  budget.removed(ranges[3]);
  EXPECT_EQ(budget.bytes(), 6000u);
}

TEST(ChunkCacheBudget, TheNextSessionSeesTheFolderAndItsRecency) {
  test::TempDir dir;
  const fs::path root = dir.path() / "cache";
  std::vector<fs::path> ranges;
  {
    ChunkCacheBudget first(root, 1'000'000);
    for (int i = 0; i < 3; ++i) {
      ranges.push_back(writeRange(root, "s", uint64_t(i) * 1000, 1000));
      first.added(ranges.back(), 1000);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));  // distinct mtimes
    }
    first.used(ranges[0]);  // touched: the most recent on disk too
  }
  // Not range files: not counted, never removed.
  std::ofstream(root / "s" / "store.txt") << "bunny.tlod\n";
  std::ofstream(root / "s" / ".tmp-1-2") << std::string(5000, 'y');
  ChunkCacheBudget next(root, 2500);
  EXPECT_EQ(next.bytes(), 3000u);
  ranges.push_back(writeRange(root, "t", 0, 500));
  next.added(ranges.back(), 500);  // 3500 > 2500: down to 2250, the oldest first
  EXPECT_FALSE(fs::exists(ranges[1]));
  EXPECT_FALSE(fs::exists(ranges[2]));
  EXPECT_TRUE(fs::exists(ranges[0])) << "read last session: kept";
  EXPECT_TRUE(fs::exists(ranges[3]));
  EXPECT_TRUE(fs::exists(root / "s" / "store.txt"));
  EXPECT_TRUE(fs::exists(root / "s" / ".tmp-1-2"));
  EXPECT_EQ(next.bytes(), 1500u);
}

TEST(ChunkCacheBudget, ARangeLargerThanTheBoundStaysAlone) {
  test::TempDir dir;
  const fs::path root = dir.path() / "cache";
  ChunkCacheBudget budget(root, 1000);
  const fs::path small = writeRange(root, "s", 0, 400);
  budget.added(small, 400);
  const fs::path big = writeRange(root, "s", 400, 3000);
  budget.added(big, 3000);
  EXPECT_FALSE(fs::exists(small));
  EXPECT_TRUE(fs::exists(big)) << "the range just written is what the site reads next";
  EXPECT_EQ(budget.bytes(), 3000u);
  // A missing root is an empty cache, not an error.
  ChunkCacheBudget none(dir.path() / "nowhere", 1000);
  EXPECT_EQ(none.bytes(), 0u);
}

}  // namespace
}  // namespace tessera::collab
