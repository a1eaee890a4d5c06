#include <tessera/interact/snap_tool.h>

#include <tessera/core/stopwatch.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_store.h>
#include <tessera/annotate/selection.h>
#include <tessera/sync/selection_mask.h>

namespace tessera::interact {

namespace {

using Clock = std::chrono::steady_clock;

/// Whether a node's box lies wholly outside one plane of the clip volume.
bool outsideFrustum(const glm::dmat4& clip_from_local, const lod::NodeInfo& n) {
  int out[6] = {};
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 p(c & 1 ? n.box_max.x : n.box_min.x, c & 2 ? n.box_max.y : n.box_min.y,
                       c & 4 ? n.box_max.z : n.box_min.z);
    const glm::dvec4 q = clip_from_local * glm::dvec4(p, 1.0);
    out[0] += q.x < -q.w;
    out[1] += q.x > q.w;
    out[2] += q.y < -q.w;
    out[3] += q.y > q.w;
    out[4] += q.z < -q.w;
    out[5] += q.z > q.w;
  }
  return std::any_of(std::begin(out), std::end(out), [](int k) { return k == 8; });
}

/// Pixels a unit length covers at eye depth `depth` (clip w = P[2][3] z + P[3][3], z = -depth).
double pixelsPerUnit(const annotate::ScreenView& v, double depth) {
  const double w = v.projection[3][3] - v.projection[2][3] * depth;
  return std::abs(v.projection[0][0]) * 0.5 * double(v.viewport.x) / std::max(std::abs(w), 1e-300);
}

/// The samples the view shows of one model and where each came from.
struct Gathered {
  annotate::SurfaceSamples samples;
  double spacing = 0.0;                                        ///< units of the positions
  std::vector<std::pair<lod::NodeId, uint32_t>> point_leaves;  ///< leaf, points (sample order)
  std::vector<lod::NodeId> patch_ids;
  std::vector<lod::MeshPatch> patches;
  std::vector<std::vector<uint32_t>> sample_of;  ///< per patch vertex
  uint64_t corrupt = 0;
};

/// The leaves whose boxes meet the frustum; SnappingError when they hold more than `cap`
/// samples (mesh leaves: half their triangles).
std::vector<lod::NodeId> leavesInView(lod::LodHierarchy& tree, const glm::dmat4& clip_from_local,
                                      bool mesh, uint64_t cap) {
  std::vector<lod::NodeId> leaves, stack{tree.root()};
  uint64_t estimate = 0;
  while (!stack.empty()) {
    const lod::NodeId id = stack.back();
    stack.pop_back();
    const lod::NodeInfo n = tree.node(id);
    if (outsideFrustum(clip_from_local, n)) continue;
    if (!n.leaf()) {
      for (lod::NodeId c : tree.children(id)) stack.push_back(c);
      continue;
    }
    leaves.push_back(id);
    estimate += mesh ? n.points / 2 : n.points;
    if (estimate > cap)
      throw annotate::SnappingError("snapSelection(): the view shows more than " + std::to_string(cap) +
                          " samples of the model; zoom in on the region to select");
  }
  std::sort(leaves.begin(), leaves.end());
  return leaves;
}

Gathered gather(const render::ModelInstance& instance, const annotate::ScreenView& sv,
                const SnapToolOptions& o) {
  Gathered g;
  const glm::dmat4 clip_from_local = sv.projection * sv.view;
  const glm::dvec3 eye = glm::dvec3(glm::inverse(sv.view) * glm::dvec4(0, 0, 0, 1));
  if (instance.mesh) {
    for (lod::NodeId id : leavesInView(*instance.mesh, clip_from_local, true, o.max_samples)) {
      try {
        g.patches.push_back(instance.mesh->readPatch(id));
        g.patch_ids.push_back(id);
      } catch (const lod::StoreError&) {
        ++g.corrupt;
      }
    }
    g.samples = annotate::surfaceFromPatches(g.patches, &g.sample_of);
    // Spacing: the mean edge length.
    double sum = 0.0;
    uint64_t edges = 0;
    for (uint32_t i = 0; i < g.samples.size(); ++i)
      for (uint32_t j : g.samples.neighboursOf(i)) {
        sum += glm::length(g.samples.positions[i] - g.samples.positions[j]);
        ++edges;
      }
    g.spacing = edges ? sum / double(edges) : 0.0;
  } else if (instance.store) {
    std::vector<std::shared_ptr<const lod::ChunkPoints>> chunks;
    double spacing = 0.0;
    for (lod::NodeId id : leavesInView(*instance.store, clip_from_local, false, o.max_samples)) {
      try {
        chunks.push_back(instance.store->loadChunk(id));
        g.point_leaves.emplace_back(id, uint32_t(chunks.back()->size()));
        spacing += instance.store->node(id).spacing;
      } catch (const lod::StoreError&) {
        ++g.corrupt;
      }
    }
    g.samples = annotate::surfaceFromChunks(chunks, o.neighbours, eye);
    g.spacing = chunks.empty() ? 0.0 : spacing / double(chunks.size());
  }
  if (g.samples.size() > o.max_samples)
    throw annotate::SnappingError("snapSelection(): the view shows " + std::to_string(g.samples.size()) +
                        " samples of the model, more than " + std::to_string(o.max_samples) +
                        "; zoom in on the region to select");
  return g;
}

/// The samples' median eye depth (of those in front; 1 when none).
double medianDepth(const annotate::SurfaceSamples& s, const annotate::ScreenView& v) {
  std::vector<double> d;
  d.reserve(s.size());
  for (const glm::dvec3& p : s.positions)
    if (const annotate::ScreenPoint q = project(v, p); q.in_front) d.push_back(q.depth);
  if (d.empty()) return 1.0;
  std::nth_element(d.begin(), d.begin() + ptrdiff_t(d.size() / 2), d.end());
  return d[d.size() / 2];
}

std::vector<glm::dvec2> windowPixels(std::span<const glm::dvec2> px, const render::ViewSetup& v,
                                     const char* what) {
  std::vector<glm::dvec2> out;
  for (const glm::dvec2& p : px) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y))
      throw annotate::SnappingError(std::string("snapSelection(): the ") + what + " is not finite");
    out.emplace_back(p.x, double(v.height) - p.y);  // annotate::ScreenView pixels: origin bottom-left
  }
  return out;
}

