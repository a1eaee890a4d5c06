// 3D lazy snapping and the robust lasso (thesis "patch-lod-annotation", chapter 4):
// select a region of a scanned surface from a few foreground and background strokes.
//
// The pipeline runs on the CPU over the samples a selection needs (the vertices of a mesh, or
// the points of a cloud, typically the leaves under the current view):
//   1. SurfaceSamples: positions, unit normals, colours and an adjacency graph (mesh edges, or
//      the symmetric k-nearest-neighbour graph of a point cloud, normals by PCA when missing).
//   2. overSegment(): watershed over-segmentation into small connected segments (4.2.2).
//   3. LazySnapping::cut(): a graph cut over the segments with the colour and normal data term
//      (eq. 4.2, 4.4) and the colour, normal and depth smoothness term (eq. 4.3, 4.5), solved
//      by Boykov-Kolmogorov max-flow (4.2.1).
//   4. robustLassoSeeds(): the heavy stroke of 4.3.1 turned into foreground and background
//      seeds for the same cut.
// Strokes are lists of sample indices (what picking under a stroke gives); pickStroke()
// computes them from a screen polyline without GL.
//
// Where this departs from the thesis: it over-segments the rendered image and carries each
// 2D cluster's normal over from the 3D patches under it; here the watershed runs on the
// surface samples themselves, so the cut labels hidden samples too (through adjacency, not
// the screen), and a cluster's depth is its centroid's eye depth. Segments weigh as many as
// their samples (see cut()); the weights' scales and lambda, which the thesis leaves open,
// are fixed below. A segment under both kinds of stroke is refined into samples.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/lod/mesh.h>
#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_store.h>

namespace tessera::annotate {

/// Input that cannot be segmented or cut (NaN positions, no strokes, an empty surface, sizes
/// that disagree). The message starts with the function and says what was expected.
class SnappingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Samples of a surface and their neighbourhood graph.
///
/// Positions are in any Cartesian frame (file units, metres for scans; relative to an origin
/// for georeferenced data, so doubles keep millimetres); the ScreenView of strokes maps this
/// frame to eye space. Normals are unit length, colours RGB 0..255 (alpha ignored). Adjacency
/// is symmetric, without self loops, in compressed rows: the neighbours of sample i are
/// neighbours[offsets[i] .. offsets[i + 1]).
struct SurfaceSamples {
  std::vector<glm::dvec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<glm::u8vec4> colors;
  std::vector<uint32_t> offsets;  ///< size() + 1 entries
  std::vector<uint32_t> neighbours;

