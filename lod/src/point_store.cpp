#include <tessera/lod/point_store.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <deque>
#include <list>
#include <unordered_map>
#include <unordered_set>

#include <tessera/core/check.h>
#include <tessera/lod/range_source.h>
#include <tessera/lod/store_format.h>

#include "chunk_codec.h"
#include "crc32c.h"
#include "point_distributor.h"

namespace tessera::lod {

struct PointStore::Impl {
  struct Entry {
    NodeInfo info;
    uint64_t payload_offset = 0;
    uint32_t payload_size = 0;
    uint32_t crc = 0;
    uint64_t page_offset = 0;
    uint32_t page_size = 0;
    bool children_loaded = true;
    std::array<NodeId, 8> children;
  };
  struct Cached {
    std::shared_ptr<const ChunkPoints> points;
    std::list<NodeId>::iterator lru;
    uint64_t bytes = 0;
  };

  std::unique_ptr<RangeSource> source;
  uint64_t file_size = 0;
  std::string name;
  CubeFrame frame;

  mutable std::shared_mutex nodes_mutex;
  std::deque<Entry> nodes;  // deque: references stay valid while pages append

  mutable std::mutex cache_mutex;
  std::list<NodeId> lru;  // front: most recent
  std::unordered_map<NodeId, Cached> cache;
  CacheStats stats;
  std::unordered_set<NodeId> corrupt_pages;  // nodes whose children's page was refused

  [[noreturn]] void fail(const std::string& what) const {
    throw StoreError("lod::PointStore: " + name + ": " + what);
  }

  void readAt(uint64_t off, void* dst, size_t n, const char* what,
              std::stop_token cancel = {}) const {
    if (off > file_size || n > file_size - off)
      fail(std::string(what) + " lies beyond the end of the file (truncated?)");
    try {
      source->read(off, dst, n, cancel);
    } catch (const ReadCancelled&) {
      throw;  // nobody needs these bytes any more: not a fault of the store
    } catch (const RangeError& e) {
      fail(std::string("reading ") + what + " failed: " + e.what());
    }
  }

  /// readAt(), then `intact()` on the bytes; when they fail it and the source can fetch them
  /// again (a cached copy was corrupt: range_source.h), reads once more. Returns intact().
  template <class Intact>
  bool readChecked(uint64_t off, void* dst, size_t n, const char* what, Intact intact,
                   std::stop_token cancel = {}) const {
    readAt(off, dst, n, what, cancel);
    if (intact()) return true;
    if (!source->refetch(off, n)) return false;
    readAt(off, dst, n, what, cancel);
    return intact();
  }

