// A volume of points: uniformly random in the unit cube [0, 1]^3, without colour (the case
// where refinement by spacing alone keeps every leaf), built into a store.
#pragma once

#include <filesystem>
#include <random>

#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>

namespace tessera::test {

/// Writes `n` random points (seeded by n: the same points every run) as a binary PLY at `ply`.
inline void randomCubePly(const std::filesystem::path& ply, size_t n) {
  lod::PointBatch cube;
  cube.reset(0);
  std::mt19937_64 rng(n);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (size_t i = 0; i < n; ++i) cube.positions.push_back({u(rng), u(rng), u(rng)});
  lod::writePly(ply, cube, glm::dvec3(0.0));
}

/// Builds `dir`/cube.tlod from `n` random points (randomCubePly()) with leaves of at most
/// `leaf_max` points, and returns its path.
inline std::filesystem::path randomCubeStore(const std::filesystem::path& dir, size_t n,
                                             uint32_t leaf_max = 16384) {
  randomCubePly(dir / "cube.ply", n);
  lod::BuildOptions o;
  o.quiet = true;
  o.leaf_max = leaf_max;
  lod::buildStore({dir / "cube.ply"}, dir / "cube.tlod", o);
  std::filesystem::remove(dir / "cube.ply");
  return dir / "cube.tlod";
}

}  // namespace tessera::test
