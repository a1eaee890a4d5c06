#include <tessera/lod/mesh_builder.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <mutex>
#include <numeric>
#include <thread>
#include <tuple>
#include <unordered_map>

#include <meshoptimizer.h>
#include <metis.h>

#include <tessera/core/check.h>
#include <tessera/core/progress.h>
#include <tessera/lod/point_reader.h>

#include "crc32c.h"
#include "file_io.h"
#include "huge_pages.h"
#include "mesh_build_steps.h"
#include "mesh_format.h"
#include "metis_pool.h"
#include "morton.h"
#include "triangle_grid.h"

#include <fcntl.h>
#include <unistd.h>

namespace tessera::lod {
namespace meshbuild {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}


constexpr size_t kChunk = 1 << 16;

/// parallelFor over [0, n) in chunks of kChunk: f(begin, end) for each (cheap bodies over large
/// arrays).
template <class F>
void parallelChunks(size_t n, uint32_t threads, const F& f) {
  parallelFor((n + kChunk - 1) / kChunk, threads,
              [&](size_t c) { f(c * kChunk, std::min(n, (c + 1) * kChunk)); });
}


/// Frees Prepared's vertex-to-triangle lists once the dual graph has them.
void releaseVertexTriangles(Prepared& p) {
  p.tri_start = {};
  p.tri_items.reset();
}

/// Ranges [n r / ranges, n (r + 1) / ranges) of [0, n), one a thread: the parallel passes
/// below split their input so, and stitch the ranges' results in range order, so every result
/// is the serial pass's, on any number of threads.
size_t rangeBegin(size_t n, size_t r, size_t ranges) {
  return n * r / ranges;
}

/// The triangles of every vertex, in triangle order, as a CSR (a counting sort of the
/// triangles' corners by vertex): each range of triangles counts its corners per vertex, the
/// counts' prefix over vertices and ranges gives each range its own place in every vertex's
/// list, and the ranges fill their places in parallel.
void vertexTriangles(Prepared& p, size_t nv, uint32_t threads) {
  const size_t nt = p.tris.size();
  const size_t ranges = std::max<size_t>(1, std::min<size_t>(threads, nt / kChunk + 1));
  std::vector<std::vector<uint32_t>> at(ranges);
  parallelFor(ranges, threads, [&](size_t r) {
    detail::assignHuge(at[r], nv, 0u);
    for (size_t i = rangeBegin(nt, r, ranges); i < rangeBegin(nt, r + 1, ranges); ++i)
      for (int k = 0; k < 3; ++k) ++at[r][p.tris[i][k]];
  });
  // Each range's first place in each vertex's list; the lists' starts.
  detail::sizeHuge(p.tri_start, nv + 1);  // every element written below
  uint32_t next = 0;
  for (size_t v = 0; v < nv; ++v) {
    p.tri_start[v] = next;
    for (size_t r = 0; r < ranges; ++r) {
      const uint32_t c = at[r][v];
      at[r][v] = next;
      next += c;
    }
  }
  p.tri_start[nv] = next;
  p.tri_items = std::make_unique_for_overwrite<uint32_t[]>(nt * 3);  // each written once
  detail::adviseHugePages(p.tri_items.get(), nt * 3 * sizeof(uint32_t));
  parallelFor(ranges, threads, [&](size_t r) {
    for (size_t i = rangeBegin(nt, r, ranges); i < rangeBegin(nt, r + 1, ranges); ++i)
      for (int k = 0; k < 3; ++k) p.tri_items[at[r][p.tris[i][k]]++] = uint32_t(i);
  });
}

UsableTriangles usableTriangles(const glm::dvec3* positions, size_t nv, const Triangle* tris,
                                size_t nt, uint32_t threads, uint8_t* used) {
  const size_t ranges = std::max<size_t>(1, std::min<size_t>(threads, nt / kChunk + 1));
  struct Range {
    size_t kept = 0;
    glm::dvec3 lo{std::numeric_limits<double>::max()}, hi{-std::numeric_limits<double>::max()};
    uint64_t bad_vertex = UINT64_MAX;  // the first corner that is not finite, if any
  };
  std::vector<Range> rs(ranges);
  parallelFor(ranges, threads, [&](size_t r) {
    Range& g = rs[r];
    for (size_t i = rangeBegin(nt, r, ranges); i < rangeBegin(nt, r + 1, ranges); ++i) {
      const Triangle& t = tris[i];
      if (!usableTriangle(t, nv)) continue;
      ++g.kept;
      for (int k = 0; k < 3; ++k) {
        if (used != nullptr) std::atomic_ref<uint8_t>(used[t[k]]).store(1, std::memory_order_relaxed);
        const glm::dvec3& v = positions[t[k]];
        if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) {
          g.bad_vertex = std::min<uint64_t>(g.bad_vertex, t[k]);
          continue;
        }
        g.lo = glm::min(g.lo, v);
        g.hi = glm::max(g.hi, v);
      }
    }
  });
  UsableTriangles u;
  u.lo = glm::dvec3(std::numeric_limits<double>::max());
  u.hi = -u.lo;
  for (const Range& g : rs) {
    if (g.bad_vertex != UINT64_MAX)  // the first range's: the same message on any threads
      throw ReadError("lod::buildMeshStore(): vertex " + std::to_string(g.bad_vertex) +
                      " is not finite");
    u.kept += g.kept;
    u.range_kept.push_back(g.kept);
    u.lo = glm::min(u.lo, g.lo);
    u.hi = glm::max(u.hi, g.hi);
  }
  if (u.kept == 0) throw ReadError("lod::buildMeshStore(): no usable triangles");
  return u;
}

double gridStep(std::vector<double>& edges, double extent) {
  extent = std::max(extent, 1e-30);
  double median = extent / 1024.0;
  if (!edges.empty()) {
    std::nth_element(edges.begin(), edges.begin() + edges.size() / 2, edges.end());
    median = edges[edges.size() / 2];
  }
  return std::max(median / 256.0, extent / double(1 << 30));
}

