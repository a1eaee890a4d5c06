// Camera paths (configs/paths/*.json, schema in camera_path.proto): camera keyframes through
// which the camera moves smoothly, and timed actions (a model's opacity or visibility, the
// shading, a screenshot). The master evaluates a path at t = frame / fps, so a scripted run is
// deterministic in frame numbers, not wall-clock time.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <tessera/camera_path.pb.h>
#include <tessera/config.pb.h>
#include <tessera/sync/config.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::sync {

/// Reads and validates a camera path: at least one keyframe; keyframe times finite and strictly
/// increasing; each keyframe's eye, target and up present and finite, eye != target, up not along
/// the view; action times finite and non-decreasing; each action one of setOpacity (a model
/// name, opacity in (0, 1]), setVisible (a model name), setShading ("color" or "edl"),
/// setAnalysis (the shading filters, checked as a scene's settings.analysis), screenshot (a path); a closed path has 3 keyframes or more and ends where it starts. Throws
/// ConfigError "sync::loadCameraPath(): FILE: FIELD: what", e.g. "keyframes[2].time: 1 is not after
/// keyframes[1] (3)".
config::CameraPath loadCameraPath(const std::filesystem::path& path);
/// Same from JSON text (`name` is used in messages).
config::CameraPath parseCameraPath(const std::string& json, const std::string& name);

/// Checks that every model an action names is a node of `scene` (by name); ConfigError names
/// `name` (the path's file) and the action, e.g.
/// "actions[1].setOpacity.model: no model 'x' in the scene".
void checkPathModels(const config::CameraPath& path, const SceneGraph& scene,
                     const std::string& name);

/// The time of the last keyframe or action, whichever is later (seconds).
double pathDuration(const config::CameraPath& path);

/// The camera at time `t` (seconds): before the first keyframe the first, after the last the
/// last; in between a cubic Hermite spline through the keyframes on eye, target and up, with
/// Catmull-Rom tangents for uneven times, (p[k+1] - p[k-1]) / (t[k+1] - t[k-1]), and at both
/// ends one-sided differences (so two keyframes give a straight, constant-speed line) or, for a
/// closed path, the neighbours across the seam. Up is then made a unit vector orthogonal to the
/// view (at and beyond the ends too). Pure and deterministic. Precondition: a validated
/// path. Cost: O(log keyframes).
config::Camera cameraAt(const config::CameraPath& path, double t);

/// The actions with t0 < time <= t1, in file order. Called with consecutive intervals, (-inf, t1]
/// first, every action comes exactly once.
std::vector<config::PathAction> actionsIn(const config::CameraPath& path, double t0, double t1);

}  // namespace tessera::sync
