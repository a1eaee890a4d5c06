#include <tessera/interact/wall_view.h>

#include <cmath>

#include <glm/glm.hpp>

#include <tessera/core/check.h>
#include <tessera/render/inset.h>
#include <tessera/sync/vec3.h>
#include <tessera/sync/viewer_head.h>

namespace tessera::interact {

scene::Head currentHead(const config::WallConfig& wall, const scene::Settings& settings) {
  if (settings.has_head()) return settings.head();
  scene::Head h;
  *h.mutable_eye() = wall.eye();
  sync::set(h.mutable_right(), glm::dvec3(1.0, 0.0, 0.0));
  h.set_eye_separation(sync::wallEyeSeparation(wall));
  return h;
}

double headYawDegrees(const scene::Head& head) {
  return glm::degrees(std::atan2(head.right().z(), head.right().x()));
}

void setHeadYaw(scene::Head& head, double degrees) {
  const double a = glm::radians(degrees);
  sync::set(head.mutable_right(), glm::dvec3(std::cos(a), 0.0, std::sin(a)));
}

std::optional<std::string> applyHead(sync::SceneGraph& graph, const config::WallConfig& wall,
                                     const scene::Head& head) {
  if (const auto why = sync::headProblem(wall, head)) return "head." + *why;
  graph.setHead(head);
  return std::nullopt;
}

scene::InsetCentre currentInset(const config::WallConfig& wall, const scene::Settings& settings,
                                int index) {
  TESSERA_CHECK(index >= 0 && index < wall.insets_size(),
                "interact::currentInset(): index of one of the wall's insets");
  const render::InsetRect r = render::insetRect(wall, index, settings.inset());
  scene::InsetCentre c;
  c.set_name(wall.insets(index).name());
  c.set_x(0.5 * (r.x0 + r.x1));
  c.set_y(0.5 * (r.y0 + r.y1));
  c.set_hidden(!r.shown);
  return c;
}

std::optional<std::string> applyInset(sync::SceneGraph& graph, const config::WallConfig& wall,
                                      const scene::InsetCentre& centre) {
  if (const auto why = render::insetPlacementProblem(wall, centre))
    return "inset." + centre.name().substr(0, 64) + ": " + *why;
  graph.setInset(centre);
  return std::nullopt;
}

}  // namespace tessera::interact
