#include <tessera/lod/mesh_samples.h>

#include <cmath>

#include "splitmix.h"

namespace tessera::lod {
namespace {

/// Noise depends only on (seed, scanner, cell) / (seed, triangle), never on threads.
uint64_t mix(uint64_t x) { return splitmix64(x); }
double unit(uint64_t& state) {
  state = mix(state);
  return double(state >> 11) * (1.0 / 9007199254740992.0);
}

}  // namespace

PointBatch sampleMeshStore(const MeshStore& store, double per_triangle, uint64_t seed) {
  const MeshSummary& s = store.summary();
  PointBatch out;
  out.attributes = kNormal | (s.colors ? kColor : 0u);
  // The mean triangle area over the leaves sets the density: per_triangle points on a triangle
  // of mean area.
  double total_area = 0.0;
  uint64_t triangles = 0;
  std::vector<MeshPatch> leaves;
  std::vector<NodeId> ids;
  for (NodeId id = 0; id < store.nodeCount(); ++id)
    if (store.record(id).child_count == 0) ids.push_back(id);
  for (NodeId id : ids) {
    MeshPatch p = store.readPatch(id);
    for (size_t t = 0; t < p.triangles(); ++t) {
      const glm::dvec3 a(p.positions[p.indices[3 * t]]), b(p.positions[p.indices[3 * t + 1]]),
          c(p.positions[p.indices[3 * t + 2]]);
      total_area += 0.5 * glm::length(glm::cross(b - a, c - a));
    }
    triangles += p.triangles();
    leaves.push_back(std::move(p));
  }
  if (triangles == 0 || !(total_area > 0)) return out;
  const double density = per_triangle * double(triangles) / total_area;  // points per unit area
  uint64_t tri_index = 0;
  for (const MeshPatch& p : leaves) {
    for (size_t t = 0; t < p.triangles(); ++t, ++tri_index) {
      const uint32_t ia = p.indices[3 * t], ib = p.indices[3 * t + 1], ic = p.indices[3 * t + 2];
      const glm::dvec3 a(p.positions[ia]), b(p.positions[ib]), c(p.positions[ic]);
      const glm::dvec3 n = glm::cross(b - a, c - a);
      const double area = 0.5 * glm::length(n);
      uint64_t state = mix(seed ^ mix(tri_index));
      const double want = area * density;
      uint64_t count = uint64_t(want);
      if (unit(state) < want - double(count)) ++count;
      const glm::vec3 normal = area > 0 ? glm::vec3(n / (2.0 * area)) : glm::vec3(0, 0, 1);
      for (uint64_t k = 0; k < count; ++k) {
        // Uniform in the triangle: fold the unit square's upper half back.
        double u = unit(state), v = unit(state);
        if (u + v > 1.0) {
          u = 1.0 - u;
          v = 1.0 - v;
        }
        out.positions.push_back(p.offset + a + (b - a) * u + (c - a) * v);
        out.normals.push_back(normal);
        if (s.colors) {
          const glm::vec4 col = glm::vec4(p.colors[ia]) * float(1.0 - u - v) +
                                glm::vec4(p.colors[ib]) * float(u) +
                                glm::vec4(p.colors[ic]) * float(v);
          out.colors.push_back(glm::u8vec4(glm::clamp(col + 0.5f, 0.0f, 255.0f)));
        }
      }
    }
  }
  return out;
}

}  // namespace tessera::lod
