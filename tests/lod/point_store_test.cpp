// The point LOD store: builds from real scans verify one to one, the hierarchy has the promised
// shape (even inner samples, bounded overhead, recorded spacing), out-of-core chunking gives the
// same guarantees, and bad stores (corrupt, truncated, newer) are refused clearly.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <tuple>

#include <tessera/lod/point_store.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/lod/store_format.h>

#include "../../lod/src/crc32c.h"
#include "../support/temp_dir.h"

namespace tessera::lod {
namespace {

const std::string kData = TESSERA_DATA_DIR;
const std::string kBunny = kData + "/stanford-bunny/scans/bun.conf";
const std::string kAutzen = kData + "/lidar/autzen_trim.las";

BuildOptions quiet(uint64_t chunk_points = 0, uint32_t leaf_max = 16384) {
  BuildOptions o;
  o.quiet = true;
  o.chunk_points = chunk_points;
  o.leaf_max = leaf_max;
  return o;
}

std::vector<NodeId> allNodes(PointStore& s) {
  std::vector<NodeId> out, stack{s.root()};
  while (!stack.empty()) {
    NodeId id = stack.back();
    stack.pop_back();
    out.push_back(id);
    for (NodeId c : s.children(id)) stack.push_back(c);
  }
  return out;
}

TEST(PointStore, BunnyScansBuildVerifyAndMeetTheBudgets) {
  test::TempDir dir;
  // The lossy mode's budgets: positions within a quarter of the spacing.
  BuildOptions lossy = quiet();
  lossy.exact_leaves = false;
  BuildReport r = buildStore({kBunny}, dir / "b.tlod", lossy);
  EXPECT_EQ(r.points, 362272u);
  VerifyReport v = verifyStore(dir / "b.tlod", {kBunny}, quiet());
  EXPECT_TRUE(v.ok()) << v.unmatched << " unmatched";
  EXPECT_EQ(v.matched, 362272u);
  EXPECT_LE(v.max_error_ratio, 1.0);

  auto s = PointStore::open(dir / "b.tlod");
  const StoreSummary& sum = s->summary();
  EXPECT_EQ(sum.points, 362272u);
  EXPECT_LE(double(sum.stored_points) / double(sum.points), 1.3);
  EXPECT_LE(double(sum.position_color_bytes) / double(sum.points), 3.5);
  EXPECT_EQ(s->sources().size(), 10u);
  EXPECT_EQ(s->sources()[9], "bun.conf:ear_back.ply");
  uint64_t leaf_points = 0;
  std::vector<uint64_t> per_source(10, 0);
  for (NodeId id : allNodes(*s)) {
    NodeInfo n = s->node(id);
    auto c = s->loadChunk(id);
    ASSERT_EQ(c->size(), n.points);
    if (n.points > 1) {
      EXPECT_GT(n.spacing, 0.f);
    }
    if (!n.leaf()) {
      // Inner nodes: at most one point per sampling cell, so at most kGrid^3, and coarser
      // than their children.
      EXPECT_LE(n.points, uint32_t(store::kGrid * store::kGrid * store::kGrid));
      for (NodeId ch : s->children(id)) EXPECT_LT(s->node(ch).spacing, n.spacing * 1.01f);
      // Spatially even, never clumped: at most one sample per cell of the kGrid^3 sampling grid
      // (or of a coarser one, where the overhead cap chose it), so a cell of a grid half as
      // fine holds at most 8 (a few more where quantisation moves a point across a face).
      std::map<std::tuple<int, int, int>, int> cells;
      double cell = 2.0 * (n.box_max.x - n.box_min.x) / store::kGrid;
      for (const auto& p : c->positions) {
        glm::dvec3 local = glm::dvec3(p) + c->offset - n.box_min;
        ++cells[{int(local.x / cell), int(local.y / cell), int(local.z / cell)}];
      }
      int most = 0;
      for (auto& [k, count] : cells) most = std::max(most, count);
      EXPECT_LE(most, 10) << "node " << id;
    } else {
      leaf_points += n.points;
      for (uint16_t src : c->sources) ++per_source[src];
    }
    for (const auto& p : c->positions) {
      glm::dvec3 local = glm::dvec3(p) + c->offset;
      ASSERT_TRUE(glm::all(glm::greaterThanEqual(local, n.box_min - 1e-6)));
      ASSERT_TRUE(glm::all(glm::lessThanEqual(local, n.box_max + double(n.error_bound) + 1e-6)));
    }
  }
  EXPECT_EQ(leaf_points, 362272u);
  // Each scan's points keep their source: bun000 has 40256 points, ear_back 32193.
  EXPECT_EQ(per_source[0], 40256u);
  EXPECT_EQ(per_source[9], 32193u);
  EXPECT_GT(sum.spacing_root, 10 * sum.spacing_finest);
}

TEST(PointStore, AutzenColourAndPositionUnderThreeAndAHalfBytes) {
  test::TempDir dir;
  BuildOptions lossy = quiet();
  lossy.exact_leaves = false;
  buildStore({kAutzen}, dir / "a.tlod", lossy);
  const VerifyReport v = verifyStore(dir / "a.tlod", {kAutzen}, quiet());
  EXPECT_TRUE(v.ok());
  EXPECT_FALSE(v.exact_store);
  auto s = PointStore::open(dir / "a.tlod");
  const StoreSummary& sum = s->summary();
  EXPECT_FALSE(sum.exact_leaves);
  EXPECT_LE(double(sum.position_color_bytes) / double(sum.points), 3.5);
  EXPECT_TRUE(sum.attributes & kColor);
  EXPECT_DOUBLE_EQ(sum.input_precision, 0.01);
  // World coordinates stay georeferenced through the double origin.
  EXPECT_NEAR(sum.origin.x + sum.bbox_min.x, 636001.76, 1e-6);
  EXPECT_NEAR(sum.origin.y + sum.bbox_max.y, 849497.9, 1e-6);
}

TEST(PointStore, AutzenLeavesKeepTheFilesIntegersByDefault) {
  test::TempDir dir;
  buildStore({kAutzen}, dir / "a.tlod", quiet());
  auto s = PointStore::open(dir / "a.tlod");
  const StoreSummary& sum = s->summary();
  EXPECT_EQ(sum.version, store::kVersion);
  EXPECT_TRUE(sum.exact_leaves);
  // Whole file, inner copies included: under 0.8x of PotreeConverter's Brotli output for the
  // same attributes (7.54 bytes a point on tiled Autzen).
  EXPECT_LE(double(sum.file_bytes) / double(sum.points), 6.0);
  const VerifyReport v = verifyStore(dir / "a.tlod", {kAutzen}, quiet());
  EXPECT_TRUE(v.ok());
  EXPECT_TRUE(v.exact_store);
  EXPECT_EQ(v.exact, 110000u);
  // Every leaf point is offset + grid + cell * step exactly: the file's 1 cm integers. The LAS
  // records' own integers, read independently of the store's reader, must all be there.
  std::ifstream f(kAutzen, std::ios::binary);
  std::vector<char> las((std::istreambuf_iterator<char>(f)), {});
  uint32_t offset_to_points, count;
  uint16_t record_length;
  double scale[3], offset[3];
  std::memcpy(&offset_to_points, las.data() + 96, 4);
  std::memcpy(&record_length, las.data() + 105, 2);
  std::memcpy(&count, las.data() + 107, 4);
  std::memcpy(scale, las.data() + 131, 24);
  std::memcpy(offset, las.data() + 155, 24);
  ASSERT_EQ(count, 110000u);
  std::map<std::tuple<int64_t, int64_t, int64_t>, int> in_file, in_store;
  for (uint32_t i = 0; i < count; ++i) {
    int32_t xyz[3];
    std::memcpy(xyz, las.data() + offset_to_points + size_t(i) * record_length, 12);
    ++in_file[{xyz[0], xyz[1], xyz[2]}];
  }
  for (NodeId id : allNodes(*s)) {
    if (!s->node(id).leaf()) continue;
    auto c = s->decodeChunk(id, {}, true);
    ASSERT_EQ(c->cells.size(), c->size());
    for (const glm::uvec3& cell : c->cells) {
      const glm::dvec3 world = sum.origin + c->offset + c->grid + glm::dvec3(cell) * c->step;
      int64_t q[3];
      for (int a = 0; a < 3; ++a) {
        const double x = (world[a] - offset[a]) / scale[a];
        q[a] = std::llround(x);
        ASSERT_NEAR(x, double(q[a]), 1e-6) << "not on the file's lattice";
      }
      ++in_store[{q[0], q[1], q[2]}];
    }
  }
  EXPECT_EQ(in_store, in_file);
}

TEST(PointStore, TemporaryRecordsAreCompactForLasAndWideWhereTheyCannotHoldThePositions) {
  test::TempDir dir;
  // Autzen declares 1 cm: its points pass the temporary files as 21-byte records.
  const BuildOptions o = quiet(20000, 400);
  EXPECT_EQ(buildStore({kAutzen}, dir / "a.tlod", o).temp_record_bytes, 21u);
  EXPECT_TRUE(verifyStore(dir / "a.tlod", {kAutzen}, o).ok());
  // A PLY declares no resolution: wide records.
  EXPECT_EQ(buildStore({kData + "/stanford-bunny/reconstruction/bun_zipper.ply"}, dir / "b.tlod",
                       quiet())
                .temp_record_bytes,
            40u);
  // 1 mm over 4000 km: 2^31 sixteenths of a millimetre reach 134 km, so the records are wide,
  // and the store still holds every point where it was.
  PointBatch far;
  for (int i = 0; i < 2000; ++i) {
    const double t = double(i) / 1999.0;
    far.positions.push_back({-2.0e6 + 4.0e6 * t, 1000.0 * std::sin(40.0 * t), 0.5 * i});
  }
  writeLas(dir / "far.las", far, glm::dvec3(0.0), {2, 0, glm::dvec3(0.001), false, 0, false});
  BuildOptions lossy = quiet();
  lossy.exact_leaves = false;
  BuildReport r = buildStore({dir / "far.las"}, dir / "far.tlod", lossy);
  EXPECT_EQ(r.temp_record_bytes, 40u);
  EXPECT_EQ(r.points, 2000u);
  VerifyReport v = verifyStore(dir / "far.tlod", {dir / "far.las"}, lossy);
  EXPECT_TRUE(v.ok()) << v.unmatched << " unmatched of " << v.input_points;
}

TEST(PointStore, OutOfCoreChunksFusedInputsAndThreadsGiveTheSameGuarantees) {
  test::TempDir dir;
  // Tiny chunks force many out-of-core work units, the oversize split and upper levels.
  BuildOptions o = quiet(20000, 400);
  o.threads = 2;
  BuildReport r = buildStore({kBunny, kData + "/stanford-bunny/reconstruction/bun_zipper.ply"},
                             dir / "f.tlod", o);
  EXPECT_GT(r.chunks, 10u);
  EXPECT_EQ(r.points, 362272u + 35947u);
  VerifyReport v = verifyStore(
      dir / "f.tlod", {kBunny, kData + "/stanford-bunny/reconstruction/bun_zipper.ply"}, o);
  EXPECT_TRUE(v.ok()) << v.unmatched << " unmatched of " << v.input_points;
  auto s = PointStore::open(dir / "f.tlod");
  EXPECT_EQ(s->sources().size(), 11u);
  // Deep hierarchy: children pages load lazily.
  size_t at_open = s->loadedNodes();
  size_t total = allNodes(*s).size();
  EXPECT_EQ(total, s->summary().nodes);
  EXPECT_LT(at_open, total);
  EXPECT_GT(s->summary().depth, uint32_t(store::kPageLevels + 1));
  // Same inputs, one thread: the same bytes.
  o.threads = 1;
  buildStore({kBunny, kData + "/stanford-bunny/reconstruction/bun_zipper.ply"}, dir / "g.tlod", o);
  EXPECT_EQ(test::readBytes(dir / "f.tlod"), test::readBytes(dir / "g.tlod"));
}

TEST(PointStore, CacheEvictsUnderItsBudgetAndServesThreads) {
  test::TempDir dir;
  buildStore({kBunny}, dir / "b.tlod", quiet(0, 2000));
  auto s = PointStore::open(dir / "b.tlod", 256 << 10);
  std::vector<NodeId> nodes = allNodes(*s);
  std::vector<std::thread> pool;
  std::atomic<int> mismatches{0};
  for (int t = 0; t < 2; ++t) {
    pool.emplace_back([&, t] {
      for (int round = 0; round < 3; ++round) {
        for (size_t i = size_t(t); i < nodes.size(); i += 1) {
          auto a = s->loadChunk(nodes[i]);
          auto b = s->decodeChunk(nodes[i]);
          if (a->positions != b->positions || a->sources != b->sources) ++mismatches;
        }
      }
    });
  }
  for (auto& th : pool) th.join();
  EXPECT_EQ(mismatches, 0);
  // The most recently used chunk is never evicted: a second load is a hit.
  s->loadChunk(nodes[0]);
  s->loadChunk(nodes[0]);
  CacheStats st = s->cacheStats();
  EXPECT_GT(st.evictions, 0u);
  EXPECT_GT(st.hits, 0u);
  EXPECT_LE(st.bytes, st.budget + (1 << 20));
}

std::string storeErrorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const StoreError& e) {
    return e.what();
  }
  return "";
}

