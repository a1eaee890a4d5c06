// 3D lazy snapping: the graph cut of thesis 4.2.1 extended to surfaces as in 4.2.2, over the
// watershed segments of watershed.cpp, solved by max_flow.cpp.
#include <tessera/annotate/lazy_snapping.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "max_flow.h"

namespace tessera::annotate {

namespace {

/// Lloyd's k-means with a farthest-point start (deterministic): the cluster centres of the
/// stroke colours {C_n} of thesis 4.2.1 (Li et al. 2004 cluster each stroke's colours too).
/// `unit`: centres are renormalised (spherical k-means, for normals).
std::vector<glm::dvec3> kMeans(const std::vector<glm::dvec3>& x, uint32_t k, bool unit) {
  std::vector<glm::dvec3> c;
  if (x.empty() || k == 0) return c;
  auto dist2 = [](const glm::dvec3& a, const glm::dvec3& b) { return glm::dot(a - b, a - b); };
  std::vector<double> nearest(x.size(), std::numeric_limits<double>::infinity());
  c.push_back(x[0]);
  while (c.size() < k) {
    size_t far = 0;
    for (size_t i = 0; i < x.size(); ++i) {
      nearest[i] = std::min(nearest[i], dist2(x[i], c.back()));
      if (nearest[i] > nearest[far]) far = i;
    }
    if (nearest[far] <= 1e-12) break;  // fewer distinct values than k
    c.push_back(x[far]);
  }
  std::vector<uint32_t> assign(x.size(), 0);
  for (int iter = 0; iter < 20; ++iter) {
    bool changed = false;
    for (size_t i = 0; i < x.size(); ++i) {
      uint32_t best = 0;
      for (uint32_t m = 1; m < c.size(); ++m)
        if (dist2(x[i], c[m]) < dist2(x[i], c[best])) best = m;
      changed = changed || best != assign[i];
      assign[i] = best;
    }
    if (!changed && iter > 0) break;
    std::vector<glm::dvec3> sum(c.size(), glm::dvec3(0.0));
    std::vector<uint32_t> count(c.size(), 0);
    for (size_t i = 0; i < x.size(); ++i) {
      sum[assign[i]] += x[i];
      ++count[assign[i]];
    }
    for (size_t m = 0; m < c.size(); ++m) {
      if (count[m] == 0) continue;
      c[m] = sum[m] / double(count[m]);
      if (unit && glm::length(c[m]) > 0) c[m] = glm::normalize(c[m]);
    }
  }
  return c;
}

/// E1 of eq. 4.2 for an unseeded node from its distances to the nearest foreground and
/// background cluster: (E1(x = 1), E1(x = 0)) = (dF, dB) / (dF + dB); even when both are 0.
std::pair<double, double> dataCost(double d_f, double d_b) {
  const double sum = d_f + d_b;
  if (!(sum > 1e-300)) return {0.5, 0.5};
  return {d_f / sum, d_b / sum};
}

/// g(c) = 1 / (c + 1) of eq. 4.3.
double gOf(double c) {
  return 1.0 / (c + 1.0);
}

}  // namespace

LazySnapping::LazySnapping(const SurfaceSamples& samples, const SnapOptions& options)
    : mSamples(samples), mOptions(options) {
  samples.validate("LazySnapping");
  if (!(options.lambda >= 0) || !(options.w_colour >= 0) || !(options.w_normal >= 0) ||
      !(options.w_depth >= 0))
    throw SnappingError("LazySnapping: lambda and the weights must be >= 0");
  const uint32_t n = uint32_t(samples.size());
  if (options.over_segment) {
    mSegmentation = overSegment(samples, options.segmentation);
  } else {
    mSegmentation.segment_of.resize(n);
    std::iota(mSegmentation.segment_of.begin(), mSegmentation.segment_of.end(), 0u);
    mSegmentation.count = n;
  }
  mGraph = buildGraph(samples, mSegmentation.segment_of, mSegmentation.count);
}

LazySnapping::NodeGraph LazySnapping::buildGraph(const SurfaceSamples& samples,
                                                 std::vector<uint32_t> node_of, uint32_t count) {
  NodeGraph g;
  g.node_of = std::move(node_of);
  g.count = count;
  g.size.assign(count, 0);
  g.colour.assign(count, glm::dvec3(0.0));
  g.normal.assign(count, glm::dvec3(0.0));
  g.centroid.assign(count, glm::dvec3(0.0));
  const uint32_t n = uint32_t(samples.size());
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t s = g.node_of[i];
    ++g.size[s];
    g.colour[s] += glm::dvec3(samples.colors[i]);
    g.normal[s] += glm::dvec3(samples.normals[i]);
    g.centroid[s] += samples.positions[i];
  }
  for (uint32_t s = 0; s < count; ++s) {
    if (g.size[s] == 0) continue;  // a segment refined into samples
    g.colour[s] /= double(g.size[s]);
    g.centroid[s] /= double(g.size[s]);
    const double len = glm::length(g.normal[s]);
    g.normal[s] = len > 0 ? g.normal[s] / len : glm::dvec3(0.0);
  }
  // Node adjacency: one graph edge per pair of touching nodes, weighted by how many sample
  // edges cross their border.
  std::vector<uint64_t> pairs;
  for (uint32_t i = 0; i < n; ++i)
    for (uint32_t j : samples.neighboursOf(i)) {
      const uint32_t a = g.node_of[i], b = g.node_of[j];
      if (i < j && a != b) pairs.push_back(uint64_t(std::min(a, b)) << 32 | std::max(a, b));
    }
  std::sort(pairs.begin(), pairs.end());
  for (size_t k = 0; k < pairs.size();) {
    size_t e = k;
    while (e < pairs.size() && pairs[e] == pairs[k]) ++e;
    g.edges.push_back({uint32_t(pairs[k] >> 32), uint32_t(pairs[k]), uint32_t(e - k)});
    k = e;
  }
  return g;
}

