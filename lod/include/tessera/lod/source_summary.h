// What `tessera-lod info` says about an input: format, counts, bounds, attributes, skips, scans.
#pragma once

#include <filesystem>
#include <string>

#include <optional>

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
};

/// Reads the whole of `path` once (streaming) to count points and bound them. Never throws for
/// bad input: a ReadError lands in `error` with whatever was read before it.
/// `quiet` silences the progress bar shown for large inputs on a terminal.
SourceSummary summarizeSource(const std::filesystem::path& path, bool quiet = false);

/// Human-readable block, one `key: value` per line.
std::string summaryText(const SourceSummary& s);
/// One JSON object with keys format, points, triangles, bbox_min, bbox_max, attributes, skipped,
/// scans (and file, format_detail, declared_points, error when set). A store adds nodes, depth,
/// bytes_per_point, spacing_root, spacing_finest, stored_points, overhead,
/// position_color_bytes_per_point and sources.
std::string summaryJson(const SourceSummary& s);

}  // namespace tessera::lod
