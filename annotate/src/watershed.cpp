// Watershed over-segmentation of surface samples (thesis 4.2.2: the graph cut runs over small
// clusters instead of pixels, found by the watershed of [27], Vincent and Soille 1991).
#include <tessera/annotate/lazy_snapping.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numeric>
#include <queue>
#include <tuple>

namespace tessera::annotate {

namespace {

constexpr uint32_t kUnlabelled = UINT32_MAX;

/// Per-sample height: where the surface bends or its colour changes, the height is high, so
/// the basins are flat, evenly coloured patches and their borders follow creases and colour
/// edges (on an image the thesis floods the gradient magnitude; on a surface the normal
/// variation plays the geometric part of that gradient).
std::vector<double> heights(const SurfaceSamples& s, const OverSegmentOptions& o) {
  const size_t n = s.size();
  std::vector<double> h(n, 0.0);
  for (uint32_t i = 0; i < n; ++i) {
    const auto nb = s.neighboursOf(i);
    if (nb.empty()) continue;
    double normal_var = 0, colour_grad = 0;
    for (uint32_t j : nb) {
      normal_var += 1.0 - double(glm::dot(s.normals[i], s.normals[j]));
      colour_grad += glm::length(glm::dvec3(s.colors[i]) - glm::dvec3(s.colors[j])) / 255.0;
    }
    h[i] = (normal_var + o.colour_weight * colour_grad) / double(nb.size());
  }
  // Scan noise makes many shallow minima; a light smoothing keeps the basins from shattering.
  std::vector<double> tmp(n);
  for (uint32_t pass = 0; pass < o.smoothing_passes; ++pass) {
    for (uint32_t i = 0; i < n; ++i) {
      double sum = h[i];
      for (uint32_t j : s.neighboursOf(i)) sum += h[j];
      tmp[i] = sum / double(s.neighboursOf(i).size() + 1);
    }
    h.swap(tmp);
  }
  return h;
}

struct UnionFind {
  std::vector<uint32_t> parent;
  explicit UnionFind(uint32_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  uint32_t find(uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
};

}  // namespace

OverSegmentation overSegment(const SurfaceSamples& s, const OverSegmentOptions& o) {
  s.validate("overSegment()");
  if (o.max_segment_size == 0) throw SnappingError("overSegment(): max_segment_size must be > 0");
  const uint32_t n = uint32_t(s.size());
  const std::vector<double> h = heights(s, o);
  // A strict total order on (height, index) makes every plateau drain to one sample, so a
  // flat region is one basin instead of one per sample.
  auto lower = [&](uint32_t a, uint32_t b) { return std::tie(h[a], a) < std::tie(h[b], b); };

  // Flooding by priority (Meyer 1991): every regional minimum starts a basin; the lowest
  // unlabelled sample next to a basin is labelled next. Where basins meet, samples on a
  // crease or colour edge have equal heights on both sides, so a sample takes the label of
  // its most similar labelled neighbour rather than of whichever basin came first.
  auto dissimilarity = [&](uint32_t i, uint32_t j) {
    return 1.0 - double(glm::dot(s.normals[i], s.normals[j])) +
           o.colour_weight * glm::length(glm::dvec3(s.colors[i]) - glm::dvec3(s.colors[j])) / 255.0;
  };
  std::vector<uint32_t> label(n, kUnlabelled);
  std::vector<uint8_t> queued(n, 0);
  using Entry = std::pair<double, int64_t>;  // (-height, -index): heaps pop the largest
  std::priority_queue<Entry> queue;
  uint32_t basins = 0;
  for (uint32_t i = 0; i < n; ++i) {
    bool minimum = true;
    for (uint32_t j : s.neighboursOf(i)) minimum = minimum && lower(i, j);
    if (!minimum) continue;
    label[i] = basins++;
    queued[i] = 1;
    for (uint32_t j : s.neighboursOf(i))
      if (!queued[j]) {
        queued[j] = 1;
        queue.emplace(-h[j], -int64_t(j));
      }
  }
  while (!queue.empty()) {
    const uint32_t i = uint32_t(-queue.top().second);
    queue.pop();
    double best = std::numeric_limits<double>::infinity();
    for (uint32_t j : s.neighboursOf(i))
      if (label[j] != kUnlabelled && dissimilarity(i, j) < best) {
        best = dissimilarity(i, j);
        label[i] = label[j];
      }
    assert(label[i] != kUnlabelled);
    for (uint32_t j : s.neighboursOf(i))
      if (!queued[j]) {
        queued[j] = 1;
        queue.emplace(-h[j], -int64_t(j));
      }
  }
  assert(std::find(label.begin(), label.end(), kUnlabelled) == label.end());

  // Bounded size: a basin larger than max_segment_size is cut into connected pieces grown
  // breadth-first from its lowest remaining sample (pieces never cross the basin's border,
  // so creases stay segment borders).
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), lower);
  std::vector<uint32_t> basin_size(basins, 0);
  for (uint32_t l : label) ++basin_size[l];
  std::vector<uint32_t> piece(n, kUnlabelled);
  uint32_t pieces = 0;
  std::vector<uint32_t> frontier;
  for (uint32_t seed : order) {
    if (piece[seed] != kUnlabelled) continue;
    const uint32_t l = label[seed], p = pieces++;
    piece[seed] = p;
    if (basin_size[l] <= o.max_segment_size) {
      // Small basin: the whole of it (connected by construction) is one piece.
      frontier.assign(1, seed);
      for (size_t k = 0; k < frontier.size(); ++k)
        for (uint32_t j : s.neighboursOf(frontier[k]))
          if (piece[j] == kUnlabelled && label[j] == l) {
            piece[j] = p;
            frontier.push_back(j);
          }
      continue;
    }
    uint32_t size = 1;
    frontier.assign(1, seed);
    for (size_t k = 0; k < frontier.size() && size < o.max_segment_size; ++k)
      for (uint32_t j : s.neighboursOf(frontier[k]))
        if (piece[j] == kUnlabelled && label[j] == l && size < o.max_segment_size) {
          piece[j] = p;
          frontier.push_back(j);
          ++size;
        }
  }