// A corrupt child hierarchy page dropped its nodes without a word.
TEST(PointStore, ACorruptChildPageIsCountedAndItsNodesLeaveCleanly) {
  test::TempDir dir;
  buildStore({kBunny}, dir / "d.tlod", quiet(20000, 400));
  auto bytes = test::readBytes(dir / "d.tlod");
  store::FileHeader h;
  std::memcpy(&h, bytes.data(), sizeof h);
  store::PageHeader root;
  std::memcpy(&root, bytes.data() + h.root_page_offset, sizeof root);
  // The first node of the root page whose children are on a page of their own.
  uint64_t page = 0;
  for (uint32_t i = 0; i < root.nodes && page == 0; ++i) {
    store::NodeRecord r;
    std::memcpy(&r, bytes.data() + h.root_page_offset + sizeof root + i * sizeof r, sizeof r);
    if (r.flags & store::kHasPage) page = r.page_offset;
  }
  ASSERT_NE(page, 0u) << "the store has no child pages";
  bytes[page + sizeof(store::PageHeader) + 5] ^= 0x5A;  // inside the records: checksum mismatch
  test::writeBytes(dir / "c.tlod", bytes);
  auto s = PointStore::open(dir / "c.tlod");
  auto walk = [&](int& failures) {
    std::vector<NodeId> out, stack{s->root()};
    while (!stack.empty()) {
      const NodeId id = stack.back();
      stack.pop_back();
      out.push_back(id);
      const std::string msg = storeErrorOf([&] {
        for (NodeId c : s->children(id)) stack.push_back(c);
      });
      if (!msg.empty()) {
        ++failures;
        EXPECT_NE(msg.find("c.tlod: hierarchy page at byte " + std::to_string(page)),
                  std::string::npos)
            << msg;
      }
    }
    return out.size();
  };
  int failures = 0;
  const size_t first = walk(failures);
  EXPECT_EQ(failures, 1);
  EXPECT_EQ(s->cacheStats().corrupt_pages, 1u);
  EXPECT_LT(first, s->summary().nodes);
  // The page is not read again and left nothing half-linked: the same nodes, no new failure.
  int again = 0;
  EXPECT_EQ(walk(again), first);
  EXPECT_EQ(again, 0);
  EXPECT_EQ(s->cacheStats().corrupt_pages, 1u);
  EXPECT_EQ(s->loadedNodes(), first);
}

