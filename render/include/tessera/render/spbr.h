// Stochastic point-based rendering (SPBR) of see-through point clouds, after Tanaka et al. 2016
// ("See-through imaging of laser-scanned 3D cultural heritage objects based on stochastic
// rendering of large-scale point clouds", ../shared/papers/spbr-see-through-point-clouds.txt).
// No depth sorting: L statistically independent ensembles of points are each drawn with an
// ordinary depth test and the L images are averaged. A surface segment of area S holding n
// points of cross-section s shows opacity alpha = 1 - (1 - s/S)^n (eq. 1); the data's n_raw
// points per S are thinned or copied by k = nL / n_raw (eq. 4) and dealt into the ensembles.
//
// Here, with LOD, every node of the cut gets its own k: its areal density is measured on its own
// points (the paper's sphere counts, with spheres sized from the node's spacing) and its points'
// cross-section follows its spacing, so the opacity holds at every level. Copies are never
// stored: the shader deals copy c of point i into ensemble (h(i) + c) mod L, h a stable hash of
// the node and the point index, so tiles of a wall agree and no point is invented.
//
// Sparse scans (2 to 8 points a pixel, where the paper assumes ~38): by default (SpbrCopies::
// kInCell) a node whose discs do not cover its points' cells (spbrCellSpread()) spreads each
// point's copies, stratified, over its surface cell (surfaceCells()) and shifts every ensemble
// within the pixel, so the L ensembles decorrelate while copies stay within the local spacing.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace tessera::render {

/// Where the copies of a point go (eq. 4's k > 1). The paper copies a point where it is, which
/// assumes ~38 points a pixel; scans give 2 to 8, and then the L ensembles hold nearly the same
/// points and average to binary noise (bench/spbr sparse).
enum class SpbrCopies {
  /// The paper (section 3.2.2): every copy where its point is. Sharp, exact for dense data;
  /// binary noise on sparse scans (std 2.1 - 8.0x the binomial on the Figure 5 plane at 10^6).
  kAtPoint,
  /// Copy c moved by a Gaussian of `copy_jitter` node spacings in the image plane, optionally
  /// over surface cells (`cell_weights`). Binomial on sparse scans, but blurs edges (1.8 - 2.2 px)
  /// and the fused bunny (RMSE 24.2 against 15.1).
  kGaussian,
  /// The default: copies stratified over the point's surface cell (surfaceCells(): its Voronoi
  /// cell in the tangent plane, sampled as the rectangle of the same second moments), their
  /// number in proportion to the cell's area, copy c at the c-th point of a randomly shifted
  /// R2 low-discrepancy sequence (Roberts 2018) in the rectangle. The copies of all points then
  /// cover the surface evenly in every ensemble, and a point's copies never leave its cell, so
  /// the jitter is bounded by the local spacing: sharp on edges, nearly still on dense scans.
  /// Needs StreamerOptions::surface_cells (on by default); chunks without cells get kAtPoint.
  kInCell,
};

