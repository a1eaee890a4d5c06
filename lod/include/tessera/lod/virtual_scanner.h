// A virtual laser scanner: ray-casts a mesh (Embree) from K scanner poses and writes range scans
// plus a `.conf` in the Stanford 3D Scanning Repository's format, so the .conf reader loads the
// result like the real bunny scans. Deterministic for a seed, whatever the thread count.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include <tessera/lod/mesh.h>
#include <tessera/lod/point_reader.h>

namespace tessera::lod {

/// Most threads a scan takes (ScanOptions::threads).
constexpr int kMaxScanThreads = 256;

struct ScanOptions {
  int scanners = 8;        ///< number of scanner poses
  uint32_t columns = 512;  ///< range-grid width (rays per row)
  uint32_t rows = 400;     ///< range-grid height
  /// false: scanners on a sphere around the model looking at its centre (perspective grid);
  /// true: scanners inside the model's box, each a full 360 x 150 degree panorama.
  bool panoramic = false;
  double noise_mm = 0.0;        ///< Gaussian range noise, standard deviation in millimetres
  double units_per_mm = 0.001;  ///< model units in one millimetre (metres: 0.001)
  uint64_t seed = 1;
  /// Rays meeting the surface more obliquely than this (degrees from the normal) return nothing,
  /// as on a real scanner.
  double max_incidence_deg = 85.0;
  bool binary = false;  ///< binary_little_endian PLY instead of ASCII (large scans)
  int threads = 0;      ///< 0: every core; at most kMaxScanThreads
  bool quiet = false;   ///< no progress output
};

struct ScanResult {
  std::filesystem::path conf;   ///< the written .conf
  std::vector<ScanInfo> scans;  ///< one per scanner, as written
  uint64_t points = 0;          ///< total points over all scans
  uint64_t rays = 0;
};

/// Scans `mesh` and writes `out_dir/scan_NNN.ply` and `out_dir/scans.conf` (the folder is created).
/// Throws std::runtime_error when a file cannot be written, PreconditionError for bad options.
ScanResult scanMesh(const Mesh& mesh, const std::filesystem::path& out_dir,
                    const ScanOptions& options);

}  // namespace tessera::lod