Prepared prepare(const Mesh& mesh, uint32_t threads) {
  Prepared p;
  p.origin = mesh.origin;
  const size_t nv = mesh.positions.size();
  if (nv > 0xFFFFFFF0ull) throw ReadError("lod::buildMeshStore(): more than 2^32 vertices");
  // Usable triangles and their box, by ranges of triangles in parallel: each range counts and
  // bounds its own, then copies them to its place.
  const size_t nin = mesh.triangles.size();
  const UsableTriangles u =
      usableTriangles(mesh.positions.data(), nv, mesh.triangles.data(), nin, threads, nullptr);
  p.lo = u.lo;
  p.hi = u.hi;
  const size_t kept = u.kept, ranges = u.range_kept.size();
  p.dropped = nin - kept;
  std::vector<size_t> range_at(ranges, 0);
  for (size_t r = 1; r < ranges; ++r) range_at[r] = range_at[r - 1] + u.range_kept[r - 1];
  auto usable = [&](const Triangle& t) { return usableTriangle(t, nv); };
  detail::sizeHuge(p.tris, kept);  // each range writes its own
  parallelFor(ranges, threads, [&](size_t r) {
    size_t at = range_at[r];
    for (size_t i = rangeBegin(nin, r, ranges); i < rangeBegin(nin, r + 1, ranges); ++i)
      if (usable(mesh.triangles[i])) p.tris[at++] = mesh.triangles[i];
  });
  // The grid: a 256th of the median edge (sampled), so quantisation stays far below the
  // detail the mesh resolves; never finer than 2^30 steps over the box (int32 coordinates).
  std::vector<double> edges;
  const size_t stride = std::max<size_t>(1, p.tris.size() / 4096);
  for (size_t i = 0; i < p.tris.size(); i += stride) {
    const double e = glm::length(mesh.positions[p.tris[i].x] - mesh.positions[p.tris[i].y]);
    if (e > 0) edges.push_back(e);
  }
  p.step = gridStep(edges, std::max({p.hi.x - p.lo.x, p.hi.y - p.lo.y, p.hi.z - p.lo.z}));
  detail::sizeHuge(p.grid, nv);  // every element written below
  detail::sizeHuge(p.pos, nv);
  std::vector<double> chunk_error((nv + kChunk - 1) / kChunk, 0.0);
  parallelChunks(nv, threads, [&](size_t begin, size_t end) {
    const size_t chunk = begin / kChunk;
    for (size_t i = begin; i < end; ++i) {
      const glm::dvec3 v = mesh.positions[i];
      if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) {  // unused
        p.grid[i] = glm::i32vec3(0);
        p.pos[i] = glm::dvec3(0.0);
        continue;
      }
      const glm::dvec3 q =
          glm::clamp(glm::round((v - p.lo) / p.step), glm::dvec3(0.0), glm::dvec3(double(1 << 30)));
      p.grid[i] = glm::i32vec3(q);
      p.pos[i] = q * p.step;  // store-local: relative to the box minimum
      chunk_error[chunk] = std::max(chunk_error[chunk], glm::length(p.pos[i] - (v - p.lo)));
    }
  });
  for (double e : chunk_error) p.quant_error = std::max(p.quant_error, e);
  // Normals: the file's, else area-weighted face normals of the whole mesh (so neighbouring
  // patches shade their shared vertices alike).
  vertexTriangles(p, nv, threads);
  const bool file_normals = mesh.normals.size() == nv;
  detail::sizeHuge(p.normals, nv);  // every element written below
  parallelChunks(nv, threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      glm::vec3 n(0.0f);
      if (file_normals) {
        n = mesh.normals[i];
      } else {  // summed in triangle order, per vertex
        for (uint32_t s = p.tri_start[i]; s < p.tri_start[i + 1]; ++s) {
          const Triangle& t = p.tris[p.tri_items[s]];
          n += glm::vec3(glm::cross(p.pos[t.y] - p.pos[t.x], p.pos[t.z] - p.pos[t.x]));
        }
      }
      p.normals[i] = meshfmt::octEncode(n);
    }
  });
  if (mesh.colors.size() == nv) p.colors = mesh.colors;
  return p;
}

/// METIS k-way partition of a CSR graph into `parts`; part ids dense from 0 (empty parts
/// dropped). Returns the part count.
uint32_t partition(MetisPool& metis, const std::vector<idx_t>& xadj,
                   const std::vector<idx_t>& adjncy, const std::vector<idx_t>* vwgt,
                   const std::vector<idx_t>* adjwgt, uint32_t parts, std::vector<uint32_t>& out) {
  const idx_t n = idx_t(xadj.size() - 1);
  out.assign(size_t(n), 0);
  if (parts <= 1 || n <= 1) return n > 0 ? 1 : 0;
  if (parts >= uint32_t(n)) {
    std::iota(out.begin(), out.end(), 0u);
    return uint32_t(n);
  }
  // The same seed for every call: a call's parts depend on its graph only (metis_pool.h), so the
  // same mesh makes the same store on any number of threads.
  constexpr idx_t kSeed = 42;
  std::vector<idx_t> part;
  const int rc = metis.partGraphKway(xadj, adjncy, vwgt, adjwgt, idx_t(parts), kSeed, part);
  if (rc != METIS_OK)
    throw std::runtime_error("lod::buildMeshStore(): METIS failed (" + std::to_string(rc) + ")");
  std::vector<int64_t> dense(parts, -1);
  uint32_t count = 0;
  for (size_t i = 0; i < part.size(); ++i) {
    auto& d = dense[size_t(part[i])];
    if (d < 0) d = count++;
    out[i] = uint32_t(d);
  }
  return count;
}