TEST(PointStore, CorruptChunksAreReportedAndSkippedNeverDrawn) {
  test::TempDir dir;
  buildStore({kAutzen}, dir / "a.tlod", quiet(0, 2000));
  auto bytes = test::readBytes(dir / "a.tlod");
  // Flip a byte in the middle of the payload.
  bytes[store::kHeaderSize + 300] ^= 0x5A;
  test::writeBytes(dir / "c.tlod", bytes);
  auto s = PointStore::open(dir / "c.tlod");
  int bad = 0, good = 0;
  for (NodeId id : allNodes(*s)) {
    std::string msg = storeErrorOf([&] { s->loadChunk(id); });
    if (msg.empty()) {
      ++good;
    } else {
      ++bad;
      EXPECT_NE(msg.find("corrupt chunk (checksum mismatch)"), std::string::npos) << msg;
      EXPECT_NE(msg.find("c.tlod"), std::string::npos) << msg;
    }
  }
  EXPECT_EQ(bad, 1);
  EXPECT_GT(good, 10);
  EXPECT_EQ(s->cacheStats().corrupt, 1u);
  VerifyReport v = verifyStore(dir / "c.tlod", {kAutzen}, quiet());
  EXPECT_FALSE(v.ok());
  EXPECT_EQ(v.corrupt_chunks > 0 || v.unmatched > 0, true);
}

