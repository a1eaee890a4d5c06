#include <tessera/render/overlay_pass.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <string_view>
#include <vector>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include "gpu_lap.h"
#include "shaders.h"
#include "shared_layout.h"
#include "text_shaper.h"

namespace tessera::render {
namespace {

/// C++ twin of shaders/shared_layout.h's OverlayVertex.
struct OverlayVertex {
  glm::vec4 clip;
  glm::vec2 uv;
  uint32_t rgba;
  uint32_t mode;
};
static_assert(sizeof(OverlayVertex) == TESSERA_OVERLAY_VERTEX_BYTES);

/// C++ twin of shaders/shared_layout.h's OverlayLine (overlay_lines.comp).
struct GpuOverlayLine {
  glm::vec4 ends;   // pixels, y down from the image's top
  glm::vec4 depth;  // window depth at the first end, per pixel along, half width, tested
  uint32_t rgb = 0;
  uint32_t base = 0;   // its first step among all lines'
  int32_t first = 0;   // its first column (x-major) or row on screen
  uint32_t flags = 0;  // bit 0: x-major
};
static_assert(sizeof(GpuOverlayLine) == TESSERA_OVERLAY_LINE_BYTES);

/// Clips the segment p + t (q - p), t in [0, 1], to the box [lo, hi] (Liang and Barsky):
/// false when nothing is left, else the interval [t0, t1].
bool clipSegment(const glm::dvec2& p, const glm::dvec2& q, const glm::dvec2& lo,
                 const glm::dvec2& hi, double& t0, double& t1) {
  t0 = 0.0;
  t1 = 1.0;
  const glm::dvec2 d = q - p;
  for (int axis = 0; axis < 2; ++axis)
    for (const auto& [num, den] :
         {std::pair{p[axis] - lo[axis], -d[axis]}, std::pair{hi[axis] - p[axis], d[axis]}}) {
      if (den == 0.0) {
        if (num < 0.0) return false;
        continue;
      }
      const double t = num / den;
      if (den < 0.0)
        t0 = std::max(t0, t);
      else
        t1 = std::min(t1, t);
    }
  return t0 <= t1;
}

/// The most steps (columns or rows of lines) overlay_lines.comp draws in one run.
constexpr size_t kMostDirectSteps = size_t(1) << 24;

uint32_t pack(const glm::u8vec4& c) {
  return uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16 | uint32_t(c.a) << 24;
}

/// Line breaks in a label's text: the lines between them.
std::vector<std::string_view> linesOf(const std::string& text) {
  std::vector<std::string_view> lines;
  size_t start = 0;
  for (size_t i = 0; i <= text.size(); ++i)
    if (i == text.size() || text[i] == '\n') {
      lines.emplace_back(text.data() + start, i - start);
      start = i + 1;
    }
  return lines;
}

/// What a run of primitives is: lines, dots, labels (flat boxes, glyphs, pictures) or textured
/// quads. Runs of one group share a draw call while their texture allows.
enum class Group : uint8_t { kLines, kDots, kLabels, kTextured };

/// Which fragment code a run needs (overlay.frag's variants): a bit per primitive mode
/// (TESSERA_OVERLAY_FLAT..GLYPH), and whether some of its primitives are depth-tested and
/// some not.
constexpr uint32_t kTestedBit = 1u << 4, kUntestedBit = 1u << 5;
/// A run whose opaque fragments write their depth (video insets: overlay.frag WRITES_DEPTH).
constexpr uint32_t kWritesDepthBit = 1u << 6;

/// A batch of vertices drawn with one texture (0: none bound yet; flat primitives take any) and
/// one fragment variant.
struct Run {
  uint32_t texture = 0;
  uint32_t first = 0, count = 0;
  Group group = Group::kLines;
  uint32_t variant = 0;
};

/// overlay.frag's #defines for a variant: the code of the modes it does not hold is left out,
/// as llvmpipe would run every branch under masks (a line's fragments sampling a texture).
std::string variantDefines(uint32_t v) {
  int kinds = 0;
  for (uint32_t m = 0; m < 4; ++m) kinds += (v >> m) & 1u;
  std::string d;
  auto def = [&](const char* name, bool on) {
    d += std::string("#define ") + name + (on ? " 1\n" : " 0\n");
  };
  def("HAS_TEXTURED", v & (1u << TESSERA_OVERLAY_TEXTURED));
  def("HAS_DOT", v & (1u << TESSERA_OVERLAY_DOT));
  def("HAS_GLYPH", v & (1u << TESSERA_OVERLAY_GLYPH));
  def("HAS_TESTED", v & kTestedBit);
  def("HAS_UNTESTED", v & kUntestedBit);
  def("ONE_MODE", kinds == 1);
  def("WRITES_DEPTH", v & kWritesDepthBit);
  return d;
}

}  // namespace

struct OverlayPass::Impl {
  std::map<uint32_t, GlProgram> programs;  // by variant, compiled on first use
  GlProgram line_passes[2];                // overlay_lines.comp, made on first use
  GlBuffer owner;                          // its per-pixel owner plane, all zero between runs
  std::vector<GpuOverlayLine> gpu_lines;   // per run(): the opaque lines it writes
  std::vector<uint32_t> step_lines;        // per run(): each step's line (overlay_lines.comp)
  TextShaper text;  // labels' glyphs (HarfBuzz, FreeType, fontconfig) in one atlas
  GlTexture white;
  GlFramebuffer framebuffer;
  GlBuffer inset_depth;  // with video insets: the target's depth plane and the insets' depth
  uint32_t vao = 0;
  // Labels' pictures by key, kept while some label of the last run showed them.
  struct Picture {
    GlTexture texture;
    uint64_t used = 0;  // the last run() that drew it
  };
  std::map<uint64_t, Picture> pictures;
  uint64_t runs_done = 0;