  /// Reads a hierarchy page. `expand`: the node whose children it holds (its first record must
  /// be that node), or kNoNode for the root page. Caller holds the unique lock.
  void loadPage(uint64_t offset, uint32_t size, NodeId expand) {
    store::PageHeader ph;
    if (size < sizeof ph)
      fail("hierarchy page at byte " + std::to_string(offset) + " is too small");
    // One read for the whole page: one round trip when the bytes come over a link.
    std::vector<uint8_t> bytes(size);
    std::vector<store::NodeRecord> recs;
    bool header_ok = false;
    const bool intact = readChecked(offset, bytes.data(), bytes.size(), "a hierarchy page", [&] {
      std::memcpy(&ph, bytes.data(), sizeof ph);
      header_ok = std::memcmp(ph.magic, "TPAG", 4) == 0 &&
                  uint64_t(ph.nodes) * sizeof(store::NodeRecord) + sizeof ph == size &&
                  ph.nodes != 0;
      return header_ok && crc32c(bytes.data() + sizeof ph, size - sizeof ph) == ph.crc;
    });
    if (!header_ok)
      fail("hierarchy page at byte " + std::to_string(offset) + " is corrupt (bad header)");
    if (!intact)
      fail("hierarchy page at byte " + std::to_string(offset) + " is corrupt (checksum mismatch)");
    recs.resize(ph.nodes);
    std::memcpy(recs.data(), bytes.data() + sizeof ph, recs.size() * sizeof(store::NodeRecord));
    std::unordered_map<CellKey, NodeId, CellKeyHash> local;
    for (size_t i = 0; i < recs.size(); ++i) {
      const store::NodeRecord& r = recs[i];
      CellKey key{r.level, r.x, r.y, r.z};
      uint64_t res = uint64_t(1) << std::min<int>(r.level, 62);
      if (r.level > store::kMaxLevel || r.x >= res || r.y >= res || r.z >= res)
        fail("hierarchy page holds a bad node key");
      NodeId id;
      if (i == 0 && expand != kNoNode) {
        const NodeInfo& e = nodes[expand].info;
        if (e.level != r.level || e.cell != glm::u32vec3(r.x, r.y, r.z))
          fail("hierarchy page does not belong to its node");
        id = expand;
      } else {
        if (i == 0 && (r.level != 0)) fail("root page does not start with the root node");
        if (i > 0) {
          auto parent = local.find(key.parent());
          if (key.level == 0 || parent == local.end() ||
              !(nodes[parent->second].info.child_mask & (1u << key.childIndex()))) {
            fail("hierarchy page lists a node without its parent");
          }
        }
        Entry e;
        e.info.level = r.level;
        e.info.cell = glm::u32vec3(r.x, r.y, r.z);
        e.info.box_min = frame.cellMin(key);
        e.info.box_max = e.info.box_min + glm::dvec3(frame.cellSize(r.level));
        e.info.points = r.points;
        e.info.spacing = r.spacing;
        e.info.error_bound = r.error_bound;
        e.info.child_mask = r.child_mask;
        e.payload_offset = r.payload_offset;
        e.payload_size = r.payload_size;
        e.crc = r.payload_crc;
        e.page_offset = r.page_offset;
        e.page_size = r.page_size;
        e.children_loaded = !(r.flags & store::kHasPage);
        e.children.fill(kNoNode);
        if ((r.payload_size > 0) != (r.points > 0) ||
            r.payload_offset + r.payload_size > file_size) {
          fail("hierarchy page holds a node with a bad payload range");
        }
        id = NodeId(nodes.size());
        nodes.push_back(e);
        if (i > 0) nodes[local.at(key.parent())].children[size_t(key.childIndex())] = id;
      }
      local[key] = id;
    }
    if (expand != kNoNode) nodes[expand].children_loaded = true;
    for (auto& [key, id] : local) {
      const Entry& e = nodes[id];
      if (!e.children_loaded) continue;
      for (int c = 0; c < 8; ++c) {
        if ((e.info.child_mask & (1u << c)) && e.children[size_t(c)] == kNoNode)
          fail("hierarchy page misses a child node");
      }
    }
  }
};

std::unique_ptr<PointStore> PointStore::open(const std::filesystem::path& path,
                                             uint64_t cache_bytes) {
  std::unique_ptr<RangeSource> source;
  try {
    source = std::make_unique<FileRangeSource>(path);
  } catch (const RangeError& e) {
    throw StoreError("lod::PointStore: " + path.string() + ": " + e.what());
  }
  return open(std::move(source), cache_bytes);
}

std::unique_ptr<PointStore> PointStore::open(std::unique_ptr<RangeSource> source,
                                             uint64_t cache_bytes) {
  TESSERA_CHECK(source != nullptr, "lod::PointStore::open(): no source");
  std::unique_ptr<PointStore> s(new PointStore());
  s->mPath = source->name();
  s->mImpl = std::make_unique<Impl>();
  Impl& m = *s->mImpl;
  m.name = source->name();
  m.file_size = source->size();
  m.source = std::move(source);
  store::FileHeader h;
  if (m.file_size < sizeof h)
    m.fail("too small to be a point store (" + std::to_string(m.file_size) + " bytes)");
  const bool header_intact = m.readChecked(0, &h, sizeof h, "the header", [&] {
    store::FileHeader zeroed = h;
    zeroed.header_crc = 0;
    return crc32c(&zeroed, sizeof zeroed) == h.header_crc;
  });
  if (std::memcmp(h.magic, store::kMagic, 4) != 0) m.fail("not a Tessera point store (bad magic)");
  if (h.version > store::kVersion) {
    m.fail("store format version " + std::to_string(h.version) +
           " is newer than this build reads (" + std::to_string(store::kVersion) +
           "): update Tessera or rebuild the store");
  }
  if (h.version == 0) m.fail("bad format version 0");
  if (!header_intact) m.fail("header is corrupt (checksum mismatch)");
  if (h.version < 3 && (h.attributes & kAmbientOcclusion))
    m.fail("version " + std::to_string(h.version) +
           " header lists ambient occlusion, which needs version 3 (corrupt header)");
  // Offset and size each within the file first: their sum must not wrap around.
  if (!(h.cube_size > 0) || h.root_page_offset > m.file_size ||
      h.root_page_size > m.file_size - h.root_page_offset || h.source_table_offset > m.file_size ||
      h.source_table_size > m.file_size - h.source_table_offset || h.sources > 65536) {
    m.fail("header is inconsistent with the file size (truncated?)");
  }
  m.frame.origin = glm::dvec3(h.origin[0], h.origin[1], h.origin[2]);
  m.frame.cube_min = glm::dvec3(h.cube_min[0], h.cube_min[1], h.cube_min[2]);
  m.frame.cube_size = h.cube_size;

  StoreSummary& sum = s->mSummary;
  sum.version = h.version;
  sum.origin = m.frame.origin;
  sum.bbox_min = glm::dvec3(h.bbox_min[0], h.bbox_min[1], h.bbox_min[2]);
  sum.bbox_max = glm::dvec3(h.bbox_max[0], h.bbox_max[1], h.bbox_max[2]);
  sum.cube_size = h.cube_size;
  sum.points = h.points;
  sum.stored_points = h.stored_points;
  sum.nodes = h.nodes;
  sum.depth = h.depth;
  sum.attributes = h.attributes;
  sum.file_bytes = m.file_size;
  sum.payload_bytes = h.payload_size;
  sum.position_color_bytes = h.payload_position_color_bytes;
  sum.spacing_root = h.spacing_root;
  sum.spacing_finest = h.spacing_finest;
  sum.input_precision = h.input_precision;
  sum.exact_leaves = h.version >= 4 && (h.flags & store::kExactLeaves);

  std::string table(h.source_table_size, '\0');
  if (!m.readChecked(h.source_table_offset, table.data(), table.size(), "the source table", [&] {
        return h.version < 2 || crc32c(table.data(), table.size()) == h.source_table_crc;
      }))
    m.fail("source table is corrupt (checksum mismatch)");
  for (size_t a = 0; a < table.size();) {
    size_t b = table.find('\n', a);
    if (b == std::string::npos) break;
    s->mSources.push_back(table.substr(a, b - a));
    a = b + 1;
  }
  {
    std::unique_lock lock(m.nodes_mutex);
    m.loadPage(h.root_page_offset, h.root_page_size, kNoNode);
  }
  m.stats.budget = cache_bytes;
  return s;
}

PointStore::~PointStore() = default;

NodeInfo PointStore::node(NodeId id) const {
  std::shared_lock lock(mImpl->nodes_mutex);
  TESSERA_CHECK(id < mImpl->nodes.size(), "lod::PointStore::node(): unknown node id");
  return mImpl->nodes[id].info;
}

bool PointStore::childrenLoaded(NodeId id) const {
  std::shared_lock lock(mImpl->nodes_mutex);
  TESSERA_CHECK(id < mImpl->nodes.size(), "lod::PointStore::childrenLoaded(): unknown node id");
  return mImpl->nodes[id].children_loaded;
}

size_t PointStore::loadedNodes() const {
  std::shared_lock lock(mImpl->nodes_mutex);
  return mImpl->nodes.size();
}

std::vector<NodeId> PointStore::children(NodeId id) {
  Impl& m = *mImpl;
  {
    std::shared_lock lock(m.nodes_mutex);
    TESSERA_CHECK(id < m.nodes.size(), "lod::PointStore::children(): unknown node id");
    if (m.nodes[id].children_loaded) {
      std::vector<NodeId> out;
      for (NodeId c : m.nodes[id].children) {
        if (c != kNoNode) out.push_back(c);
      }
      return out;
    }
  }
  std::unique_lock lock(m.nodes_mutex);
  if (!m.nodes[id].children_loaded) {
    const size_t known = m.nodes.size();
    try {
      m.loadPage(m.nodes[id].page_offset, m.nodes[id].page_size, id);
    } catch (const StoreError&) {
      // Undo what the page added before it failed, and never read it again: the node has no
      // children from now on, and the page is counted so a renderer can say what is missing.
      m.nodes.resize(known);
      m.nodes[id].children.fill(kNoNode);
      m.nodes[id].children_loaded = true;
      std::lock_guard stats_lock(m.cache_mutex);
      if (m.corrupt_pages.insert(id).second) ++m.stats.corrupt_pages;
      throw;
    }
  }
  std::vector<NodeId> out;
  for (NodeId c : m.nodes[id].children) {
    if (c != kNoNode) out.push_back(c);
  }
  return out;
}

uint32_t PointStore::chunkBytes(NodeId id) const {
  std::shared_lock lock(mImpl->nodes_mutex);
  TESSERA_CHECK(id < mImpl->nodes.size(), "lod::PointStore::chunkBytes(): unknown node id");
  return mImpl->nodes[id].payload_size;
}

std::shared_ptr<ChunkPoints> PointStore::decodeChunk(NodeId id, std::stop_token cancel,
                                                     bool with_cells) const {
  const Impl& m = *mImpl;
  Impl::Entry e;
  {
    std::shared_lock lock(m.nodes_mutex);
    TESSERA_CHECK(id < m.nodes.size(), "lod::PointStore::decodeChunk(): unknown node id");
    e = m.nodes[id];
  }
  auto out = std::make_shared<ChunkPoints>();
  out->offset = e.info.box_min;
  if (e.payload_size == 0) return out;
  thread_local std::vector<uint8_t> bytes;
  bytes.resize(e.payload_size);
  const std::string what = m.name + ": node " + std::to_string(id) + " (level " +
                           std::to_string(e.info.level) + ", payload at byte " +
                           std::to_string(e.payload_offset) + ")";
  if (!m.readChecked(
          e.payload_offset, bytes.data(), bytes.size(), "a chunk payload",
          [&] { return crc32c(bytes.data(), bytes.size()) == e.crc; }, cancel)) {
    throw StoreError("lod::PointStore: " + what + ": corrupt chunk (checksum mismatch); skipped");
  }
  lod::decodeChunk(bytes, e.info.box_min, *out, what, with_cells);
  if (out->size() != e.info.points)
    throw StoreError("lod::PointStore: " + what + ": point count differs from the hierarchy");
  return out;
}

std::shared_ptr<const ChunkPoints> PointStore::loadChunk(NodeId id) {
  Impl& m = *mImpl;
  {
    std::lock_guard lock(m.cache_mutex);
    auto it = m.cache.find(id);
    if (it != m.cache.end()) {
      m.lru.splice(m.lru.begin(), m.lru, it->second.lru);
      ++m.stats.hits;
      return it->second.points;
    }
    ++m.stats.misses;
  }
  std::shared_ptr<const ChunkPoints> points;
  try {
    points = decodeChunk(id);
  } catch (const StoreError&) {
    std::lock_guard lock(m.cache_mutex);
    ++m.stats.corrupt;
    throw;
  }
  std::lock_guard lock(m.cache_mutex);
  auto it = m.cache.find(id);
  if (it != m.cache.end()) return it->second.points;  // another thread decoded it meanwhile
  m.lru.push_front(id);
  uint64_t bytes = points->byteSize();
  m.cache.emplace(id, Impl::Cached{points, m.lru.begin(), bytes});
  m.stats.bytes += bytes;
  while (m.stats.bytes > m.stats.budget && m.lru.size() > 1) {
    NodeId victim = m.lru.back();
    m.lru.pop_back();
    auto v = m.cache.find(victim);
    m.stats.bytes -= v->second.bytes;
    m.cache.erase(v);
    ++m.stats.evictions;
  }
  return points;
}

CacheStats PointStore::cacheStats() const {
  std::lock_guard lock(mImpl->cache_mutex);
  return mImpl->stats;
}

}  // namespace tessera::lod
