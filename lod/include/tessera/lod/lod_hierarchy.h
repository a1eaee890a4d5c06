// A multiresolution hierarchy as a view cuts and streams it (Bettio et al. 2009, section 4.1):
// the point store's octree (point_store.h) and the mesh patch hierarchy (mesh_store.h). The cut
// selection (render/lod_selector.h) and the chunk streamer's hierarchy paging and bookkeeping
// (render/chunk_streamer.h) see only this interface, so a second kind of hierarchy needs no
// second copy of them: only its payload's decoding.
//
// Contract: nodes are self-contained (one node's payload draws on its own, so a cut is drawn
// from its nodes only); a node's spacing is the distance below which its samples do not resolve
// detail (points: the mean sample spacing; meshes: the geometric error), in local units; the
// children's metadata may live in pages read on demand (children() may do I/O,
// childrenLoaded() says whether it would). Implementations are thread-safe.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include <glm/glm.hpp>

namespace tessera::lod {

using NodeId = uint32_t;
constexpr NodeId kNoNode = ~NodeId(0);

/// One node's metadata.
struct NodeInfo {
  uint8_t level = 0;
  glm::u32vec3 cell{0};     ///< octree cell at `level`
  glm::dvec3 box_min{0.0};  ///< local frame
  glm::dvec3 box_max{0.0};
  uint32_t points = 0;
  float spacing = 0.f;      ///< mean distance between this node's samples
  float error_bound = 0.f;  ///< max stored-position error
  uint8_t child_mask = 0;
  bool leaf() const { return child_mask == 0; }
};

class LodHierarchy {
 public:
  virtual ~LodHierarchy() = default;
  /// The file it reads (for messages).
  virtual const std::filesystem::path& path() const = 0;
  virtual NodeId root() const = 0;
  /// Node metadata (a copy: loading pages may grow the table).
  virtual NodeInfo node(NodeId id) const = 0;
  /// A node's children; reads their page on first use (may throw the store's error type).
  virtual std::vector<NodeId> children(NodeId id) = 0;
  /// Whether children() would answer without I/O.
  virtual bool childrenLoaded(NodeId id) const = 0;
  /// The node's payload size on disk, bytes (what streaming it costs).
  virtual uint32_t chunkBytes(NodeId id) const = 0;
};

}  // namespace tessera::lod