  // Per run():
  std::vector<OverlayVertex> vertices;
  std::vector<Run> runs;
  std::vector<glm::vec4> anchors;  // labels' (overlay.vert)
  std::vector<glm::vec4> placed;   // labels' boxes so far this run, pixels (min x, y, max x, y)
  uint32_t flags = 0;              // or-ed into every vertex's mode: depth test, anchor
  glm::dmat4 clip_from_world{1.0};
  glm::dvec3 eye{0.0};
  glm::dvec2 size{1.0};
  double bias = 0.0;

  /// Clip position of a world point, pulled towards the eye by the bias, in the framebuffer's
  /// convention (y flipped: row 0 is the image's top).
  /// Non-finite positions (NaN, infinities from outside data) give a w of NaN: every caller
  /// skips primitives whose w is not > 0, so they are never drawn.
  glm::dvec4 clip(const glm::dvec3& world) const {
    if (!std::isfinite(world.x) || !std::isfinite(world.y) || !std::isfinite(world.z))
      return glm::dvec4(std::numeric_limits<double>::quiet_NaN());
    const glm::dvec3 p = eye + (world - eye) * (1.0 - bias);
    glm::dvec4 c = clip_from_world * glm::dvec4(p, 1.0);
    c.y = -c.y;
    return c;
  }
  /// Moves a clip position by `px` pixels (x right, y down).
  glm::dvec4 shifted(glm::dvec4 c, const glm::dvec2& px) const {
    c.x += px.x * 2.0 / size.x * c.w;
    c.y += px.y * 2.0 / size.y * c.w;
    return c;
  }
  /// Primitives from here on belong to `group`, are drawn with `texture` (0: any, for flat
  /// ones), depth-tested against the scene or not. A new run (one draw call) only where the
  /// group or the texture changes: on llvmpipe a draw call costs more than the primitives of a
  /// label, and a run of one group needs only its own fragment code (a line's fragments
  /// sample no texture, a label's read no depth).
  void begin(Group group, uint32_t texture, bool depth_test) {
    flags = depth_test ? TESSERA_OVERLAY_DEPTH_TESTED : 0u;
    if (!runs.empty() && runs.back().group == group) {
      if (texture == 0 || runs.back().texture == texture) return;
      if (runs.back().texture == 0) {  // only flat ones so far: bind this
        runs.back().texture = texture;
        return;
      }
    }
    runs.push_back({texture, uint32_t(vertices.size()), 0, group, 0});
  }
  /// Two triangles a b c, a c d.
  void quad(const std::array<glm::dvec4, 4>& c, const std::array<glm::vec2, 4>& uv, uint32_t rgba,
            uint32_t mode) {
    for (int k : {0, 1, 2, 0, 2, 3})
      vertices.push_back({glm::vec4(c[k]), uv[k], rgba, mode | flags});
    runs.back().count += 6;
    runs.back().variant |= 1u << (mode & 0xFFu) | (flags ? kTestedBit : kUntestedBit);
  }
  /// The program of a run's variant.
  GlProgram& program(uint32_t variant) {
    auto [it, fresh] = programs.try_emplace(variant);
    if (fresh)
      it->second = GlProgram::graphics(shaders::kOverlayVert, shaders::kOverlayFrag,
                                       "overlay.vert/frag", variantDefines(variant));
    return it->second;
  }
  /// A pixel-space rectangle around a clip position (all corners at its depth).
  void sprite(const glm::dvec4& anchor, glm::vec2 lo, glm::vec2 hi, glm::vec2 uv_lo,
              glm::vec2 uv_hi, uint32_t rgba, uint32_t mode) {
    quad({shifted(anchor, {lo.x, lo.y}), shifted(anchor, {hi.x, lo.y}),
          shifted(anchor, {hi.x, hi.y}), shifted(anchor, {lo.x, hi.y})},
         {glm::vec2(uv_lo.x, uv_lo.y), glm::vec2(uv_hi.x, uv_lo.y), glm::vec2(uv_hi.x, uv_hi.y),
          glm::vec2(uv_lo.x, uv_hi.y)},
         rgba, mode);
  }