  size_t size() const { return positions.size(); }
  std::span<const uint32_t> neighboursOf(uint32_t i) const {
    return {neighbours.data() + offsets[i], neighbours.data() + offsets[i + 1]};
  }
  /// Throws SnappingError unless the arrays agree in size, positions and normals are finite
  /// and the adjacency is in range. `who` starts the message.
  void validate(const char* who) const;
};

/// Samples from the vertices of a mesh: adjacency along triangle edges, area-weighted vertex
/// normals from the triangles when the mesh has none (orientation from the winding), grey
/// (128) when it has no colours. Vertices of no triangle are kept, isolated. Cost: O(triangles).
SurfaceSamples surfaceFromMesh(const lod::Mesh& mesh);

/// Samples from a point cloud: the symmetric k-nearest-neighbour graph (a kd-tree; k = 8 by
/// default, enough to connect scans of even density without bridging 1-sample gaps), normals
/// by PCA over the k nearest neighbours when `normals` is empty (the eigenvector of the
/// smallest eigenvalue of their covariance), oriented towards `viewpoint` (the scanner or the
/// eye; the stroke view is a good choice). `colors` may be empty (grey). Throws SnappingError
/// on NaN positions or sizes that disagree. Cost: O(n k log n).
SurfaceSamples surfaceFromPoints(std::span<const glm::dvec3> positions,
                                 std::span<const glm::u8vec4> colors,
                                 std::span<const glm::vec3> normals, uint32_t k,
                                 const glm::dvec3& viewpoint);

/// Samples from decoded point chunks (PointStore::loadChunk(), e.g. the nodes of the region
/// being selected), in the store's local frame (local = chunk offset + position; add the
/// store origin for world coordinates): concatenated in the order given, then as
/// surfaceFromPoints(). A sample's index is its rank in that concatenation.
SurfaceSamples surfaceFromChunks(std::span<const std::shared_ptr<const lod::ChunkPoints>> chunks,
                                 uint32_t k, const glm::dvec3& viewpoint);

/// Samples from decoded mesh patches (MeshStore::readPatch(), e.g. the leaves of a region),
/// in the store's local frame. Vertices that patches share on their borders are welded by
/// their grid coordinates (exact), or by position when a patch has no grid, so the adjacency
/// runs across patch borders. `sample_of[p][v]` (filled when not null) is the sample of patch
/// p's vertex v. Normals and colours are the patches' (grey when a patch has none). Throws
/// SnappingError on indices out of range or arrays that disagree in size.
SurfaceSamples surfaceFromPatches(std::span<const lod::MeshPatch> patches,
                                  std::vector<std::vector<uint32_t>>* sample_of = nullptr);

struct OverSegmentOptions {
  /// Segments are split into connected pieces of at most this many samples.
  uint32_t max_segment_size = 64;
  /// Segments smaller than this merge into their most similar neighbour (when one is similar
  /// enough: normals within `merge_max_angle_deg` and colours within `merge_max_color`).
  uint32_t min_segment_size = 8;
  double merge_max_angle_deg = 20.0;
  double merge_max_color = 40.0;  ///< RGB distance, 0..441
  /// Height function = normal variation + colour_weight * colour gradient (see overSegment()).
  double colour_weight = 1.0;
  uint32_t smoothing_passes = 1;  ///< neighbour averages of the height before flooding
};

/// A partition of the samples into segments numbered 0 .. count - 1.
struct OverSegmentation {
  std::vector<uint32_t> segment_of;  ///< per sample
  uint32_t count = 0;
};

/// Watershed over-segmentation of the samples (thesis 4.2.2, after Vincent and Soille [27];
/// flooding by priority as Meyer does, on the sample graph instead of the pixel grid). The
/// height is the mean normal variation to the neighbours, 1 - n_i . n_j, plus the colour
/// gradient scaled to the same range, so basins are smooth, evenly coloured patches and
/// their borders fall on creases and colour edges. Every sample is in exactly one segment;
/// segments are connected in the adjacency graph and hold at most max_segment_size samples.
/// Throws SnappingError on invalid samples. Cost: O(n log n).
OverSegmentation overSegment(const SurfaceSamples& samples, const OverSegmentOptions& options = {});

/// A view for strokes and the depth term: `view` maps sample positions to eye space (camera
/// at the origin looking down -z, units of the positions), `projection` eye to clip space (GL
/// conventions), `viewport` the window size in pixels. Window pixels have their origin at the
/// bottom-left, as gl_FragCoord.
struct ScreenView {
  glm::dmat4 view{1.0};
  glm::dmat4 projection{1.0};
  glm::uvec2 viewport{1, 1};
};

/// Window position (pixels) and eye depth (units of the positions, > 0 in front) of a point.
struct ScreenPoint {
  glm::dvec2 pixel;
  double depth;
  bool in_front;  ///< inside the near/far range and in front of the camera
};
ScreenPoint project(const ScreenView& view, const glm::dvec3& position);

/// Which samples are seen from the view: a CPU depth buffer where each sample covers a disc
/// of `splat_px` pixels; a sample is visible when no other is nearer than its own depth minus
/// `depth_tolerance` (units of the positions; a few sample spacings) at its pixel.
std::vector<uint8_t> visibleSamples(const SurfaceSamples& samples, const ScreenView& view,
                                    double splat_px, double depth_tolerance);

/// The visible samples under a stroke drawn on the screen: within `radius_px` of the polyline
/// `stroke` (window pixels), what picking under the stroke gives. `visible` as from
/// visibleSamples() (empty: all samples count as visible).
std::vector<uint32_t> pickStroke(const SurfaceSamples& samples, const ScreenView& view,
                                 std::span<const glm::dvec2> stroke, double radius_px,
                                 std::span<const uint8_t> visible);

/// Foreground and background strokes as sample indices.
struct Strokes {
  std::vector<uint32_t> foreground;
  std::vector<uint32_t> background;
};

/// Weights of the energy. Per sample the data term is at most w_c + w_n and a border edge
/// costs up to lambda (w_c + w_n + w_d). With lambda = 1 the normal data term alone can pull
/// in whole regions that merely face the way the foreground stroke faces (the bunny's flank
/// for a stroke on its ear); from lambda ~ 3 the border settles on creases and colour edges
/// between the strokes on the bunny and on the synthetic models alike, hence 4.
struct SnapOptions {
  OverSegmentOptions segmentation;
  /// false: one graph node per sample (the baseline without over-segmentation).
  bool over_segment = true;
  double lambda = 4.0;    ///< weight of the smoothness term, eq. 4.1
  double w_colour = 1.0;  ///< w_c of eq. 4.4 and 4.5
  double w_normal = 1.0;  ///< w_n of eq. 4.4 and 4.5
  double w_depth = 1.0;   ///< w_d of eq. 4.5 (needs a view; ignored without one)
  uint32_t clusters = 8;  ///< k-means clusters per stroke kind (colours, and normals)
};

/// The outcome of a cut.
struct SnapResult {
  std::vector<uint8_t> selected;      ///< per sample, 1 = foreground
  std::vector<uint32_t> indices;      ///< the foreground samples, ascending
  uint32_t graph_nodes = 0;           ///< nodes of the cut graph (segments, refined samples)
  uint32_t conflicting_segments = 0;  ///< segments under both stroke kinds (refined)
  double energy = 0;                  ///< E(X) of eq. 4.1 at the minimum (= the max flow)
};

/// 3D lazy snapping on one surface: the over-segmentation and the segment graph are built once
/// (the thesis does it in the background when the camera stops), each cut() then costs a
/// k-means over the stroke samples and a max-flow over the segment graph.
class LazySnapping {
 public:
  /// Validates and over-segments `samples` (kept by reference: it must outlive this).
  explicit LazySnapping(const SurfaceSamples& samples, const SnapOptions& options = {});