struct SpbrOptions {
  uint32_t ensembles = 16;       ///< L: ensembles per frame
  uint32_t progressive_max = 0;  ///< >L: a resting view keeps adding ensembles up to this many
  bool slant_shading =
      true;  ///< eq. 2's opacity gradation on slanted surfaces (off: s cos(theta) / cos(phi))
  /// Largest adjustment ratio k (eq. 4) before cross-sections grow instead. The default keeps
  /// the paper's fixed cross-section (the opaque disc) and copies points as k requires (up to
  /// one copy in each ensemble, or max_share x L with copies moved off their point).
  /// 1 makes every ensemble hold its own points (statistically independent, noise falls as
  /// 1/sqrt(L)) by growing the discs instead: smooth but blurred, since discs grow with L
  /// (bench/spbr measures both against an exact compositor).
  double max_k = 1e9;
  /// Where copies go (see SpbrCopies); all apply only with max_k > 1 (max_k 1: independent
  /// ensembles, no copies).
  SpbrCopies copies = SpbrCopies::kInCell;
  /// kGaussian: the offset's standard deviation in node spacings, in the image plane
  /// (deterministic from the node, the point index and c). Blurs edges by about 2.6 x this x the
  /// spacing in pixels (10-90%).
  double copy_jitter = 1.5;
  /// kGaussian and kInCell: the largest share of the L ensembles one point's copies fill before
  /// cross-sections grow instead. Below 1 each ensemble is a random thinning of the surface
  /// cover, closer to the independent placement eq. 1 assumes, but discs grow sooner (blur).
  double max_share = 1.0;
  /// kInCell: each ensemble is shifted as a whole by a random sub-pixel offset within a square
  /// of this side, pixels (x the node's spread; from a hash of the ensemble index, the same on
  /// every tile), as a temporal antialiasing jitter: the average then samples each pixel at L
  /// places, a box filter over what structure of the cover remains at the scale of a cell (the
  /// rectangles only approximate the cells), which dominates the noise near alpha 1 (bench/spbr
  /// sparse: std 1.63x the binomial at alpha 0.95 without, 1.21x with). Widens edges by about
  /// 0.4 px (10-90%); 0: off. Scaled by spbrShiftScale() of the ensembles in all.
  double ensemble_shift = 1.0;
  /// kGaussian: scale each point's copies by its surface cell's area and centre them on the
  /// cell's centroid (needs StreamerOptions::surface_cells).
  bool cell_weights = true;
  /// The paper's copies (SpbrCopies::kAtPoint), the rest of `base` kept.
  static SpbrOptions papersCopies(SpbrOptions base);
  static SpbrOptions papersCopies() { return papersCopies(SpbrOptions()); }
  /// The sparse-scan method before copies in cells (bench/spbr sparse, "gaussian"): copies
  /// jittered by a Gaussian of 1.5 spacings over surface cells, the rest of `base` kept.
  static SpbrOptions gaussianJitter(SpbrOptions base);
  static SpbrOptions gaussianJitter() { return gaussianJitter(SpbrOptions()); }
  /// See-through views refine the LOD cut this much finer than opaque ones: denser nodes let
  /// each ensemble take fewer points of smaller cross-section.
  double lod_scale = 0.5;
  /// Point copies drawn per frame at most (the work, and the memory a materialised copy would
  /// take at 16 bytes each): a request beyond it is refused with the opacity that fits.
  uint64_t max_copies_per_frame = 3'000'000'000ull;
  uint64_t buffer_bytes = 512ull << 20;  ///< ensemble depth + colour layers drawn at once
  uint32_t seed = 0x5EEDu;
  /// Benchmarks only: draw the same adjusted points into one depth layer (an opaque pass over
  /// them), the speed baseline SPBR is held to.
  bool single_layer_baseline = false;
};

inline SpbrOptions SpbrOptions::papersCopies(SpbrOptions base) {
  base.copies = SpbrCopies::kAtPoint;
  return base;
}

inline SpbrOptions SpbrOptions::gaussianJitter(SpbrOptions base) {
  base.copies = SpbrCopies::kGaussian;
  base.copy_jitter = 1.5;
  base.cell_weights = true;
  base.max_share = 0.5;
  return base;
}

/// Opacity of a segment of area S holding n points of cross-section s (eq. 1).
double spbrOpacity(double n, double s, double S);
/// Points per segment area S that give opacity alpha with cross-section s (eq. 1 inverted).
double spbrPointsFor(double alpha, double s, double S);

/// The points per disc (rho s) below which SpbrCopies::kInCell spreads a node's copies over
/// their cells: between the sparse random plane's nodes (0.66 - 0.87 at 2 points a pixel) and
/// registered range scans' (1 - 2.5 on the bunny's).
inline constexpr double kSpreadBelowPerDisc = 0.93;

/// Whether SpbrCopies::kInCell spreads a node's copies over their cells: 1 or 0, from the node's
/// points per disc rho s = `density` x pi `spacing`^2 (s the cross-section, the opaque disc).
/// Below 1 the mean cell (1 / density) is larger than a disc: copies at their points leave
/// holes in every ensemble's cover that no number of ensembles closes, the binary noise of a
/// random sample (rho s = pi / 4 for uniformly random points, whose mean spacing is half the
/// mean distance). From 1 on the discs cover the cells (scan grids) and what gaps remain are
/// the data's, which an exact compositor shows: copies stay at their points, as the paper.
/// A step at kSpreadBelowPerDisc, not a ramp: copies spread part way (rectangles shrunk towards
/// their points) cover unevenly, 1.5 - 3.7x the binomial noise at three quarters to half the
/// spread on the Figure 5 plane, and a node so drawn stands out a few grey levels from its
/// neighbours (bench/spbr opacity). Either side of the step the opacity is the one asked.
double spbrCellSpread(double density, double spacing);

/// How much wider SpbrOptions::ensemble_shift is over `total_ensembles`: 1 up to 64, then
/// (L / 64)^0.3 (1.52 at 256). The structure that remains of the cover at the scale of a cell is
/// the same in every ensemble, so it does not average away as the binomial noise does (it
/// falls as 1 / sqrt(L)); a wider shift filters it more: on the Figure 5 plane at alpha 0.9 and
/// L = 256 the noise is 1.72x the binomial with a 1 px shift and 1.46x with 1.5 px, edges 1.35
/// and 1.70 px wide (bench/spbr opacity).
double spbrShiftScale(uint32_t total_ensembles);