  /// The texture of a label's picture (uploaded on its first use), or null when its pixels do
  /// not match its size.
  const GlTexture* pictureTexture(const LabelPicture& p) {
    if (!p.rgba || p.width == 0 || p.height == 0 || p.width > 4096 || p.height > 4096 ||
        p.rgba->size() != size_t(p.width) * p.height * 4)
      return nullptr;
    auto [it, fresh] = pictures.try_emplace(p.key);
    if (fresh || it->second.texture.width() != p.width || it->second.texture.height() != p.height) {
      it->second.texture = GlTexture(p.width, p.height, GL_RGBA8);
      it->second.texture.upload(p.rgba->data());
    }
    it->second.used = runs_done;
    return &it->second.texture;
  }

  /// `l` as a quad of the raster pass, or with `direct` as a line of overlay_lines.comp.
  void addLine(const OverlayLine& l, bool direct);
  /// Writes the direct lines into the image (overlay_lines.comp's two passes).
  void drawDirectLines(FrameTarget& target, uint32_t depth);
  /// Draws runs [`begin`, `end`) over the target's image, depth-tested against `depth` (a plane
  /// of the target's size).
  void drawRuns(FrameTarget& target, const ViewSetup& view, uint32_t depth, size_t begin,
                size_t end);
  /// The end of a run(): unused pictures released; the pass's milliseconds.
  double finish(GpuLap& lap);
  void addLabel(const OverlayLabel& l, const FrameTarget& target, const glm::dmat4& projection);
  /// `l` moved (its offset and alignment) to where its box meets no label placed before it
  /// this run, its anchor at pixel `at`; the box is then taken.
  OverlayLabel place(const OverlayLabel& l, glm::vec2 at);
  /// The label's box; with an anchor, its background and glyphs drawn there, their modes or-ed
  /// with `anchored`.
  glm::vec2 layout(const OverlayLabel& l, const glm::dvec4* anchor, uint32_t anchored = 0);
};

void OverlayPass::Impl::addLine(const OverlayLine& l, bool direct) {
  glm::dvec4 a = clip(l.a), b = clip(l.b);
  if (std::isnan(a.w) || std::isnan(b.w) || !(l.width_px > 0.0f) || !std::isfinite(l.width_px))
    return;
  // Clip against the near plane (z >= -w) so the screen-space widening stays valid.
  const double da = a.z + a.w, db = b.z + b.w;
  if (da < 0.0 && db < 0.0) return;
  if (da < 0.0) a = b + (a - b) * (db / (db - da));
  if (db < 0.0) b = a + (b - a) * (da / (da - db));
  const glm::dvec2 sa = glm::dvec2(a) / a.w * size * 0.5, sb = glm::dvec2(b) / b.w * size * 0.5;
  glm::dvec2 d = sb - sa;
  const double len = glm::length(d);
  d = len > 1e-9 ? d / len : glm::dvec2(1.0, 0.0);
  const double h = 0.5 * double(l.width_px);
  const glm::dvec2 along = d * h, across = glm::dvec2(-d.y, d.x) * h;
  // Pixels, y down from the image's top (the clip position's y is flipped already), and
  // window depths. An end millions of pixels away (just in front of the eye) is left to the
  // raster's clipping: float steps there are pixels wide.
  const glm::dvec2 pa = (glm::dvec2(a) / a.w * 0.5 + 0.5) * size,
                   pb = (glm::dvec2(b) / b.w * 0.5 + 0.5) * size;
  const double za = a.z / a.w * 0.5 + 0.5, zb = b.z / b.w * 0.5 + 0.5;
  auto near = [](const glm::dvec2& p) { return std::abs(p.x) < 1e6 && std::abs(p.y) < 1e6; };
  if (direct && near(pa) && near(pb) && std::isfinite(za) && std::isfinite(zb)) {
    // Clipped to the view widened by the line's half width and a pixel.
    double t0 = 0.0, t1 = 1.0;
    const glm::dvec2 margin(h + 1.0);
    if (!clipSegment(pa, pb, -margin, size + margin, t0, t1)) return;
    GpuOverlayLine g;
    const glm::dvec2 qa = pa + (pb - pa) * t0, qb = pa + (pb - pa) * t1;
    g.ends = glm::vec4(qa.x, qa.y, qb.x, qb.y);
    // Depth as the raster's quad has it: za at the start cap's edge (h before a), zb at the end
    // cap's, linear in between; from the clipped start on, per pixel along the line.
    const double full = glm::length(pb - pa), per_px = (zb - za) / (full + 2.0 * h);
    g.depth = glm::vec4(float(za + per_px * (t0 * full + h)), float(per_px), float(h),
                        flags ? 1.0f : 0.0f);
    g.rgb = pack(l.color) & 0xFFFFFFu;
    // Its steps: the columns (or rows) its rectangle spans on screen, a pixel wider each side.
    const glm::vec2 fa(g.ends.x, g.ends.y), fb(g.ends.z, g.ends.w);
    const bool x_major = std::abs(fb.x - fa.x) >= std::abs(fb.y - fa.y);
    const int axis = x_major ? 0 : 1;
    const double lo = std::min(fa[axis], fb[axis]) - h - 1.0,
                 hi = std::max(fa[axis], fb[axis]) + h + 1.0;
    const int first = std::max(0, int(std::floor(lo)));
    const int last = std::min(int(size[axis]) - 1, int(std::ceil(hi)));
    if (last < first) return;
    // (A frame of more than 2^24 steps, 64 MB of step list: the rest are quads of the raster.)
    if (step_lines.size() + size_t(last - first + 1) <= kMostDirectSteps) {
      g.base = uint32_t(step_lines.size());
      g.first = first;
      g.flags = x_major ? 1u : 0u;
      step_lines.insert(step_lines.end(), size_t(last - first + 1), uint32_t(gpu_lines.size()));
      gpu_lines.push_back(g);
      return;
    }
  }
  const uint32_t rgba = pack(l.color);
  quad({shifted(a, -along - across), shifted(b, along - across), shifted(b, along + across),
        shifted(a, -along + across)},
       {glm::vec2(0), glm::vec2(0), glm::vec2(0), glm::vec2(0)}, rgba, TESSERA_OVERLAY_FLAT);
}

void OverlayPass::Impl::drawDirectLines(FrameTarget& target, uint32_t depth) {
  for (int pass = 0; pass < 2; ++pass)
    if (!line_passes[pass])
      line_passes[pass] = GlProgram::compute(shaders::kOverlayLines, "overlay_lines.comp",
                                             "#define PASS " + std::to_string(pass) + "\n");
  const size_t plane = target.pixels() * sizeof(uint32_t);
  if (owner.bytes() != plane) {
    owner = GlBuffer(plane, nullptr);
    owner.clear(0u);
  }
  const GlBuffer lines(gpu_lines.size() * sizeof(GpuOverlayLine), gpu_lines.data());
  const GlBuffer steps(step_lines.size() * sizeof(uint32_t), step_lines.data());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_OVERLAY_LINES, lines.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_OVERLAY_STEPS, steps.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_OVERLAY_OWNER, owner.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_DEPTH, depth);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, target.image().name());
  for (int pass = 0; pass < 2; ++pass) {
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    const GlProgram& p = line_passes[pass];
    p.use();
    p.set("uSize", glm::ivec2(target.width(), target.height()));
    p.set("uSteps", uint32_t(step_lines.size()));
    constexpr size_t kStepsPerDispatch = 65535 * 64;
    for (size_t first = 0; first < step_lines.size(); first += kStepsPerDispatch) {
      p.set("uFirst", uint32_t(first));
      const size_t n = std::min(kStepsPerDispatch, step_lines.size() - first);
      glDispatchCompute(GLuint((n + 63) / 64), 1, 1);
    }
  }
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_PIXEL_BUFFER_BARRIER_BIT);
}

