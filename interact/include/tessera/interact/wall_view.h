// How the wall is seen, as the console's controls change it: the viewer's head (scene
// settings.head, sync/viewer_head.h) and where each foveal inset is and whether it shows (scene
// settings.inset, render/inset.h). Window-free, so a test drives them as the console's panel
// does. Each edit passes the same wall checks as a camera path's setHead and setInset and a
// site's head message (sync::headProblem(), render::insetPlacementProblem()), then goes into the
// scene through the same calls (SceneGraph::setHead(), SceneGraph::setInset()), so every node
// draws it from the next frame.
#pragma once

#include <optional>
#include <string>

#include <tessera/config.pb.h>
#include <tessera/scene.pb.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::interact {

/// The head the wall is seen from now: settings.head, else the wall's eye with +x as its right
/// axis and the wall's eye separation (sync::wallEyeSeparation()).
scene::Head currentHead(const config::WallConfig& wall, const scene::Settings& settings);

/// The head's turn about the wall's vertical (y) axis, degrees: 0 with its right axis along +x,
/// positive turned to the right (the right axis towards +z, (cos a, 0, sin a)).
double headYawDegrees(const scene::Head& head);
/// Sets the head's right axis to yaw `degrees` (as headYawDegrees() reads it), level.
void setHeadYaw(scene::Head& head, double degrees);

/// Moves the viewer's head to `head` when it passes sync::headProblem() on `wall`; else leaves
/// the scene as it is and returns why, naming the field ("head.eye: ...").
std::optional<std::string> applyHead(sync::SceneGraph& graph, const config::WallConfig& wall,
                                     const scene::Head& head);

/// Inset `index`'s placement now: its centre (the rectangle render::insetRect() gives) and
/// whether it is switched off. Precondition (TESSERA_CHECK): index < wall.insets_size().
scene::InsetCentre currentInset(const config::WallConfig& wall, const scene::Settings& settings,
                                int index);

/// Places an inset as `centre` says (its centre and whether it shows) when it passes
/// render::insetPlacementProblem() on `wall`; else leaves the scene as it is and returns why
/// ("inset.fovea: ...").
std::optional<std::string> applyInset(sync::SceneGraph& graph, const config::WallConfig& wall,
                                      const scene::InsetCentre& centre);

}  // namespace tessera::interact
