#include <tessera/lod/mesh.h>

#include <algorithm>
#include <limits>
#include <system_error>

#include <tessera/lod/point_reader.h>

#include "huge_pages.h"

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
  // The header's counts (trusted only up to what the file's size can hold: a vertex takes at
  // least 6 bytes of text, a triangle 4) size the arrays once, in huge pages (huge_pages.h):
  // the build reads them at random.
  std::error_code ec;
  const uint64_t file_bytes = std::filesystem::file_size(path, ec);
  if (!ec && reader->info().has_declared_points) {
    const size_t points =
        size_t(std::min<uint64_t>(reader->info().declared_points, file_bytes / 6));
    const size_t tris =
        size_t(std::min<uint64_t>(reader->info().declared_triangles, file_bytes / 4));
    detail::reserveHuge(mesh.positions, points);
    if (colors) detail::reserveHuge(mesh.colors, points);
    if (normals) detail::reserveHuge(mesh.normals, points);
    detail::reserveHuge(mesh.triangles, tris);
  }
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
