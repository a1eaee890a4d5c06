#include <tessera/render/stereo.h>

#include <cmath>
#include <cstring>
#include <filesystem>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/check.h>
#include <tessera/render/gl_context.h>

namespace tessera::render {

StereoLayout parseStereoLayout(const std::string& text, const std::string& what) {
  if (text == "sbs") return StereoLayout::kSideBySide;
  if (text == "tb") return StereoLayout::kTopBottom;
  if (text == "anaglyph") return StereoLayout::kAnaglyph;
  if (text == "pair") return StereoLayout::kPair;
  throw RenderError(what + ": '" + text + "' is not a stereo layout (sbs, tb, anaglyph, pair)");
}

ViewSetup stereoEyeView(const ViewSetup& mono, const glm::dvec3& eye_offset,
                        double screen_distance) {
  TESSERA_CHECK(std::isfinite(screen_distance) && screen_distance > 0.0 && eye_offset.z == 0.0 &&
                    mono.projection[2][3] == -1.0 && mono.projection[3][3] == 0.0,
                "render::stereoEyeView(): a perspective view, a screen in front, an offset in "
                "the screen's plane");
  ViewSetup v = mono;
  // Camera space moves the other way than the eye.
  v.view = glm::translate(glm::dmat4(1.0), -eye_offset) * mono.view;
  // NDC x = P00 x / -z - P20 for a frustum: a point of the screen plane (z = -D) seen from the
  // moved eye keeps its NDC when P20 loses P00 e.x / D (and P21 likewise in y).
  v.projection[2][0] -= mono.projection[0][0] * eye_offset.x / screen_distance;
  v.projection[2][1] -= mono.projection[1][1] * eye_offset.y / screen_distance;
  v.eye_offset = mono.eye_offset + eye_offset;
  v.eye_world = glm::dvec3(glm::inverse(mono.view) * glm::dvec4(eye_offset, 1.0));
  return v;
}

Image composeStereo(const Image& left, const Image& right, StereoLayout layout) {
  TESSERA_CHECK(left.width == right.width && left.height == right.height &&
                    left.rgba.size() == size_t(left.width) * left.height * 4 &&
                    right.rgba.size() == left.rgba.size() && layout != StereoLayout::kPair,
                "render::composeStereo(): two pictures of one size, one image's layout");
  const uint32_t w = left.width, h = left.height;
  Image out;
  if (layout == StereoLayout::kAnaglyph) {
    out = right;
    for (size_t i = 0; i < size_t(w) * h; ++i) out.rgba[4 * i] = left.rgba[4 * i];
    return out;
  }
  const bool sbs = layout == StereoLayout::kSideBySide;
  out.width = sbs ? 2 * w : w;
  out.height = sbs ? h : 2 * h;
  out.rgba.resize(size_t(out.width) * out.height * 4);
  const size_t row = size_t(w) * 4;
  for (uint32_t y = 0; y < h; ++y) {
    if (sbs) {
      std::memcpy(&out.rgba[size_t(y) * 2 * row], &left.rgba[y * row], row);
      std::memcpy(&out.rgba[size_t(y) * 2 * row + row], &right.rgba[y * row], row);
    } else {
      std::memcpy(&out.rgba[size_t(y) * row], &left.rgba[y * row], row);
      std::memcpy(&out.rgba[size_t(y + h) * row], &right.rgba[y * row], row);
    }
  }
  return out;
}

std::string stereoPairPath(const std::string& path, bool right) {
  const std::filesystem::path p(path);
  const std::string tail = (right ? "-right" : "-left") + p.extension().string();
  return (p.parent_path() / (p.stem().string() + tail)).string();
}

}  // namespace tessera::render
