// What `tessera-lod info` says about an input: format, counts, bounds, attributes, skips, scans;
// for a point store (.tlod) or a mesh store (.tmesh), what its header and node table say.
#pragma once

#include <filesystem>
#include <string>

#include <optional>

#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_store.h>

namespace tessera::lod {

struct SourceSummary {
  std::string path;
  SourceInfo info;
  ReadStats stats;           ///< points/triangles actually read, skips by reason
  glm::dvec3 bbox_min{0.0};  ///< file coordinates (world = origin + local), double
  glm::dvec3 bbox_max{0.0};
  std::string error;    ///< empty when the whole file read cleanly
  bool opened = false;  ///< header parsed (info valid)
  /// Set for a .tlod point store (then `info` is unused).
  std::optional<StoreSummary> store;
  std::vector<std::string> store_sources;
  /// Set for a .tmesh mesh store (then `info` is unused), with its patches by depth.
  std::optional<MeshSummary> mesh_store;
  struct MeshLevel {
    uint64_t patches = 0;
    uint64_t triangles = 0;
    double max_error = 0.0;  ///< the largest simplification error a patch states, store units
  };
  std::vector<MeshLevel> mesh_levels;  ///< index: depth (0 the root)
};

/// Reads the whole of `path` once (streaming) to count points and bound them; of a store, only
/// its header and node table. Never throws for bad input: a ReadError or StoreError lands in
/// `error` with whatever was read before it.
/// `quiet` silences the progress bar shown for large inputs on a terminal.
SourceSummary summarizeSource(const std::filesystem::path& path, bool quiet = false);

/// Human-readable block, one `key: value` per line; a mesh store, its summary line by line and
/// one line per depth.
std::string summaryText(const SourceSummary& s);
/// One JSON object with keys format, points, triangles, bbox_min, bbox_max, attributes, skipped,
/// scans (and file, format_detail, declared_points, error when set). A point store adds version,
/// origin, nodes, depth, bytes_per_point, spacing_root, spacing_finest, stored_points, overhead,
/// position_color_bytes_per_point, exact_leaves, input_precision and sources. A mesh store ("format": "tmesh"; points are its
/// input vertices, triangles its input triangles) adds version, vertices, origin, size, nodes,
/// depth, stored_triangles, overhead, grid_step, file_bytes, bytes_per_triangle and levels (per
/// depth: patches, triangles, max_error).
std::string summaryJson(const SourceSummary& s);

}  // namespace tessera::lod