glm::vec2 OverlayPass::Impl::layout(const OverlayLabel& l, const glm::dvec4* anchor,
                                    uint32_t anchored) {
  const float scale = l.height_px / TextShaper::kPixelSize;
  const float pad = 0.2f * l.height_px;
  // Lines break at '\n', each kLineSpacing label heights below the one before.
  constexpr float kLineSpacing = 1.2f;
  const std::vector<std::string_view> text_lines = linesOf(l.text);
  float width = 0.0f;
  const int lines = int(text_lines.size());
  for (std::string_view line : text_lines) width = std::max(width, text.shape(line).width * scale);
  const float text_height = l.height_px * (1.0f + kLineSpacing * float(lines - 1));
  // Pictures in a row under the text, `pad` apart.
  glm::vec2 row(0.0f);
  for (const LabelPicture& p : l.pictures) {
    if (!(p.size_px.x > 0.0f && p.size_px.y > 0.0f && p.size_px.x < 1e4f && p.size_px.y < 1e4f))
      continue;
    row.x += (row.x > 0.0f ? pad : 0.0f) + p.size_px.x;
    row.y = std::max(row.y, p.size_px.y);
  }
  const float pictures_top = text_height + (row.y > 0.0f ? pad : 0.0f);
  const glm::vec2 box(std::max(width, row.x) + 2.0f * pad, pictures_top + row.y + 2.0f * pad);
  if (!anchor) return box;
  const glm::vec2 o = l.offset_px - glm::clamp(l.align, glm::vec2(0.0f), glm::vec2(1.0f)) * box;
  // A label is hidden or shown whole by its anchor (addLabel()), then drawn over the scene: a
  // surface in front of the box (the model curving towards the eye) must not eat its text.
  if (l.background.a > 0) {
    begin(Group::kLabels, 0, false);
    sprite(*anchor, o, o + box, glm::vec2(0), glm::vec2(1), pack(l.background),
           TESSERA_OVERLAY_FLAT | anchored);
  }
  begin(Group::kLabels, text.texture(), false);
  float top = o.y + pad;
  const uint32_t rgba = pack(l.color);
  for (std::string_view line : text_lines) {
    for (const ShapedGlyph& g : text.shape(line).glyphs) {
      const glm::vec2 at(o.x + pad, top);
      sprite(*anchor, at + g.lo * scale, at + g.hi * scale, g.uv0, g.uv1, rgba,
             TESSERA_OVERLAY_GLYPH | anchored);
    }
    top += kLineSpacing * l.height_px;
  }
  float left = o.x + pad;
  for (const LabelPicture& p : l.pictures) {
    if (!(p.size_px.x > 0.0f && p.size_px.y > 0.0f && p.size_px.x < 1e4f && p.size_px.y < 1e4f))
      continue;
    if (const GlTexture* texture = pictureTexture(p)) {
      begin(Group::kLabels, texture->name(), false);
      const glm::vec2 lo(left, o.y + pad + pictures_top);
      sprite(*anchor, lo, lo + p.size_px, glm::vec2(0), glm::vec2(1), 0xFFFFFFFFu,
             TESSERA_OVERLAY_TEXTURED | anchored);
    }
    left += p.size_px.x + pad;
  }
  return box;
}

