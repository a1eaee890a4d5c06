// A scene node's transform (scene.proto Transform) as a matrix, and a matrix as the smallest
// Transform that gives it back exactly: 16 doubles, or for a rigid motion its translation and
// the unit quaternion of its rotation (44 bytes on the wire instead of 130; every avatar moves
// every frame, so this is most of what a site receives while others move).
#pragma once

#include <span>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include <tessera/scene.pb.h>

namespace tessera::sync {

/// The matrix `t` stands for: identity when empty, its 16 numbers (column-major), or the rigid
/// motion of its translation and rotation (normalised here). Precondition: `t` passed the
/// checks of SceneGraph::apply() or setTransform() (sizes, finite, a unit quaternion).
glm::dmat4 transformMatrix(const scene::Transform& t);

/// The rigid motion that rotates by `rotation` (normalised when decoded), then moves by
/// `translation`, in the rigid form. The avatars' poses are made this way: a matrix given as
/// 16 numbers takes that form only when a quaternion recovered from it in floats decodes to
/// exactly those numbers, which a general rotation's seldom does.
scene::Transform rigidTransform(const glm::quat& rotation, const glm::dvec3& translation);

/// `matrix` (16 numbers, column-major, or none: identity) as a Transform: the rigid form when
/// transformMatrix() of it gives back exactly these 16 numbers (translations, quarter turns), else
/// the numbers themselves.
scene::Transform encodeTransform(std::span<const double> matrix);

}  // namespace tessera::sync