/// A cut's samples as the store's leaf elements.
annotate::Selection mapBack(const Gathered& g, std::span<const uint8_t> selected) {
  if (!g.patches.empty()) {
    annotate::Selection sel(annotate::SelectionElements::kTriangles);
    for (size_t p = 0; p < g.patches.size(); ++p) {
      const lod::MeshPatch& patch = g.patches[p];
      const uint32_t n = uint32_t(patch.triangles());
      std::vector<uint64_t> bits((size_t(n) + 63) / 64, 0);
      for (uint32_t t = 0; t < n; ++t) {
        bool all = true;
        for (int k = 0; k < 3; ++k) all = all && selected[g.sample_of[p][patch.indices[3 * t + k]]];
        if (all) bits[t / 64] |= 1ull << (t % 64);
      }
      if (n) sel.set(g.patch_ids[p], annotate::NodeSelection::fromBits(n, std::move(bits)));
    }
    return sel;
  }
  annotate::Selection sel(annotate::SelectionElements::kPoints);
  size_t at = 0;
  for (const auto& [id, n] : g.point_leaves) {
    std::vector<uint64_t> bits((size_t(n) + 63) / 64, 0);
    for (uint32_t i = 0; i < n; ++i)
      if (selected[at + i]) bits[i / 64] |= 1ull << (i % 64);
    at += n;
    if (n) sel.set(id, annotate::NodeSelection::fromBits(n, std::move(bits)));
  }
  return sel;
}

