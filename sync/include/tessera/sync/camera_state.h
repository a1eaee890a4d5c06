// The camera's wire form (scene::CameraState, see scene.proto): eye in doubles, view = target -
// eye in floats, up as one roll angle. The master stores its camera in this form, so what a node
// decodes is bit for bit what the master decodes, and no rounding drifts between them.
#pragma once

#include <tessera/config.pb.h>
#include <tessera/scene.pb.h>

namespace tessera::sync {

/// Encodes a camera (metres, scene frame). The up vector need not be orthogonal to the view;
/// only its component orthogonal to it counts (as with a look-at matrix).
/// Precondition (TESSERA_CHECK): finite numbers, eye != target, up not zero or along the view.
scene::CameraState encodeCamera(const config::Camera& camera);

/// Decodes a complete CameraState: eye as stored, target = eye + view, up a unit vector
/// orthogonal to the view. Deterministic: the same state gives the same bits on every process
/// of one build. Precondition (TESSERA_CHECK): isCompleteCamera(state).
config::Camera decodeCamera(const scene::CameraState& state);

/// True when `state` has 3 finite eye numbers, 3 finite view numbers of non-zero length and a
/// finite roll: what a snapshot and the scene graph hold.
bool isCompleteCamera(const scene::CameraState& state);

}  // namespace tessera::sync
