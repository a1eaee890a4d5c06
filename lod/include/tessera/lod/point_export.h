// Export: the points of a scan or a store, whole or cut by a box or planes, as LAS, LAZ or PLY
// for another program. What a conservator does first after looking: cut out a region and hand
// it on.
//
//  - LAS or LAZ in, LAS or LAZ out: the input's records are copied as they are (every attribute,
//    its scale and offset, its VLRs and EVLRs, its CRS); only the records outside the cut are
//    left out and the header's counts and bounds recomputed.
//  - Any other scan (PLY, E57, .conf, XYZ, OBJ) or a .tlod store: LAS 1.4 point format 7
//    (format 6 without colour) with the positions in double precision quantised to the input's
//    own precision when it declares one (a store: its leaves' step), else 0.1 mm; intensity,
//    classification and colour where the input has them. A store gives its leaves: every input
//    point once, at the positions the store keeps (the input's own coordinates where its
//    leaves are exact, the default; else within the error bound the store states).
//  - PLY out: binary, positions as doubles, the attributes PLY holds.
// The output is written to a temporary file and renamed: a failed export leaves nothing.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/lod/lod_hierarchy.h>

namespace tessera::lod {

struct ExportOptions {
  /// Keep points inside this box (world coordinates, bounds included).
  std::optional<std::pair<glm::dvec3, glm::dvec3>> box;
  /// Keep points with dot(plane.xyz, p) + plane.w >= 0 for every plane (world coordinates).
  std::vector<glm::dvec4> planes;
  /// Coordinate resolution of converted points (0: the input's own precision, else 0.1 mm).
  /// Records copied from LAS or LAZ keep their file's scale.
  double scale = 0.0;
  unsigned threads = 0;  ///< LAZ chunks decoded or encoded at once (0: one per core)
  bool quiet = true;     ///< no progress bar
  /// A store input only: the leaves to read (a selection's nodes) instead of every leaf, which
  /// of a leaf's points (by index in its decoded chunk) to keep, and how many points each leaf
  /// had when the selection was made. A leaf this store does not have, or one of another size,
  /// is a ReadError: the selection was made on another store.
  std::optional<std::vector<NodeId>> leaves;
  std::function<bool(NodeId leaf, uint32_t index)> keep_element;
  std::function<uint32_t(NodeId leaf)> leaf_size;
};

struct ExportReport {
  uint64_t read = 0;     ///< points looked at
  uint64_t written = 0;  ///< points written
  std::string method;    ///< "records copied", "points converted to LAS 1.4 format 7", ...
};

/// Writes the points of `input` kept by `options` to `output` (.las, .laz or .ply). Throws
/// ReadError for a bad input, StoreError for a bad store, WriteError when writing fails or the
/// output cannot hold the input (waveform packets, coordinates beyond the LAS range).
ExportReport exportPoints(const std::filesystem::path& input, const std::filesystem::path& output,
                          const ExportOptions& options = {});

}  // namespace tessera::lod