/// Gathers, seeds (by `seeds`), cuts, maps back and masks.
template <class Seeds>
SnapSelection run(const render::ModelInstance& instance, uint32_t model_node,
                  const render::ViewSetup& view, const SnapToolOptions& o, Seeds seeds) {
  SnapSelection out;
  if (view.width == 0 || view.height == 0)
    throw annotate::SnappingError("snapSelection(): the view has no pixels");
  annotate::ScreenView sv;
  sv.view = view.view * instance.model;
  sv.projection = view.projection;
  sv.viewport = {view.width, view.height};

  auto t0 = Clock::now();
  const Gathered g = gather(instance, sv, o);
  out.corrupt = g.corrupt;
  out.stats.samples = g.samples.size();
  out.stats.leaves = g.patches.size() + g.point_leaves.size();
  if (g.samples.size() == 0)
    throw annotate::SnappingError("snapSelection(): the view shows no surface of the model");
  out.stats.gather_ms = msSince(t0);

  t0 = Clock::now();
  const double spacing_px = g.spacing * pixelsPerUnit(sv, medianDepth(g.samples, sv));
  const std::vector<uint8_t> visible =
      annotate::visibleSamples(g.samples, sv, std::clamp(1.2 * spacing_px, 1.0, 8.0), 4.0 * g.spacing);
  const annotate::Strokes strokes = seeds(g.samples, sv, visible);
  if (strokes.foreground.empty())
    throw annotate::SnappingError("snapSelection(): no visible surface of the model under the foreground");
  if (strokes.background.empty())
    throw annotate::SnappingError("snapSelection(): no visible surface of the model under the background");
  const annotate::LazySnapping snapping(g.samples, o.snap);
  const annotate::SnapResult r = snapping.cut(strokes, &sv);
  out.stats.graph_nodes = r.graph_nodes;
  out.stats.cut_ms = msSince(t0);

  t0 = Clock::now();
  const annotate::Selection sel = mapBack(g, r.selected);
  out.count = sel.count();
  out.stats.map_ms = msSince(t0);
  if (out.count == 0) return out;

  t0 = Clock::now();
  const SnapMask mask = selectionMask(g.samples, r.selected, g.spacing, sv, o);
  out.stats.mask_width = mask.width;
  out.stats.mask_height = mask.height;
  scene::SelectionPayload& s = out.payload;
  s.set_model(model_node);
  const glm::dmat4 vp = view.projection * view.view;
  for (int k = 0; k < 16; ++k) s.add_lasso_clip_from_world(vp[k / 4][k % 4]);
  s.set_mask(sync::encodeSelectionMask(mask.cells));
  s.set_mask_width(mask.width);
  s.set_mask_height(mask.height);
  s.set_visible_only(true);
  const std::vector<uint8_t> bytes = sel.serialize();
  s.set_elements(std::string(bytes.begin(), bytes.end()));
  s.set_count(out.count);
  out.stats.mask_ms = msSince(t0);
  return out;
}

/// Counts of set cells in [x0, x1) x [y0, y1) from an integral image.
struct Integral {
  uint32_t w, h;
  std::vector<uint32_t> sum;  ///< (w + 1) x (h + 1)
  Integral(uint32_t width, uint32_t height, auto&& set) : w(width), h(height) {
    sum.assign(size_t(w + 1) * (h + 1), 0);
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x)
        sum[size_t(y + 1) * (w + 1) + x + 1] =
            (set(x, y) ? 1u : 0u) + sum[size_t(y) * (w + 1) + x + 1] +
            sum[size_t(y + 1) * (w + 1) + x] - sum[size_t(y) * (w + 1) + x];
  }
  /// Set cells and cells of the window inside the image, around (x, y) by r.
  std::pair<uint32_t, uint32_t> window(uint32_t x, uint32_t y, uint32_t r) const {
    const uint32_t x0 = x >= r ? x - r : 0, y0 = y >= r ? y - r : 0;
    const uint32_t x1 = std::min(w, x + r + 1), y1 = std::min(h, y + r + 1);
    const uint32_t n = sum[size_t(y1) * (w + 1) + x1] - sum[size_t(y0) * (w + 1) + x1] -
                       sum[size_t(y1) * (w + 1) + x0] + sum[size_t(y0) * (w + 1) + x0];
    return {n, (x1 - x0) * (y1 - y0)};
  }
};

}  // namespace

