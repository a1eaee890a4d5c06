// A triangle mesh held whole in memory (the virtual scanner's input; meshes for later LOD work).
#pragma once

#include <filesystem>
#include <vector>

#include <tessera/lod/point_batch.h>

namespace tessera::lod {

struct Mesh {
  std::vector<glm::dvec3> positions;  ///< file units, world = origin + position
  glm::dvec3 origin{0.0};
  std::vector<Triangle> triangles;
  std::vector<glm::u8vec4> colors;  ///< per vertex, empty when the file has none
  std::vector<glm::vec3> normals;    ///< per vertex, empty when the file has none

  /// Axis-aligned bounds of the vertices (relative to origin). Empty mesh: min > max.
  std::pair<glm::dvec3, glm::dvec3> bounds() const;
};

/// Reads a mesh through openPointReader() (PLY or OBJ with faces). Throws ReadError, including
/// when the file has no triangles.
Mesh readMesh(const std::filesystem::path& path);

}  // namespace tessera::lod
