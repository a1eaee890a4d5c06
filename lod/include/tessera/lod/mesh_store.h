// Read-only access to a .tmesh mesh store ("Meshes"): a patch hierarchy after the
// patch-LOD thesis (../shared/papers/patch-lod-annotation-thesis.txt, chapter 3). The leaves are
// METIS patches of the input mesh at full resolution; each inner node is its children merged and
// simplified with the borders it shares with the rest of the mesh locked, so any cut of the tree
// is a crack-free surface (the thesis' Figure 3.4): every patch border is made of input edges.
//
// A node's `spacing` (lod_hierarchy.h) is its geometric error: an upper bound, in store units,
// on the distance from the input surface it stands for to its own triangles (measured at build
// time, never below its children's). Its `points` is its triangle count. The whole node table
// is read on open (80 bytes a node: 10^8 triangles make about 40 000 nodes), so children() never
// does I/O. Payloads are read on demand, checked against their CRC-32C, then decoded.
//
// File layout (little-endian; mesh_store.cpp has the byte offsets):
//   header (128 bytes, its own CRC) | node table (its own CRC) | payloads, depth-first
// A payload is meshoptimizer's vertex codec over quantised vertices (8 or 16 bytes, plus 4 for
// colour) followed by its index codec. Positions sit on one grid for the whole store (`step`
// units from bbox_min), so a vertex shared by neighbouring patches decodes to the same float in
// both and no sub-pixel crack opens between them.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <stop_token>
#include <vector>

#include <tessera/lod/lod_hierarchy.h>
#include <tessera/lod/point_store.h>  // StoreError
#include <tessera/lod/range_source.h>

namespace tessera::lod {

/// One decoded patch: positions relative to `offset` (store-local frame: local = offset +
/// position, world = origin + local), a unit normal and an rgba per vertex (rgba 255 grey when
/// the store has no colour), and triangles as vertex indices.
struct MeshPatch {
  glm::dvec3 offset{0.0};
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<glm::u8vec4> colors;  ///< empty when the store has no colour
  std::vector<uint32_t> indices;    ///< 3 per triangle
  /// Per vertex, the store's integer grid coordinates (position = bbox_min + grid * step,
  /// exactly): what the verifier compares.
  std::vector<glm::i32vec3> grid;
  size_t triangles() const { return indices.size() / 3; }
};

struct MeshSummary {
  uint32_t version = 0;
  glm::dvec3 origin{0.0};
  glm::dvec3 bbox_min{0.0}, bbox_max{0.0};  ///< local frame
  double step = 0.0;                        ///< quantisation grid, store units
  uint64_t input_triangles = 0;             ///< the leaves hold each once
  uint64_t input_vertices = 0;
  uint64_t stored_triangles = 0;  ///< over all nodes
  uint64_t nodes = 0;
  uint32_t depth = 0;
  bool colors = false;
  uint64_t file_bytes = 0;
  uint64_t payload_bytes = 0;
};

/// What one node of the table holds besides NodeInfo.
struct MeshNodeRecord {
  glm::vec3 box_min{0.0f}, box_max{0.0f};  ///< local frame
  float error = 0.0f;
  uint32_t triangles = 0, vertices = 0;
  uint32_t first_child = 0;
  uint8_t child_count = 0, level = 0, wide = 0;  ///< wide: 32-bit grid offsets (else 16-bit)
  glm::i32vec3 grid_base{0};                      ///< the patch's lowest grid coordinates
  uint64_t payload_offset = 0;
  uint32_t payload_bytes = 0, payload_crc = 0;
};

class MeshStore : public LodHierarchy {
 public:
  /// Opens a store: reads and checks the header and the node table. Throws StoreError naming
  /// the file and what is wrong (not a mesh store, newer version, truncated, checksum, a table
  /// that is not a tree).
  static std::unique_ptr<MeshStore> open(const std::filesystem::path& path);
  /// The same over any source of the store's bytes (range_source.h).
  static std::unique_ptr<MeshStore> open(std::unique_ptr<RangeSource> source);
  ~MeshStore() override;

  const std::filesystem::path& path() const override { return mPath; }
  NodeId root() const override { return 0; }
  NodeInfo node(NodeId id) const override;
  std::vector<NodeId> children(NodeId id) override;
  bool childrenLoaded(NodeId) const override { return true; }
  uint32_t chunkBytes(NodeId id) const override { return mNodes.at(id).payload_bytes; }

  const MeshSummary& summary() const { return mSummary; }
  const MeshNodeRecord& record(NodeId id) const { return mNodes.at(id); }
  size_t nodeCount() const { return mNodes.size(); }

  /// Reads, checks and decodes one patch. Thread-safe (positional reads). Throws StoreError
  /// naming the node when its bytes fail their CRC or do not decode to what the table says.
  /// Cost: one read of chunkBytes(id) and about 1 ms per 10^4 triangles to decode. A stopped
  /// `cancel` gives up a slow read with lod::ReadCancelled (range_source.h).
  MeshPatch readPatch(NodeId id, std::stop_token cancel = {}) const;
  /// The node's parent (kNoNode for the root).
  NodeId parent(NodeId id) const { return mParents.at(id); }
  /// Geomorphing targets of a decoded patch: for each vertex, the nearest point of its parent's
  /// surface (in the patch's frame) and the parent's normal there, where the vertex sits while
  /// the patch replaces its parent (render/mesh_pass.h). Border vertices are the parent's own
  /// (locked), so they stay and no crack opens while a patch morphs. The root's targets are its
  /// own. Reads and decodes the parent: about twice readPatch()'s cost.
  struct MorphTargets {
    std::vector<glm::vec3> positions, normals;
  };
  MorphTargets morphTargets(NodeId id, const MeshPatch& patch, std::stop_token cancel = {}) const;

 private:
  MeshStore() = default;
  std::filesystem::path mPath;
  std::unique_ptr<RangeSource> mSource;
  MeshSummary mSummary;
  std::vector<MeshNodeRecord> mNodes;
  std::vector<NodeId> mParents;
};

/// Whether a regular file starts like a mesh store (its magic), without opening it further;
/// false for anything else (FIFOs and devices are not opened).
bool isMeshStore(const std::filesystem::path& path);

}  // namespace tessera::lod
