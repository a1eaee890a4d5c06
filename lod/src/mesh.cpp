#include <tessera/lod/mesh.h>

#include <limits>

#include <tessera/lod/point_reader.h>

namespace tessera::lod {

std::pair<glm::dvec3, glm::dvec3> Mesh::bounds() const {
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  for (const auto& p : positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  return {lo, hi};
}

Mesh readMesh(const std::filesystem::path& path) {
  auto reader = openPointReader(path);
  Mesh mesh;
  mesh.origin = reader->info().origin;
  PointBatch batch;
  bool colors = reader->info().attributes & kColor;
  bool normals = reader->info().attributes & kNormal;
  while (reader->next(batch)) {
    mesh.positions.insert(mesh.positions.end(), batch.positions.begin(), batch.positions.end());
    if (colors) mesh.colors.insert(mesh.colors.end(), batch.colors.begin(), batch.colors.end());
    if (normals)
      mesh.normals.insert(mesh.normals.end(), batch.normals.begin(), batch.normals.end());
    mesh.triangles.insert(mesh.triangles.end(), batch.triangles.begin(), batch.triangles.end());
  }
  if (mesh.triangles.empty()) {
    throw ReadError("lod::readMesh(): " + path.string() +
                    ": no triangles (a point cloud, not a mesh)");
  }
  return mesh;
}

}  // namespace tessera::lod