/// The opacity to ask of eq. 1 so that copies moved over surface cells (`copies`, spread by
/// `spread`, spbrCellSpread()) show `alpha`. Such a cover is more regular than the independent
/// placement eq. 1 assumes: its discs overlap less, so the same lambda = -ln(1 - alpha) covers
/// more. Fitted on the Figure 5 plane (bench/spbr sparse); `alpha` itself for
/// SpbrCopies::kAtPoint, and for kInCell with spread 0.
double spbrCoverAlpha(double alpha, SpbrCopies copies, double spread = 1.0);

/// One node's SPBR parameters.
struct SpbrNodeParams {
  double cross_section = 0;  ///< s, store units squared
  double k = 0;              ///< adjustment ratio nL / n_raw (eq. 4) over the L_total ensembles
};

/// Parameters for a node of areal `density` (points per unit area) and mean `spacing`, for
/// opacity `alpha` in (0, 1] over `total_ensembles` ensembles. The cross-section is the disc
/// the opaque renderer draws (diameter 2 x spacing), enlarged where k would exceed `max_k` or
/// `total_ensembles` (k scales as 1 / s). alpha = 1: every point in every ensemble.
SpbrNodeParams spbrNodeParams(double alpha, double density, double spacing,
                              uint32_t total_ensembles, double max_k = 1.0);

/// Areal density by the paper's estimator (section 3.2.1, steps 2-3): the mean number of
/// points in `centres` spheres of `radius` around points chosen at random (deterministic from
/// `seed`), divided by the great circle's area. Centres closer than `radius` to the box of the
/// points are avoided where possible (a sphere cut by the data's edge undercounts); the centre
/// itself is not counted. Inputs beyond `max_points` are subsampled at random with spheres
/// widened to hold as many points. O(n).
double sphereDensity(std::span<const glm::vec3> points, double radius, uint32_t centres,
                     uint32_t seed, size_t max_points = 65536);

/// Each point's density relative to its node's: `node_density` / (points within `radius` /
/// (pi radius^2)), clamped to [1/8, 8], for points at least `radius` inside `box` (on the axes
/// where it is wider than 4 radii); 1 elsewhere
/// (spheres cut by the node's faces would undercount). Scaling k by it evens out density jumps
/// inside a node, such as overlapping scans (bench/spbr, "where it breaks"). Inputs beyond
/// `max_points` count neighbours among a random subset with wider spheres. O(n).
std::vector<float> densityRatios(std::span<const glm::vec3> points, double radius,
                                 const glm::vec3& box_min, const glm::vec3& box_max,
                                 double node_density, size_t max_points = 65536);

/// Unit normals by principal component analysis of the points within `radius` of each point,
/// packed as 10:10:10 signed normalised integers (x in the low bits); 0 where fewer than 3
/// points are near. For turning the slant shading off (cross-section s cos(theta) / cos(phi), eq.
/// 2).
std::vector<uint32_t> estimateNormals(std::span<const glm::vec3> points, double radius);

/// A point's share of its surface (surfaceCells()): where its copies are centred, over what
/// they spread and how many it gets.
struct SurfaceCell {
  glm::vec3 offset{0.0f};  ///< from the point to its cell's centroid, the points' units
  float weight = 1.0f;     ///< the cell's area times the node's density: 1 on average
  /// Half-sides of the rectangle with the cell's area moments (its principal axes, in the
  /// tangent plane, orthogonal; the points' units): copies spread uniformly over
  /// offset + [-1, 1] axis_u + [-1, 1] axis_v. Open cells get the square of the node's mean
  /// cell area (1 / node_density) around the point; points without a tangent plane, zero.
  glm::vec3 axis_u{0.0f};
  glm::vec3 axis_v{0.0f};
};

/// Each point's Voronoi cell among its neighbours within `radius` (about 6 node spacings), in
/// the tangent plane of those neighbours (PCA), cut by the node's box [`box_min`, `box_max`]
/// (the points' frame; the cells of neighbouring nodes then meet at its faces): the area relative
/// to the node's mean (x `node_density`, points per unit area; clamped to [1/8, 8]) and the offset
/// to the centroid, and the rectangle of its area moments (SurfaceCell::axis_u, axis_v). Points
/// whose cell stays open (still touching the radius-sized square it is cut from: the edge of the
/// data, or of the node, whose neighbours beyond its faces are elsewhere) get weight 1, no offset
/// and the square of the mean cell around themselves; points with fewer than 3 neighbours get
/// weight 1 and nothing else. Spreading each point's copies over its rectangle, their number
/// scaled by its weight, turns the random sample of a sparse scan into an even cover of its
/// surface (spbr_raster.comp). O(n) with ~20 neighbours a point; about twice the cost of
/// decoding.
std::vector<SurfaceCell> surfaceCells(
    std::span<const glm::vec3> points, double radius, double node_density,
    const glm::vec3& box_min = glm::vec3(-std::numeric_limits<float>::infinity()),
    const glm::vec3& box_max = glm::vec3(std::numeric_limits<float>::infinity()));

}  // namespace tessera::render
