#include <tessera/sync/view.h>

#include <algorithm>
#include <cmath>

#include <tessera/core/cli.h>
#include <tessera/sync/vec3.h>

namespace tessera::sync {

std::optional<ViewProblem> viewProblem(const glm::dvec3& eye, const glm::dvec3& target,
                                       const glm::dvec3& up) {
  if (!finite(eye) || !finite(target) || !finite(up))
    return ViewProblem{false, "numbers must be finite"};
  const glm::dvec3 view = target - eye;
  const double dist = glm::length(view);
  const double scale = std::max({glm::length(eye), glm::length(target), 1.0});
  // The wire carries the view direction in floats (camera_state.h): it must stay finite there.
  if (!(dist > 1e-12 * scale) || !finite(glm::dvec3(glm::vec3(view))))
    return ViewProblem{false, "eye and target coincide"};
  const double up_len = glm::length(up);
  if (!(up_len > 0.0) || !std::isfinite(up_len)) return ViewProblem{true, "up is zero"};
  // Above 1e-6 the part of up across the view survives the float view direction's rounding
  // (about 6e-8) with room, so encodeCamera() always finds a roll.
  if (!(glm::length(glm::cross(view / dist, up / up_len)) > 1e-6))
    return ViewProblem{true, "up is along the view direction"};
  return std::nullopt;
}

std::optional<ViewProblem> viewProblem(const config::Camera& camera) {
  return viewProblem(vec(camera.eye()), vec(camera.target()), vec(camera.up()));
}

std::string describe(const ViewProblem& problem, const std::string& field) {
  std::string where = field;
  if (problem.on_up) where += where.empty() ? "up" : ".up";
  return where.empty() ? problem.what : where + ": " + problem.what;
}

void requireView(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up,
                 const std::string& option) {
  if (const auto problem = viewProblem(eye, target, up))
    throw cli::UsageError(option + ": " + problem->what);
}

}  // namespace tessera::sync
