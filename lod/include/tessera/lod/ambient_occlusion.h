// Ambient occlusion of range scans, per point, after Sabbadin, Palma, Cignoni and Scopigno,
// "Multi-View Ambient Occlusion for Enhancing Visualization of Raw Scanning Data" (2016):
//
//  - per range map, screen-space AO in the scan's own grid (section 4, eq. 3-5), a 5x5 Gaussian
//    after it;
//  - multi-view integration (section 5, eq. 6-12): each point's AO is the weighted mean of the
//    SSAO of the points every scan measured at the same place, weighted by scan distance (w_d),
//    view direction (w_n) and distance to the scan's depth discontinuities (w_b), from 1, 3x3
//    or 5x5 grid neighbours per scan;
//  - the real-time variant (section 6): a sparse voxel grid keyed by Morton code accumulating
//    SSAO x weight and weight as scans arrive one by one;
//  - two ray-traced references (Embree 3) with the same AO definition, to measure the others
//    against: the scans' surface reconstruction (meshReferenceAo(), independent of the scans'
//    normals and registration layers) and every scan's points as oriented discs (referenceAo()).
//
// AO here is a visibility in [0, 1]: 1 is fully open (a plane), 0 fully occluded. The quantity
// every method estimates is eq. 1's obscurance with rho = smoothstep(0, t_max, d) (eq. 4): the
// cosine-weighted mean over the hemisphere of rho(distance to the first surface), 1 where no
// surface lies within t_max.
//
// A range map is a scan's own grid (a Stanford range_grid, an E57 scan's row and column
// indices, a virtual scan's rays). A scan without one gets a grid by orthographic projection of
// its points along its scanner's view axis (-z of the scanner frame), the paper's own fallback
// for scanners that keep no depth map (section 7). Scanners look along -z of their frame (the
// Stanford and OpenGL convention, and what `tessera-lod scan` writes).
//
// Everything is deterministic for a seed whatever the thread count. Bad input (no scans, a scan
// that cannot be gridded, NaN parameters) throws AoError naming the file and the scan.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/lod/mesh.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/store_builder.h>

namespace tessera::lod {

/// Input that AO cannot be computed for: no scans, a scan without a grid when projection is
/// refused or impossible, bad parameters from outside. The message names the file and scan.
class AoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// How a range map's pixels relate to its scanner frame.
enum class ScanProjection {
  kOrthographic,  ///< pixel = affine(x, y, z): a translating scanner (Cyberware 3030)
  kPerspective,   ///< pixel = affine(x / -z, y / -z): a camera at the origin looking along -z
  kPanoramic,     ///< pixel = affine(azimuth, elevation) around the origin (terrestrial LiDAR)
};
const char* projectionName(ScanProjection p);

constexpr uint32_t kNoPixel = 0xFFFFFFFFu;

/// One scan as an image: per pixel (index row * columns + column) a point in the scanner frame,
/// its normal (unit, towards the scanner), its radius rad(p), its SSAO and its distance to the
/// nearest depth discontinuity. Pixels without a point have valid = 0.
struct RangeMap {
  std::string name;
  RigidPose pose;  ///< scanner frame -> registered frame
  uint32_t columns = 0, rows = 0;
  ScanProjection projection = ScanProjection::kOrthographic;
  bool projected = false;  ///< the grid comes from the fallback projection, not from the file
  /// Pixel = (dot(col_axis, f(p)) + col_offset, dot(row_axis, f(p)) + row_offset) with f(p) the
  /// projection's coordinates ((x, y, z), (x/-z, y/-z, 0) or (azimuth, elevation, 0)), fitted by
  /// least squares to the grid's own points.
  glm::dvec3 col_axis{0.0}, row_axis{0.0};
  double col_offset = 0.0, row_offset = 0.0;
  double fit_rms_px = 0.0;   ///< RMS distance of the fitted pixel from the real one
  glm::dvec3 view{0, 0, 1};  ///< orthographic: unit direction towards the scanner
  std::vector<uint8_t> valid;
  std::vector<glm::vec3> positions;  ///< scanner frame
  std::vector<glm::vec3> normals;    ///< scanner frame, facing the scanner
  std::vector<float> radius;         ///< rad(p), section 5: 2 sqrt(d_k^2 / k)
  std::vector<float> ssao;           ///< eq. 3 after the 5x5 Gaussian (computeSsao())
  std::vector<float> border_px;      ///< distance in pixels to a depth edge (computeBorders())

