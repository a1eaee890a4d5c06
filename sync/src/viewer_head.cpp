#include <tessera/sync/viewer_head.h>

#include <cstdio>

#include <tessera/core/check.h>
#include <tessera/sync/vec3.h>

#include "scene_checks.h"

namespace tessera::sync {

int tileNotFacing(const config::WallConfig& wall, const glm::dvec3& point) {
  for (int i = 0; i < wall.tiles_size(); ++i) {
    const config::Tile& t = wall.tiles(i);
    const glm::dvec3 o = t.has_origin() ? vec(t.origin()) : glm::dvec3(t.x(), t.y(), 0.0);
    const glm::dvec3 r = t.has_right() ? glm::normalize(vec(t.right())) : glm::dvec3(1, 0, 0);
    const glm::dvec3 u = t.has_up() ? glm::normalize(vec(t.up())) : glm::dvec3(0, 1, 0);
    if (!(glm::dot(point - o, glm::cross(r, u)) > 1e-6)) return i;
  }
  return -1;
}

double wallEyeSeparation(const config::WallConfig& wall) {
  return wall.has_eye_separation() ? wall.eye_separation() : kDefaultEyeSeparation;
}

std::optional<std::string> headProblem(const config::WallConfig& wall, const scene::Head& head) {
  if (auto p = checks::checkHead(head)) return p;
  const glm::dvec3 eye = vec(head.eye()), right = glm::normalize(vec(head.right()));
  const double half =
      0.5 * (head.has_eye_separation() ? head.eye_separation() : wallEyeSeparation(wall));
  const char* names[3] = {"the head", "its left eye", "its right eye"};
  const glm::dvec3 points[3] = {eye, eye - half * right, eye + half * right};
  for (int k = 0; k < 3; ++k) {
    const int i = tileNotFacing(wall, points[k]);
    if (i < 0) continue;
    char at[96];
    std::snprintf(at, sizeof at, " (%.6g, %.6g, %.6g)", points[k].x, points[k].y, points[k].z);
    return "eye: " + std::string(names[k]) + at + " is behind the plane of tiles[" +
           std::to_string(i) + "] ('" + wall.tiles(i).name() +
           "'): the head must be in front of every tile, on the side right x up points to";
  }
  return std::nullopt;
}

std::optional<std::string> pathHeadProblem(const config::CameraPath& path,
                                           const config::WallConfig& wall) {
  for (int i = 0; i < path.actions_size(); ++i) {
    if (!path.actions(i).has_set_head()) continue;
    if (const auto why = headProblem(wall, path.actions(i).set_head()))
      return "actions[" + std::to_string(i) + "].setHead." + *why;
  }
  return std::nullopt;
}

ViewerHead viewerHead(const config::WallConfig& wall, const scene::Settings& settings) {
  ViewerHead h;
  if (!settings.has_head()) {
    h.eye = vec(wall.eye());
    return h;
  }
  const scene::Head& head = settings.head();
  TESSERA_CHECK(!checks::checkHead(head), "sync::viewerHead(): a checked head");
  h.eye = vec(head.eye());
  h.right = glm::normalize(vec(head.right()));
  if (head.has_eye_separation()) h.separation = head.eye_separation();
  return h;
}

glm::dvec3 eyeOffset(const config::WallConfig& wall, const ViewerHead& head, int eye,
                     double slot_separation) {
  const double separation = head.separation.value_or(slot_separation);
  return head.eye - vec(wall.eye()) + (0.5 * double(eye) * separation) * head.right;
}

}  // namespace tessera::sync
