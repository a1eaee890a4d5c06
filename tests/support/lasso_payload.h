// Views and lassos for the selection tint tests (render/screen_passes.h HighlightPass): a
// perspective view looking at a point, and a SELECTION payload from a lasso drawn in a view's
// pixels.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/render/scene_overlay.h>
#include <tessera/render/tile_frustum.h>

namespace tessera::test {

/// A w x h view from `eye` towards `target`, y up, `fovy_deg` vertical, near 0.02 m, far 5 m.
inline render::ViewSetup lookingAt(const glm::dvec3& eye, const glm::dvec3& target, uint32_t w,
                                   uint32_t h, double fovy_deg = 35.0, double near = 0.02) {
  render::ViewSetup v;
  v.eye_world = eye;
  v.view = glm::lookAt(eye, target, glm::dvec3(0, 1, 0));
  v.projection = glm::perspective(glm::radians(fovy_deg), double(w) / h, near, 5.0);
  v.width = w;
  v.height = h;
  return v;
}

/// A SELECTION payload on MODEL node `model`: the lasso `px` (pixels of view `v`, y down) and
/// that view, no elements.
inline scene::SelectionPayload lassoPayload(uint32_t model, const render::ViewSetup& v,
                                            const std::vector<glm::dvec2>& px) {
  scene::SelectionPayload s;
  s.set_model(model);
  render::setSelectionLasso(s, v, px);
  return s;
}

}  // namespace tessera::test