SnapMask selectionMask(const annotate::SurfaceSamples& samples, std::span<const uint8_t> selected,
                       double spacing, const annotate::ScreenView& view, const SnapToolOptions& o) {
  SnapMask m;
  const double scale = std::min(1.0, double(std::max(o.max_mask_side, 1u)) /
                                         double(std::max(view.viewport.x, view.viewport.y)));
  m.width = std::max(1u, uint32_t(std::lround(view.viewport.x * scale)));
  m.height = std::max(1u, uint32_t(std::lround(view.viewport.y * scale)));
  const double cx = double(m.width) / view.viewport.x, cy = double(m.height) / view.viewport.y;
  // The nearest sample per cell decides: 1 selected, 2 not selected, 0 no sample.
  std::vector<float> depth(size_t(m.width) * m.height, INFINITY);
  std::vector<uint8_t> label(depth.size(), 0);
  for (size_t i = 0; i < samples.size(); ++i) {
    const annotate::ScreenPoint q = project(view, samples.positions[i]);
    if (!q.in_front) continue;
    const glm::dvec2 c(q.pixel.x * cx, q.pixel.y * cy);
    // Footprint: three quarters of the spacing, so neighbours' discs overlap on a regular grid.
    const double r = std::clamp(0.75 * spacing * pixelsPerUnit(view, q.depth) * cx, 0.5, 8.0);
    const int x0 = std::max(0, int(std::floor(c.x - r))),
              x1 = std::min(int(m.width) - 1, int(c.x + r));
    const int y0 = std::max(0, int(std::floor(c.y - r))),
              y1 = std::min(int(m.height) - 1, int(c.y + r));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double dx = x + 0.5 - c.x, dy = y + 0.5 - c.y;
        if (dx * dx + dy * dy > r * r) continue;
        const size_t k = size_t(y) * m.width + size_t(x);
        if (float(q.depth) < depth[k]) {
          depth[k] = float(q.depth);
          label[k] = selected[i] ? 1 : 2;
        }
      }
  }
  // Closing: dilate the selected cells into cells no unselected sample is nearest in, then
  // erode, counting unselected cells and the image's outside as present, so the erosion undoes
  // the dilation only at silhouettes (gaps inside the region stay filled, borders with
  // unselected surface stay where the samples put them).
  const uint32_t k = o.close_cells;
  const Integral sel(m.width, m.height,
                     [&](uint32_t x, uint32_t y) { return label[size_t(y) * m.width + x] == 1; });
  std::vector<uint8_t> dilated(label.size(), 0);
  for (uint32_t y = 0; y < m.height; ++y)
    for (uint32_t x = 0; x < m.width; ++x) {
      const size_t i = size_t(y) * m.width + x;
      dilated[i] = label[i] == 1 || (label[i] == 0 && sel.window(x, y, k).first > 0);
    }
  const Integral present(m.width, m.height, [&](uint32_t x, uint32_t y) {
    const size_t i = size_t(y) * m.width + x;
    return dilated[i] || label[i] == 2;
  });
  m.cells.assign(label.size(), 0);
  for (uint32_t y = 0; y < m.height; ++y)
    for (uint32_t x = 0; x < m.width; ++x) {
      const size_t i = size_t(y) * m.width + x;
      if (!dilated[i]) continue;
      const auto [n, cells] = present.window(x, y, k);
      m.cells[i] = label[i] == 1 || n == cells;
    }
  return m;
}

SnapSelection snapSelection(const render::ModelInstance& instance, uint32_t model_node,
                            const render::ViewSetup& view, std::span<const glm::dvec2> foreground,
                            std::span<const glm::dvec2> background,
                            const SnapToolOptions& options) {
  if (foreground.empty() || background.empty())
    throw annotate::SnappingError("snapSelection(): needs a foreground and a background stroke");
  const std::vector<glm::dvec2> fg = windowPixels(foreground, view, "foreground stroke");
  const std::vector<glm::dvec2> bg = windowPixels(background, view, "background stroke");
  return run(
      instance, model_node, view, options,
      [&](const annotate::SurfaceSamples& s, const annotate::ScreenView& sv, const std::vector<uint8_t>& visible) {
        annotate::Strokes st;
        st.foreground = annotate::pickStroke(s, sv, fg, options.stroke_radius_px, visible);
        st.background = annotate::pickStroke(s, sv, bg, options.stroke_radius_px, visible);
        return st;
      });
}

SnapSelection robustLassoSelection(const render::ModelInstance& instance, uint32_t model_node,
                                   const render::ViewSetup& view, std::span<const glm::dvec2> heavy,
                                   double width_px, const SnapToolOptions& options) {
  if (heavy.size() < 3 || !(width_px > 0.0) || !std::isfinite(width_px))
    throw annotate::SnappingError(
        "robustLassoSelection(): needs a closed stroke of 3 points or more and a width > 0");
  annotate::HeavyStroke h;
  h.polyline = windowPixels(heavy, view, "heavy stroke");
  h.width_px = width_px;
  h.seed_band_px = width_px;
  return run(
      instance, model_node, view, options,
      [&](const annotate::SurfaceSamples& s, const annotate::ScreenView& sv, const std::vector<uint8_t>& visible) {
        return annotate::robustLassoSeeds(s, sv, h, visible);
      });
}

}  // namespace tessera::interact