void OverlayPass::Impl::addLabel(const OverlayLabel& l, const FrameTarget& target,
                                 const glm::dmat4& projection) {
  const glm::dvec4 a = clip(l.at);
  // Behind the eye, outside the depth range, not finite, or of no size.
  if (!(a.w > 0.0) || a.z < -a.w || a.z > a.w || !(l.height_px > 0.0f) ||
      !std::isfinite(l.height_px) || !std::isfinite(l.offset_px.x) ||
      !std::isfinite(l.offset_px.y) || !std::isfinite(l.align.x) || !std::isfinite(l.align.y))
    return;
  // Hidden when the scene is in front of its anchor, by more than 2% of the distance (anchors
  // sit on the surface the splats cover; a measurement's middle on a chord just under it):
  // tested on the GPU per vertex (overlay.vert), so no label waits for a read-back. The
  // anchor's pixel in the framebuffer's convention (row 0 the image's top, as gl_FragCoord).
  const double x = (a.x / a.w * 0.5 + 0.5) * size.x, y = (0.5 + a.y / a.w * 0.5) * size.y;
  const bool perspective = projection[2][3] != 0.0;
  uint32_t anchored = 0;
  if (anchors.size() < TESSERA_OVERLAY_MAX_ANCHORS) {
    anchored = TESSERA_OVERLAY_ANCHORED | uint32_t(anchors.size()) << TESSERA_OVERLAY_ANCHOR_SHIFT;
    anchors.emplace_back(float(x), float(y), float(perspective ? a.w : a.z / a.w),
                         perspective ? 1.0f : 0.0f);
  } else if (x >= 0.0 && y >= 0.0 && x < size.x && y < size.y) {
    // Beyond the anchors' buffer (16384 labels in one view): one depth value read back (the
    // depth plane is bottom row first).
    const uint32_t d =
        target.readAt(target.depth(), uint32_t(x), uint32_t(size.y) - 1 - uint32_t(y));
    if (d != kEmptyDepth) {
      float f = 0.0f;
      std::memcpy(&f, &d, 4);
      const double ndc = 2.0 * double(f) - 1.0;
      const double stored = perspective ? projection[3][2] / (ndc + projection[2][2]) : ndc;
      const double anchor = perspective ? a.w : a.z / a.w;
      if (perspective ? anchor > 1.02 * std::abs(stored) : anchor > stored + 0.02) return;
    }
  }
  layout(place(l, glm::vec2(float(x), float(y))), &a, anchored);
}