/// A triangle set's vertices numbered in order of first use: `verts` gets the global ids,
/// `local` the local index of each triangle corner. O(corners): an open-addressing table sized
/// to the set (per thread, reused), not one over every vertex of the mesh, which each of
/// parallelFor()'s new threads had to allocate and fill (36 MB a thread at 9 M vertices).
void localVertices(size_t vertex_count, const std::vector<Triangle>& tris,
                   std::vector<uint32_t>& verts, std::vector<uint32_t>& local) {
  thread_local std::vector<uint64_t> table;  // (global id + 1) << 32 | local index; 0: empty
  const size_t most = std::min(tris.size() * 3, vertex_count);  // distinct vertices
  int bits = 4;
  while ((size_t(1) << bits) < 2 * most) ++bits;  // at most half full
  const size_t mask = (size_t(1) << bits) - 1;
  table.assign(mask + 1, 0);
  verts.clear();
  local.resize(tris.size() * 3);
  for (size_t t = 0; t < tris.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = tris[t][k];
      const uint64_t key = (uint64_t(v) + 1) << 32;
      size_t h = size_t((uint64_t(v) * 0x9E3779B97F4A7C15ull) >> (64 - bits));
      while (table[h] != 0 && (table[h] & ~0xFFFFFFFFull) != key) h = (h + 1) & mask;
      if (table[h] == 0) {
        table[h] = key | verts.size();
        verts.push_back(v);
      }
      local[3 * t + size_t(k)] = uint32_t(table[h]);
    }
}

constexpr size_t kBlockPatches = 64;

/// std::sort of `v` (whose elements are all distinct, so the order is unique) by ranges in
/// parallel, then merged pairwise.
template <class T, class A>
void sortInRanges(std::vector<T, A>& v, uint32_t threads) {
  const size_t ranges = std::max<size_t>(1, std::min<size_t>(threads, v.size() / kChunk + 1));
  parallelFor(ranges, threads, [&](size_t r) {
    std::sort(v.begin() + std::ptrdiff_t(rangeBegin(v.size(), r, ranges)),
              v.begin() + std::ptrdiff_t(rangeBegin(v.size(), r + 1, ranges)));
  });
  for (size_t width = 1; width < ranges; width *= 2) {
    const size_t pairs = (ranges + 2 * width - 1) / (2 * width);
    parallelFor(pairs, threads, [&](size_t i) {
      const size_t a = 2 * width * i, m = std::min(ranges, a + width),
                   b = std::min(ranges, a + 2 * width);
      if (m == b) return;
      std::inplace_merge(v.begin() + std::ptrdiff_t(rangeBegin(v.size(), a, ranges)),
                         v.begin() + std::ptrdiff_t(rangeBegin(v.size(), m, ranges)),
                         v.begin() + std::ptrdiff_t(rangeBegin(v.size(), b, ranges)));
    });
  }
}

/// Leaf patches: METIS k-way on the dual graph, into parts of about `patch` triangles. Large
/// meshes are first cut into blocks of consecutive triangles in Morton order of their
/// centroids (kBlockPatches patches each), partitioned in parallel: METIS on the whole graph
/// took 94 of a 17.8 M-triangle build's 189 s on one core. `part` gets each triangle's patch.
uint32_t leafPatches(const Prepared& p, const detail::HugeVector<idx_t>& xadj,
                     const detail::HugeVector<idx_t>& adjncy, uint32_t patch, uint32_t threads,
                     MetisPool& metis, detail::HugeVector<uint32_t>& part) {
  const size_t nt = p.tris.size(), block = size_t(patch) * kBlockPatches;
  detail::sizeHuge(part, nt);  // written by the blocks below (`order` is a permutation)
  // Triangles in Morton order of their centroids' grid cells (21 bits an axis).
  detail::HugeVector<std::pair<uint64_t, uint32_t>> order;
  detail::sizeHuge(order, nt);
  glm::i64vec3 hi(1);
  for (const glm::i32vec3& g : p.grid) hi = glm::max(hi, glm::i64vec3(g));
  const int shift =
      std::max(0, int(std::ceil(std::log2(double(std::max({hi.x, hi.y, hi.z}) + 1)))) - 21);
  parallelChunks(nt, threads, [&](size_t begin, size_t end) {
    for (size_t t = begin; t < end; ++t) {
      const glm::i64vec3 c =
          (glm::i64vec3(p.grid[p.tris[t].x]) + glm::i64vec3(p.grid[p.tris[t].y]) +
           glm::i64vec3(p.grid[p.tris[t].z])) /
          int64_t(3);
      order[t] = {
          mortonEncode(uint64_t(c.x >> shift), uint64_t(c.y >> shift), uint64_t(c.z >> shift)),
          uint32_t(t)};
    }
  });
  if (nt > block) sortInRanges(order, threads);
  const size_t blocks = (nt + block - 1) / block;
  std::vector<uint32_t> first_part(blocks + 1, 0), block_parts(blocks, 0);
  detail::HugeVector<uint32_t> local_of;
  detail::sizeHuge(local_of, nt);
  parallelChunks(nt, threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) local_of[order[i].second] = uint32_t(i % block);
  });
  parallelFor(blocks, threads, [&](size_t b) {
    const size_t begin = b * block, end = std::min(nt, begin + block);
    // The block's own graph: edges to other blocks dropped.
    std::vector<idx_t> bx(end - begin + 1, 0), ba;
    for (size_t i = begin; i < end; ++i) {
      const uint32_t t = order[i].second;
      for (idx_t e = xadj[t]; e < xadj[t + 1]; ++e) {
        const uint32_t u = uint32_t(adjncy[size_t(e)]);
        const size_t ui = size_t(local_of[u]) + begin;
        if (ui < end && order[ui].second == u) ba.push_back(idx_t(local_of[u]));
      }
      bx[i - begin + 1] = idx_t(ba.size());
    }
    std::vector<uint32_t> local;
    const uint32_t want = uint32_t((end - begin + patch - 1) / patch);
    block_parts[b] = partition(metis, bx, ba, nullptr, nullptr, want, local);
    for (size_t i = begin; i < end; ++i) part[order[i].second] = local[i - begin];
  });
  for (size_t b = 0; b < blocks; ++b) first_part[b + 1] = first_part[b] + block_parts[b];
  parallelChunks(nt, threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) part[order[i].second] += first_part[i / block];
  });
  return first_part[blocks];
}