  size_t pixels() const { return size_t(columns) * rows; }
  /// Continuous pixel coordinates of a scanner-frame point (may be outside the grid).
  glm::dvec2 pixelOf(const glm::dvec3& local) const;
  /// Unit direction from a scanner-frame point towards the scanner.
  glm::dvec3 towardScanner(const glm::dvec3& local) const;
  /// Distance from the scanner for eq. 10 (orthographic scans: 0, their resolution does not
  /// depend on depth).
  double depth(const glm::dvec3& local) const;
  /// World units per pixel at `local` along columns and rows (the disk radius of eq. 3).
  glm::dvec2 pixelSize(const glm::dvec3& local) const;
};

/// Every scan of a source plus its points in the order the source's reader delivers them (the
/// order the store builder reads them: BuildOptions::ambient_occlusion).
struct ScanSet {
  std::filesystem::path source;
  glm::dvec3 origin{0.0};  ///< world = origin + position
  std::vector<RangeMap> maps;
  std::vector<glm::dvec3> positions;  ///< registered frame, relative to origin
  std::vector<uint16_t> scan_of_point;
  std::vector<uint32_t> pixel_of_point;  ///< pixel in its scan's map
  size_t size() const { return positions.size(); }
  /// World-frame (registered) normal of point i (its map's normal rotated by the pose).
  glm::dvec3 normal(size_t i) const;
};

struct RangeMapOptions {
  /// Scans without a grid are projected (the paper's fallback); false: such a scan is an error.
  bool allow_projection = true;
  int threads = 0;  ///< 0: every core
};

/// Reads a Stanford .conf, a range-grid PLY or an E57 and makes one range map per scan with
/// normals (PCA of the 5x5 grid neighbourhood, the paper's [HDD92] fallback on a grid) and
/// radii. Throws ReadError for unreadable input, AoError for no scans or a scan without a grid
/// when projection is refused or impossible (fewer than 3 points, no extent).
ScanSet loadScans(const std::filesystem::path& path, const RangeMapOptions& options = {});

/// One scan given in memory (tests, benchmarks): per pixel a scanner-frame point, NaN where the
/// scanner saw nothing; `columns` x `rows`, row-major.
struct GridScan {
  std::string name;
  RigidPose pose;
  uint32_t columns = 0, rows = 0;
  std::vector<glm::vec3> points;
};
/// The same as loadScans() over scans in memory; the point order is scan by scan, row-major.
ScanSet makeScanSet(const std::vector<GridScan>& scans, const RangeMapOptions& options = {});

struct AoOptions {
  double t_max = 0.0;       ///< falloff distance of eq. 4 (world units); 0: 5% of the diagonal
  double radius = 0.0;      ///< r_s, the disk of eq. 3 (world units); 0: t_max / 2
  int samples = 32;         ///< N of eq. 3
  int neighbours = 1;       ///< 1, 3 or 5: N = 1, 3x3, 5x5 samples per scan in eq. 8
  double border_px = 16.0;  ///< t_p of eq. 12 in pixels
  double grid_cell = 0.0;   ///< section 6 voxel size; 0: t_max / 4
  bool blur = true;         ///< section 4's 5x5 Gaussian
  /// Angle bias beta in [0, 0.5): eq. 5 with max(n . v - beta, 0) / (1 - beta), so samples less
  /// than asin(beta) above the tangent plane do not occlude (the bias of screen-space methods
  /// such as Alchemy AO, not in the paper). 0: eq. 5 as written. The estimate of the elevation
  /// n . v carries the normal's error and the scanner's noise, which darken open surfaces in
  /// every view alike (bunny: open points read 0.992 at 0, 0.9975 at 0.1).
  double angle_bias = 0.0;
  uint64_t seed = 1;
  int threads = 0;
};

/// t_max and radius resolved against the scans' extent (a copy with the zeros filled in).
/// Throws AoError for NaN, infinite or negative values, samples outside 1..4096, neighbours
/// other than 1, 3, 5, an angle bias outside [0, 0.5).
AoOptions resolveAoOptions(const ScanSet& scans, AoOptions options);

/// Section 4: SSAO of every valid pixel of `map` (eq. 3-5), then the 5x5 Gaussian. Rows run in
/// parallel; each pixel's samples come from a hash of (seed, scan, pixel). `options` resolved.
void computeSsao(RangeMap& map, uint32_t scan_index, const AoOptions& options);
/// Section 5: depth edges (|Laplacian of depth| above its 95th percentile, plus the edge of the
/// scanned area) and their exact Euclidean distance transform in pixels (two passes,
/// Felzenszwalb and Huttenlocher, on the CPU instead of the paper's GPU jump flooding).
void computeBorders(RangeMap& map, int threads = 0);

/// Each point's SSAO in its own scan (the single-view baseline). Needs computeSsao() on every map.
std::vector<float> ownSsao(const ScanSet& scans);
/// Section 5, eq. 6-12: MVAO of every point. Needs computeSsao() and computeBorders().
/// `own_share`, when given, receives per point the share of eq. 8's weight that came from the
/// point's own scan (1 where no other scan contributes).
std::vector<float> integrateMvao(const ScanSet& scans, const AoOptions& options,
                                 std::vector<float>* own_share = nullptr);

/// Section 6: a sparse voxel grid keyed by the Morton code of the cell, each cell holding the
/// accumulated SSAO x weight and weight (eq. 9 without w_b). Scans are added one at a time, as a
/// stream; value() interpolates trilinearly between cell centres.
class MvaoGrid {
 public:
  MvaoGrid(const glm::dvec3& lo, double cell);
  /// Accumulates every valid pixel of `map` (SSAO computed). `d_min`, `d_max` as in eq. 10.
  void addScan(const RangeMap& map, const glm::dvec3& origin, double d_min, double d_max);
  /// Accumulated AO at a point (registered frame, relative to the same origin); -1 if empty.
  float value(const glm::dvec3& p) const;
  size_t cells() const;

