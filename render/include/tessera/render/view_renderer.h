// One view of a point store, end to end: LOD cut for the view's frustum, chunks decoded through
// the store's cache, points rasterised by compute shaders, image read back. Synchronous for now
// (every chunk of the cut is loaded before drawing); the streaming loader comes with the wall.
// A GL 4.5 context must be current.
#pragma once

#include <span>

#include <tessera/lod/point_store.h>
#include <tessera/render/lod_selector.h>
#include <tessera/render/point_rasterizer.h>
#include <tessera/render/tile_frustum.h>

namespace tessera::render {

struct RenderOptions {
  double lod_pixels = 1.0;
  glm::vec3 background{0.0f};
  glm::u8vec3 default_color{200, 200, 200};  ///< for stores without colour
  float edl_strength = 0.0f;                 ///< eye-dome lighting (0: off, 1: usual)
  int edl_radius = 1;                        ///< EDL neighbour distance, pixels
};

struct RenderStats {
  size_t nodes = 0;
  uint64_t points = 0;
  size_t corrupt_chunks = 0;  ///< skipped: checksum or decoding failed
  double select_ms = 0, load_ms = 0, raster_ms = 0;
};

/// A store placed in the world: world = model * local.
struct ModelInstance {
  lod::PointStore* store = nullptr;
  glm::dmat4 model{1.0};
};

class ViewRenderer {
 public:
  ViewRenderer(uint32_t width, uint32_t height) : mRaster(width, height) {}
  /// Renders every model into one image (nearest point wins across models).
  Image render(std::span<const ModelInstance> models, const ViewSetup& view,
               const RenderOptions& options, RenderStats* stats = nullptr);

 private:
  void addModel(lod::PointStore& store, const glm::dmat4& model, const ViewSetup& view,
                const RenderOptions& options, std::vector<DrawBatch>& batches, RenderStats& stats);
  PointRasterizer mRaster;
  std::vector<GpuPoint> mPoints;
};

/// The store's local frame in the world: a translation by its origin (world = origin + local).
glm::dmat4 storeModel(const lod::PointStore& store);

}  // namespace tessera::render