/// Simplifies a group's merged triangles with its border locked; returns the parent's triangles
/// and its error: the larger of meshoptimizer's quadric estimate and the largest distance from
/// the group's removed vertices (a sample of them) to the parent's triangles.
std::pair<std::vector<Triangle>, double> simplifyGroup(const Prepared& p,
                                                       const std::vector<Triangle>& tris,
                                                       uint32_t target) {
  // Local vertices (meshoptimizer allocates per vertex: keep it to the group's).
  std::vector<uint32_t> verts, local;
  localVertices(p.grid.size(), tris, verts, local);
  std::vector<glm::vec3> pos(verts.size());
  glm::dvec3 base = p.pos[verts[0]];
  for (size_t i = 0; i < verts.size(); ++i) pos[i] = glm::vec3(p.pos[verts[i]] - base);
  std::vector<uint32_t> out(local.size());
  float rel_error = 0.0f;
  const size_t kept = meshopt_simplify(out.data(), local.data(), local.size(), &pos[0].x,
                                       pos.size(), sizeof(glm::vec3), size_t(target) * 3, 1.0f,
                                       meshopt_SimplifyLockBorder, &rel_error);
  out.resize(kept);
  std::vector<Triangle> result(kept / 3);
  for (size_t t = 0; t < result.size(); ++t)
    result[t] = Triangle(verts[out[3 * t]], verts[out[3 * t + 1]], verts[out[3 * t + 2]]);
  // Measured: the group's vertices against the simplified surface (the parent's vertices are a
  // subset of them, so this is where detail was lost).
  std::vector<uint32_t> flat(result.size() * 3);
  for (size_t t = 0; t < result.size(); ++t)
    for (int k = 0; k < 3; ++k) flat[3 * t + k] = result[t][k];
  // Kept vertices lie on it; the removed ones are sampled (at most kErrorSamples, evenly over
  // the group) so the measurement costs a bounded share of the build.
  constexpr size_t kErrorSamples = 1024;
  double measured = 0.0;
  if (!result.empty()) {
    std::vector<uint8_t> kept_vertex(verts.size(), 0);
    for (uint32_t i : out) kept_vertex[i] = 1;
    std::vector<uint32_t> removed;
    for (size_t i = 0; i < verts.size(); ++i)
      if (!kept_vertex[i]) removed.push_back(verts[i]);
    const size_t stride = std::max<size_t>(1, removed.size() / kErrorSamples);
    TriangleGrid grid(p.pos, flat);
    for (size_t i = 0; i < removed.size(); i += stride)
      measured = std::max(measured, grid.distance(p.pos[removed[i]]));
  }
  const double estimated =
      double(rel_error) * meshopt_simplifyScale(&pos[0].x, pos.size(), sizeof(glm::vec3));
  return {std::move(result), std::max(measured, estimated)};
}

void bounds(const Prepared& p, BuildNode& n) {
  n.lo = glm::dvec3(std::numeric_limits<double>::max());
  n.hi = -n.lo;
  for (const Triangle& t : n.tris)
    for (int k = 0; k < 3; ++k) {
      n.lo = glm::min(n.lo, p.pos[t[k]]);
      n.hi = glm::max(n.hi, p.pos[t[k]]);
    }
}

/// The triangles' dual graph (triangles sharing an edge), CSR for METIS.
void dualGraph(const Prepared& p, uint32_t threads, detail::HugeVector<idx_t>& xadj,
               detail::HugeVector<idx_t>& adjncy) {
  const size_t nt = p.tris.size();
  const detail::HugeVector<uint32_t>& start = p.tri_start;
  const uint32_t* items = p.tri_items.get();
  // Neighbours per triangle in parallel, at most kSlots each (an edge of a manifold has one
  // other triangle; a non-manifold edge's further ones beyond the slots are left out of the
  // graph: it only steers the partition), then packed.
  constexpr int kSlots = 6;
  const auto slots = std::make_unique_for_overwrite<uint32_t[]>(nt * kSlots);  // counts[i] used
  detail::adviseHugePages(slots.get(), nt * kSlots * sizeof(uint32_t));
  detail::HugeVector<uint8_t> counts;
  detail::sizeHuge(counts, nt);  // every element written below
  parallelChunks(nt, threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const Triangle& t = p.tris[i];
      uint32_t* mine = &slots[i * kSlots];
      int n = 0;
      for (int k = 0; k < 3; ++k) {
        // The triangles on edge (a, b): those in both corners' lists, which are sorted (the
        // lists are in triangle order), so a merge finds them without reading any triangle.
        const uint32_t a = t[k], b = t[(k + 1) % 3];
        uint32_t sb = start[b];
        const uint32_t eb = start[b + 1];
        for (uint32_t s = start[a]; s < start[a + 1] && n < kSlots; ++s) {
          const uint32_t u = items[s];
          while (sb < eb && items[sb] < u) ++sb;
          if (sb == eb) break;
          if (items[sb] != u || u == i) continue;
          if (std::find(mine, mine + n, u) == mine + n) mine[n++] = u;
        }
      }
      counts[i] = uint8_t(n);
    }
  });
  detail::sizeHuge(xadj, nt + 1);
  xadj[0] = 0;
  for (size_t i = 0; i < nt; ++i) xadj[i + 1] = xadj[i] + counts[i];
  detail::sizeHuge(adjncy, size_t(xadj[nt]));  // every element written below
  parallelChunks(nt, threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i)
      for (int k = 0; k < counts[i]; ++k)
        adjncy[size_t(xadj[i]) + k] = idx_t(slots[i * kSlots + k]);
  });
}

