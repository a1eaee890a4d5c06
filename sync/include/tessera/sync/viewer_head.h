// The viewer's head on a wall: the point every tile's off-axis frustum (Kooima's "Generalized
// Perspective Projection", render::screenProjection()) and each stereo eye are seen from. It is
// a scene property (scene::Settings::head), so the master moves it and every node, the console
// and `tessera-render` agree; a scene without one sees from the wall's `eye` with +x as the
// head's right axis.
//
// Frames: the wall frame (config::WallConfig: the wall plane z = 0, x right, y up, metres). The
// scene camera places the wall's `eye` in the world (render/tile_frustum.h), so a head elsewhere
// is an eye offset from it: the world stays where the wall shows it and the frusta follow the
// head, as head tracking does. A stereo eye is the head's point moved by -/+ half the eye
// separation along the head's right axis.
//
// One rule at every gate (scene file, camera path, console, site message): headProblem() with the
// wall names what is wrong; without the wall, sync's scene checks hold the parts that need none.
#pragma once

#include <optional>
#include <string>

#include <glm/glm.hpp>

#include <tessera/camera_path.pb.h>
#include <tessera/config.pb.h>
#include <tessera/scene.pb.h>

namespace tessera::sync {

/// Metres between the eyes when neither the head nor the wall (or inset) says.
constexpr double kDefaultEyeSeparation = 0.065;

/// The first tile of `wall` that `point` (wall frame, metres) is not in front of (more than
/// 1e-6 m on the side its right x up points to; a planar tile: z > 0), or -1 when it is in front
/// of every tile.
int tileNotFacing(const config::WallConfig& wall, const glm::dvec3& point);

/// What is wrong with `head` as the viewer's head on `wall`, or nothing: the checks without a
/// wall (eye and right finite, right not zero, eye_separation in (0, 1]), then the head's point
/// and both eyes (at its separation, else the wall's) in front of every tile. The text names the
/// field under the head ("eye: ...", "right: ...", "eye_separation: ..."); the caller says where
/// the head came from ("settings.head.", "actions[2].setHead.", "head.").
std::optional<std::string> headProblem(const config::WallConfig& wall, const scene::Head& head);

/// The first setHead action of `path` that headProblem() refuses on `wall`, as
/// "actions[i].setHead.FIELD: what", or nothing.
std::optional<std::string> pathHeadProblem(const config::CameraPath& path,
                                           const config::WallConfig& wall);

/// The head every view of `wall` is seen from, with its right axis unit length.
struct ViewerHead {
  glm::dvec3 eye{0.0};
  glm::dvec3 right{1.0, 0.0, 0.0};
  /// The head's own separation (metres), or none: each stereo slot's (the wall's, the inset's).
  std::optional<double> separation;
};

/// settings.head when the scene has one, else the wall's eye, +x, no separation of its own.
/// Precondition (TESSERA_CHECK): a head in `settings` passes sync's checks (a replica's and a
/// scene file's settings always do).
ViewerHead viewerHead(const config::WallConfig& wall, const scene::Settings& settings);

/// The offset from the wall's eye (wall frame, metres) of eye `eye` (-1 left, 0 the head's point,
/// +1 right) of `head`: head.eye - wall.eye + eye * separation / 2 * head.right, separation the
/// head's own or else `slot_separation`. What render::tileView() takes as its eye offset.
glm::dvec3 eyeOffset(const config::WallConfig& wall, const ViewerHead& head, int eye,
                     double slot_separation);

/// The wall's own eye separation for stereo tiles: eye_separation, else kDefaultEyeSeparation.
double wallEyeSeparation(const config::WallConfig& wall);

}  // namespace tessera::sync
