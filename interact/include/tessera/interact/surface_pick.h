// Picking for measurement: the surface under a pixel found in the full-resolution data, not in
// the coarse cut the view happens to show (Atelier3D section 4.1). The frame's pick
// ids say which model is there and roughly where (ViewRenderer::pick()); this goes down the
// model's hierarchy to the leaves around the pixel's ray and returns a real sample (points) or
// the ray's hit on an input triangle (meshes), in double precision world coordinates. Also the
// surface projectors that measurement.h's area needs, on the same data. CPU only, no GL: the
// master, the console and a site can all call it.
#pragma once

#include <cstdint>
#include <optional>
#include <span>

#include <glm/glm.hpp>

#include <tessera/annotate/measurement.h>
#include <tessera/interact/point_pick.h>
#include <tessera/render/view_renderer.h>

namespace tessera::interact {

struct SurfacePick {
  /// Points: the stored sample's own position (a real measurement of the scanner); meshes: the
  /// ray's intersection with the triangle. World frame, metres. Its uncertainty: the leaf's
  /// quantisation error plus half its sample spacing (points) or half the quantisation grid's
  /// diagonal (meshes), scaled to the world.
  annotate::SurfacePoint point;
  size_t model = 0;                 ///< index into the models searched
  lod::NodeId node = lod::kNoNode;  ///< the leaf holding the element
  uint32_t index = 0;               ///< the point in its chunk, or the triangle in its patch
  bool triangle = false;
  glm::dvec3 normal{0.0};  ///< meshes: the triangle's unit normal (world); points: 0
};

/// The surface nearest along the ray from `origin` in direction `dir` (world), searched in the
/// leaves of every model. Points: among the samples within `options.radius_px` pixels of the
/// ray (at least the leaf's spacing), the front surface (samples within two spacings of the
/// nearest one) and there the sample nearest to the ray. Meshes: the nearest triangle the ray
/// crosses. What a model's clip planes cut away (ModelInstance::clip) is skipped: a ray
/// through a cut surface finds what lies behind. `only_model`: search that model alone (the one
/// the pick ids name). Reads at most `options.max_chunks` chunks or patches per model; corrupt
/// ones are skipped.
std::optional<SurfacePick> pickSurface(std::span<const render::ModelInstance> models,
                                       const glm::dvec3& origin, const glm::dvec3& dir,
                                       const PickOptions& options = {},
                                       std::optional<size_t> only_model = std::nullopt);

/// The options a click on `view` picks with: the cone of PickOptions::radius_px pixels at the
/// view's own angle a pixel.
PickOptions pickOptionsFor(const render::ViewSetup& view);

/// The surface under pixel `px` (x right, y down, fractional) of the last frame `renderer` drew
/// of `view`: the frame's pick ids name the model (nullopt on background), then pickSurface()
/// refines along the pixel's ray in that model's full resolution (a see-through frame has no
/// pick ids: then every model's data along the ray is searched); where the refinement finds
/// nothing (a corrupt chunk), the pixel's own depth, with a pixel's width of uncertainty. What
/// the console's and a site's measuring tools click.
std::optional<SurfacePick> pickUnderPixel(const render::ViewRenderer& renderer,
                                          std::span<const render::ModelInstance> models,
                                          const render::ViewSetup& view, glm::dvec2 px);

/// A projector onto a point model's surface: from the sample nearest to the point, the plane
/// fitted (least squares) to the leaf samples within `radius` metres of it, the point dropped
/// onto it, refitted once where it landed (a moving least-squares step). nullopt where no sample
/// lies within `reach` metres or fewer than 8 within 8 times `radius`. `radius` <= 0: four
/// times the spacing of the leaf holding the nearest sample; `reach` <= 0: a tenth of the
/// model's diagonal. The instance's store must outlive the projector.
annotate::SurfaceProjector pointSurfaceProjector(const render::ModelInstance& model,
                                                 double radius = 0.0, double reach = 0.0);

/// A projector onto a mesh model's input surface: the nearest point of the leaf triangles
/// within `reach` metres (<= 0: a tenth of the model's diagonal). Keeps up to 512 decoded
/// patches.
annotate::SurfaceProjector meshSurfaceProjector(const render::ModelInstance& model,
                                                double reach = 0.0);

/// The finest sample spacing (points) or quantisation step (meshes) of a model, metres: a
/// measuring tool's useful resolution (AreaOptions::min_edge).
double dataResolution(const render::ModelInstance& model);

}  // namespace tessera::interact
