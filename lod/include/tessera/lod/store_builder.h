// Builds a .tlod point store out of core from any readable inputs (store_format.h describes the
// result). Input streams through; peak memory stays within BuildOptions::memory_mb plus a small
// constant whatever the input size; every core is used for the per-chunk work.
//
// Passes: (1) inputs parsed once into fixed-size records, bounds and counts; (2) a 128^3 counting
// grid; chunking: octree cells holding at most what fits in memory; (3) distribution of the points
// into one temporary file, each chunk contiguous; (4) per chunk, in parallel: the subtree,
// grid-sampled top-down, each node encoded; (5) levels above the chunks, sampled bottom-up from the
// chunk roots; (6) payload copied in (level, Morton) order, hierarchy pages, header; the file is
// renamed into place at the end. Inputs that state their bounding box (LAS, LAZ) fold (2) and (3)
// into (1): the cube is known before reading, so reading counts the grid and writes each point
// into its spatial bucket, and (4) reads each bucket once (point_distributor.h).
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include <tessera/lod/point_store.h>

namespace tessera::lod {

/// Most threads a build, a verify or a virtual scan takes (BuildOptions::threads,
/// ScanOptions::threads): more only cost memory and thread stacks.
constexpr int kMaxThreads = 256;

struct BuildOptions {
  uint64_t memory_mb = 2048;
  int threads = 0;     ///< 0: every core; at most kMaxThreads
  bool quiet = false;  ///< no progress output
  int zstd_level = 5;
  uint32_t leaf_max = 16384;  ///< nodes with at most this many points stay leaves
  /// Leaves keep the input's own resolution (its declared precision, e.g. a LAS scale factor,
  /// their cells the input's own integers; a 1024th of the leaf spacing when it declares none)
  /// for measurement-grade picks (interact/surface_pick.h). false (`--lossy`): a quarter of
  /// their spacing (Euclidean), a smaller store.
  bool exact_leaves = true;
  /// Points per out-of-core chunk; 0 derives it from memory_mb (tests force small chunks).
  uint64_t chunk_points = 0;
  /// Temporary files go here (default: beside the output). Needs up to 80 bytes per point.
  std::filesystem::path temp_dir;
  /// Per input point, in the order the readers deliver them (inputs in turn; what
  /// lod::loadScans() lists), its ambient-occlusion byte (ambient_occlusion.h): the store then
  /// carries kAmbientOcclusion (format version 3). Empty: none. A count that differs from the
  /// points read is a ReadError. The caller keeps the bytes alive during the build.
  std::span<const uint8_t> ambient_occlusion;
  /// Temporary points bypass the page cache (O_DIRECT) on the route that reads the inputs once
  /// (LAS and LAZ through their reader): 1 always, 0 never, -1 when they would take more than
  /// half the machine's memory (the cache could not hold them, and moving them through it costs
  /// more than the build's own work on them). File systems without direct I/O go through it.
  int direct_io = -1;
};

struct BuildReport {
  uint64_t points = 0;
  uint64_t skipped = 0;  ///< input points skipped by the readers (non-finite, ...)
  uint64_t nodes = 0;
  uint64_t stored_points = 0;  ///< over all nodes: stored_points / points is the overhead
  uint32_t depth = 0;
  uint64_t chunks = 0;  ///< out-of-core work units
  uint64_t file_bytes = 0;
  uint64_t position_color_bytes = 0;
  double seconds = 0.0;
  double seconds_read = 0.0;     ///< passes 1-3 (reading and distributing)
  double seconds_process = 0.0;  ///< chunk and upper-level work
  double seconds_write = 0.0;
  double max_error = 0.0;  ///< largest quantisation error of any stored point
  size_t temp_record_bytes = 0;  ///< bytes a point in the temporary files (21 compact, 40 wide)
  /// The inputs went the bucketed route (point_distributor.h): one pass over them counted and
  /// bucketed every point in the cube of their header boxes.
  bool bucketed = false;
};

/// Builds `output` from `inputs`. Throws ReadError for bad input, StoreError for failures writing
/// (disk full, ...) and, before anything is written, when `output` is one of the files read
/// (filesRead(), by any path). On any failure the output path is left untouched (no half file).
/// PreconditionError: options.threads outside [0, kMaxThreads].
BuildReport buildStore(const std::vector<std::filesystem::path>& inputs,
                       const std::filesystem::path& output, const BuildOptions& options = {});

struct VerifyReport {
  uint64_t input_points = 0;
  uint64_t store_points = 0;
  uint64_t matched = 0;
  uint64_t unmatched = 0;        ///< input points with no stored point within the bound
  double max_error = 0.0;        ///< largest distance input point -> its stored point
  double max_error_ratio = 0.0;  ///< largest (distance / node error bound)
  uint64_t corrupt_chunks = 0;
  uint64_t stray_points = 0;  ///< inner-node points outside their node box
  /// The store says its leaves keep the input's integers (StoreSummary::exact_leaves); then
  /// every input point must be stored at exactly its own integer coordinates.
  bool exact_store = false;
  uint64_t exact = 0;  ///< matched points stored at the input's own integers (exact stores)
  bool ok() const {
    return unmatched == 0 && input_points == store_points && corrupt_chunks == 0 &&
           stray_points == 0 && (!exact_store || exact == input_points);
  }
};

/// Checks that every input point is in the store within its node's error bound (one-to-one),
/// and that the counts match. Out of core like the build (memory_mb bounds the work).
VerifyReport verifyStore(const std::filesystem::path& store,
                         const std::vector<std::filesystem::path>& inputs,
                         const BuildOptions& options = {});

}  // namespace tessera::lod
