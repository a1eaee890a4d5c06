#include <tessera/interact/measure_tool.h>

#include <tessera/render/scene_overlay.h>
#include <tessera/sync/scene_edits.h>

namespace tessera::interact {

void MeasureTool::setMode(Mode mode) {
  mMode = mode;
  mPoints.clear();
}

MeasureTool::Mode MeasureTool::cycle() {
  setMode(mMode == Mode::kArea ? Mode::kOff : Mode(int(mMode) + 1));
  return mMode;
}

scene::MeasurementPayload::Type MeasureTool::typeOf(Mode mode) {
  switch (mode) {
    case Mode::kPath: return scene::MeasurementPayload::POLYLINE;
    case Mode::kAngle: return scene::MeasurementPayload::ANGLE;
    case Mode::kArea: return scene::MeasurementPayload::AREA;
    default: return scene::MeasurementPayload::DISTANCE;
  }
}

const char* MeasureTool::name(Mode mode) {
  switch (mode) {
    case Mode::kDistance:
      return "distance";
    case Mode::kPath:
      return "path";
    case Mode::kAngle:
      return "angle";
    case Mode::kArea:
      return "area";
    default:
      return "off";
  }
}

std::optional<MeasureTool::Finished> MeasureTool::addPoint(
    const SurfacePick& pick, std::span<const render::ModelInstance> models) {
  if (mMode == Mode::kOff) return std::nullopt;
  if (mPoints.size() >= annotate::kMaxAreaLoop) return std::nullopt;  // the area's limit; paths alike
  mPoints.push_back(pick);
  const size_t complete = mMode == Mode::kDistance ? 2 : mMode == Mode::kAngle ? 3 : 0;
  if (complete && mPoints.size() == complete) return measure(models);
  return std::nullopt;
}

std::optional<MeasureTool::Finished> MeasureTool::complete(
    std::span<const render::ModelInstance> models) {
  if ((mMode == Mode::kPath && mPoints.size() >= 2) ||
      (mMode == Mode::kArea && mPoints.size() >= 3))
    return measure(models);
  return std::nullopt;
}

namespace {

sync::SceneGraph::NodeId addNode(sync::SceneGraph& graph, const MeasureTool::Finished& f,
                                 const std::string& author) {
  const auto layer = sync::layerGroup(graph, "measurements", author);
  return sync::addMeasurement(graph, layer, author, f.type, f.points, f.measured.value,
                              f.measured.uncertainty);
}

}  // namespace

std::optional<sync::SceneGraph::NodeId> MeasureTool::add(
    const SurfacePick& pick, sync::SceneGraph& graph,
    std::span<const render::ModelInstance> models, const std::string& author) {
  if (const std::optional<Finished> f = addPoint(pick, models)) return addNode(graph, *f, author);
  return std::nullopt;
}

std::optional<sync::SceneGraph::NodeId> MeasureTool::finish(
    sync::SceneGraph& graph, std::span<const render::ModelInstance> models,
    const std::string& author) {
  if (const std::optional<Finished> f = complete(models)) return addNode(graph, *f, author);
  return std::nullopt;
}

bool MeasureTool::undoPoint() {
  if (mPoints.empty()) return false;
  mPoints.pop_back();
  return true;
}

MeasureTool::Finished MeasureTool::measure(std::span<const render::ModelInstance> models) {
  std::vector<annotate::SurfacePoint> pts;
  std::vector<glm::dvec3> world;
  for (const SurfacePick& p : mPoints) {
    pts.push_back(p.point);
    world.push_back(p.point.world);
  }
  annotate::Measurement m;
  scene::MeasurementPayload::Type type = scene::MeasurementPayload::DISTANCE;
  switch (mMode) {
    case Mode::kDistance:
      m = distance(pts[0], pts[1]);
      break;
    case Mode::kAngle:
      m = angle(pts[0], pts[1], pts[2]);
      type = scene::MeasurementPayload::ANGLE;
      break;
    case Mode::kPath:
      m = annotate::polylineLength(pts);
      type = scene::MeasurementPayload::POLYLINE;
      break;
    default: {
      type = scene::MeasurementPayload::AREA;
      const size_t model = mPoints.front().model;
      if (model >= models.size())
        throw annotate::MeasureError("interact::MeasureTool: the area's model is no longer in the scene");
      const render::ModelInstance& instance = models[model];
      const annotate::SurfaceProjector project = instance.mesh ? meshSurfaceProjector(instance)
                                                     : pointSurfaceProjector(instance);
      annotate::AreaOptions o;
      o.min_edge = 2.0 * dataResolution(instance);
      m = annotate::surfaceArea(pts, project, o);
    }
  }
  mPoints.clear();
  Finished out{type, std::move(world), m};
  scene::MeasurementPayload shown;
  shown.set_type(type);
  shown.set_value(m.value);
  shown.set_uncertainty(m.uncertainty);
  mLastLabel = render::measurementLabel(shown);
  return out;
}

}  // namespace tessera::interact