 private:
  struct Impl;
  std::shared_ptr<Impl> mImpl;
};
/// The grid variant over a whole set, scans added in order; per point.
std::vector<float> gridMvao(const ScanSet& scans, const AoOptions& options);

enum class AoMethod { kSsao, kMvao, kGrid };
/// The whole pipeline: SSAO of every map, borders, then the method's value per point.
std::vector<float> computeAmbientOcclusion(ScanSet& scans, AoMethod method,
                                           const AoOptions& options);

/// Reference AO of the listed points: `rays` stratified cosine-weighted rays (a square number
/// of strata, jittered) against every scan's points as Embree oriented discs of radius
/// 0.75 rad(p), each hit at distance d counting rho(d) = smoothstep(0, t_max, d), a miss 1 (eq. 1
/// with eq. 4's falloff). Rays start rad(p) / 4 above the point along its normal; they go on
/// through discs met from behind (layers of the point's own surface in other scans) and
/// through discs facing the point's way within 4 rad(p) of its tangent plane. `options` resolved.
std::vector<float> referenceAo(const ScanSet& scans, std::span<const uint32_t> points, int rays,
                               const AoOptions& options);

/// The second reference, on a surface reconstruction of the same scans (the bunny's
/// bun_zipper.ply): each listed point goes to its nearest point q on the mesh, the normal is the
/// mesh's (vertex normals, area-weighted, interpolated at q, turned towards the point's scanner),
/// and `rays` stratified cosine-weighted rays from a quarter of the median edge above q meet the
/// mesh's triangles (Embree 3), each hit at distance d counting rho(d) of eq. 4, a miss 1. It
/// shares nothing with the scans' own normals, radii or registration layers.
struct MeshAoReference {
  std::vector<float> ao;         ///< per listed point, eq. 1 with eq. 4's falloff
  std::vector<float> distance;   ///< from the point to q (world units)
  std::vector<float> thickness;  ///< from q inwards along -normal to the next surface; inf: none
  std::vector<glm::vec3> normal;  ///< the mesh's unit normal at q, towards the point's scanner
  double edge = 0;               ///< the mesh's median edge length
};
/// Throws AoError for a mesh without triangles. The mesh's frame is the scans' registered frame.
MeshAoReference meshReferenceAo(const ScanSet& scans, const Mesh& mesh,
                                std::span<const uint32_t> points, int rays,
                                const AoOptions& options);

/// Visibility 0..1 as the store's byte: round(255 v).
inline uint8_t aoByte(float v) {
  return uint8_t(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

struct AoStoreReport {
  BuildReport build;
  size_t scans = 0;
  uint64_t points = 0;
  double seconds_load = 0;       ///< reading the scans, range maps, normals, radii
  double seconds_ssao = 0;       ///< section 4 over every map
  double seconds_integrate = 0;  ///< borders and section 5, or section 6's grid
  AoOptions resolved;            ///< the parameters used
};
/// `tessera-lod ao`: AO of every point of `scans` (loadScans()) by `method`, then a store of
/// those points carrying it (buildStore() with BuildOptions::ambient_occlusion). Progress on
/// stderr unless build.quiet. Throws what loadScans(), resolveAoOptions() and buildStore() throw;
/// the output is refused before any work when it is one of the files read.
AoStoreReport buildStoreWithAo(const std::filesystem::path& scans,
                               const std::filesystem::path& output, AoMethod method,
                               const AoOptions& options, BuildOptions build);
/// `tessera-lod build --ao`: the same over several inputs, each one's scans on their own (AO is
/// not integrated across inputs; t_max 0 resolves per input), the bytes in input order, one
/// store of every input's points. Every input must hold scans with poses: one that does not is
/// an AoError naming it, before anything is written. The report sums scans, points and times;
/// `resolved` is the last input's.
AoStoreReport buildStoreWithAo(const std::vector<std::filesystem::path>& inputs,
                               const std::filesystem::path& output, AoMethod method,
                               const AoOptions& options, BuildOptions build);

/// Point subsets the accuracy is reported on: seen at a grazing angle by its own scanner (normal
/// more than 60 degrees from the scanner direction) and within 8 px of a depth edge.
bool grazingPoint(const ScanSet& scans, size_t i);
bool borderPoint(const ScanSet& scans, size_t i);

}  // namespace tessera::lod
