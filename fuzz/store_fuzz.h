// The bodies of the .tlod fuzz targets and their regression replay.
//
// readStore(): the bytes are a whole store file. Every structure of the format is checksummed,
// so random mutations would only ever exercise the checksum tests; fixChecksums() first makes
// the header's, the reachable pages' and their chunks' CRCs right, so mutations reach the
// header checks, the hierarchy pages (node keys, parents, children, page links) and the chunk
// decoder behind them. The store is opened from a memfd as a user's file would be, every page
// reachable is loaded and every node's chunk decoded.
//
// decodeChunkBytes(): the bytes are one node's payload, straight into the chunk decoder.
//
// StoreError is the only failure allowed; a broken invariant aborts (fuzz_reader.h).
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <set>
#include <string>
#include <vector>

#include <tessera/lod/point_store.h>
#include <tessera/lod/store_format.h>

#include "../lod/src/chunk_codec.h"
#include "../lod/src/crc32c.h"
#include "fuzz_reader.h"

namespace tessera::fuzz {

/// Checks a decoded chunk against what ChunkPoints promises.
inline void checkChunk(const lod::ChunkPoints& c) {
  using namespace tessera::lod;
  const size_t n = c.size();
  require(!(c.attributes & kColor) || c.colors.size() == n, "colors.size() != size()");
  require(!(c.attributes & kIntensity) || c.intensities.size() == n, "intensities.size()");
  require(!(c.attributes & kScanIndex) || c.sources.size() == n, "sources.size()");
  require(!(c.attributes & kClassification) || c.classifications.size() == n,
          "classifications.size()");
  require((c.attributes & kAmbientOcclusion) ? c.ambient_occlusion.size() == n
                                             : c.ambient_occlusion.empty(),
          "ambient_occlusion.size()");
  for (const glm::vec3& p : c.positions)
    require(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z),
            "non-finite decoded position");
}

/// Makes the CRCs of `file` right: the header's, the source table's, and for each page
/// reachable from the root page (at most 64) the page's and its nodes' payloads' where they
/// lie inside the file.
inline void fixChecksums(std::vector<uint8_t>& file) {
  using namespace tessera::lod::store;
  if (file.size() < sizeof(FileHeader)) return;
  FileHeader h;
  std::memcpy(&h, file.data(), sizeof h);
  std::vector<std::pair<uint64_t, uint32_t>> pages{{h.root_page_offset, h.root_page_size}};
  std::set<uint64_t> seen;
  while (!pages.empty() && seen.size() < 64) {
    const uint64_t off = pages.back().first;
    pages.pop_back();
    if (!seen.insert(off).second) continue;
    if (off > file.size() || sizeof(PageHeader) > file.size() - off) continue;
    PageHeader ph;
    std::memcpy(&ph, file.data() + off, sizeof ph);
    const uint64_t room = (file.size() - off - sizeof ph) / sizeof(NodeRecord);
    if (ph.nodes > room) continue;
    uint8_t* recs = file.data() + off + sizeof ph;
    for (uint64_t i = 0; i < ph.nodes; ++i) {
      NodeRecord r;
      std::memcpy(&r, recs + i * sizeof r, sizeof r);
      if (r.payload_offset <= file.size() && r.payload_size <= file.size() - r.payload_offset)
        r.payload_crc = lod::crc32c(file.data() + r.payload_offset, r.payload_size);
      std::memcpy(recs + i * sizeof r, &r, sizeof r);
      if (r.flags & kHasPage) pages.emplace_back(r.page_offset, r.page_size);
    }
    ph.crc = lod::crc32c(recs, ph.nodes * sizeof(NodeRecord));
    std::memcpy(file.data() + off, &ph, sizeof ph);
  }
  if (h.source_table_offset <= file.size() &&
      h.source_table_size <= file.size() - h.source_table_offset)
    h.source_table_crc = lod::crc32c(file.data() + h.source_table_offset, h.source_table_size);
  h.header_crc = 0;
  h.header_crc = lod::crc32c(&h, sizeof h);
  std::memcpy(file.data(), &h, sizeof h);
}

/// Opens `data` (checksums fixed) as a store and walks it: at most 4096 nodes.
inline int readStore(const uint8_t* data, size_t size) {
  using namespace tessera::lod;
  std::vector<uint8_t> file(data, data + size);
  fixChecksums(file);
  const int fd = ::memfd_create("tlod-fuzz", MFD_CLOEXEC);
  require(fd >= 0, "memfd_create failed");
  for (size_t done = 0; done < file.size();) {
    const ssize_t n = ::write(fd, file.data() + done, file.size() - done);
    require(n > 0, "writing the memfd failed");
    done += size_t(n);
  }
  try {
    auto store = PointStore::open("/proc/self/fd/" + std::to_string(fd), 16u << 20);
    std::vector<NodeId> todo{store->root()};
    for (size_t visited = 0; !todo.empty() && visited < 4096; ++visited) {
      const NodeId id = todo.back();
      todo.pop_back();
      const NodeInfo info = store->node(id);
      require(info.level <= store::kMaxLevel, "node deeper than kMaxLevel");
      try {
        const auto points = store->loadChunk(id);
        require(points->size() == info.points, "chunk size differs from the node's count");
        checkChunk(*points);
      } catch (const StoreError&) {
      }
      try {
        for (NodeId c : store->children(id)) {
          require(store->node(c).level == info.level + 1, "a child not one level down");
          todo.push_back(c);
        }
      } catch (const StoreError&) {
      }
    }
  } catch (const StoreError&) {
  }
  ::close(fd);
  return 0;
}

/// Decodes `data` as one chunk payload of a node at the origin, with its cells (either chunk
/// format: byte 25 tells them apart).
inline int decodeChunkBytes(const uint8_t* data, size_t size) {
  lod::ChunkPoints out;
  try {
    lod::decodeChunk(std::span<const uint8_t>(data, size), glm::dvec3(0.0), out, "fuzz chunk",
                     true);
    checkChunk(out);
    require(out.cells.size() == out.size(), "cells.size() != size()");
    for (double g : {out.grid.x, out.grid.y, out.grid.z})
      require(g <= 0.0 && g >= -out.step, "grid origin outside its step");
  } catch (const lod::StoreError&) {
  }
  return 0;
}

}  // namespace tessera::fuzz
