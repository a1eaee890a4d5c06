// The measuring tool: points picked one by one on the model (surface_pick.h) become a
// MEASUREMENT node of the scene (layer "measurements"), measured with measurement.h, so every
// tile and site shows it with its label. A distance ends at its second point and an angle at its
// third (the vertex is the second); a path and an area end when the user says so. Window-free:
// the console feeds it clicks, a test feeds it picks.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <vector>

#include <tessera/annotate/measurement.h>
#include <tessera/interact/surface_pick.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::interact {

class MeasureTool {
 public:
  enum class Mode { kOff, kDistance, kPath, kAngle, kArea };

  Mode mode() const { return mMode; }
  /// Switches the tool (dropping the points of an unfinished measurement).
  void setMode(Mode mode);
  /// Off -> distance -> path -> angle -> area -> off.
  Mode cycle();
  /// "distance", "path", "angle", "area" or "off".
  static const char* name(Mode mode);
  /// The MEASUREMENT node's type a mode makes (kOff: DISTANCE).
  static scene::MeasurementPayload::Type typeOf(Mode mode);

  /// A completed measurement: what a MEASUREMENT node holds.
  struct Finished {
    scene::MeasurementPayload::Type type = scene::MeasurementPayload::DISTANCE;
    std::vector<glm::dvec3> points;  ///< world, metres
    annotate::Measurement measured;
  };
  /// As add() and finish(), without a scene: the completed measurement for the caller to send
  /// (a remote site asks the master to add it: site.proto SiteMeasure).
  std::optional<Finished> addPoint(const SurfacePick& pick,
                                   std::span<const render::ModelInstance> models);
  std::optional<Finished> complete(std::span<const render::ModelInstance> models);

  /// Adds a picked point. A distance's second or an angle's third point completes it: the node
  /// is made in `graph` (author `author`) and returned. `models` are the instances the picks'
  /// model indices refer to (an area's surface is the first point's model).
  std::optional<sync::SceneGraph::NodeId> add(const SurfacePick& pick, sync::SceneGraph& graph,
                                              std::span<const render::ModelInstance> models,
                                              const std::string& author);
  /// Ends a path (>= 2 points) or an area (>= 3): the node, or nullopt with nothing changed.
  /// Throws MeasureError when the area cannot be measured.
  std::optional<sync::SceneGraph::NodeId> finish(sync::SceneGraph& graph,
                                                 std::span<const render::ModelInstance> models,
                                                 const std::string& author);
  /// Drops the newest point of the unfinished measurement; false when there is none.
  bool undoPoint();

  /// The unfinished measurement's points (world, metres).
  const std::vector<SurfacePick>& points() const { return mPoints; }
  /// The label of the last measurement made ("14.2 cm ± 0.3 mm"), "" before the first.
  const std::string& lastLabel() const { return mLastLabel; }

 private:
  Finished measure(std::span<const render::ModelInstance> models);
  Mode mMode = Mode::kOff;
  std::vector<SurfacePick> mPoints;
  std::string mLastLabel;
};

}  // namespace tessera::interact
