// The mesh builder's steps (mesh_builder.h), shared by the in-memory build (mesh_builder.cpp) and
// the build in blocks for meshes beyond the memory budget (mesh_builder_blocks.cpp): a vertex
// set on the store's grid with triangles over it (Prepared), its leaf patches and their
// adjacency, the bottom-up levels, a node's payload, and the file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <unordered_map>
#include <vector>

#include <tessera/core/parallel.h>
#include <tessera/core/progress.h>
#include <tessera/lod/mesh_builder.h>

#include "huge_pages.h"
#include "mesh_format.h"
#include "metis_pool.h"

namespace tessera::lod::meshbuild {

using tessera::parallelFor;
using tessera::threadCount;

/// Throws PreconditionError for options out of range (patch size, arity, threads).
void checkOptions(const MeshBuildOptions& o);

/// Vertices and triangles as the builder works on them: grid positions, normals, triangles by
/// index into them.
struct Prepared {
  glm::dvec3 origin{0.0}, lo{0.0}, hi{0.0};
  double step = 1.0, quant_error = 0.0;
  // The large arrays are written in parallel passes without being zero-filled first
  // (huge_pages.h: DefaultInitAllocator).
  detail::HugeVector<glm::i32vec3> grid;  ///< per vertex
  detail::HugeVector<glm::dvec3> pos;     ///< per vertex: lo + grid * step (what the store holds)
  detail::HugeVector<uint16_t> normals;   ///< octahedral
  std::vector<glm::u8vec4> colors;
  detail::HugeVector<Triangle> tris;
  uint64_t dropped = 0;
  /// Per vertex, the triangles using it, in triangle order (CSR: vertex v's are
  /// tri_items[tri_start[v] .. tri_start[v + 1])); for the normals and the dual graph, then
  /// released.
  detail::HugeVector<uint32_t> tri_start;
  std::unique_ptr<uint32_t[]> tri_items;
};

/// Fills p.tri_start and p.tri_items for `nv` vertices.
void vertexTriangles(Prepared& p, size_t nv, uint32_t threads);

/// A triangle the builder keeps: indices below `nv`, three distinct corners.
inline bool usableTriangle(const Triangle& t, size_t nv) {
  return t.x < nv && t.y < nv && t.z < nv && t.x != t.y && t.y != t.z && t.x != t.z;
}

struct UsableTriangles {
  uint64_t kept = 0;
  std::vector<size_t> range_kept;  ///< per range of the pass (ranges of equal input counts)
  glm::dvec3 lo{0.0}, hi{0.0};     ///< the usable triangles' corners' box
};

/// The usable triangles of tris[0, nt) over `nv` vertices and their box, by ranges in parallel;
/// `used`, when given, gets 1 for every vertex a usable triangle uses. Throws ReadError naming
/// the first corner that is not finite, or when no triangle is usable.
UsableTriangles usableTriangles(const glm::dvec3* positions, size_t nv, const Triangle* tris,
                                size_t nt, uint32_t threads, uint8_t* used);

/// The grid step for a mesh of box extent `extent` (its largest side) whose sampled edge
/// lengths are `edges` (reordered): a 256th of the median edge, never finer than 2^30 steps
/// over the box.
double gridStep(std::vector<double>& edges, double extent);

/// A node while building: its triangles (vertex ids of its Prepared), error, children.
struct BuildNode {
  std::vector<Triangle> tris;
  std::vector<uint32_t> children;  ///< indices into the node list
  float error = 0.0f;
  uint8_t level = 0;  ///< 0 for leaves, one above its highest child otherwise
  glm::dvec3 lo{0.0}, hi{0.0};
};

/// Per node of the current level: the nodes (by their place in the level) it shares edges with,
/// and how many.
using Adjacency = std::vector<std::unordered_map<uint32_t, uint32_t>>;

/// A triangle set's vertices numbered in order of first use: `verts` gets the ids, `local` the
/// local index of each triangle corner (3 a triangle).
void localVertices(size_t vertex_count, const std::vector<Triangle>& tris,
                   std::vector<uint32_t>& verts, std::vector<uint32_t>& local);

/// The leaves: METIS patches of p's dual graph (which releases p's vertex-to-triangle lists),
/// appended to `nodes`; `level` gets their indices, `adjacency` their shared edges.
void buildLeaves(Prepared& p, const MeshBuildOptions& o, uint32_t threads, MetisPool& metis,
                 std::vector<BuildNode>& nodes, std::vector<uint32_t>& level,
                 Adjacency& adjacency);

/// Bottom up while `level` holds more than `stop_at` nodes: groups of neighbours (METIS on the
/// adjacency), merged and simplified with the group's border locked, appended to `nodes`;
/// `level` and `adjacency` are the last level's. `progress` counts groups.
void buildLevels(const Prepared& p, const MeshBuildOptions& o, uint32_t threads,
                 MetisPool& metis, std::vector<BuildNode>& nodes, std::vector<uint32_t>& level,
                 Adjacency& adjacency, size_t stop_at, Progress& progress);

/// The groups buildLevels() makes from `n` nodes, summed over the levels up to one node.
uint64_t groupsUpToRoot(size_t n, uint32_t arity);

/// A node's payload; fills rec's payload, box, error, level and child count (not the offset or
/// the first child).
std::vector<uint8_t> encodeNode(const Prepared& p, const BuildNode& b, MeshNodeRecord& rec);

/// Node ids breadth-first from `root` (children contiguous) of a tree given by `children`.
std::vector<uint32_t> breadthFirst(uint32_t root,
                                   const std::function<const std::vector<uint32_t>&(uint32_t)>& children);

/// Writes the store: `records` by id (first children set, payload fields but the offset set),
/// payloads in depth-first order from `payload(id, bytes)`, through out + ".partial", renamed.
/// Fills the summary's node count, stored triangles, depth and file bytes.
void writeStore(const std::filesystem::path& out, MeshSummary& s,
                std::vector<MeshNodeRecord>& records,
                const std::function<void(uint32_t, std::vector<uint8_t>&)>& payload);

/// The build in blocks (mesh_builder_blocks.cpp): for meshes whose build beyond the budget.
MeshBuildReport buildInBlocks(const std::vector<std::filesystem::path>& inputs,
                              const std::filesystem::path& out, const MeshBuildOptions& o);
MeshBuildReport buildInBlocks(const Mesh& mesh, const std::filesystem::path& out,
                              const MeshBuildOptions& o);

/// Whether the in-memory build of `inputs` fits `memory_mb`, from their headers' counts (a file
/// without counts, OBJ, is judged by its size).
bool inMemoryBuildFits(const std::vector<std::filesystem::path>& inputs, uint64_t memory_mb);

/// Bytes the in-memory build needs for a mesh of `triangles` and `vertices`.
inline uint64_t inMemoryBuildBytes(uint64_t triangles, uint64_t vertices) {
  return triangles * 110 + vertices * 64;
}

}  // namespace tessera::lod::meshbuild
