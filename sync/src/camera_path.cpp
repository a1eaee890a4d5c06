#include <tessera/sync/camera_path.h>

#include <algorithm>
#include <cmath>

#include <glm/glm.hpp>

#include <tessera/core/check.h>

#include "config_json.h"
#include "scene_checks.h"

namespace tessera::sync {
namespace {

using detail::failConfig;

config::Camera keyframeCamera(const config::CameraKeyframe& k) {
  config::Camera c;
  *c.mutable_eye() = k.eye();
  *c.mutable_target() = k.target();
  *c.mutable_up() = k.up();
  return c;
}

void checkModelName(const std::string& model, const char* fn, const std::string& name,
                    const std::string& field) {
  if (model.empty()) failConfig(fn, name, field, "names no model");
}

/// Hermite interpolation of one keyframe quantity (`get` reads it from a keyframe) in the
/// segment [k, k+1] at parameter s in [0, 1]. Tangents as documented at cameraAt().
template <typename Get>
glm::dvec3 hermite(const config::CameraPath& path, int k, double s, Get get) {
  const auto& kf = path.keyframes();
  const int last = kf.size() - 1;
  auto p = [&](int i) { return vec(get(kf[i])); };
  auto t = [&](int i) { return kf[i].time(); };
  auto tangent = [&](int i) {
    if (path.closed() && (i == 0 || i == last)) {  // the neighbours across the seam
      return (p(1) - p(last - 1)) / ((t(1) - t(0)) + (t(last) - t(last - 1)));
    }
    const int a = std::max(i - 1, 0), b = std::min(i + 1, last);
    return (p(b) - p(a)) / (t(b) - t(a));
  };
  const double h = t(k + 1) - t(k);
  const double s2 = s * s, s3 = s2 * s;
  return (2 * s3 - 3 * s2 + 1) * p(k) + (s3 - 2 * s2 + s) * h * tangent(k) +
         (-2 * s3 + 3 * s2) * p(k + 1) + (s3 - s2) * h * tangent(k + 1);
}

}  // namespace

config::CameraPath parseCameraPath(const std::string& json, const std::string& name) {
  const char* fn = "sync::loadCameraPath()";
  config::CameraPath path;
  detail::parseConfigJson(json, name, fn, path);
  if (path.keyframes_size() == 0)
    failConfig(fn, name, "keyframes", "a path needs at least one keyframe");
  for (int i = 0; i < path.keyframes_size(); ++i) {
    const config::CameraKeyframe& k = path.keyframes(i);
    const std::string f = "keyframes[" + std::to_string(i) + "]";
    if (!std::isfinite(k.time())) failConfig(fn, name, f + ".time", "must be finite (seconds)");
    if (i > 0 && !(k.time() > path.keyframes(i - 1).time())) {
      failConfig(fn, name, f + ".time",
                 std::to_string(k.time()) + " is not after keyframes[" + std::to_string(i - 1) +
                     "] (" + std::to_string(path.keyframes(i - 1).time()) + ")");
    }
    if (!k.has_eye() || !k.has_target() || !k.has_up())
      failConfig(fn, name, f, "needs eye, target and up");
    detail::checkConfigCamera(keyframeCamera(k), fn, name, f);
  }
  if (path.closed()) {
    const auto& first = path.keyframes(0);
    const auto& last = path.keyframes(path.keyframes_size() - 1);
    if (path.keyframes_size() < 3 || vec(first.eye()) != vec(last.eye()) ||
        vec(first.target()) != vec(last.target()) || vec(first.up()) != vec(last.up())) {
      failConfig(fn, name, "closed",
                 "a closed path needs 3 keyframes or more, the last the same camera as the first");
    }
  }
  for (int i = 0; i < path.actions_size(); ++i) {
    const config::PathAction& a = path.actions(i);
    const std::string f = "actions[" + std::to_string(i) + "]";
    if (!std::isfinite(a.time())) failConfig(fn, name, f + ".time", "must be finite (seconds)");
    if (i > 0 && a.time() < path.actions(i - 1).time())
      failConfig(fn, name, f + ".time", "actions must be in time order");
    switch (a.action_case()) {
      case config::PathAction::kSetOpacity:
        checkModelName(a.set_opacity().model(), fn, name, f + ".setOpacity.model");
        if (!(a.set_opacity().opacity() > 0 && a.set_opacity().opacity() <= 1))
          failConfig(fn, name, f + ".setOpacity.opacity", "must be in (0, 1]");
        break;
      case config::PathAction::kSetVisible:
        checkModelName(a.set_visible().model(), fn, name, f + ".setVisible.model");
        break;
      case config::PathAction::kSetShading:
        if (a.set_shading() != "color" && a.set_shading() != "edl")
          failConfig(fn, name, f + ".setShading",
                     "'" + a.set_shading() + "' is not one of color, edl");
        break;
      case config::PathAction::kScreenshot:
        if (a.screenshot().empty()) failConfig(fn, name, f + ".screenshot", "needs a path");
        break;
      case config::PathAction::kSetAnalysis:
        if (const auto problem = checks::checkAnalysis(a.set_analysis()))
          failConfig(fn, name, f + ".setAnalysis", *problem);
        break;
      case config::PathAction::kSetInset: {
        // Whether the inset exists and stays on the wall is checked against the wall by the
        // master (render::checkPathInsets()).
        const scene::InsetCentre& c = a.set_inset();
        if (c.name().empty() || c.name().size() > 64)
          failConfig(fn, name, f + ".setInset.name", "needs the inset's name (1..64 bytes)");
        if (!std::isfinite(c.x()) || !std::isfinite(c.y()))
          failConfig(fn, name, f + ".setInset", "x and y must be finite (metres)");
        break;
      }
      case config::PathAction::kSetHead:
        // That the head is in front of every tile is checked against the wall by the master
        // (sync::pathHeadProblem()).
        if (const auto problem = checks::checkHead(a.set_head())) {
          const size_t colon = problem->find(": ");
          failConfig(fn, name, f + ".setHead." + problem->substr(0, colon),
                     problem->substr(colon + 2));
        }
        break;
      default:
        failConfig(fn, name, f,
                   "needs one of setOpacity, setVisible, setShading, setAnalysis, setInset, "
                   "setHead, screenshot");
    }
  }
  return path;
}

config::CameraPath loadCameraPath(const std::filesystem::path& path) {
  return parseCameraPath(detail::readConfigFile(path, "sync::loadCameraPath()"), path.string());
}

void checkPathModels(const config::CameraPath& path, const SceneGraph& scene,
                     const std::string& name) {
  auto known = [&](const std::string& model) { return scene.findByName(model).has_value(); };
  for (int i = 0; i < path.actions_size(); ++i) {
    const config::PathAction& a = path.actions(i);
    std::string model, field = "actions[" + std::to_string(i) + "]";
    if (a.has_set_opacity()) {
      model = a.set_opacity().model();
      field += ".setOpacity.model";
    } else if (a.has_set_visible()) {
      model = a.set_visible().model();
      field += ".setVisible.model";
    } else {
      continue;
    }
    if (!known(model))
      failConfig("sync::checkPathModels()", name, field, "no model '" + model + "' in the scene");
  }
}

double pathDuration(const config::CameraPath& path) {
  double end = path.keyframes_size() > 0 ? path.keyframes(path.keyframes_size() - 1).time() : 0.0;
  for (const config::PathAction& a : path.actions()) end = std::max(end, a.time());
  return end;
}

config::Camera cameraAt(const config::CameraPath& path, double t) {
  const auto& kf = path.keyframes();
  TESSERA_CHECK(!kf.empty(), "sync::cameraAt(): the path has no keyframes");
  glm::dvec3 eye, target, up;
  int near = 0;  // the keyframe whose up takes over should the spline's be along the view
  if (!(t > kf[0].time()) || t >= kf[kf.size() - 1].time()) {  // NaN: the first
    near = t >= kf[kf.size() - 1].time() ? kf.size() - 1 : 0;
    eye = vec(kf[near].eye());
    target = vec(kf[near].target());
    up = vec(kf[near].up());
  } else {
    // The segment [k, k+1] holding t: k is the last keyframe at or before t.
    auto after =
        std::upper_bound(kf.begin(), kf.end(), t,
                         [](double v, const config::CameraKeyframe& k) { return v < k.time(); });
    const int k = int(after - kf.begin()) - 1;
    const double s = (t - kf[k].time()) / (kf[k + 1].time() - kf[k].time());
    near = s < 0.5 ? k : k + 1;
    eye = hermite(
        path, k, s, [](const auto& f) -> const auto& { return f.eye(); });
    target = hermite(
        path, k, s, [](const auto& f) -> const auto& { return f.target(); });
    up = hermite(
        path, k, s, [](const auto& f) -> const auto& { return f.up(); });
  }
  // Re-orthonormalise up against the view (Gram-Schmidt). Keyframes were checked to be valid,
  // but a spline may still bring up along the view: then the nearer keyframe's up, then an axis.
  const glm::dvec3 d = glm::normalize(target - eye);
  auto orthogonal = [&](const glm::dvec3& u) { return u - d * glm::dot(d, u); };
  glm::dvec3 ortho = orthogonal(up);
  if (!(glm::length(ortho) > 1e-9 * glm::length(up))) {
    up = vec(kf[near].up());
    ortho = orthogonal(up);
  }
  if (!(glm::length(ortho) > 1e-9 * glm::length(up))) {
    up = std::abs(d.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(0, 1, 0);
    ortho = orthogonal(up);
  }
  config::Camera camera;
  *camera.mutable_eye() = toVec3(eye);
  *camera.mutable_target() = toVec3(target);
  *camera.mutable_up() = toVec3(glm::normalize(ortho));
  return camera;
}

std::vector<config::PathAction> actionsIn(const config::CameraPath& path, double t0, double t1) {
  std::vector<config::PathAction> out;
  for (const config::PathAction& a : path.actions()) {
    if (a.time() > t0 && a.time() <= t1) out.push_back(a);
  }
  return out;
}

}  // namespace tessera::sync