  /// Graph cut from strokes. `view` (may be null) gives the depth term of eq. 4.5. A segment
  /// under both kinds of stroke straddles the wanted border: for this cut its samples become
  /// nodes of their own (a corrective stroke inside a segment then takes effect, which the
  /// thesis leaves to the lasso). A sample under both kinds stays unseeded. Throws
  /// SnappingError when a stroke kind is empty or an index is out of range.
  SnapResult cut(const Strokes& strokes, const ScreenView* view = nullptr) const;

  const OverSegmentation& segmentation() const { return mSegmentation; }
  const SnapOptions& options() const { return mOptions; }

 private:
  /// The graph a cut runs on: nodes are segments (or samples), with their mean attributes.
  struct NodeGraph {
    std::vector<uint32_t> node_of;  ///< per sample
    uint32_t count = 0;
    std::vector<uint32_t> size;
    std::vector<glm::dvec3> colour;  ///< mean, 0..255
    std::vector<glm::dvec3> normal;  ///< mean, unit (zero when the normals cancel)
    std::vector<glm::dvec3> centroid;
    struct Edge {
      uint32_t a, b;   ///< nodes, a < b
      uint32_t count;  ///< sample edges across the border
    };
    std::vector<Edge> edges;
  };
  static NodeGraph buildGraph(const SurfaceSamples& samples, std::vector<uint32_t> node_of,
                              uint32_t count);

  const SurfaceSamples& mSamples;
  SnapOptions mOptions;
  OverSegmentation mSegmentation;
  NodeGraph mGraph;
};

/// The heavy stroke of the robust lasso (thesis 4.3.1): a closed polyline in window pixels
/// drawn along the border of the wanted region, `width_px` wide.
struct HeavyStroke {
  std::vector<glm::dvec2> polyline;  ///< closed implicitly (last point joins the first)
  double width_px = 20.0;
  /// Seeds lie in bands this wide along the inner and outer sides of the stroke (the markers
  /// the thesis draws automatically); 0 = everything inside / outside.
  double seed_band_px = 20.0;
};

/// Seeds of the robust lasso: visible samples in the band just inside the stroke are
/// foreground, just outside background; samples under the stroke stay unknown for the cut.
/// Throws SnappingError when the polyline has fewer than 3 points or is not finite.
Strokes robustLassoSeeds(const SurfaceSamples& samples, const ScreenView& view,
                         const HeavyStroke& stroke, std::span<const uint8_t> visible);

/// Triangles whose three vertices are selected (vertex indices as in surfaceFromMesh()).
std::vector<uint32_t> selectedTriangles(const lod::Mesh& mesh, std::span<const uint8_t> selected);

/// |A and B| / |A or B| of two per-sample masks of equal size (1 when both are empty).
double intersectionOverUnion(std::span<const uint8_t> a, std::span<const uint8_t> b);

}  // namespace tessera::annotate