OverlayLabel OverlayPass::Impl::place(const OverlayLabel& l, glm::vec2 at) {
  // Labels make room for each other: the first place of these whose box meets no box placed
  // before it this run: as asked, mirrored left-right, up-down, both, then as asked and moved
  // up by one to three box heights (a stack); else as asked. Earlier labels keep their place.
  const glm::vec2 box = layout(l, nullptr);
  const glm::vec2 align = glm::clamp(l.align, glm::vec2(0.0f), glm::vec2(1.0f));
  auto rect = [&](glm::vec2 offset, glm::vec2 al) {
    const glm::vec2 lo = at + offset - al * box;
    return glm::vec4(lo, lo + box);
  };
  auto free = [&](const glm::vec4& r) {
    for (const glm::vec4& q : placed)
      if (r.x < q.z && q.x < r.z && r.y < q.w && q.y < r.w) return false;
    return true;
  };
  OverlayLabel out = l;
  const glm::vec2 o = l.offset_px;
  const std::array<std::pair<glm::vec2, glm::vec2>, 7> tries = {{
      {o, align},
      {{-o.x, o.y}, {1.0f - align.x, align.y}},
      {{o.x, -o.y}, {align.x, 1.0f - align.y}},
      {-o, glm::vec2(1.0f) - align},
      {o - glm::vec2(0.0f, box.y + 2.0f), align},
      {o - glm::vec2(0.0f, 2.0f * (box.y + 2.0f)), align},
      {o - glm::vec2(0.0f, 3.0f * (box.y + 2.0f)), align},
  }};
  glm::vec4 chosen = rect(o, align);
  for (const auto& [offset, al] : tries) {
    const glm::vec4 r = rect(offset, al);
    if (!free(r)) continue;
    out.offset_px = offset;
    out.align = al;
    chosen = r;
    break;
  }
  placed.push_back(chosen);
  return out;
}

