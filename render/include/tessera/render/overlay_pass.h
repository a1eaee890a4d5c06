// The overlay pass: what is drawn on top of the scene, on the GPU, with depth test against the
// frame target's depth so the model hides what is behind it: lines (measurements, sketches),
// points (picks, avatars' heads), text labels (annotations) and textured quads (video insets) in
// the world, and rectangles in screen space (the console's bars, screen-fixed insets). World
// positions are in double precision and projected on the CPU, so georeferenced scenes stay
// exact; an overlay holds hundreds to thousands of primitives, not millions.
//
// Cost, only when the overlay is not empty: the image copied into a framebuffer's colour (no
// shader), the primitives' triangles (each fragment depth-tested against the frame target's
// depth in the fragment shader), and one read of the image back into the frame target: 0.5 to
// 1.5 ms at 640x360 on llvmpipe for 4 to 16 avatars (bench/sites; a full-screen load pass cost
// 2.7 ms of it before). A GL 4.5 context must be current for the object's whole life.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/render/frame_target.h>
#include <tessera/render/gl_objects.h>
#include <tessera/render/tile_frustum.h>

namespace tessera::render {

/// A segment in the world, `width` pixels wide on every view (square caps).
struct OverlayLine {
  glm::dvec3 a{0.0}, b{0.0};
  glm::u8vec4 color{255, 255, 255, 255};
  float width_px = 2.0f;
};

/// A round dot at a world position, `size_px` across on every view; with ring_px > 0 only its
/// outer ring of that width (a marker that leaves what it marks visible).
struct OverlayPoint {
  glm::dvec3 at{0.0};
  glm::u8vec4 color{255, 255, 255, 255};
  float size_px = 8.0f;
  float ring_px = 0.0f;
};

/// Text (and pictures) at a world position: its box's top-left corner `offset_px` from where the position
/// projects (y down), then moved by -align times the box's size (so align (0.5, 1) puts the
/// box's bottom centre at the offset: text centred above its anchor), `height_px` tall, over a
/// `background` box (alpha 0: none). UTF-8; glyphs the font lacks show as '?'. Hidden when its
/// anchor is (the scene nearer than it by over 2% at the anchor's pixel: one depth value read
/// back per label), else drawn whole over the scene. Labels make room for each other: one whose
/// box would meet an earlier label's is mirrored to another side of its anchor, or stacked above
/// (overlay_pass.cpp place()); earlier labels keep their place.
/// A picture in a label's box, under its text (an open note's image items): RGBA8 pixels, top
/// row first, shown `size_px` large. The pass keeps a texture per `key` while labels use it, so
/// the same key must always mean the same pixels (scene_overlay.cpp hashes them).
struct LabelPicture {
  uint64_t key = 0;
  uint32_t width = 0, height = 0;
  std::shared_ptr<const std::vector<uint8_t>> rgba;  ///< width * height * 4 bytes
  glm::vec2 size_px{0.0f};
};

struct OverlayLabel {
  glm::dvec3 at{0.0};
  std::string text;
  glm::u8vec4 color{255, 255, 255, 255};
  glm::u8vec4 background{0, 0, 0, 160};
  float height_px = 20.0f;
  glm::vec2 offset_px{8.0f, -28.0f};
  glm::vec2 align{0.0f};  ///< fractions of the box's width and height, each in [0, 1]
  std::vector<LabelPicture> pictures{};  ///< in a row under the text, inside the box
};

/// A textured quad in the world, corners in order (texture u, v): (0,0) (1,0) (1,1) (0,1), v = 0
/// at the texture's top row. The texture must outlive the frame that draws it.
struct OverlayQuad {
  std::array<glm::dvec3, 4> corners{};
  const GlTexture* texture = nullptr;  ///< null: a flat `tint`
  glm::u8vec4 tint{255, 255, 255, 255};
};

/// A rectangle in the view's pixels (x right, y down from the top-left), over everything.
struct ScreenRect {
  glm::vec2 min{0.0f}, max{0.0f};
  glm::u8vec4 color{255, 255, 255, 255};
  const GlTexture* texture = nullptr;  ///< multiplied by `color`
};

struct Overlay {
  std::vector<OverlayLine> lines;
  std::vector<OverlayPoint> points;
  std::vector<OverlayLabel> labels;
  std::vector<OverlayQuad> quads;
  std::vector<ScreenRect> rects;
  /// World primitives are tested at their position moved towards the eye by this fraction of
  /// its distance, so what lies on the model's surface is not hidden by the surface's own
  /// samples (points' splats stand up to a spacing in front of it).
  double depth_bias = 0.005;

  bool empty() const {
    return lines.empty() && points.empty() && labels.empty() && quads.empty() && rects.empty();
  }
};

class OverlayPass {
 public:
  OverlayPass();
  ~OverlayPass();
  OverlayPass(const OverlayPass&) = delete;
  OverlayPass& operator=(const OverlayPass&) = delete;

  /// Draws `overlay` onto `target`'s image as seen from `view` (its size must be the target's),
  /// alpha blended, world primitives depth-tested against the target's depth. Milliseconds.
  double run(FrameTarget& target, const ViewSetup& view, const Overlay& overlay);

  /// A label's box size in pixels (width, height) as run() lays it out.
  glm::vec2 measure(const OverlayLabel& label) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> mImpl;
};

}  // namespace tessera::render
