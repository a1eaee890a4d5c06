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
  return graph.add(scene::SceneNode::GROUP, parent, name, {}, author);
}

}  // namespace

std::string freshName(const SceneGraph& graph, SceneGraph::NodeId parent,
                      std::string_view prefix) {
  uint64_t largest = 0;
  for (SceneGraph::NodeId id : graph.children(parent)) {
    const std::string& name = graph.node(id).name();
    if (name.size() <= prefix.size() + 1 || name.compare(0, prefix.size(), prefix) != 0 ||
        name[prefix.size()] != ' ')
      continue;
    uint64_t n = 0;
    bool digits = true;
    for (size_t i = prefix.size() + 1; i < name.size() && digits; ++i) {
      digits = name[i] >= '0' && name[i] <= '9' && n < (uint64_t(1) << 60);
      n = n * 10 + uint64_t(name[i] - '0');
    }
    if (digits) largest = std::max(largest, n);
  }
  return std::string(prefix) + " " + std::to_string(largest + 1);
}

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
  const glm::dvec3 origin = points.front();
  scene::SketchPayload p;
  for (const glm::dvec3& q : points)
    for (int k = 0; k < 3; ++k) p.add_points(float(q[k] - origin[k]));
  *p.mutable_color() = color;
  p.set_width(width);
  const glm::dmat4 t = glm::translate(glm::dmat4(1.0), origin);
  return graph.add(scene::SceneNode::SKETCH, layer, freshName(graph, layer, "sketch"),
                   std::move(p), author, std::span<const double>(glm::value_ptr(t), 16));
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
  return graph.add(scene::SceneNode::MEASUREMENT, layer, freshName(graph, layer, name),
                   std::move(p), author);
}

}  // namespace tessera::sync
