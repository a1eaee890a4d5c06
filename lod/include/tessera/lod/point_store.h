// Read-only access to a .tlod point store (see store_format.h): the node hierarchy, loaded
// lazily page by page, and decoded chunks through a thread-safe LRU cache with a byte budget.
// This is what render nodes use to pick and stream the cut their tile needs.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <stdexcept>
#include <stop_token>
#include <string>
#include <vector>

#include <tessera/lod/lod_hierarchy.h>
#include <tessera/lod/point_batch.h>
#include <tessera/lod/range_source.h>

namespace tessera::lod {

/// A store that cannot be opened or a chunk that cannot be used (corrupt, truncated, newer
/// format). The message names the file and what is wrong.
class StoreError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Decoded points of one node. Positions are floats relative to `offset` (the node box minimum
/// in the store's local frame), so precision does not depend on where the data lies on Earth:
/// local = offset + position, world = store origin + local.
struct ChunkPoints {
  /// kColor, kIntensity, kScanIndex (= source id), kClassification, kAmbientOcclusion
  AttributeMask attributes = 0;
  glm::dvec3 offset{0.0};
  double step = 0.0;  ///< quantisation step
  /// Position of cell 0 relative to `offset` (each axis in [-step, 0]): every position is
  /// grid + cell * step with whole cells, and offset + grid + cell * step (in double) is the
  /// stored point exactly, at the input's own resolution where the store keeps it.
  glm::dvec3 grid{0.0};
  /// Each point's cell (whole steps from grid), exact where the float positions round:
  /// filled only when asked for (PointStore::decodeChunk(id, cancel, true)), else empty.
  std::vector<glm::uvec3> cells;
  std::vector<glm::vec3> positions;
  std::vector<glm::u8vec4> colors;
  std::vector<uint16_t> intensities;
  std::vector<uint16_t> sources;  ///< index into PointStore::sources()
  std::vector<uint8_t> classifications;
  /// kAmbientOcclusion: per point its ambient-occlusion visibility, 0 (occluded) .. 255 (open),
  /// i.e. v / 255 of lod/ambient_occlusion.h; empty without it.
  std::vector<uint8_t> ambient_occlusion;

  size_t size() const { return positions.size(); }
  size_t byteSize() const;
};

struct StoreSummary {
  uint32_t version = 0;
  glm::dvec3 origin{0.0};
  glm::dvec3 bbox_min{0.0}, bbox_max{0.0};  ///< local frame
  double cube_size = 0.0;
  uint64_t points = 0;         ///< input points (each in exactly one leaf)
  uint64_t stored_points = 0;  ///< over all nodes, inner copies included
  uint64_t nodes = 0;
  uint32_t depth = 0;
  AttributeMask attributes = 0;
  uint64_t file_bytes = 0;
  uint64_t payload_bytes = 0;
  uint64_t position_color_bytes = 0;
  double spacing_root = 0.0, spacing_finest = 0.0;
  double input_precision = 0.0;
  /// Every leaf keeps the input's own integers at input_precision (store::kExactLeaves):
  /// a leaf point is offset + grid + cell * step exactly (ChunkPoints::grid).
  bool exact_leaves = false;
};

struct CacheStats {
  uint64_t hits = 0, misses = 0, evictions = 0;
  uint64_t bytes = 0, budget = 0;
  uint64_t corrupt = 0;  ///< chunks refused because their checksum or decoding failed
  /// Hierarchy pages refused (checksum, header, node keys): the nodes below them are missing
  /// from children(), so whoever draws should say so.
  uint64_t corrupt_pages = 0;
};

/// The point LOD hierarchy (lod_hierarchy.h): nodes are point chunks, spacing their mean
/// sample distance.
class PointStore : public LodHierarchy {
 public:
  /// Opens the store: reads and checks the header and the root hierarchy page only (fast for
  /// any size). `cache_bytes` bounds the decoded chunks kept in memory. Throws StoreError.
  static std::unique_ptr<PointStore> open(const std::filesystem::path& path,
                                          uint64_t cache_bytes = 512ull << 20);
  /// The same over any source of the store's bytes (range_source.h: a file, or ranges fetched
  /// from a chunk server); path() is the source's name. Every read is one byte range checked
  /// by its CRC-32C; one that fails it is read once more when the source can fetch it again
  /// (RangeSource::refetch()). A read that fails (RangeError) is a StoreError naming the
  /// store and what was read. Throws StoreError.
  static std::unique_ptr<PointStore> open(std::unique_ptr<RangeSource> source,
                                          uint64_t cache_bytes = 512ull << 20);
  ~PointStore() override;

  const StoreSummary& summary() const { return mSummary; }
  const std::vector<std::string>& sources() const { return mSources; }
  const std::filesystem::path& path() const override { return mPath; }

  NodeId root() const override { return 0; }
  /// Node metadata. Thread-safe. Copies, because loading pages may grow the table.
  NodeInfo node(NodeId id) const override;
  /// Children of a node (loads their hierarchy page on first use; may throw StoreError for a
  /// corrupt page, counted once per page in cacheStats().corrupt_pages). Thread-safe.
  std::vector<NodeId> children(NodeId id) override;
  /// Whether the children of `id` are already in memory (no I/O needed to list them).
  bool childrenLoaded(NodeId id) const override;
  /// Number of nodes whose metadata is in memory.
  size_t loadedNodes() const;

  /// Decoded points of a node, from the cache or the file. Thread-safe; concurrent loads of
  /// different nodes proceed in parallel. Throws StoreError for a corrupt chunk (checksum
  /// mismatch or bad encoding): such a chunk is never returned as garbage.
  std::shared_ptr<const ChunkPoints> loadChunk(NodeId id);
  /// Like loadChunk but bypassing the cache (verification, benchmarks, the chunk streamer).
  /// When `cancel` is stopped while its bytes are read from a slow source (range_source.h),
  /// throws lod::ReadCancelled, not StoreError.
  /// `with_cells`: also fill ChunkPoints::cells (verification).
  std::shared_ptr<ChunkPoints> decodeChunk(NodeId id, std::stop_token cancel = {},
                                           bool with_cells = false) const;
  /// Compressed bytes of a node's chunk on disk.
  uint32_t chunkBytes(NodeId id) const override;

  CacheStats cacheStats() const;

 private:
  struct Impl;
  PointStore() = default;
  std::filesystem::path mPath;
  StoreSummary mSummary;
  std::vector<std::string> mSources;
  std::unique_ptr<Impl> mImpl;
};

}  // namespace tessera::lod
