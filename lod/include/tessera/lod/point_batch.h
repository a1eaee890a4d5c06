// A batch of points streamed out of a reader: structure of arrays, positions in double.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

namespace tessera::lod {

/// Optional per-point attributes a source may carry (bit flags).
enum Attribute : uint32_t {
  kNormal = 1u << 0,          ///< unit normal, file frame
  kColor = 1u << 1,           ///< RGB, 8 bits per channel
  kAlpha = 1u << 2,           ///< alpha, 8 bits (stored in color.a; 255 when absent)
  kIntensity = 1u << 3,       ///< return intensity as stored (LAS: 0..65535, PLY: as declared)
  kConfidence = 1u << 4,      ///< scanner confidence as stored
  kScanIndex = 1u << 5,       ///< index of the range scan (or input file) the point came from
  kGridPosition = 1u << 6,    ///< (column, row) cell in the scan's range grid
  kClassification = 1u << 7,  ///< LAS classification code
  /// Ambient-occlusion visibility, one byte (0..255 = 0..1); stores only, never a reader
  /// (lod/ambient_occlusion.h computes it; store format version 3).
  kAmbientOcclusion = 1u << 8,
};
using AttributeMask = uint32_t;

/// Names of the attributes set in `mask`, in bit order ("normal", "color", ...).
std::vector<const char*> attributeNames(AttributeMask mask);

/// A triangle of vertex indices counted over the whole source (first vertex is 0).
using Triangle = glm::u32vec3;

/// Points (and, for meshes, triangles) delivered by a `PointReader`.
///
/// Positions are in the source's units relative to `PointReader::info().origin`, in double, so
/// georeferenced coordinates keep their precision: world = origin + position. Only the arrays
/// of attributes in `attributes` are filled; each filled array has `size()` entries.
struct PointBatch {
  AttributeMask attributes = 0;
  std::vector<glm::dvec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<glm::u8vec4> colors;  ///< rgba; a = 255 unless kAlpha
  std::vector<float> intensities;
  std::vector<float> confidences;
  std::vector<uint16_t> scan_indices;
  std::vector<glm::u16vec2> grid_positions;  ///< (column, row)
  std::vector<uint8_t> classifications;
  /// Triangles completed by this batch (meshes only), indices over every vertex delivered so
  /// far and to come; never refer to a skipped vertex.
  std::vector<Triangle> triangles;

  size_t size() const { return positions.size(); }
  bool empty() const { return positions.empty() && triangles.empty(); }
  /// Empties every array, keeping capacity, and sets the attribute mask.
  void reset(AttributeMask mask);
  /// Makes room for `n` points in every array the mask enables (values unspecified).
  void resize(size_t n);
  /// Appends point `i` of `other` (same attribute mask) to this batch.
  void appendFrom(const PointBatch& other, size_t i);
  /// Appends points [first, first + count) of `other` (same attribute mask).
  void appendRange(const PointBatch& other, size_t first, size_t count);
};

}  // namespace tessera::lod
