// Builds a .tmesh patch hierarchy (mesh_store.h) from triangle meshes, and verifies one against
// its inputs. After the patch-LOD thesis (../shared/papers/patch-lod-annotation-thesis.txt,
// chapter 3, Figures 3.3 and 3.4), with its two slow steps replaced:
//  - patches: METIS (k-way, on the triangles' dual graph) cuts the mesh into patches of about
//    `patch_triangles`; groups of `arity` neighbouring nodes are found bottom up by METIS on the
//    graph of the level below (edges weighted by shared border length);
//  - each group is merged and simplified to `patch_triangles` by meshoptimizer's quadric
//    simplifier with the group's border locked (meshopt_SimplifyLockBorder), so the group's
//    border stays made of input edges and any cut of the tree is crack-free. Groups of one level
//    are simplified in parallel (the thesis' "future work").
// A node's error is measured as well as estimated: the larger of meshoptimizer's quadric error
// and the largest distance from its children's removed vertices (up to 1024 of them, evenly
// sampled) to its triangles, plus the largest of its children's errors (by the triangle
// inequality an upper bound on the distance to the input surface, up to that sampling;
// `tessera-lod verify` measures each level against the input both ways).
//
// Memory: a build in memory holds the whole mesh (about 110 bytes a triangle at the peak,
// measured at 17.8 M triangles: 1.8 GB). A mesh whose build would need more than `memory_mb`
// is built in blocks instead (lod/src/mesh_builder_blocks.cpp): the inputs streamed to files
// beside the output, the vertex arrays mapped (about 45 bytes a vertex), one block of as many
// triangles as the rest of the budget allows built at a time, the blocks' tops joined last.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include <tessera/lod/mesh.h>
#include <tessera/lod/mesh_store.h>

namespace tessera::lod {

constexpr uint32_t kMaxMeshThreads = 256;

struct MeshBuildOptions {
  uint32_t patch_triangles = 4096;  ///< leaf patch size and inner nodes' target, 64..1<<20
  uint32_t arity = 4;               ///< children per inner node, 2..8
  uint32_t threads = 0;             ///< 0: every core
  uint64_t memory_mb = 16384;       ///< builds needing more in memory are made in blocks
  /// Triangles a block (0: as many as `memory_mb` allows, and blocks only when the whole mesh
  /// does not fit); set, the build is made in blocks of at most this many (tests, benchmarks).
  uint64_t block_triangles = 0;
  std::filesystem::path temp_dir;  ///< a build in blocks' temporary files (empty: beside `out`)
  bool quiet = false;
};

struct MeshBuildReport {
  uint64_t triangles = 0, vertices = 0;
  uint64_t dropped_triangles = 0;  ///< index out of range or repeated vertex (named on stderr)
  uint64_t nodes = 0, leaves = 0, stored_triangles = 0;
  uint32_t depth = 0;
  uint64_t file_bytes = 0;
  double step = 0.0;            ///< quantisation grid, input units
  double quant_error = 0.0;     ///< largest distance of a vertex to its grid point
  double root_error = 0.0;      ///< the root's error bound, input units
  double seconds = 0.0, seconds_read = 0.0, seconds_partition = 0.0, seconds_simplify = 0.0,
         seconds_write = 0.0;
  uint64_t peak_bytes = 0;  ///< the build's estimated peak memory
  uint64_t blocks = 0;      ///< blocks built one at a time (0: built whole in memory)
};

/// Reads `inputs` (PLY or OBJ meshes, fused into one in the first one's frame) and writes `out`
/// (through out + ".partial", renamed when complete; a build in blocks keeps its temporary
/// files beside it, as out + ".partial.*", and removes them). Throws ReadError for bad inputs,
/// StoreError when the output cannot be written, PreconditionError for bad options.
/// With more than one thread and more than one leaf block (64 patches), a build forks up to
/// `threads` partition workers at its start (lod/src/metis_pool.h: METIS's random generator is
/// process-wide), which only run METIS and are reaped before it returns or throws.
MeshBuildReport buildMeshStore(const std::vector<std::filesystem::path>& inputs,
                               const std::filesystem::path& out, const MeshBuildOptions& options);
/// The same from a mesh in memory (benchmarks, tests).
MeshBuildReport buildMeshStore(const Mesh& mesh, const std::filesystem::path& out,
                               const MeshBuildOptions& options, double seconds_read = 0.0);

struct MeshLevelError {
  uint32_t depth = 0;           ///< from the root; the cut of every node at it (leaves above)
  uint64_t triangles = 0;
  double stated = 0.0;          ///< the largest stated error on the cut
  double max_to_input = 0.0;    ///< sampled: from the cut's surface to the input's
  double max_from_input = 0.0;  ///< sampled: from the input's vertices to the cut's surface
  double mean_to_input = 0.0;
};

struct MeshVerifyReport {
  uint64_t input_triangles = 0;  ///< usable input triangles (dropped ones as the builder drops)
  uint64_t leaf_triangles = 0;
  uint64_t matched = 0;          ///< input triangles found once at the leaves
  uint64_t missing = 0, extra = 0;
  uint64_t corrupt_patches = 0;
  uint64_t error_order_violations = 0;  ///< parents with an error below a child's
  std::vector<MeshLevelError> levels;
  bool ok() const {
    return missing == 0 && extra == 0 && corrupt_patches == 0 && error_order_violations == 0 &&
           matched == input_triangles;
  }
};

/// Checks that the leaves hold every usable input triangle exactly once (as grid positions),
/// that every patch decodes, that errors grow towards the root, and measures each level's
/// distance to the input surface. Throws ReadError / StoreError for files that cannot be read.
MeshVerifyReport verifyMeshStore(const std::filesystem::path& store,
                                 const std::vector<std::filesystem::path>& inputs,
                                 bool quiet = false);

}  // namespace tessera::lod
