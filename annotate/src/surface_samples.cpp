// Surface samples for lazy snapping: mesh vertices with their edges, or points with their
// k-nearest-neighbour graph and PCA normals.
#include <tessera/annotate/lazy_snapping.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <queue>
#include <string>
#include <unordered_map>
#include <utility>

namespace tessera::annotate {

namespace {

bool finite(const glm::dvec3& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

/// Compressed rows from an unsorted list of directed pairs (each undirected edge twice).
void buildRows(size_t n, std::vector<std::pair<uint32_t, uint32_t>>& pairs, SurfaceSamples& s) {
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  s.offsets.assign(n + 1, 0);
  for (const auto& [a, b] : pairs) ++s.offsets[a + 1];
  for (size_t i = 0; i < n; ++i) s.offsets[i + 1] += s.offsets[i];
  s.neighbours.resize(pairs.size());
  for (size_t k = 0; k < pairs.size(); ++k) s.neighbours[k] = pairs[k].second;
}

/// A balanced kd-tree over the points (implicit: the median of each range is its node).
class KdTree {
 public:
  explicit KdTree(std::span<const glm::dvec3> points) : mPoints(points) {
    mOrder.resize(points.size());
    std::iota(mOrder.begin(), mOrder.end(), 0u);
    mAxis.resize(points.size());
    build(0, mOrder.size());
  }

  /// The k nearest points to point `q` other than itself, nearest first.
  void nearest(uint32_t q, uint32_t k, std::vector<std::pair<double, uint32_t>>& heap) const {
    heap.clear();
    search(0, mOrder.size(), q, k, heap);
    std::sort_heap(heap.begin(), heap.end());
  }

 private:
  void build(size_t lo, size_t hi) {
    if (hi - lo <= 1) return;
    glm::dvec3 mn(INFINITY), mx(-INFINITY);
    for (size_t i = lo; i < hi; ++i) {
      mn = glm::min(mn, mPoints[mOrder[i]]);
      mx = glm::max(mx, mPoints[mOrder[i]]);
    }
    const glm::dvec3 ext = mx - mn;
    const uint8_t axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    const size_t mid = (lo + hi) / 2;
    std::nth_element(mOrder.begin() + std::ptrdiff_t(lo), mOrder.begin() + std::ptrdiff_t(mid),
                     mOrder.begin() + std::ptrdiff_t(hi),
                     [&](uint32_t a, uint32_t b) { return mPoints[a][axis] < mPoints[b][axis]; });
    mAxis[mid] = axis;
    build(lo, mid);
    build(mid + 1, hi);
  }

  void search(size_t lo, size_t hi, uint32_t q, uint32_t k,
              std::vector<std::pair<double, uint32_t>>& heap) const {
    if (lo >= hi) return;
    const size_t mid = (lo + hi) / 2;
    const uint32_t p = mOrder[mid];
    const glm::dvec3 d = mPoints[q] - mPoints[p];
    if (p != q) {
      const double d2 = glm::dot(d, d);
      if (heap.size() < k) {
        heap.emplace_back(d2, p);
        std::push_heap(heap.begin(), heap.end());
      } else if (d2 < heap.front().first) {
        std::pop_heap(heap.begin(), heap.end());
        heap.back() = {d2, p};
        std::push_heap(heap.begin(), heap.end());
      }
    }
    const double diff = mPoints[q][mAxis[mid]] - mPoints[p][mAxis[mid]];
    const bool left_first = diff < 0;
    if (left_first)
      search(lo, mid, q, k, heap);
    else
      search(mid + 1, hi, q, k, heap);
    if (heap.size() < k || diff * diff < heap.front().first) {
      if (left_first)
        search(mid + 1, hi, q, k, heap);
      else
        search(lo, mid, q, k, heap);
    }
  }

  std::span<const glm::dvec3> mPoints;
  std::vector<uint32_t> mOrder;
  std::vector<uint8_t> mAxis;
};

/// Eigenvector of the smallest eigenvalue of a symmetric 3x3 matrix (cyclic Jacobi rotations;
/// converges in a handful of sweeps at this size).
glm::dvec3 smallestEigenvector(glm::dmat3 a) {
  glm::dmat3 v(1.0);
  for (int sweep = 0; sweep < 16; ++sweep) {
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    if (off < 1e-30) break;
    for (int p = 0; p < 2; ++p)
      for (int q = p + 1; q < 3; ++q) {
        if (std::abs(a[p][q]) < 1e-300) continue;
        const double theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
        const double t =
            (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1));
        const double c = 1 / std::sqrt(t * t + 1), s = t * c;
        glm::dmat3 r(1.0);  // rotation in the (p, q) plane; a <- r^T a r, v <- v r
        r[p][p] = c;
        r[q][q] = c;
        r[q][p] = s;   // column q, row p
        r[p][q] = -s;  // column p, row q
        a = glm::transpose(r) * a * r;
        v = v * r;
      }
  }
  int m = 0;
  for (int i = 1; i < 3; ++i)
    if (a[i][i] < a[m][m]) m = i;
  return v[m];  // column m
}

}  // namespace

void SurfaceSamples::validate(const char* who) const {
  const std::string w = who;
  if (positions.empty()) throw SnappingError(w + ": the surface has no samples");
  if (normals.size() != positions.size() || colors.size() != positions.size())
    throw SnappingError(w + ": " + std::to_string(positions.size()) + " positions but " +
                        std::to_string(normals.size()) + " normals and " +
                        std::to_string(colors.size()) + " colours (expected one each)");
  if (offsets.size() != positions.size() + 1 || offsets.front() != 0 ||
      offsets.back() != neighbours.size())
    throw SnappingError(w + ": adjacency offsets do not match the samples");
  for (size_t i = 0; i < positions.size(); ++i) {
    if (!finite(positions[i]) || !finite(glm::dvec3(normals[i])))
      throw SnappingError(w + ": sample " + std::to_string(i) +
                          " has a non-finite position or normal");
    if (offsets[i] > offsets[i + 1])
      throw SnappingError(w + ": adjacency offsets decrease at sample " + std::to_string(i));
  }
  for (uint32_t j : neighbours)
    if (j >= positions.size())
      throw SnappingError(w + ": neighbour index " + std::to_string(j) + " out of range");
}

SurfaceSamples surfaceFromMesh(const lod::Mesh& mesh) {
  const size_t n = mesh.positions.size();
  SurfaceSamples s;
  s.positions = mesh.positions;
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  pairs.reserve(mesh.triangles.size() * 6);
  std::vector<glm::dvec3> normals(n, glm::dvec3(0.0));
  for (const lod::Triangle& t : mesh.triangles) {
    if (t.x >= n || t.y >= n || t.z >= n)
      throw SnappingError("surfaceFromMesh(): a triangle refers to a vertex out of range");
    for (int e = 0; e < 3; ++e) {
      const uint32_t a = t[e], b = t[(e + 1) % 3];
      if (a == b) continue;
      pairs.emplace_back(a, b);
      pairs.emplace_back(b, a);
    }
    // The cross product's length is twice the area: area-weighted vertex normals.
    const glm::dvec3 c = glm::cross(mesh.positions[t.y] - mesh.positions[t.x],
                                    mesh.positions[t.z] - mesh.positions[t.x]);
    if (finite(c))
      for (int e = 0; e < 3; ++e) normals[t[e]] += c;
  }
  buildRows(n, pairs, s);
  s.normals.resize(n);
  for (size_t i = 0; i < n; ++i) {
    if (mesh.normals.size() == n) {
      s.normals[i] = mesh.normals[i];
    } else {
      const double len = glm::length(normals[i]);
      s.normals[i] = len > 0 ? glm::vec3(normals[i] / len) : glm::vec3(0.0f);
    }
  }
  s.colors = mesh.colors.size() == n ? mesh.colors
                                     : std::vector<glm::u8vec4>(n, glm::u8vec4(128, 128, 128, 255));
  return s;
}

SurfaceSamples surfaceFromPoints(std::span<const glm::dvec3> positions,
                                 std::span<const glm::u8vec4> colors,
                                 std::span<const glm::vec3> normals, uint32_t k,
                                 const glm::dvec3& viewpoint) {
  const size_t n = positions.size();
  if (n == 0) throw SnappingError("surfaceFromPoints(): no points");
  if (n > size_t(UINT32_MAX) - 1) throw SnappingError("surfaceFromPoints(): too many points");
  if (k == 0) throw SnappingError("surfaceFromPoints(): k must be at least 1");
  if (!colors.empty() && colors.size() != n)
    throw SnappingError("surfaceFromPoints(): " + std::to_string(colors.size()) + " colours for " +
                        std::to_string(n) + " points");
  if (!normals.empty() && normals.size() != n)
    throw SnappingError("surfaceFromPoints(): " + std::to_string(normals.size()) + " normals for " +
                        std::to_string(n) + " points");
  for (size_t i = 0; i < n; ++i)
    if (!finite(positions[i]))
      throw SnappingError("surfaceFromPoints(): point " + std::to_string(i) +
                          " has a non-finite position");
  SurfaceSamples s;
  s.positions.assign(positions.begin(), positions.end());
  s.colors = colors.empty() ? std::vector<glm::u8vec4>(n, glm::u8vec4(128, 128, 128, 255))
                            : std::vector<glm::u8vec4>(colors.begin(), colors.end());
  s.normals.assign(normals.begin(), normals.end());
  if (s.normals.empty()) s.normals.resize(n);

  const KdTree tree(positions);
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  pairs.reserve(n * k * 2);
  std::vector<std::pair<double, uint32_t>> heap;
  for (uint32_t i = 0; i < n; ++i) {
    tree.nearest(i, k, heap);
    for (const auto& [d2, j] : heap) {
      pairs.emplace_back(i, j);
      pairs.emplace_back(j, i);  // symmetric: i is a neighbour of j too
    }
    if (!normals.empty()) continue;
    // PCA normal over the point and its k nearest neighbours (Hoppe et al. 1992).
    glm::dvec3 mean = positions[i];
    for (const auto& nb : heap) mean += positions[nb.second];
    mean /= double(heap.size() + 1);
    glm::dmat3 cov(0.0);
    auto add = [&](const glm::dvec3& p) {
      const glm::dvec3 d = p - mean;
      cov += glm::outerProduct(d, d);
    };
    add(positions[i]);
    for (const auto& nb : heap) add(positions[nb.second]);
    glm::dvec3 nrm = heap.size() >= 2 ? smallestEigenvector(cov) : glm::dvec3(0.0);
    if (glm::dot(nrm, viewpoint - positions[i]) < 0) nrm = -nrm;
    s.normals[i] = glm::vec3(nrm);
  }
  buildRows(n, pairs, s);
  return s;
}

SurfaceSamples surfaceFromChunks(std::span<const std::shared_ptr<const lod::ChunkPoints>> chunks,
                                 uint32_t k, const glm::dvec3& viewpoint) {
  std::vector<glm::dvec3> positions;
  std::vector<glm::u8vec4> colors;
  bool any_colour = false;
  for (const auto& c : chunks) any_colour = any_colour || (c && (c->attributes & lod::kColor));
  for (const auto& c : chunks) {
    if (!c) throw SnappingError("surfaceFromChunks(): a chunk is null");
    const bool coloured = (c->attributes & lod::kColor) && c->colors.size() == c->size();
    for (size_t i = 0; i < c->size(); ++i) {
      positions.push_back(c->offset + glm::dvec3(c->positions[i]));
      if (any_colour) colors.push_back(coloured ? c->colors[i] : glm::u8vec4(128, 128, 128, 255));
    }
  }
  return surfaceFromPoints(positions, colors, {}, k, viewpoint);
}

SurfaceSamples surfaceFromPatches(std::span<const lod::MeshPatch> patches,
                                  std::vector<std::vector<uint32_t>>* sample_of) {
  // Patches of one store quantise their vertices on one grid, so a vertex two patches share
  // has the same grid coordinates in both: the key to weld them by.
  struct KeyHash {
    size_t operator()(const glm::i64vec3& k) const {
      return size_t(uint64_t(k.x) * 73856093u) ^ size_t(uint64_t(k.y) * 19349663u) ^
             size_t(uint64_t(k.z) * 83492791u);
    }
  };
  std::unordered_map<glm::i64vec3, uint32_t, KeyHash> by_grid;
  std::unordered_map<glm::i64vec3, uint32_t, KeyHash> by_position;  // bit patterns of doubles
  SurfaceSamples s;
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  if (sample_of) sample_of->assign(patches.size(), {});
  std::vector<uint32_t> local;
  for (size_t p = 0; p < patches.size(); ++p) {
    const lod::MeshPatch& patch = patches[p];
    const size_t nv = patch.positions.size();
    if (patch.normals.size() != nv || (!patch.colors.empty() && patch.colors.size() != nv) ||
        (!patch.grid.empty() && patch.grid.size() != nv) || patch.indices.size() % 3 != 0)
      throw SnappingError("surfaceFromPatches(): patch " + std::to_string(p) +
                          " has arrays of different sizes");
    local.resize(nv);
    for (size_t v = 0; v < nv; ++v) {
      const glm::dvec3 pos = patch.offset + glm::dvec3(patch.positions[v]);
      if (!finite(pos))
        throw SnappingError("surfaceFromPatches(): patch " + std::to_string(p) + " vertex " +
                            std::to_string(v) + " is not finite");
      glm::i64vec3 key;
      auto* map = &by_grid;
      if (!patch.grid.empty()) {
        key = glm::i64vec3(patch.grid[v]);
      } else {
        std::memcpy(&key, &pos, sizeof key);
        map = &by_position;
      }
      const auto [it, added] = map->try_emplace(key, uint32_t(s.positions.size()));
      if (added) {
        s.positions.push_back(pos);
        s.normals.push_back(patch.normals[v]);
        s.colors.push_back(patch.colors.empty() ? glm::u8vec4(128, 128, 128, 255)
                                                : patch.colors[v]);
      }
      local[v] = it->second;
    }
    for (size_t t = 0; t < patch.indices.size(); t += 3)
      for (int e = 0; e < 3; ++e) {
        const uint32_t a = patch.indices[t + size_t(e)];
        const uint32_t b = patch.indices[t + size_t((e + 1) % 3)];
        if (a >= nv || b >= nv)
          throw SnappingError("surfaceFromPatches(): patch " + std::to_string(p) +
                              " has a vertex index out of range");
        if (local[a] == local[b]) continue;
        pairs.emplace_back(local[a], local[b]);
        pairs.emplace_back(local[b], local[a]);
      }
    if (sample_of) (*sample_of)[p] = local;
  }
  buildRows(s.positions.size(), pairs, s);
  return s;
}

}  // namespace tessera::annotate
