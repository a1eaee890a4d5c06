// Edits that more than one participant makes the same way (the master's console, remote sites'
// requests through collab/site_roster.h), so a sketch drawn at the wall and one drawn in Kyoto
// are the same nodes.
#pragma once

#include <span>
#include <string_view>

#include <glm/glm.hpp>

#include <tessera/sync/scene_graph.h>

namespace tessera::sync {

/// "PREFIX N" for a new child of `parent`: N is one more than the largest N among the children
/// named "PREFIX N", so a name is never given twice while its node exists (a count of children
/// would repeat one after a deletion).
std::string freshName(const SceneGraph& graph, SceneGraph::NodeId parent, std::string_view prefix);

/// The GROUP node named `name` under the root (the first such), made when there is none.
SceneGraph::NodeId layerGroup(SceneGraph& graph, std::string_view name, std::string_view author);

/// The GROUP node of a hierarchical layer "a/b/c": nested GROUP nodes named "a", "b", "c" from
/// the root down (each the first such child), made where missing; hiding one hides its
/// sublayers. "a" alone is layerGroup(graph, "a", author). Precondition: segments not empty.
SceneGraph::NodeId layerPath(SceneGraph& graph, std::string_view path, std::string_view author);

/// A SKETCH node (a 3D polyline, metres, scene frame) under `layer`, recorded as `author`'s:
/// points relative to the first in float, the first in the node's transform in double, so a
/// georeferenced sketch keeps its millimetres. Returns its id. Preconditions (TESSERA_CHECK):
/// 2..3000 finite points within 1e8 m, colour in [0, 1], width in (0, 64] pixels.
SceneGraph::NodeId addSketch(SceneGraph& graph, SceneGraph::NodeId layer, std::string_view author,
                             std::span<const glm::dvec3> points, const scene::Color& color,
                             float width);

/// A MEASUREMENT node under `layer`, recorded as `author`'s: the picked points (metres, scene
/// frame, double), the value and its uncertainty as measured (annotate/measurement.h). Named
/// after its type and number in the layer ("distance 3"); no colour: the overlay's. Throws
/// PreconditionError (TESSERA_CHECK) when the payload is not valid (point count for the type,
/// non-finite numbers).
SceneGraph::NodeId addMeasurement(SceneGraph& graph, SceneGraph::NodeId layer,
                                  std::string_view author,
                                  scene::MeasurementPayload::Type type,
                                  std::span<const glm::dvec3> points, double value,
                                  double uncertainty, const scene::Color* color = nullptr);

}  // namespace tessera::sync