/// The inputs fused into one mesh in the first one's frame.
Mesh readMeshes(const std::vector<std::filesystem::path>& inputs) {
  Mesh mesh;
  for (const auto& in : inputs) {
    Mesh m = readMesh(in);
    if (mesh.positions.empty()) {
      mesh = std::move(m);
      continue;
    }
    const uint32_t base = uint32_t(mesh.positions.size());
    const glm::dvec3 shift = m.origin - mesh.origin;
    for (const glm::dvec3& v : m.positions) mesh.positions.push_back(v + shift);
    for (const Triangle& t : m.triangles) mesh.triangles.push_back(t + base);
    // Attributes survive only when every input has them.
    if (mesh.colors.size() + m.colors.size() == mesh.positions.size()) {
      mesh.colors.insert(mesh.colors.end(), m.colors.begin(), m.colors.end());
    } else {
      mesh.colors.clear();
    }
    if (mesh.normals.size() + m.normals.size() == mesh.positions.size()) {
      mesh.normals.insert(mesh.normals.end(), m.normals.begin(), m.normals.end());
    } else {
      mesh.normals.clear();
    }
  }
  return mesh;
}

void buildLeaves(Prepared& p, const MeshBuildOptions& o, uint32_t threads, MetisPool& metis,
                 std::vector<BuildNode>& nodes, std::vector<uint32_t>& level,
                 Adjacency& adjacency) {
  detail::HugeVector<idx_t> xadj, adjncy;
  dualGraph(p, threads, xadj, adjncy);
  releaseVertexTriangles(p);
  detail::HugeVector<uint32_t> part;
  const uint32_t parts = leafPatches(p, xadj, adjncy, o.patch_triangles, threads, metis, part);
  // Each leaf's triangles and shared edges, by ranges of leaves in parallel. Every range scans
  // all triangles in order, so a leaf gets its triangles, and its map their neighbours, in the
  // order of one pass: the same store on any number of threads.
  const size_t first = nodes.size();
  nodes.resize(first + parts);
  adjacency.assign(parts, {});
  const size_t ranges = std::min<size_t>(threads, parts);
  parallelFor(ranges, threads, [&](size_t range) {
    const uint32_t lo = uint32_t(parts * range / ranges);
    const uint32_t hi = uint32_t(parts * (range + 1) / ranges);
    std::vector<uint32_t> count(hi - lo, 0);
    for (uint32_t a : part)
      if (a >= lo && a < hi) ++count[a - lo];
    for (uint32_t a = lo; a < hi; ++a) nodes[first + a].tris.reserve(count[a - lo]);
    for (size_t t = 0; t < p.tris.size(); ++t) {
      const uint32_t a = part[t];
      if (a < lo || a >= hi) continue;
      nodes[first + a].tris.push_back(p.tris[t]);
      for (idx_t e = xadj[t]; e < xadj[t + 1]; ++e) {
        const uint32_t b = part[size_t(adjncy[size_t(e)])];
        if (a != b) ++adjacency[a][b];
      }
    }
  });
  parallelFor(parts, threads, [&](size_t i) {
    bounds(p, nodes[first + i]);
    nodes[first + i].error = float(p.quant_error);
  });
  level.resize(parts);
  std::iota(level.begin(), level.end(), uint32_t(first));
}

uint64_t groupsUpToRoot(size_t n, uint32_t arity) {
  uint64_t groups = 0;
  for (; n > 1; n = (n + arity - 1) / arity) groups += (n + arity - 1) / arity;
  return groups;
}

void buildLevels(const Prepared& p, const MeshBuildOptions& o, uint32_t threads,
                 MetisPool& metis, std::vector<BuildNode>& nodes, std::vector<uint32_t>& level_nodes,
                 Adjacency& adjacency, size_t stop_at, Progress& progress) {
  while (level_nodes.size() > std::max<size_t>(1, stop_at)) {
    const size_t n = level_nodes.size();
    std::vector<uint32_t> group;
    uint32_t groups = 1;
    if (n > o.arity) {
      std::vector<idx_t> xadj(n + 1, 0), adjncy, vwgt(n), adjwgt;
      for (size_t i = 0; i < n; ++i) {
        for (const auto& [j, w] : adjacency[i]) {
          adjncy.push_back(idx_t(j));
          adjwgt.push_back(idx_t(std::min<uint32_t>(w, 1u << 30)));
        }
        xadj[i + 1] = idx_t(adjncy.size());
        vwgt[i] = idx_t(std::max<size_t>(1, nodes[level_nodes[i]].tris.size()));
      }
      groups = partition(metis, xadj, adjncy, &vwgt, &adjwgt, uint32_t((n + o.arity - 1) / o.arity),
                         group);
    } else {
      group.assign(n, 0);
    }
    // METIS may make a group larger than the arity allows (child_count is a byte): split those.
    std::vector<std::vector<uint32_t>> members(groups);
    for (size_t i = 0; i < n; ++i) members[group[i]].push_back(uint32_t(i));
    std::vector<std::vector<uint32_t>> split;
    for (auto& m : members) {
      for (size_t s = 0; s < m.size(); s += meshfmt::kMaxChildren)
        split.emplace_back(
            m.begin() + std::ptrdiff_t(s),
            m.begin() + std::ptrdiff_t(std::min(m.size(), s + meshfmt::kMaxChildren)));
    }
    std::vector<uint32_t> group_of(n);
    for (size_t g = 0; g < split.size(); ++g)
      for (uint32_t i : split[g]) group_of[i] = uint32_t(g);
    const size_t first = nodes.size();
    nodes.resize(first + split.size());
    std::mutex progress_mutex;
    parallelFor(split.size(), threads, [&](size_t g) {
      BuildNode& parent = nodes[first + g];
      std::vector<Triangle> merged;
      float child_error = 0.0f;
      uint8_t child_level = 0;
      for (uint32_t i : split[g]) {
        const BuildNode& c = nodes[level_nodes[i]];
        merged.insert(merged.end(), c.tris.begin(), c.tris.end());
        parent.children.push_back(level_nodes[i]);
        child_error = std::max(child_error, c.error);
        child_level = std::max(child_level, c.level);
      }
      const uint32_t target =
          uint32_t(std::min<size_t>(o.patch_triangles, std::max<size_t>(1, merged.size() / 2)));
      auto [tris, measured] = simplifyGroup(p, merged, target);
      parent.tris = std::move(tris);
      parent.error = float(double(child_error) + measured);
      parent.error = std::nextafter(parent.error, std::numeric_limits<float>::infinity());
      parent.level = uint8_t(child_level + 1);
      bounds(p, parent);
      for (uint32_t i : split[g]) {  // a parent's box holds its children's (culling)
        parent.lo = glm::min(parent.lo, nodes[level_nodes[i]].lo);
        parent.hi = glm::max(parent.hi, nodes[level_nodes[i]].hi);
      }
      std::lock_guard lock(progress_mutex);
      progress.add(1);
    });
    Adjacency next(split.size());
    for (size_t i = 0; i < n; ++i)
      for (const auto& [j, w] : adjacency[i])
        if (group_of[i] != group_of[j]) next[group_of[i]][group_of[j]] += w;
    adjacency = std::move(next);
    level_nodes.resize(split.size());
    std::iota(level_nodes.begin(), level_nodes.end(), uint32_t(first));
  }
}

