// A mesh as points for see-through rendering: stochastic point-based rendering draws polygon
// meshes by sampling points on their triangles by area (Tanaka et al. 2016, section 3,
// ../shared/papers/spbr-see-through-point-clouds.txt), so a see-through mesh fuses with scans in
// one picture with no depth sorting. The scene path draws a .tmesh model whose opacity is below 1
// from such a point store (store_cache.h builds and caches it), and the mesh pass otherwise.
#pragma once

#include <cstdint>

#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_batch.h>

namespace tessera::lod {

/// Points on the store's leaf triangles (every input triangle once), `per_triangle` of them per
/// triangle on average, each triangle getting its share of the area (stratified: the whole part
/// of area x density, plus one more with the remainder's probability), uniformly inside it;
/// colour interpolated from the vertices when the store has colour, a normal from the triangle.
/// Positions are store-local (world = summary().origin + position). Deterministic for a seed.
/// Throws StoreError when a patch cannot be read.
PointBatch sampleMeshStore(const MeshStore& store, double per_triangle = 4.0, uint64_t seed = 1);

}  // namespace tessera::lod
