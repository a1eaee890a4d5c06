// An exact CPU reference for see-through images, independent of the GPU renderer: every point
// of every leaf (full resolution) is splatted as a disc of its leaf's spacing, the fragments of
// each pixel are sorted by depth, grouped into surface layers (one model, depth gaps below three
// spacings), and the layers are composited front to back with the opacity the theory gives:
// alpha for a surface parallel to the image, 1 - (1 - alpha)^(cos(phi) / cos(theta)) on a slant
// (Tanaka et al. 2016, eq. 2, with theta the angle between the surface normal and the ray and
// phi between the ray and the view axis: the renderer's discs face the image plane; alpha
// itself with slant shading off). Slow (seconds for 10^6 points); for
// tests and benchmarks of see-through methods.
#pragma once

#include <span>

#include <tessera/render/image.h>
#include <tessera/render/tile_frustum.h>
#include <tessera/render/view_renderer.h>

namespace tessera::render {

struct ReferenceOptions {
  glm::vec3 background{0.0f};
  glm::u8vec3 default_color{200, 200, 200};
  bool slant_shading = true;
  float splat_scale = 2.0f;  ///< disc diameter in leaf spacings, as RenderOptions::splat_scale
};

/// The reference image of `models` (each with its opacity) from `view`.
Image referenceSeeThrough(std::span<const ModelInstance> models, const ViewSetup& view,
                          const ReferenceOptions& options = {});

}  // namespace tessera::render