TEST(PointStore, BadStoresAreRefusedWithTheReason) {
  test::TempDir dir;
  buildStore({kAutzen}, dir / "a.tlod", quiet());
  auto bytes = test::readBytes(dir / "a.tlod");
  auto openErr = [&](const std::vector<uint8_t>& b) {
    test::writeBytes(dir / "x.tlod", b);
    return storeErrorOf([&] { PointStore::open(dir / "x.tlod"); });
  };
  // A newer format version (with a valid checksum) is named as such.
  {
    auto b = bytes;
    store::FileHeader h;
    std::memcpy(&h, b.data(), sizeof h);
    h.version = store::kVersion + 1;
    // The version is checked before the checksum, so a newer store is named as such.
    std::memcpy(b.data(), &h, sizeof h);
    EXPECT_NE(openErr(b).find("newer than this build reads"), std::string::npos) << openErr(b);
  }
  EXPECT_NE(openErr(std::vector<uint8_t>(bytes.begin(), bytes.begin() + 100)).find("too small"),
            std::string::npos);
  EXPECT_NE(openErr(std::vector<uint8_t>(bytes.begin(), bytes.end() - 40)).find("truncated"),
            std::string::npos)
      << openErr(std::vector<uint8_t>(bytes.begin(), bytes.end() - 40));
  {
    auto b = bytes;
    b[40] ^= 1;  // inside the header
    EXPECT_NE(openErr(b).find("header is corrupt"), std::string::npos);
  }
  {
    auto b = bytes;
    b[0] = 'X';
    EXPECT_NE(openErr(b).find("not a Tessera point store"), std::string::npos);
  }
  store::FileHeader h;
  std::memcpy(&h, bytes.data(), sizeof h);
  // The source table had no checksum, so a flipped byte renamed a source silently.
  {
    auto b = bytes;
    b[h.source_table_offset] ^= 0x20;
    EXPECT_NE(openErr(b).find("source table is corrupt (checksum mismatch)"), std::string::npos)
        << openErr(b);
  }
  // A version 1 store (no source table checksum, the field was reserved) still opens.
  {
    auto b = bytes;
    store::FileHeader v1 = h;
    v1.version = 1;
    v1.source_table_crc = 0;
    v1.header_crc = 0;
    v1.header_crc = crc32c(&v1, sizeof v1);
    std::memcpy(b.data(), &v1, sizeof v1);
    EXPECT_EQ(openErr(b), "");
  }
  // Offsets and sizes whose sum wraps around are refused before anything is allocated.
  {
    auto b = bytes;
    store::FileHeader w = h;
    w.source_table_offset = ~uint64_t(0) - 10;
    w.source_table_size = 0xFFFFFF00u;
    w.header_crc = 0;
    w.header_crc = crc32c(&w, sizeof w);
    std::memcpy(b.data(), &w, sizeof w);
    EXPECT_NE(openErr(b).find("inconsistent with the file size"), std::string::npos) << openErr(b);
  }
}

}  // namespace
namespace {

/// A store's bytes in memory whose reads at `broken_offset` are corrupt until refetch() is
/// called for them (a cache's bad copy), or forever when not `mendable` (bad bytes at the
/// source). Remembers the last range read.
class FlakySource final : public RangeSource {
 public:
  FlakySource(const std::vector<uint8_t>& bytes, bool mendable, uint64_t broken_offset)
      : mBytes(bytes), mMendable(mendable), mBroken(broken_offset) {}
  uint64_t size() const override { return mBytes.size(); }
  std::string name() const override { return "flaky.tlod"; }
  void readRange(uint64_t offset, void* dst, size_t n, std::stop_token) const override {
    std::lock_guard lock(mMutex);
    std::memcpy(dst, mBytes.data() + offset, n);
    last_offset = offset;
    if (offset == mBroken && !mMended) static_cast<uint8_t*>(dst)[n / 2] ^= 0x40;
  }
  bool refetch(uint64_t offset, size_t) const override {
    std::lock_guard lock(mMutex);
    ++refetches;
    if (!mMendable || offset != mBroken) return false;
    mMended = true;
    return true;
  }
  mutable uint64_t last_offset = 0, refetches = 0;