std::vector<uint8_t> encodeNode(const Prepared& p, const BuildNode& b, MeshNodeRecord& rec) {
  const bool colors = !p.colors.empty();
  std::vector<uint32_t> ids, idx;
  localVertices(p.grid.size(), b.tris, ids, idx);
  std::vector<meshfmt::QuantVertex> verts(ids.size());
  for (size_t i = 0; i < ids.size(); ++i) {
    verts[i].grid = p.grid[ids[i]];
    verts[i].normal = p.normals[ids[i]];
    if (colors) verts[i].color = p.colors[ids[i]];
  }
  std::vector<uint8_t> payload = meshfmt::encodePatch(std::move(verts), std::move(idx), colors, rec);
  rec.payload_bytes = uint32_t(payload.size());
  rec.payload_crc = crc32c(payload.data(), payload.size());
  rec.box_min = glm::vec3(b.lo);
  rec.box_max = glm::vec3(b.hi);
  rec.error = b.error;
  rec.level = b.level;
  rec.child_count = uint8_t(b.children.size());
  return payload;
}

std::vector<uint32_t> breadthFirst(
    uint32_t root, const std::function<const std::vector<uint32_t>&(uint32_t)>& children) {
  std::vector<uint32_t> bfs{root};
  for (size_t i = 0; i < bfs.size(); ++i)
    for (uint32_t c : children(bfs[i])) bfs.push_back(c);
  return bfs;
}

void writeStore(const std::filesystem::path& out, MeshSummary& s,
                std::vector<MeshNodeRecord>& records,
                const std::function<void(uint32_t, std::vector<uint8_t>&)>& payload) {
  s.nodes = records.size();
  s.stored_triangles = 0;
  uint32_t depth = 0;
  for (const auto& rec : records) {
    s.stored_triangles += rec.triangles;
    depth = std::max<uint32_t>(depth, rec.level);
  }
  s.depth = depth + 1;
  // Depth-first payload order (a subtree's patches lie together on disk).
  std::vector<uint32_t> dfs, stack{0};
  while (!stack.empty()) {
    const uint32_t id = stack.back();
    stack.pop_back();
    dfs.push_back(id);
    for (uint32_t c = records[id].child_count; c-- > 0;)
      stack.push_back(records[id].first_child + c);
  }
  uint64_t at = meshfmt::kHeaderBytes;
  for (uint32_t id : dfs) {
    records[id].payload_offset = at;
    at += records[id].payload_bytes;
  }
  const uint64_t table_offset = at;
  std::vector<uint8_t> table;
  for (const auto& rec : records) {
    const auto bytes = meshfmt::writeNode(rec);
    table.insert(table.end(), bytes.begin(), bytes.end());
  }
  s.file_bytes = table_offset + table.size();
  const std::filesystem::path partial = out.string() + ".partial";
  {
    ScopedFd fd(partial, O_WRONLY | O_CREAT | O_TRUNC, "the mesh store being written");
    const auto header = meshfmt::writeHeader(s, table_offset, crc32c(table.data(), table.size()));
    pwriteAll(fd.get(), header.data(), header.size(), 0, fd.name());
    std::vector<uint8_t> bytes;
    for (uint32_t id : dfs) {
      payload(id, bytes);
      TESSERA_CHECK(bytes.size() == records[id].payload_bytes,
                    "lod::buildMeshStore(): a payload changed size");
      pwriteAll(fd.get(), bytes.data(), bytes.size(), records[id].payload_offset, fd.name());
    }
    pwriteAll(fd.get(), table.data(), table.size(), table_offset, fd.name());
    if (::fsync(fd.get()) != 0)
      throw StoreError("lod::buildMeshStore(): fsync " + fd.name() + " failed");
  }
  std::error_code ec;
  std::filesystem::rename(partial, out, ec);
  if (ec) {
    std::filesystem::remove(partial, ec);
    throw StoreError("lod::buildMeshStore(): cannot rename " + partial.string() + " to " +
                     out.string());
  }
}

void checkOptions(const MeshBuildOptions& o) {
  TESSERA_CHECK(o.patch_triangles >= 64 && o.patch_triangles <= (1u << 20),
                "lod::buildMeshStore(): patch_triangles must be in 64..1048576");
  TESSERA_CHECK(o.arity >= 2 && o.arity <= 8, "lod::buildMeshStore(): arity must be in 2..8");
  TESSERA_CHECK(o.threads <= kMaxMeshThreads, "lod::buildMeshStore(): at most 256 threads");
}

}  // namespace meshbuild