SnapResult LazySnapping::cut(const Strokes& strokes, const ScreenView* view) const {
  const uint32_t n = uint32_t(mSamples.size());
  if (strokes.foreground.empty() || strokes.background.empty())
    throw SnappingError(std::string("LazySnapping::cut(): needs both a foreground and a "
                                    "background stroke (got ") +
                        std::to_string(strokes.foreground.size()) + " foreground and " +
                        std::to_string(strokes.background.size()) + " background samples)");
  for (const auto* list : {&strokes.foreground, &strokes.background})
    for (uint32_t i : *list)
      if (i >= n)
        throw SnappingError("LazySnapping::cut(): stroke sample " + std::to_string(i) +
                            " out of range (" + std::to_string(n) + " samples)");

  // Seeds: F_seed and B_seed of 4.2.1, assigned to segments as 4.2.2 does. A segment under
  // both kinds of stroke straddles the wanted border, so the cut refines it into its samples.
  enum : uint8_t { kFree = 0, kFg = 1, kBg = 2, kBoth = 3 };
  auto seedsOf = [&](const NodeGraph& graph) {
    std::vector<uint8_t> seed(graph.count, kFree);
    for (uint32_t i : strokes.foreground) seed[graph.node_of[i]] |= kFg;
    for (uint32_t i : strokes.background) seed[graph.node_of[i]] |= kBg;
    return seed;
  };
  SnapResult result;
  std::vector<uint8_t> seed = seedsOf(mGraph);
  NodeGraph refined;
  const NodeGraph* graph = &mGraph;
  const uint32_t conflicts = uint32_t(std::count(seed.begin(), seed.end(), kBoth));
  if (conflicts > 0) {
    std::vector<uint32_t> node_of = mGraph.node_of;
    uint32_t count = mGraph.count;
    for (uint32_t i = 0; i < n; ++i)
      if (seed[mGraph.node_of[i]] == kBoth) node_of[i] = count++;
    refined = buildGraph(mSamples, std::move(node_of), count);
    graph = &refined;
    seed = seedsOf(refined);
  }
  result.conflicting_segments = conflicts;
  for (uint8_t& s : seed)
    if (s == kBoth) s = kFree;  // one sample under both strokes: the cut decides
  const NodeGraph& g = *graph;
  const uint32_t m = g.count;
  result.graph_nodes = m - conflicts;  // refined segments are empty nodes now

  // Stroke clusters: colours as in 4.2.1, normals for E1^n of eq. 4.4.
  auto gather = [&](const std::vector<uint32_t>& idx, bool normals) {
    std::vector<glm::dvec3> x;
    x.reserve(idx.size());
    for (uint32_t i : idx)
      x.push_back(normals ? glm::dvec3(mSamples.normals[i]) : glm::dvec3(mSamples.colors[i]));
    return x;
  };
  const uint32_t k = std::max(1u, mOptions.clusters);
  const auto colour_f = kMeans(gather(strokes.foreground, false), k, false);
  const auto colour_b = kMeans(gather(strokes.background, false), k, false);
  const auto normal_f = kMeans(gather(strokes.foreground, true), k, true);
  const auto normal_b = kMeans(gather(strokes.background, true), k, true);
  auto nearestColour = [](const glm::dvec3& c, const std::vector<glm::dvec3>& centres) {
    double d = std::numeric_limits<double>::infinity();
    for (const glm::dvec3& x : centres) d = std::min(d, glm::length(c - x));
    return d;
  };
  auto nearestNormal = [](const glm::dvec3& nrm, const std::vector<glm::dvec3>& centres) {
    double d = std::numeric_limits<double>::infinity();
    for (const glm::dvec3& x : centres) d = std::min(d, std::abs(1.0 - glm::dot(nrm, x)));
    return d;
  };

  // Data term E'1 = w_c E1^c + w_n E1^n (eq. 4.4), per segment. Each segment counts as many
  // times as it has samples, and each border as many times as sample edges cross it, so the
  // segment graph's energy is the per-sample energy of labels constant on segments, with the
  // segments' means in place of the samples' own values (the thesis weighs clusters equally;
  // with segments of very different sizes that lets a crumb outvote a large patch).
  std::vector<double> e1_fg(m, 0.0), e1_bg(m, 0.0);  // E'1(x = 1), E'1(x = 0)
  double finite_sum = 0;
  for (uint32_t s = 0; s < m; ++s) {
    if (seed[s] != kFree) continue;
    const auto [cf, cb] =
        dataCost(nearestColour(g.colour[s], colour_f), nearestColour(g.colour[s], colour_b));
    const auto [nf, nb] =
        dataCost(nearestNormal(g.normal[s], normal_f), nearestNormal(g.normal[s], normal_b));
    const double w = double(g.size[s]);
    e1_fg[s] = w * (mOptions.w_colour * cf + mOptions.w_normal * nf);
    e1_bg[s] = w * (mOptions.w_colour * cb + mOptions.w_normal * nb);
    finite_sum += std::max(e1_fg[s], e1_bg[s]);
  }

  // Smoothness term E'2 (eq. 4.5) on each segment border: g of the colour difference C_ij
  // (squared RGB distance, eq. 4.3), of the normal difference N_ij = 1 - N_i . N_j and of the
  // eye-depth difference D_ij. The thesis leaves their scales open; each is divided by its
  // mean over the graph's edges (as GrabCut's beta does, Rother et al. 2004), so g spans
  // the same range on any model and in any units.
  std::vector<double> depth(m, 0.0);
  const bool use_depth = view != nullptr && mOptions.w_depth > 0;
  if (use_depth)
    for (uint32_t s = 0; s < m; ++s) depth[s] = -(view->view * glm::dvec4(g.centroid[s], 1.0)).z;
  std::vector<glm::dvec3> diff(g.edges.size());  // (C_ij, N_ij, D_ij)
  glm::dvec3 mean(0.0);
  for (size_t e = 0; e < g.edges.size(); ++e) {
    const NodeGraph::Edge& ed = g.edges[e];
    const glm::dvec3 dc = g.colour[ed.a] - g.colour[ed.b];
    const double dd = depth[ed.a] - depth[ed.b];
    diff[e] = {glm::dot(dc, dc), 1.0 - glm::dot(g.normal[ed.a], g.normal[ed.b]), dd * dd};
    mean += diff[e];
  }
  if (!g.edges.empty()) mean /= double(g.edges.size());
  for (int c = 0; c < 3; ++c)
    if (!(mean[c] > 1e-300)) mean[c] = 1.0;
  std::vector<double> weight(g.edges.size());
  for (size_t e = 0; e < g.edges.size(); ++e) {
    double w =
        mOptions.w_colour * gOf(diff[e].x / mean.x) + mOptions.w_normal * gOf(diff[e].y / mean.y);
    if (use_depth) w += mOptions.w_depth * gOf(diff[e].z / mean.z);
    weight[e] = mOptions.lambda * double(g.edges[e].count) * w;
    finite_sum += weight[e];
  }

  // Source = foreground. A seed's infinite t-link of eq. 4.2 is a capacity above any finite
  // cut, so the minimum never severs it.
  const double hard = 1.0 + 2.0 * finite_sum;
  MaxFlowGraph graph_cut(m, g.edges.size());
  for (uint32_t s = 0; s < m; ++s) {
    if (seed[s] == kFg)
      graph_cut.addTerminalWeights(s, hard, 0.0);
    else if (seed[s] == kBg)
      graph_cut.addTerminalWeights(s, 0.0, hard);
    else  // cut from the source (label 0) costs E1(x = 0); from the sink, E1(x = 1)
      graph_cut.addTerminalWeights(s, e1_bg[s], e1_fg[s]);
  }
  for (size_t e = 0; e < g.edges.size(); ++e)
    graph_cut.addEdge(g.edges[e].a, g.edges[e].b, weight[e], weight[e]);
  result.energy = graph_cut.maxflow();

  result.selected.resize(n);
  for (uint32_t i = 0; i < n; ++i) {
    result.selected[i] = graph_cut.isSourceSide(g.node_of[i]) ? 1 : 0;
    if (result.selected[i]) result.indices.push_back(i);
  }
  return result;
}

std::vector<uint32_t> selectedTriangles(const lod::Mesh& mesh, std::span<const uint8_t> selected) {
  if (selected.size() != mesh.positions.size())
    throw SnappingError("selectedTriangles(): " + std::to_string(selected.size()) + " labels for " +
                        std::to_string(mesh.positions.size()) + " vertices");
  std::vector<uint32_t> out;
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const lod::Triangle& tri = mesh.triangles[t];
    if (tri.x < selected.size() && tri.y < selected.size() && tri.z < selected.size() &&
        selected[tri.x] && selected[tri.y] && selected[tri.z])
      out.push_back(uint32_t(t));
  }
  return out;
}

double intersectionOverUnion(std::span<const uint8_t> a, std::span<const uint8_t> b) {
  if (a.size() != b.size())
    throw SnappingError("intersectionOverUnion(): masks of " + std::to_string(a.size()) + " and " +
                        std::to_string(b.size()) + " samples");
  size_t inter = 0, uni = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    inter += (a[i] && b[i]) ? 1 : 0;
    uni += (a[i] || b[i]) ? 1 : 0;
  }
  return uni == 0 ? 1.0 : double(inter) / double(uni);
}

}  // namespace tessera::annotate
