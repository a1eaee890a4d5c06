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

}  // namespace

glm::dmat4 storeModel(const lod::PointStore& store) {
  return glm::translate(glm::dmat4(1.0), store.summary().origin);
}

Image ViewRenderer::render(std::span<const ModelInstance> models, const ViewSetup& view,
                           const RenderOptions& options, RenderStats* stats) {
  RenderStats st;
  mPoints.clear();
  std::vector<DrawBatch> batches;
  for (const ModelInstance& m : models) addModel(*m.store, m.model, view, options, batches, st);
  auto t2 = std::chrono::steady_clock::now();
  mRaster.setPoints(mPoints);
  RasterShading shading;
  bool any_color = false;
  for (const ModelInstance& m : models)
    any_color |= (m.store->summary().attributes & lod::kColor) != 0;
  if (!any_color) {
    shading.uniform_color = uint32_t(options.default_color.r) |
                            uint32_t(options.default_color.g) << 8 |
                            uint32_t(options.default_color.b) << 16 | 0xFF000000u;
  }
  shading.edl_strength = options.edl_strength;
  shading.edl_radius = options.edl_radius;
  shading.projection = view.projection;
  mRaster.render(batches, options.background, shading);
  Image img = mRaster.read();
  st.raster_ms = msSince(t2);
  st.points = mPoints.size();
  if (stats) *stats = st;
  return img;
}

void ViewRenderer::addModel(lod::PointStore& store, const glm::dmat4& model, const ViewSetup& view,
                            const RenderOptions& options, std::vector<DrawBatch>& batches,
                            RenderStats& stats) {
  auto t0 = std::chrono::steady_clock::now();
  CutOptions co;
  co.pixel_threshold = options.lod_pixels;
  Cut cut = selectCut(store, model, view, co);
  // Node order decides ties between points at equal depth: by id, the same in every view.
  std::sort(cut.nodes.begin(), cut.nodes.end(),
            [](const CutNode& a, const CutNode& b) { return a.id < b.id; });
  stats.select_ms += msSince(t0);
  stats.nodes += cut.nodes.size();

  auto t1 = std::chrono::steady_clock::now();
  const glm::dmat4 clip_from_world = view.projection * view.view;
  const uint32_t grey = uint32_t(options.default_color.r) | uint32_t(options.default_color.g) << 8 |
                        uint32_t(options.default_color.b) << 16;
  for (const CutNode& n : cut.nodes) {
    std::shared_ptr<const lod::ChunkPoints> chunk;
    try {
      chunk = store.loadChunk(n.id);
    } catch (const lod::StoreError&) {
      ++stats.corrupt_chunks;  // reported by the store's cache stats too; never drawn
      continue;
    }
    DrawBatch b;
    b.first = uint32_t(mPoints.size());
    b.count = uint32_t(chunk->size());
    // Double precision down to the node, float within it: georeferenced data stays exact.
    b.clip_from_local =
        glm::mat4(clip_from_world * model * glm::translate(glm::dmat4(1.0), chunk->offset));
    b.splat_radius = std::clamp(int(std::ceil(n.projected_spacing_px * 0.5 - 0.5)), 0, 8);
    const bool color = !chunk->colors.empty();
    for (size_t i = 0; i < chunk->size(); ++i) {
      uint32_t rgba = grey;
      if (color) {
        const glm::u8vec4 c = chunk->colors[i];
        rgba = uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16;
      }
      mPoints.push_back({chunk->positions[i], rgba});
    }
    batches.push_back(b);
  }
  stats.load_ms += msSince(t1);
}

}  // namespace tessera::render