 private:
  const std::vector<uint8_t>& mBytes;
  bool mMendable;
  uint64_t mBroken;
  mutable bool mMended = false;
  mutable std::mutex mMutex;
};

}  // namespace

// A store read through a RangeSource (a chunk server and its disk cache) decodes the
// same points as from its file; bytes that fail a checksum are read once more when the source
// can fetch them again, else refused as before, naming the source.
TEST(PointStore, RangeSourcesReadTheSameStoreAndACorruptCopyIsFetchedAgain) {
  test::TempDir dir;
  buildStore({kBunny}, dir / "b.tlod", quiet());
  auto file = PointStore::open(dir / "b.tlod");
  const std::vector<uint8_t> bytes = test::readBytes(dir / "b.tlod");
  auto whole = std::make_unique<FlakySource>(bytes, true, ~0ull);
  FlakySource* probe = whole.get();
  auto same = PointStore::open(std::move(whole));
  EXPECT_EQ(same->path(), "flaky.tlod");
  NodeId victim = kNoNode;
  for (NodeId id : allNodes(*same)) {
    const auto a = file->decodeChunk(id);
    const auto b = same->decodeChunk(id);
    ASSERT_EQ(a->positions, b->positions) << "node " << id;
    ASSERT_EQ(a->colors, b->colors) << "node " << id;
    if (victim == kNoNode && id != same->root() && a->size() > 0) victim = id;
  }
  ASSERT_NE(victim, kNoNode);
  (void)same->decodeChunk(victim);
  const uint64_t payload = probe->last_offset;  // one read per chunk: its payload's range

  // A cached copy gone bad: refused by the CRC, fetched again, decoded right.
  auto mend = std::make_unique<FlakySource>(bytes, true, payload);
  FlakySource* m = mend.get();
  auto mended = PointStore::open(std::move(mend));
  (void)allNodes(*mended);
  EXPECT_EQ(mended->decodeChunk(victim)->positions, file->decodeChunk(victim)->positions);
  EXPECT_EQ(m->refetches, 1u);
  // Bad at the source: refused as a corrupt chunk, as from a file.
  auto bad = PointStore::open(std::make_unique<FlakySource>(bytes, false, payload));
  (void)allNodes(*bad);
  const std::string msg = storeErrorOf([&] { bad->decodeChunk(victim); });
  EXPECT_NE(msg.find("flaky.tlod"), std::string::npos) << msg;
  EXPECT_NE(msg.find("corrupt chunk (checksum mismatch)"), std::string::npos) << msg;
  // The header itself from a bad copy: fetched again too.
  auto header = std::make_unique<FlakySource>(bytes, true, 0);
  FlakySource* h = header.get();
  std::unique_ptr<PointStore> from_bad_header;
  EXPECT_NO_THROW(from_bad_header = PointStore::open(std::move(header)));
  EXPECT_EQ(h->refetches, 1u);  // while the store (which owns the source) is open
}

}  // namespace tessera::lod
