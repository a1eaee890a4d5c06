// The one rule for a view (eye, target, up): every gate that takes a camera from outside (the
// command line, scene and wall files, camera paths, scene frames, a site's pose and script, the
// annotation database's stored views) asks it, so a camera one gate accepts every other gate
// accepts, and sync::encodeCamera() (camera_state.h) encodes it without a precondition failure.
#pragma once

#include <optional>
#include <string>

#include <glm/glm.hpp>

#include <tessera/config.pb.h>

namespace tessera::sync {

/// What is wrong with a view, and where: `on_up` when the fault is up's (a caller names its
/// field "<field>.up"), else the view's own.
struct ViewProblem {
  bool on_up = false;
  std::string what;  ///< "numbers must be finite", "eye and target coincide", "up is zero",
                     ///< "up is along the view direction"
};

/// The rule: eye, target and up finite; the view direction target - eye longer than 1e-12 of
/// the coordinates' size (below that it is rounding noise) and finite in single precision (the
/// wire's); up non-zero, at more than 1e-6 radians from the view direction.
std::optional<ViewProblem> viewProblem(const glm::dvec3& eye, const glm::dvec3& target,
                                       const glm::dvec3& up);
std::optional<ViewProblem> viewProblem(const config::Camera& camera);

/// "FIELD: what" or "FIELD.up: what" for a problem found in `field` (an empty field: "what").
std::string describe(const ViewProblem& problem, const std::string& field);

/// For the command line: throws cli::UsageError "OPTION: what" unless the view passes the rule.
void requireView(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up,
                 const std::string& option);

}  // namespace tessera::sync