OverlayPass::OverlayPass() : mImpl(std::make_unique<Impl>()) {
  Impl& s = *mImpl;
  s.white = GlTexture(1, 1, GL_RGBA8);
  const uint32_t white = 0xFFFFFFFFu;
  s.white.upload(&white);
  glCreateVertexArrays(1, &s.vao);
}

OverlayPass::~OverlayPass() {
  if (mImpl->vao) glDeleteVertexArrays(1, &mImpl->vao);
}

glm::vec2 OverlayPass::measure(const OverlayLabel& label) const {
  return mImpl->layout(label, nullptr);
}

void OverlayPass::Impl::drawRuns(FrameTarget& target, const ViewSetup& view, uint32_t depth,
                                 size_t begin_run, size_t end_run) {
  if (vertices.empty()) return;
  if (framebuffer.width() != target.width() || framebuffer.height() != target.height())
    framebuffer = GlFramebuffer(target.width(), target.height(), false);
  // The image into the framebuffer's colour (row 0 = the image's top row): a copy from the
  // buffer, no shader. The depth test reads `depth` in the overlay's fragment shader, where a
  // primitive covers a pixel, so nothing is done per pixel of the view.
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_PIXEL_BUFFER_BARRIER_BIT |
                  GL_TEXTURE_UPDATE_BARRIER_BIT);
  glBindBuffer(GL_PIXEL_UNPACK_BUFFER, target.image().name());
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
  glTextureSubImage2D(framebuffer.color().name(), 0, 0, 0, GLsizei(target.width()),
                      GLsizei(target.height()), GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
  glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer.name());
  glViewport(0, 0, GLsizei(target.width()), GLsizei(target.height()));
  glBindVertexArray(vao);
  glDisable(GL_DEPTH_TEST);

  const GlBuffer vertex_buffer(vertices.size() * sizeof(OverlayVertex), vertices.data());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_OVERLAY, vertex_buffer.name());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_DEPTH, depth);
  if (anchors.empty()) anchors.emplace_back(0.0f);  // a buffer is bound either way
  const GlBuffer anchor_buffer(anchors.size() * sizeof(glm::vec4), anchors.data());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_OVERLAY_ANCHORS, anchor_buffer.name());
  // Colour blends over the scene, the image's alpha stays opaque; runs after the insets do not
  // hide each other (later ones draw on top).
  glEnable(GL_BLEND);
  glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
  for (size_t i = begin_run; i < end_run; ++i) {
    const Run& r = runs[i];
    if (r.count == 0) continue;
    GlProgram& draw = program(r.variant);
    draw.use();
    draw.set("uTexture", 0);
    draw.set("uSize", glm::ivec2(target.width(), target.height()));
    draw.set("uDepthFromNdc",
             glm::vec2(float(view.projection[3][2]), float(view.projection[2][2])));
    glBindTextureUnit(0, r.texture ? r.texture : white.name());
    glDrawArrays(GL_TRIANGLES, GLint(r.first), GLsizei(r.count));
    // An inset's depth is seen by the next inset's fragments.
    if (r.variant & kWritesDepthBit) glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
  glDisable(GL_BLEND);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, target.image().name());
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadPixels(0, 0, GLsizei(target.width()), GLsizei(target.height()), GL_RGBA, GL_UNSIGNED_BYTE,
               nullptr);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glBindVertexArray(0);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_PIXEL_BUFFER_BARRIER_BIT);
}