  // Tiny pieces (noise minima, leftovers of the split) join their most similar neighbour when
  // one is alike in normal and colour, so the cut graph is not dominated by crumbs.
  std::vector<uint32_t> size(pieces, 0);
  std::vector<glm::dvec3> nsum(pieces, glm::dvec3(0.0)), csum(pieces, glm::dvec3(0.0));
  for (uint32_t i = 0; i < n; ++i) {
    ++size[piece[i]];
    nsum[piece[i]] += glm::dvec3(s.normals[i]);
    csum[piece[i]] += glm::dvec3(s.colors[i]);
  }
  std::vector<std::vector<uint32_t>> members(pieces);
  for (uint32_t i = 0; i < n; ++i) members[piece[i]].push_back(i);
  std::vector<uint32_t> small(pieces);
  std::iota(small.begin(), small.end(), 0u);
  std::stable_sort(small.begin(), small.end(),
                   [&](uint32_t a, uint32_t b) { return size[a] < size[b]; });
  UnionFind uf(pieces);
  const double cos_max = std::cos(o.merge_max_angle_deg * M_PI / 180.0);
  std::vector<uint32_t> shared(pieces, 0);
  std::vector<uint32_t> touched;
  for (uint32_t p : small) {
    const uint32_t rp = uf.find(p);
    if (size[rp] >= o.min_segment_size) continue;
    touched.clear();
    for (uint32_t i : members[rp])
      for (uint32_t j : s.neighboursOf(i)) {
        const uint32_t rq = uf.find(piece[j]);
        if (rq == rp) continue;
        if (shared[rq]++ == 0) touched.push_back(rq);
      }
    uint32_t best = kUnlabelled, best_shared = 0;
    const glm::dvec3 np = glm::length(nsum[rp]) > 0 ? glm::normalize(nsum[rp]) : glm::dvec3(0);
    for (uint32_t rq : touched) {
      const glm::dvec3 nq = glm::length(nsum[rq]) > 0 ? glm::normalize(nsum[rq]) : glm::dvec3(0);
      const bool alike = glm::dot(np, nq) >= cos_max &&
                         glm::length(csum[rp] / double(size[rp]) - csum[rq] / double(size[rq])) <=
                             o.merge_max_color &&
                         size[rp] + size[rq] <= o.max_segment_size;
      if (alike && shared[rq] > best_shared) {
        best = rq;
        best_shared = shared[rq];
      }
    }
    for (uint32_t rq : touched) shared[rq] = 0;
    if (best == kUnlabelled) continue;
    uf.parent[rp] = best;
    size[best] += size[rp];
    nsum[best] += nsum[rp];
    csum[best] += csum[rp];
    members[best].insert(members[best].end(), members[rp].begin(), members[rp].end());
    members[rp].clear();
  }

  OverSegmentation result;
  result.segment_of.resize(n);
  std::vector<uint32_t> compact(pieces, kUnlabelled);
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t r = uf.find(piece[i]);
    if (compact[r] == kUnlabelled) compact[r] = result.count++;
    result.segment_of[i] = compact[r];
  }
  return result;
}

}  // namespace tessera::annotate
