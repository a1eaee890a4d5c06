// The scene graph's checks of values from outside (frames and snapshots from the master, scene
// files) and of the master's own mutations: each returns an error text naming the field, or
// nothing. SceneGraph (scene_graph.cpp) turns a text into a SyncError or a PreconditionError.
#pragma once

#include <optional>
#include <span>
#include <string>

#include <tessera/scene.pb.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::sync::checks {

using Problem = std::optional<std::string>;

/// "%g" of `v`, for error texts.
std::string num(double v);
/// A Kind a node may have (not KIND_UNSPECIFIED, not unknown).
bool validKind(int kind);
/// The payload field a node of `kind` carries (PAYLOAD_NOT_SET: none, as GROUP).
scene::SceneNode::PayloadCase payloadCaseOf(SceneGraph::Kind kind);
/// r, g, b in [0, 1]; `field` names it in the text.
Problem checkColor(const scene::Color& c, const std::string& field);
/// A transform as 16 numbers, column-major (or none: identity), and as it travels.
Problem checkTransform(std::span<const double> m);
Problem checkTransform(const scene::Transform& t);
/// The fields present in `n` (a full state or a delta) for a node of `kind`, its payload too.
Problem checkNodeFields(const scene::SceneNode& n, SceneGraph::Kind kind);
/// A delta of the settings (or complete settings).
Problem checkSettings(const scene::Settings& s);
/// The analysis filters' settings (scene::Analysis).
Problem checkAnalysis(const scene::Analysis& a);
/// settings.inset: names non-empty (at most 64 bytes) and unique, centres finite, at most 256.
Problem checkInsetPlacement(const scene::InsetPlacement& p);
/// A viewer's head on its own (no wall): eye and right present and finite, right non-zero,
/// eye_separation in (0, 1] when present. The text names the field under the head ("eye: ...",
/// "right: ...", "eye_separation: ...").
Problem checkHead(const scene::Head& h);
/// A delta of the camera: each part absent or complete.
Problem checkCameraDelta(const scene::CameraState& c);
Problem checkCommand(const scene::Command& c);

}  // namespace tessera::sync::checks