double OverlayPass::run(FrameTarget& target, const ViewSetup& view, const Overlay& overlay) {
  if (overlay.empty()) return 0.0;
  GpuLap lap;
  Impl& s = *mImpl;
  s.text.beginFrame();
  s.vertices.clear();
  s.runs.clear();
  s.anchors.clear();
  s.placed.clear();
  s.clip_from_world = view.projection * view.view;
  s.eye = view.eye_world;
  s.size = glm::dvec2(target.width(), target.height());
  s.bias = std::clamp(overlay.depth_bias, 0.0, 0.5);

  for (const OverlayQuad& q : overlay.quads) {
    s.begin(Group::kTextured, q.texture ? q.texture->name() : s.white.name(), true);
    std::array<glm::dvec4, 4> c;
    for (int k = 0; k < 4; ++k) c[k] = s.clip(q.corners[k]);
    if (!(c[0].w > 0.0) || !(c[1].w > 0.0) || !(c[2].w > 0.0) || !(c[3].w > 0.0)) continue;
    s.quad(c, {glm::vec2(0, 0), glm::vec2(1, 0), glm::vec2(1, 1), glm::vec2(0, 1)}, pack(q.tint),
           TESSERA_OVERLAY_TEXTURED);
  }
  // The insets' runs write their depth into a copy of the depth plane: what is drawn after them
  // (lines, dots, labels, other insets) is hidden behind them as behind the scene. Opaque lines
  // go straight into the image (overlay_lines.comp: llvmpipe rasterises long thin quads slowly),
  // after the insets and before the other runs.
  const size_t inset_runs = s.runs.size();
  for (size_t i = 0; i < inset_runs; ++i) s.runs[i].variant |= kWritesDepthBit;
  s.gpu_lines.clear();
  s.step_lines.clear();
  s.begin(Group::kLines, 0, true);
  for (const OverlayLine& l : overlay.lines) s.addLine(l, l.color.a == 255);
  s.begin(Group::kDots, 0, true);
  for (const OverlayPoint& p : overlay.points) {
    const glm::dvec4 a = s.clip(p.at);
    if (!(a.w > 0.0) || !(p.size_px > 0.0f) || !std::isfinite(p.size_px)) continue;
    const float r = 0.5f * p.size_px;
    // A ring keeps radii above 1 - ring / r: the fraction rides in the mode's upper bits.
    const float hole = p.ring_px > 0.0f ? std::clamp(1.0f - p.ring_px / r, 0.0f, 1.0f) : 0.0f;
    s.sprite(a, glm::vec2(-r), glm::vec2(r), glm::vec2(0), glm::vec2(1), pack(p.color),
             TESSERA_OVERLAY_DOT | uint32_t(std::lround(hole * 255.0f)) << 8);
  }
  for (const OverlayLabel& l : overlay.labels) s.addLabel(l, target, view.projection);
  for (const ScreenRect& r : overlay.rects) {
    if (!std::isfinite(r.min.x) || !std::isfinite(r.min.y) || !std::isfinite(r.max.x) ||
        !std::isfinite(r.max.y))
      continue;
    s.begin(Group::kTextured, r.texture ? r.texture->name() : s.white.name(), false);
    const glm::dvec4 origin(-1.0, -1.0, -1.0, 1.0);  // the image's top-left corner, nearest
    s.sprite(origin, r.min, r.max, glm::vec2(0), glm::vec2(1), pack(r.color),
             TESSERA_OVERLAY_TEXTURED);
  }

  uint32_t depth = target.depth().name();
  if (inset_runs > 0) {
    const size_t plane = target.pixels() * sizeof(uint32_t);
    if (s.inset_depth.bytes() != plane) s.inset_depth = GlBuffer(plane, nullptr);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
    glCopyNamedBufferSubData(depth, s.inset_depth.name(), 0, 0, GLsizeiptr(plane));
    depth = s.inset_depth.name();
    s.drawRuns(target, view, depth, 0, inset_runs);
  }
  if (!s.gpu_lines.empty()) s.drawDirectLines(target, depth);
  if (s.runs.size() > inset_runs) s.drawRuns(target, view, depth, inset_runs, s.runs.size());
  return s.finish(lap);
}

double OverlayPass::Impl::finish(GpuLap& lap) {
  // Pictures no label showed this time are released (a note closed).
  std::erase_if(pictures, [&](const auto& p) { return p.second.used != runs_done; });
  ++runs_done;
  return lap();
}

}  // namespace tessera::render
