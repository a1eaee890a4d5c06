#include <tessera/render/view_renderer.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

namespace tessera::render {
namespace {

double msSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

uint32_t packRgb(const glm::u8vec3& c) {
  return uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16;
}

}  // namespace

glm::dmat4 storeModel(const lod::PointStore& store) {
  return glm::translate(glm::dmat4(1.0), store.summary().origin);
}

ViewRenderer::ViewRenderer(uint32_t width, uint32_t height, std::shared_ptr<ChunkStreamer> streamer,
                           const StreamerOptions& stream_options)
    : mStreamer(streamer ? std::move(streamer) : std::make_shared<ChunkStreamer>(stream_options)),
      mRaster(width, height) {}

Image ViewRenderer::render(std::span<const ModelInstance> models, const ViewSetup& view,
                           const RenderOptions& options, RenderStats* stats) {
  RenderStats st;
  draw(models, view, options, &st);
  const auto t0 = std::chrono::steady_clock::now();
  Image img = mRaster.read();
  st.readback_ms = msSince(t0);
  if (stats) *stats = st;
  return img;
}

void ViewRenderer::draw(std::span<const ModelInstance> models, const ViewSetup& view,
                        const RenderOptions& options, RenderStats* stats) {
  RenderStats st;
  mStreamer->beginFrame();
  st.upload_ms = mStreamer->stats().upload_ms;
  std::vector<DrawBatch> batches;
  for (const ModelInstance& m : models) addModel(*m.store, m.model, view, options, batches, st);
  mStreamer->endFrame();
  st.stream = mStreamer->stats();

  RasterShading shading;
  bool any_color = false;
  for (const ModelInstance& m : models)
    any_color |= (m.store->summary().attributes & lod::kColor) != 0;
  // Points without colour need only the depth pass.
  if (!any_color) shading.uniform_color = packRgb(options.default_color) | 0xFF000000u;
  shading.edl_strength = options.edl_strength;
  shading.edl_radius = options.edl_radius;
  shading.projection = view.projection;
  const RasterTimings t = mRaster.render(batches, options.background, shading);
  st.depth_ms = t.depth_ms;
  st.color_ms = t.color_ms;
  st.resolve_ms = t.resolve_ms;
  if (stats) *stats = st;
}

Image ViewRenderer::renderSettled(std::span<const ModelInstance> models, const ViewSetup& view,
                                  const RenderOptions& options, RenderStats* stats) {
  RenderStats st;
  Image img;
  // Each round either finds the cut complete or makes the loader fetch at least one missing
  // chunk or page, so this ends; the bound only guards against a bug.
  for (size_t frame = 1; frame <= 100000; ++frame) {
    img = render(models, view, options, &st);
    st.frames = frame;
    if (st.stream.requested == 0 && st.stream.pages_requested == 0) break;
    mStreamer->waitForLoader();
  }
  if (stats) *stats = st;
  return img;
}

void ViewRenderer::addModel(lod::PointStore& store, const glm::dmat4& model, const ViewSetup& view,
                            const RenderOptions& options, std::vector<DrawBatch>& batches,
                            RenderStats& stats) {
  auto t0 = std::chrono::steady_clock::now();
  CutOptions co;
  co.pixel_threshold = options.lod_pixels;
  // Hierarchy pages not in memory are read by the loader; refinement waits a frame for them.
  co.may_load_children = [&](lod::NodeId id) {
    mStreamer->requestChildren(store, id);
    return false;
  };
  const Cut cut = selectCut(store, model, view, co);
  stats.cut_nodes += cut.nodes.size();

  const glm::dmat4 clip_from_world = view.projection * view.view;
  const double k = pixelsPerUnitAtDistanceOne(view);
  auto addBatch = [&](const CutNode& n, const GpuChunk& chunk) {
    DrawBatch b;
    b.buffer = chunk.buffer.name();
    b.count = chunk.count;
    // Double precision down to the node, float within it: georeferenced data stays exact.
    b.clip_from_local =
        glm::mat4(clip_from_world * model * glm::translate(glm::dmat4(1.0), chunk.offset));
    b.spacing_k = float(n.spacing * k * options.splat_scale);
    b.splat_radius = options.max_splat_radius;
    batches.push_back(b);
    stats.points += chunk.count;
    ++stats.nodes;
  };
  std::vector<bool> drawn_above(cut.above.size(), false);
  for (const CutNode& n : cut.nodes) {  // nearest first
    if (const GpuChunk* chunk = mStreamer->find(store, n.id)) {
      addBatch(n, *chunk);
      continue;
    }
    ++stats.missing_nodes;
    if (mStreamer->failed(store, n.id)) {
      ++stats.corrupt_chunks;
    } else {
      mStreamer->request(store, n.id, n.level, n.distance);
    }
    // The nearest resident ancestor stands in; ancestors on the way are fetched too, coarse
    // first, so a new view fills in from coarse to fine.
    for (int32_t p = n.parent; p >= 0; p = cut.above[size_t(p)].parent) {
      const CutNode& a = cut.above[size_t(p)];
      if (drawn_above[size_t(p)]) break;
      if (const GpuChunk* chunk = mStreamer->find(store, a.id)) {
        addBatch(a, *chunk);
        drawn_above[size_t(p)] = true;
        ++stats.fallback_nodes;
        break;
      }
      if (!mStreamer->failed(store, a.id)) mStreamer->request(store, a.id, a.level, a.distance);
    }
  }
  stats.select_ms += msSince(t0);
}

}  // namespace tessera::render
