// The body of the .tmesh fuzz target and its regression replay: bytes read as a .tmesh mesh
// store (lod/mesh_store.h). Every structure of the format is checksummed, so the header's, the
// node table's and every payload's CRC are made right first (the byte offsets of
// lod/src/mesh_format.h) and mutations reach the header checks, the tree checks of the node
// table and the patch decoder behind them. Every patch is decoded and its geomorphing targets
// computed (which decodes its parent too).
//
// StoreError is the only failure allowed; a broken invariant aborts (fuzz_reader.h).
#pragma once

#include <cmath>
#include <cstring>
#include <vector>

#include <tessera/lod/mesh_store.h>

#include "../lod/src/crc32c.h"
#include "../lod/src/mesh_format.h"
#include "fuzz_reader.h"

namespace tessera::fuzz {

class MeshMemorySource final : public lod::RangeSource {
 public:
  explicit MeshMemorySource(std::vector<uint8_t> bytes) : mBytes(std::move(bytes)) {}
  uint64_t size() const override { return mBytes.size(); }
  std::string name() const override { return "fuzz.tmesh"; }

 private:
  void readRange(uint64_t offset, void* dst, size_t n, std::stop_token) const override {
    if (n > 0) std::memcpy(dst, mBytes.data() + offset, n);
  }
  std::vector<uint8_t> mBytes;
};

template <class T>
T loadField(const std::vector<uint8_t>& f, size_t at) {
  T v{};
  std::memcpy(&v, f.data() + at, sizeof v);
  return v;
}
template <class T>
void storeField(std::vector<uint8_t>& f, size_t at, T v) {
  std::memcpy(f.data() + at, &v, sizeof v);
}

/// Header fields (mesh_format.h): nodes at 44, table offset at 128, file bytes at 136, table CRC
/// at 144, header CRC at 148. Node records: payload offset at 56, bytes at 64, CRC at 68.
inline void fixMeshChecksums(std::vector<uint8_t>& f) {
  namespace fmt = lod::meshfmt;
  if (f.size() < fmt::kHeaderBytes) return;
  storeField<uint64_t>(f, 136, f.size());
  const uint32_t nodes = loadField<uint32_t>(f, 44);
  const uint64_t table = loadField<uint64_t>(f, 128);
  if (nodes <= fmt::kMaxNodes && table <= f.size() &&
      uint64_t(nodes) * fmt::kNodeBytes <= f.size() - table) {
    for (uint32_t i = 0; i < nodes; ++i) {
      const size_t rec = size_t(table) + size_t(i) * fmt::kNodeBytes;
      const uint64_t off = loadField<uint64_t>(f, rec + 56);
      const uint32_t bytes = loadField<uint32_t>(f, rec + 64);
      if (off <= f.size() && bytes <= f.size() - off)
        storeField<uint32_t>(f, rec + 68, lod::crc32c(f.data() + off, bytes));
    }
    storeField<uint32_t>(f, 144, lod::crc32c(f.data() + table, size_t(nodes) * fmt::kNodeBytes));
  }
  storeField<uint32_t>(f, 148, lod::crc32c(f.data(), 148));
}

/// Opens `data` as a mesh store (checksums fixed) and decodes every patch.
inline int readMeshStore(const uint8_t* data, size_t size) {
  std::vector<uint8_t> bytes(data, data + size);
  fixMeshChecksums(bytes);
  std::unique_ptr<lod::MeshStore> s;
  try {
    s = lod::MeshStore::open(std::make_unique<MeshMemorySource>(std::move(bytes)));
  } catch (const lod::StoreError&) {
    return 0;
  }
  for (lod::NodeId id = 0; id < s->nodeCount() && id < 256; ++id) {
    require(s->node(id).box_min.x == s->node(id).box_min.x, "NaN box");
    for (lod::NodeId c : s->children(id)) require(c < s->nodeCount(), "child beyond the table");
    try {
      const lod::MeshPatch p = s->readPatch(id);
      for (uint32_t i : p.indices) require(i < p.positions.size(), "index beyond the vertices");
      require(p.normals.size() == p.positions.size(), "normals.size()");
      const auto m = s->morphTargets(id, p);
      require(m.positions.size() == p.positions.size(), "morph targets' size");
    } catch (const lod::StoreError&) {
    }
  }
  return 0;
}

}  // namespace tessera::fuzz
