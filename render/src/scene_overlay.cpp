#include <tessera/render/scene_overlay.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

#include <tessera/render/scene_draw_list.h>
#include <tessera/sync/selection_mask.h>

namespace tessera::render {

namespace {

/// Colours when a payload has none.
constexpr glm::u8vec3 kSketchDefault{255, 255, 255};
constexpr glm::u8vec3 kAvatarDefault{255, 160, 40};
constexpr glm::u8vec3 kAnnotationDot{255, 210, 60};
constexpr glm::u8vec3 kMeasurementDefault{90, 230, 255};

glm::u8vec4 colorOf(bool has, const scene::Color& c, glm::u8vec3 fallback, float opacity) {
  const glm::u8vec3 rgb =
      has ? glm::u8vec3(glm::clamp(glm::vec3(c.r(), c.g(), c.b()), 0.0f, 1.0f) * 255.0f + 0.5f)
          : fallback;
  return {rgb, uint8_t(std::lround(std::clamp(opacity, 0.0f, 1.0f) * 255.0f))};
}

/// `alpha` (0..255) scaled by the opacity.
uint8_t fade(uint8_t alpha, float opacity) {
  return uint8_t(std::lround(alpha * std::clamp(opacity, 0.0f, 1.0f)));
}

glm::dvec3 toWorld(const glm::dmat4& world, double x, double y, double z) {
  return glm::dvec3(world * glm::dvec4(x, y, z, 1.0));
}

void addSketch(const scene::SketchPayload& s, const glm::dmat4& world, float opacity,
               const SceneOverlayOptions& o, Overlay& out) {
  const size_t n = size_t(s.points_size()) / 3;
  if (n == 0) return;
  const glm::u8vec4 color = colorOf(s.has_color(), s.color(), kSketchDefault, opacity);
  const float width = s.width() > 0.0f ? s.width() : o.sketch_width_px;
  const auto& p = s.points();
  auto at = [&](size_t i) { return toWorld(world, p[3 * i], p[3 * i + 1], p[3 * i + 2]); };
  glm::dvec3 a = at(0), previous_dir(0.0);
  bool segments = false;
  for (size_t i = 1; i < n; ++i) {
    const glm::dvec3 b = at(i);
    // A repeated point (a pen held still) adds nothing: no zero-length segment, no extra join.
    if (b == a) continue;
    const glm::dvec3 dir = glm::normalize(b - a);
    // A round join over the square caps where the stroke turns by more than 25 degrees; below
    // that the caps overlap with at most a fifth of the width open on the outside, under a
    // pixel for strokes up to 4 px (a dense stroke turns little at each sample: this halves its
    // primitives, which llvmpipe sets up one by one).
    if (segments && glm::dot(dir, previous_dir) < 0.906) out.points.push_back({a, color, width});
    out.lines.push_back({a, b, color, width});
    segments = true;
    previous_dir = dir;
    a = b;
  }
  if (!segments) out.points.push_back({a, color, width});  // one point (or all the same): a dot
}

void addAvatar(const scene::SceneNode& node, const glm::dmat4& world, float opacity,
               const SceneOverlayOptions& o, Overlay& out) {
  const scene::AvatarPayload& a = node.avatar();
  const glm::u8vec4 color = colorOf(a.has_color(), a.color(), kAvatarDefault, opacity);
  const glm::dvec3 eye = toWorld(world, 0.0, 0.0, 0.0);
  // The view frustum in the node frame (the participant's camera: looking down -z, y up), out to
  // the far face at `reach`.
  const double half_h =
      double(a.reach()) * std::tan(double(a.fovy_deg()) * std::numbers::pi / 360.0);
  const double half_w = half_h * double(a.aspect());
  if (a.fovy_deg() > 0.0f && a.aspect() > 0.0f && a.reach() > 0.0f && std::isfinite(half_w) &&
      half_w > 0.0 && half_h > 0.0) {
    const double z = -double(a.reach());
    const glm::dvec3 c[4] = {toWorld(world, -half_w, -half_h, z),
                             toWorld(world, half_w, -half_h, z), toWorld(world, half_w, half_h, z),
                             toWorld(world, -half_w, half_h, z)};
    for (int k = 0; k < 4; ++k) {
      out.lines.push_back({eye, c[k], color, o.avatar_frustum_px});
      out.lines.push_back({c[k], c[(k + 1) % 4], color, o.avatar_frustum_px});
    }
  }
  // The head: a dark disc, then the coloured dot on it (overlays drawn later lie on top).
  if (o.avatar_ring_px > 0.0f)
    out.points.push_back(
        {eye, {16, 16, 16, fade(255, opacity)}, o.avatar_head_px + 2.0f * o.avatar_ring_px});
  out.points.push_back({eye, color, o.avatar_head_px});
  const std::string& name = a.site().empty() ? node.name() : a.site();
  if (name.empty()) return;
  OverlayLabel label;
  label.at = eye;
  label.text = name;
  label.color = color;
  label.background = {0, 0, 0, fade(200, opacity)};
  label.height_px = o.label_px;
  label.offset_px = {0.0f, -(0.5f * o.avatar_head_px + o.avatar_ring_px + 3.0f)};
  label.align = {0.5f, 1.0f};  // centred above the head
  out.labels.push_back(std::move(label));
}

}  // namespace

std::string noteText(const scene::AnnotationPayload& a) {
  if (!a.open() || a.items_size() == 0) return a.text();
  // One line per item (a text's first line, cut), at most kMaxLines in all.
  constexpr int kMaxLines = 12;
  constexpr size_t kMaxLine = 72;
  auto clipped = [&](std::string line) {
    if (const size_t nl = line.find('\n'); nl != std::string::npos) line = line.substr(0, nl) + " ...";
    if (line.size() <= kMaxLine) return line;
    size_t n = kMaxLine - 4;
    while (n > 0 && (static_cast<unsigned char>(line[n]) & 0xc0) == 0x80) --n;
    return line.substr(0, n) + " ...";
  };
  std::string out;
  int lines = 0;
  for (const scene::AnnotationItem& it : a.items()) {
    if (lines == kMaxLines - 1 && a.items_size() > kMaxLines) {
      out += "\n(" + std::to_string(a.items_size() - lines) + " more)";
      break;
    }
    std::string line = it.title();
    if (it.kind() == "number") {
      char number[64];
      std::snprintf(number, sizeof number, ": %.6g", it.number());
      line += number;
      if (!it.unit().empty()) line += " " + it.unit();
    } else if (it.kind() == "link") {
      line += it.uri().empty() ? " -> item " + std::to_string(it.link_item()) : " -> " + it.uri();
    } else if (!it.text().empty()) {
      line += ": " + it.text();
    }
    if (it.kind() == "image" && !it.picture_problem().empty())
      line += " (no picture: " + it.picture_problem() + ")";
    out += (lines++ ? "\n" : "") + clipped(line);
  }
  return out;
}

std::vector<LabelPicture> notePictures(const scene::AnnotationPayload& a, float max_px) {
  std::vector<LabelPicture> out;
  if (!(max_px > 0.0f)) return out;
  for (const scene::AnnotationItem& it : a.items()) {
    const uint32_t w = it.picture_width(), h = it.picture_height();
    if (it.picture().empty() || w == 0 || h == 0 || it.picture().size() != size_t(w) * h * 4)
      continue;  // the scene graph checked it; a payload made elsewhere may not be
    LabelPicture p;
    p.width = w;
    p.height = h;
    p.rgba = std::make_shared<const std::vector<uint8_t>>(it.picture().begin(), it.picture().end());
    // FNV-1a over the size and the pixels: the pass keeps a texture per key.
    uint64_t key = 0xcbf29ce484222325ull;
    auto mix = [&](uint8_t b) { key = (key ^ b) * 0x100000001b3ull; };
    for (int k = 0; k < 4; ++k) mix(uint8_t(w >> (8 * k))), mix(uint8_t(h >> (8 * k)));
    for (uint8_t b : *p.rgba) mix(b);
    p.key = key;
    const float scale = std::min(1.0f, max_px / float(std::max(w, h)));
    p.size_px = {float(w) * scale, float(h) * scale};
    out.push_back(std::move(p));
  }
  return out;
}

namespace {

void addAnnotation(const scene::AnnotationPayload& a, const glm::dmat4& world, float opacity,
                   const SceneOverlayOptions& o, Overlay& out) {
  const glm::dvec3 at = toWorld(world, a.anchor().x(), a.anchor().y(), a.anchor().z());
  out.points.push_back({at, {kAnnotationDot, fade(255, opacity)}, o.annotation_dot_px});
  if (a.radius() > 0.0) {
    // A hot spot's focus circle (Bettio et al. 2009, sec. 3.4), facing its stored view (else
    // the node frame's z axis), radius in the node frame's units.
    glm::dvec3 normal(0.0, 0.0, 1.0);
    if (a.view_size() == 10) {
      const glm::dvec3 d(a.view(3) - a.view(0), a.view(4) - a.view(1), a.view(5) - a.view(2));
      if (glm::length(d) > 0.0) normal = glm::normalize(d);
    }
    const glm::dvec3 ref = std::abs(normal.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    const glm::dvec3 u = glm::normalize(glm::cross(normal, ref)), v = glm::cross(normal, u);
    constexpr int kSegments = 32;
    const glm::u8vec4 ring{kAnnotationDot, fade(220, opacity)};
    const glm::dvec3 c = {a.anchor().x(), a.anchor().y(), a.anchor().z()};
    auto on = [&](int i) {
      const double t = 2.0 * std::numbers::pi * i / kSegments;
      const glm::dvec3 p = c + a.radius() * (std::cos(t) * u + std::sin(t) * v);
      return toWorld(world, p.x, p.y, p.z);
    };
    for (int i = 0; i < kSegments; ++i) out.lines.push_back({on(i), on(i + 1), ring, 1.5f});
  }
  if (a.text().empty() && a.items_size() == 0) return;
  OverlayLabel label;
  label.at = at;
  label.text = noteText(a);
  if (a.open()) label.pictures = notePictures(a, o.note_picture_px);
  label.color = {255, 255, 255, fade(255, opacity)};
  label.background = {0, 0, 0, fade(200, opacity)};
  label.height_px = o.label_px;
  const float gap = 0.5f * o.annotation_dot_px + 2.0f;
  label.offset_px = {gap, -gap};
  label.align = {0.0f, 1.0f};  // up and right of the dot
  out.labels.push_back(std::move(label));
}

void addMeasurement(const scene::MeasurementPayload& m, const glm::dmat4& world, float opacity,
                    const SceneOverlayOptions& o, Overlay& out) {
  const size_t n = size_t(m.points_size()) / 3;
  if (n == 0) return;
  const glm::u8vec4 color = colorOf(m.has_color(), m.color(), kMeasurementDefault, opacity);
  const auto& p = m.points();
  auto at = [&](size_t i) { return toWorld(world, p[3 * i], p[3 * i + 1], p[3 * i + 2]); };
  const bool closed = m.type() == scene::MeasurementPayload::AREA && n >= 3;
  glm::dvec3 centroid(0.0);
  for (size_t i = 0; i < n; ++i) {
    centroid += at(i) / double(n);
    if (i + 1 < n || closed) out.lines.push_back({at(i), at((i + 1) % n), color, o.measure_width_px});
    // A dot on each picked point.
    out.points.push_back({at(i), color, o.measure_dot_px, 0.0f});
  }
  OverlayLabel label;
  label.at = m.type() == scene::MeasurementPayload::DISTANCE ? 0.5 * (at(0) + at(n - 1))
             : m.type() == scene::MeasurementPayload::ANGLE  ? at(1)
             : m.type() == scene::MeasurementPayload::AREA   ? centroid
                                                             : at(n - 1);
  label.text = measurementLabel(m);
  label.color = color;
  label.background = {0, 0, 0, fade(200, opacity)};
  label.height_px = o.label_px;
  label.offset_px = {o.measure_dot_px, -o.measure_dot_px};
  label.align = {0.0f, 1.0f};
  out.labels.push_back(std::move(label));
}

/// A CLIP node's outline, faint, so people see where the cut is: a box's 12 edges, or for each
/// plane a square of half-width `outline` around the plane's point nearest the node origin
/// (none when outline is 0). The cut's own faces are not drawn.
void addClip(const scene::ClipPayload& c, const glm::dmat4& world, float opacity, Overlay& out) {
  const glm::u8vec4 color{255, 255, 255, fade(90, opacity)};
  constexpr float kWidth = 1.5f;
  auto line = [&](const glm::dvec3& a, const glm::dvec3& b) {
    out.lines.push_back({glm::dvec3(world * glm::dvec4(a, 1.0)),
                         glm::dvec3(world * glm::dvec4(b, 1.0)), color, kWidth});
  };
  if (c.has_box_half_extents()) {
    const glm::dvec3 m(c.box_center().x(), c.box_center().y(), c.box_center().z());
    const glm::dvec3 h(c.box_half_extents().x(), c.box_half_extents().y(),
                       c.box_half_extents().z());
    auto corner = [&](int k) {
      return m + h * glm::dvec3(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1);
    };
    for (int k = 0; k < 8; ++k)
      for (int axis : {1, 2, 4})
        if (!(k & axis)) line(corner(k), corner(k | axis));
    return;
  }
  if (!(c.outline() > 0.0f)) return;
  for (int i = 0; i + 3 < c.planes_size(); i += 4) {
    const glm::dvec3 n(c.planes(i), c.planes(i + 1), c.planes(i + 2));
    const double len = glm::length(n);
    if (!(len > 0.0)) continue;
    const glm::dvec3 u = n / len;
    const glm::dvec3 at = -c.planes(i + 3) / len * u;  // the plane's point nearest the origin
    // Two axes in the plane: the one of x, y, z least along the normal, crossed.
    const glm::dvec3 pick = std::abs(u.x) < 0.6 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    const glm::dvec3 e1 = glm::normalize(glm::cross(u, pick)) * double(c.outline());
    const glm::dvec3 e2 = glm::cross(u, e1);
    const glm::dvec3 q[4] = {at - e1 - e2, at + e1 - e2, at + e1 + e2, at - e1 + e2};
    for (int k = 0; k < 4; ++k) line(q[k], q[(k + 1) % 4]);
  }
}

/// `v` in the unit of `units` (factor, name; largest first) that keeps it at 1 or more.
std::string inUnit(double v, std::initializer_list<std::pair<double, const char*>> units,
                   const char* format) {
  std::pair<double, const char*> u = *(units.end() - 1);
  for (const auto& c : units) {
    if (std::abs(v) >= c.first) {
      u = c;
      break;
    }
  }
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v / u.first, u.second);
  return buf;
}

/// Where a VIDEO_INSET node is drawn: a world quad or a rectangle of the view's pixels.
struct InsetPlace {
  bool screen = false;
  std::array<glm::dvec3, 4> corners{};  // world: top-left, top-right, bottom-right, bottom-left
  glm::vec2 min{0.0f}, max{0.0f};       // screen: pixels, y down
  const GlTexture* texture = nullptr;
};

std::optional<InsetPlace> placeInset(const scene::VideoInsetPayload& v, const glm::dmat4& world,
                                     const SceneOverlayOptions& o) {
  InsetPlace place;
  place.texture = o.video_texture ? o.video_texture(v.source()) : nullptr;
  const double aspect = place.texture && place.texture->width() > 0
                            ? double(place.texture->height()) / place.texture->width()
                            : 0.75;
  if (!v.screen()) {
    const double hw = 0.5 * double(v.width()), hh = 0.5 * double(v.height());
    if (!(hw > 0.0 && hh > 0.0)) return {};
    place.corners = {toWorld(world, -hw, hh, 0.0), toWorld(world, hw, hh, 0.0),
                     toWorld(world, hw, -hh, 0.0), toWorld(world, -hw, -hh, 0.0)};
    return place;
  }
  if (!(o.view_px.x > 0.0 && o.view_px.y > 0.0)) return {};
  const glm::dvec4& w = o.screen_wall;
  const glm::dvec4& s = o.screen_view;
  const double ww = w.z - w.x, wh = w.w - w.y, sw = s.z - s.x, sh = s.w - s.y;
  if (!(ww > 0.0 && wh > 0.0 && sw > 0.0 && sh > 0.0)) return {};
  // The rectangle on the screen (its units, y up), then in this view's pixels (y down).
  const double x0 = w.x + double(v.screen_x()) * ww, y0 = w.y + double(v.screen_y()) * wh;
  const double width = double(v.screen_width()) * ww;
  const double height = v.screen_height() > 0.0f ? double(v.screen_height()) * wh : width * aspect;
  if (!(width > 0.0 && height > 0.0)) return {};
  const double px = o.view_px.x / sw, py = o.view_px.y / sh;
  place.screen = true;
  place.min = glm::vec2(float((x0 - s.x) * px), float((s.w - (y0 + height)) * py));
  place.max = glm::vec2(float((x0 + width - s.x) * px), float((s.w - y0) * py));
  return place;
}

void addVideoInset(const scene::VideoInsetPayload& v, const glm::dmat4& world, float opacity,
                   const SceneOverlayOptions& o, Overlay& out) {
  const std::optional<InsetPlace> place = placeInset(v, world, o);
  if (!place) return;
  // A picture in its own colours; a dark quad while none is decoded.
  const glm::u8vec4 tint = place->texture ? glm::u8vec4(255, 255, 255, fade(255, opacity))
                                          : glm::u8vec4(40, 40, 48, fade(220, opacity));
  if (place->screen)
    out.rects.push_back({place->min, place->max, tint, place->texture});
  else
    out.quads.push_back({place->corners, place->texture, tint});
}

}  // namespace

std::string measurementLabel(const scene::MeasurementPayload& m) {
  const double v = m.value(), u = m.uncertainty();
  std::string value, error;
  switch (m.type()) {
    case scene::MeasurementPayload::ANGLE:
      value = inUnit(v * 180.0 / std::numbers::pi, {{1.0, "\u00b0"}}, "%.2f%s");
      error = inUnit(u * 180.0 / std::numbers::pi, {{1.0, "\u00b0"}}, "%.2g%s");
      break;
    case scene::MeasurementPayload::AREA:
      value = inUnit(v, {{1e6, " km\u00b2"}, {1.0, " m\u00b2"}, {1e-4, " cm\u00b2"}, {1e-6, " mm\u00b2"}},
                     "%.4g%s");
      error = inUnit(u, {{1e6, " km\u00b2"}, {1.0, " m\u00b2"}, {1e-4, " cm\u00b2"}, {1e-6, " mm\u00b2"}},
                     "%.2g%s");
      break;
    default:
      value = inUnit(v, {{1e3, " km"}, {1.0, " m"}, {1e-2, " cm"}, {1e-3, " mm"}}, "%.4g%s");
      error = inUnit(u, {{1e3, " km"}, {1.0, " m"}, {1e-2, " cm"}, {1e-3, " mm"}}, "%.2g%s");
  }
  const char* what = m.type() == scene::MeasurementPayload::POLYLINE ? "path "
                     : m.type() == scene::MeasurementPayload::AREA   ? "area "
                                                                     : "";
  return what + value + " \u00b1 " + error;
}

std::shared_ptr<const std::vector<uint32_t>> highlightMaskOf(const scene::SelectionPayload& s) {
  std::vector<uint8_t> cells;
  if (sync::decodeSelectionMask(s.mask(), s.mask_width(), s.mask_height(), &cells)) return nullptr;
  // Nearest cell at each highlight cell's centre: both cover the view's NDC square from the
  // bottom row up.
  constexpr uint32_t n = kHighlightMaskSize;
  const uint32_t w = s.mask_width(), h = s.mask_height();
  auto bits = std::make_shared<std::vector<uint32_t>>(size_t(n) * n / 32, 0u);
  std::vector<uint32_t> column(n);
  for (uint32_t col = 0; col < n; ++col)
    column[col] = uint32_t((uint64_t(col) * 2 + 1) * w / (2 * n));
  for (uint32_t row = 0; row < n; ++row) {
    const uint8_t* src = &cells[size_t((uint64_t(row) * 2 + 1) * h / (2 * n)) * w];
    for (uint32_t col = 0; col < n; ++col)
      if (src[column[col]]) {
        const size_t bit = size_t(row) * n + col;
        (*bits)[bit >> 5] |= 1u << (bit & 31u);
      }
  }
  return bits;
}

std::vector<Highlight> sceneHighlights(const sync::SceneGraph& graph) {
  std::vector<Highlight> out;
  for (const sync::SceneGraph::NodeId id : graph.ids()) {
    const scene::SceneNode& node = graph.node(id);
    if (node.kind() != scene::SceneNode::SELECTION) continue;
    const NodePlacement placed = placeNode(graph, id);
    if (!placed.visible || !(placed.opacity > 0.0f)) continue;
    const scene::SelectionPayload& s = node.selection();
    if (s.lasso_clip_from_world_size() != 16) continue;
    Highlight h;
    for (int k = 0; k < 16; ++k) h.clip_from_world[k / 4][k % 4] = s.lasso_clip_from_world(k);
    if (s.mask_width() != 0 || !s.mask().empty()) {  // a region mask (lazy snapping)
      auto bits = highlightMaskOf(s);
      if (!bits) continue;  // does not check (a graph validates it: not seen there)
      h.mask = std::move(bits);
    } else {
      if (s.lasso_size() < 6) continue;
      std::vector<glm::dvec2> lasso;
      for (int k = 0; k + 1 < s.lasso_size(); k += 2) lasso.push_back({s.lasso(k), s.lasso(k + 1)});
      h.mask = std::make_shared<const std::vector<uint32_t>>(rasterizeLasso(lasso));
    }
    if (s.has_color()) h.tint = colorOf(true, s.color(), {}, 1.0f);
    h.model_node = s.model();
    h.visible_only = s.visible_only();
    h.tint.a = uint8_t(std::lround(120.0f * std::clamp(placed.opacity, 0.0f, 1.0f)));
    out.push_back(std::move(h));
  }
  return out;
}

void setSelectionLasso(scene::SelectionPayload& s, const ViewSetup& view,
                       std::span<const glm::dvec2> px) {
  s.clear_lasso_clip_from_world();
  s.clear_lasso();
  const glm::dmat4 vp = view.projection * view.view;
  for (int k = 0; k < 16; ++k) s.add_lasso_clip_from_world(vp[k / 4][k % 4]);
  for (const glm::dvec2& p : px) {
    s.add_lasso(p.x / view.width * 2.0 - 1.0);
    s.add_lasso(1.0 - p.y / view.height * 2.0);
  }
}

bool isOverlayKind(sync::SceneGraph::Kind kind) {
  return kind == scene::SceneNode::SKETCH || kind == scene::SceneNode::AVATAR ||
         kind == scene::SceneNode::ANNOTATION || kind == scene::SceneNode::VIDEO_INSET ||
         kind == scene::SceneNode::MEASUREMENT || kind == scene::SceneNode::CLIP;
}

std::set<uint32_t> shownVideoSources(const sync::SceneGraph& graph, const ViewSetup& view,
                                     const SceneOverlayOptions& options) {
  std::set<uint32_t> shown;
  const Frustum frustum = Frustum::fromMatrix(view.projection * view.view);
  for (const sync::SceneGraph::NodeId id : graph.ids()) {
    const scene::SceneNode& node = graph.node(id);
    if (node.kind() != scene::SceneNode::VIDEO_INSET) continue;
    const NodePlacement placed = placeNode(graph, id);
    if (!placed.visible || !(placed.opacity > 0.0f)) continue;
    const std::optional<InsetPlace> place = placeInset(node.video_inset(), placed.world, options);
    if (!place) continue;
    bool in_view = false;
    if (place->screen) {
      in_view = place->max.x > 0.0f && place->min.x < float(options.view_px.x) &&
                place->max.y > 0.0f && place->min.y < float(options.view_px.y);
    } else {
      glm::dvec3 lo(place->corners[0]), hi(place->corners[0]);
      for (const glm::dvec3& c : place->corners) {
        lo = glm::min(lo, c);
        hi = glm::max(hi, c);
      }
      in_view = frustum.intersects(lo, hi);
    }
    if (in_view) shown.insert(node.video_inset().source());
  }
  return shown;
}

size_t appendSceneOverlay(const sync::SceneGraph& graph, Overlay& out,
                          const SceneOverlayOptions& options) {
  size_t drawn = 0;
  for (const sync::SceneGraph::NodeId id : graph.ids()) {
    const scene::SceneNode& node = graph.node(id);
    if (!isOverlayKind(node.kind())) continue;
    const NodePlacement placed = placeNode(graph, id);
    if (!placed.visible || !(placed.opacity > 0.0f)) continue;
    switch (node.kind()) {
      case scene::SceneNode::SKETCH:
        addSketch(node.sketch(), placed.world, placed.opacity, options, out);
        break;
      case scene::SceneNode::AVATAR: {
        // A participant's own glyph, or any standing at the viewer's eye (a follower and its
        // leader), would fill the view from inside: left out.
        if (!options.hide_site.empty() && node.avatar().site() == options.hide_site) continue;
        if (options.hide_near_m > 0.0 &&
            glm::length(glm::dvec3(placed.world[3]) - options.viewer_eye) <= options.hide_near_m)
          continue;
        addAvatar(node, placed.world, placed.opacity, options, out);
        break;
      }
      case scene::SceneNode::ANNOTATION:
        addAnnotation(node.annotation(), placed.world, placed.opacity, options, out);
        break;
      case scene::SceneNode::MEASUREMENT:
        addMeasurement(node.measurement(), placed.world, placed.opacity, options, out);
        break;
      case scene::SceneNode::CLIP:
        addClip(node.clip(), placed.world, placed.opacity, out);
        break;
      case scene::SceneNode::VIDEO_INSET:
        // A site's own inset: it has the picture in front of it already.
        if (!options.hide_site.empty() && node.video_inset().stream() == options.hide_site)
          continue;
        addVideoInset(node.video_inset(), placed.world, placed.opacity, options, out);
        break;
      default:
        break;
    }
    ++drawn;
  }
  return drawn;
}

const Overlay& SceneOverlay::update(const sync::SceneGraph& graph,
                                    const sync::SceneChanges& changes) {
  if (mStarted && !changes.everything && changes.nodes.empty()) return mOverlay;
  mStarted = true;
  mOverlay = Overlay();
  appendSceneOverlay(graph, mOverlay, mOptions);
  mHighlights = sceneHighlights(graph);
  return mOverlay;
}

}  // namespace tessera::render
