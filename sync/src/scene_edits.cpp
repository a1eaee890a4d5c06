#include <tessera/sync/scene_edits.h>

#include <cctype>
#include <cmath>
#include <string>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <tessera/core/check.h>

namespace tessera::sync {

namespace {

/// The first GROUP child of `parent` named `name`, made when there is none.
SceneGraph::NodeId groupChild(SceneGraph& graph, SceneGraph::NodeId parent, std::string_view name,
                              std::string_view author) {
  for (SceneGraph::NodeId id : graph.children(parent)) {
    const scene::SceneNode& n = graph.node(id);
    if (n.kind() == scene::SceneNode::GROUP && n.name() == name) return id;
  }
  const SceneGraph::NodeId id = graph.add(scene::SceneNode::GROUP, parent, name);
  graph.setAuthor(id, author);
  return id;
}

}  // namespace

SceneGraph::NodeId layerGroup(SceneGraph& graph, std::string_view name, std::string_view author) {
  return groupChild(graph, SceneGraph::kRoot, name, author);
}

SceneGraph::NodeId layerPath(SceneGraph& graph, std::string_view path, std::string_view author) {
  SceneGraph::NodeId parent = SceneGraph::kRoot;
  while (true) {
    const size_t slash = path.find('/');
    const std::string_view name = path.substr(0, slash);
    TESSERA_CHECK(!name.empty(), "sync::layerPath(): empty layer segment");
    parent = groupChild(graph, parent, name, author);
    if (slash == std::string_view::npos) return parent;
    path.remove_prefix(slash + 1);
  }
}

SceneGraph::NodeId addSketch(SceneGraph& graph, SceneGraph::NodeId layer, std::string_view author,
                             std::span<const glm::dvec3> points, const scene::Color& color,
                             float width) {
  TESSERA_CHECK(points.size() >= 2 && points.size() <= 3000,
                "sync::addSketch(): needs 2..3000 points");
  for (const glm::dvec3& p : points)
    for (int k = 0; k < 3; ++k)
      TESSERA_CHECK(std::isfinite(p[k]) && std::abs(p[k]) <= 1e8,
                    "sync::addSketch(): points must be finite, within 1e8 m");
  TESSERA_CHECK(width > 0.0f && width <= 64.0f, "sync::addSketch(): width in (0, 64] pixels");
  const SceneGraph::NodeId id =
      graph.add(scene::SceneNode::SKETCH, layer,
                "sketch " + std::to_string(graph.children(layer).size() + 1));
  const glm::dvec3 origin = points.front();
  scene::SketchPayload p;
  for (const glm::dvec3& q : points)
    for (int k = 0; k < 3; ++k) p.add_points(float(q[k] - origin[k]));
  *p.mutable_color() = color;
  p.set_width(width);
  graph.setPayload(id, p);  // checks the colour
  const glm::dmat4 t = glm::translate(glm::dmat4(1.0), origin);
  graph.setTransform(id, std::span<const double>(glm::value_ptr(t), 16));
  graph.setAuthor(id, author);
  return id;
}

SceneGraph::NodeId addMeasurement(SceneGraph& graph, SceneGraph::NodeId layer,
                                  std::string_view author,
                                  scene::MeasurementPayload::Type type,
                                  std::span<const glm::dvec3> points, double value,
                                  double uncertainty, const scene::Color* color) {
  scene::MeasurementPayload p;
  p.set_type(type);
  for (const glm::dvec3& q : points)
    for (int k = 0; k < 3; ++k) p.add_points(q[k]);
  p.set_value(value);
  p.set_uncertainty(uncertainty);
  if (color) *p.mutable_color() = *color;
  std::string name = scene::MeasurementPayload::Type_Name(type);
  for (char& c : name) c = char(std::tolower(static_cast<unsigned char>(c)));
  const SceneGraph::NodeId id =
      graph.add(scene::SceneNode::MEASUREMENT, layer,
                name + " " + std::to_string(graph.children(layer).size() + 1));
  try {
    graph.setPayload(id, p);
  } catch (...) {
    graph.remove(id);  // no half-made node stays behind
    throw;
  }
  graph.setAuthor(id, author);
  return id;
}

}  // namespace tessera::sync