using namespace meshbuild;

MeshBuildReport buildMeshStore(const std::vector<std::filesystem::path>& inputs,
                               const std::filesystem::path& out, const MeshBuildOptions& o) {
  TESSERA_CHECK(!inputs.empty(), "lod::buildMeshStore(): no inputs");
  if (o.block_triangles > 0 || !inMemoryBuildFits(inputs, o.memory_mb))
    return buildInBlocks(inputs, out, o);
  const auto t0 = Clock::now();
  const Mesh mesh = readMeshes(inputs);
  return buildMeshStore(mesh, out, o, since(t0));
}

MeshBuildReport buildMeshStore(const Mesh& mesh, const std::filesystem::path& out,
                               const MeshBuildOptions& o, double seconds_read) {
  checkOptions(o);
  const uint64_t need = inMemoryBuildBytes(mesh.triangles.size(), mesh.positions.size());
  if (o.block_triangles > 0 || need > o.memory_mb * (1ull << 20))
    return buildInBlocks(mesh, out, o);
  const auto t0 = Clock::now();
  MeshBuildReport r;
  r.seconds_read = seconds_read;
  r.peak_bytes = need;
  const uint32_t threads =
      threadCount(int(o.threads));
  // Partition workers, one per thread that can use one, forked before any thread starts and
  // while the process is smallest (metis_pool.h: METIS's generator is process-wide). Leaf
  // blocks are the only calls made concurrently; a single block needs none.
  const size_t blocks = (mesh.triangles.size() + size_t(o.patch_triangles) * kBlockPatches - 1) /
                        (size_t(o.patch_triangles) * kBlockPatches);
  MetisPool metis(threads > 1 && blocks > 1 ? uint32_t(std::min<size_t>(threads, blocks)) : 0);
  Prepared p = prepare(mesh, threads);
  r.triangles = p.tris.size();
  r.dropped_triangles = p.dropped;
  r.step = p.step;
  r.quant_error = p.quant_error;
  for (size_t v = 0; v < p.grid.size(); ++v) r.vertices += p.tri_start[v + 1] > p.tri_start[v];

  // Leaves: METIS patches of the dual graph.
  const auto tp = Clock::now();
  std::vector<BuildNode> nodes;
  std::vector<uint32_t> level_nodes;  // the current level's node indices
  Adjacency adjacency;                // per current node: shared edges
  buildLeaves(p, o, threads, metis, nodes, level_nodes, adjacency);
  r.leaves = nodes.size();
  r.seconds_partition = since(tp);

  // Bottom up: group neighbours, merge, simplify with the group's border locked.
  const auto ts = Clock::now();
  Progress progress("simplify", groupsUpToRoot(level_nodes.size(), o.arity), "patches", o.quiet);
  buildLevels(p, o, threads, metis, nodes, level_nodes, adjacency, 1, progress);
  progress.finish();
  r.seconds_simplify = since(ts);

  // Ids breadth-first from the root (children contiguous), payloads depth-first.
  const auto tw = Clock::now();
  const std::vector<uint32_t> bfs =
      breadthFirst(level_nodes.front(), [&](uint32_t i) -> const std::vector<uint32_t>& {
        return nodes[i].children;
      });
  std::vector<uint32_t> id_of(nodes.size());
  for (size_t i = 0; i < bfs.size(); ++i) id_of[bfs[i]] = uint32_t(i);
  std::vector<MeshNodeRecord> records(bfs.size());
  std::vector<std::vector<uint8_t>> payloads(bfs.size());
  parallelFor(bfs.size(), threads, [&](size_t id) {
    const BuildNode& b = nodes[bfs[id]];
    payloads[id] = encodeNode(p, b, records[id]);
    records[id].first_child = b.children.empty() ? 0 : id_of[b.children.front()];
  });
  // Children were pushed in order, so their ids are contiguous; check it.
  for (size_t id = 0; id < bfs.size(); ++id) {
    const BuildNode& b = nodes[bfs[id]];
    for (size_t c = 0; c < b.children.size(); ++c)
      TESSERA_CHECK(id_of[b.children[c]] == records[id].first_child + c,
                    "lod::buildMeshStore(): children not contiguous");
  }
  MeshSummary s;
  s.origin = p.origin + p.lo;  // store-local frame: the box minimum at 0
  s.bbox_min = glm::dvec3(0.0);
  s.bbox_max = p.hi - p.lo;
  s.step = p.step;
  s.input_triangles = r.triangles;
  s.input_vertices = r.vertices;
  s.colors = !p.colors.empty();
  writeStore(out, s, records,
             [&](uint32_t id, std::vector<uint8_t>& bytes) { bytes.swap(payloads[id]); });
  r.nodes = records.size();
  r.depth = s.depth;
  r.stored_triangles = s.stored_triangles;
  r.file_bytes = s.file_bytes;
  r.root_error = records[0].error;
  r.seconds_write = since(tw);
  r.seconds = seconds_read + since(t0);
  return r;
}

namespace {

/// A triangle by its vertices' grid positions, rotated so the smallest comes first (the
/// orientation kept): the same key wherever the triangle is stored.
uint64_t triangleKey(glm::i32vec3 a, glm::i32vec3 b, glm::i32vec3 c) {
  auto less = [](const glm::i32vec3& x, const glm::i32vec3& y) {
    return std::tie(x.x, x.y, x.z) < std::tie(y.x, y.y, y.z);
  };
  if (less(b, a) && !less(c, b))
    std::tie(a, b, c) = std::make_tuple(b, c, a);
  else if (less(c, a) && less(c, b))
    std::tie(a, b, c) = std::make_tuple(c, a, b);
  uint64_t h = 0x243F6A8885A308D3ull;
  for (const glm::i32vec3* v : {&a, &b, &c})
    for (int k = 0; k < 3; ++k) {
      h ^= uint64_t(uint32_t((*v)[k])) + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
      h = (h ^ (h >> 31)) * 0xBF58476D1CE4E5B9ull;
    }
  return h;
}

}  // namespace

MeshVerifyReport verifyMeshStore(const std::filesystem::path& store_path,
                                 const std::vector<std::filesystem::path>& inputs, bool quiet) {
  auto store = MeshStore::open(store_path);
  const MeshSummary& s = store->summary();
  const Mesh mesh = readMeshes(inputs);
  MeshVerifyReport r;
  // The input on the store's grid, in the store's local frame.
  const glm::dvec3 shift = s.origin - mesh.origin;
  std::vector<glm::i32vec3> grid(mesh.positions.size());
  std::vector<glm::dvec3> input_pos(mesh.positions.size());
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const glm::dvec3 q = glm::round((mesh.positions[i] - shift) / s.step);
    grid[i] = glm::i32vec3(glm::clamp(q, glm::dvec3(-2e9), glm::dvec3(2e9)));
    input_pos[i] = mesh.positions[i] - shift;
  }
  std::vector<uint64_t> want;
  std::vector<uint32_t> input_idx;
  const size_t nv = mesh.positions.size();
  for (const Triangle& t : mesh.triangles) {
    if (t.x >= nv || t.y >= nv || t.z >= nv || t.x == t.y || t.y == t.z || t.x == t.z) continue;
    want.push_back(triangleKey(grid[t.x], grid[t.y], grid[t.z]));
    input_idx.insert(input_idx.end(), {t.x, t.y, t.z});
  }
  r.input_triangles = want.size();
  // Decode every patch once: leaves' keys, each node's triangles for the level cuts.
  std::vector<std::vector<glm::dvec3>> patch_pos(store->nodeCount());
  std::vector<std::vector<uint32_t>> patch_idx(store->nodeCount());
  std::vector<uint64_t> have;
  std::vector<uint32_t> depth_of(store->nodeCount(), 0);
  Progress progress("verify", store->nodeCount(), "patches", quiet);
  for (NodeId id = 0; id < store->nodeCount(); ++id) {
    const MeshNodeRecord& rec = store->record(id);
    for (uint32_t c = 0; c < rec.child_count; ++c) {
      depth_of[rec.first_child + c] = depth_of[id] + 1;
      if (store->record(rec.first_child + c).error > rec.error) ++r.error_order_violations;
    }
    try {
      MeshPatch patch = store->readPatch(id);
      for (const glm::i32vec3& g : patch.grid) patch_pos[id].push_back(glm::dvec3(g) * s.step);
      patch_idx[id] = patch.indices;
      if (rec.child_count == 0) {
        for (size_t t = 0; t < patch.triangles(); ++t)
          have.push_back(triangleKey(patch.grid[patch.indices[3 * t]],
                                     patch.grid[patch.indices[3 * t + 1]],
                                     patch.grid[patch.indices[3 * t + 2]]));
      }
    } catch (const StoreError& e) {
      std::fprintf(stderr, "%s\n", e.what());
      ++r.corrupt_patches;
    }
    progress.add(1);
  }
  progress.finish();
  r.leaf_triangles = have.size();
  std::sort(want.begin(), want.end());
  std::sort(have.begin(), have.end());
  size_t i = 0, j = 0;
  while (i < want.size() || j < have.size()) {
    if (j == have.size() || (i < want.size() && want[i] < have[j])) {
      ++r.missing;
      ++i;
    } else if (i == want.size() || have[j] < want[i]) {
      ++r.extra;
      ++j;
    } else {
      ++r.matched;
      ++i;
      ++j;
    }
  }
  // Each level's cut against the input surface, both ways, sampled.
  const TriangleGrid input_grid(input_pos, input_idx);
  const uint32_t max_depth = *std::max_element(depth_of.begin(), depth_of.end());
  constexpr size_t kSamples = 20000;
  for (uint32_t d = 0; d <= max_depth; ++d) {
    MeshLevelError e;
    e.depth = d;
    std::vector<glm::dvec3> pos;
    std::vector<uint32_t> idx;
    for (NodeId id = 0; id < store->nodeCount(); ++id) {
      const bool on_cut =
          depth_of[id] == d || (depth_of[id] < d && store->record(id).child_count == 0);
      if (!on_cut) continue;
      e.stated = std::max(e.stated, double(store->record(id).error));
      const uint32_t base = uint32_t(pos.size());
      pos.insert(pos.end(), patch_pos[id].begin(), patch_pos[id].end());
      for (uint32_t k : patch_idx[id]) idx.push_back(base + k);
    }
    e.triangles = idx.size() / 3;
    if (idx.empty()) continue;
    const TriangleGrid cut(pos, idx);
    // The cut's triangles (centroids and edge midpoints) to the input.
    const size_t nt = idx.size() / 3, step_t = std::max<size_t>(1, nt / kSamples);
    double sum = 0.0;
    size_t count = 0;
    for (size_t t = 0; t < nt; t += step_t) {
      const glm::dvec3 a = pos[idx[3 * t]], b = pos[idx[3 * t + 1]], c = pos[idx[3 * t + 2]];
      for (const glm::dvec3& q : {(a + b + c) / 3.0, (a + b) / 2.0, (b + c) / 2.0}) {
        const double dist = input_grid.distance(q);
        e.max_to_input = std::max(e.max_to_input, dist);
        sum += dist;
        ++count;
      }
    }
    e.mean_to_input = count ? sum / double(count) : 0.0;
    const size_t step_v = std::max<size_t>(1, input_idx.size() / kSamples);
    for (size_t k = 0; k < input_idx.size(); k += step_v)
      e.max_from_input = std::max(e.max_from_input, cut.distance(input_pos[input_idx[k]]));
    r.levels.push_back(e);
  }
  return r;
}

}  // namespace tessera::lod
