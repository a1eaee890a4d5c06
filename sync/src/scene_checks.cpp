#include "scene_checks.h"

#include <cmath>
#include <cstdio>

#include <tessera/sync/selection_mask.h>
#include <tessera/sync/transform.h>
#include <tessera/sync/vec3.h>
#include <tessera/sync/view.h>

namespace tessera::sync::checks {

using scene::SceneNode;
using NodeId = SceneGraph::NodeId;

/// Largest magnitude of a transform entry: scales and moves beyond it put a model out of any
/// view, or overflow to infinity once multiplied by coordinates (1e300).
constexpr double kMaxTransformValue = 1e9;

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

bool validKind(int kind) {
  return SceneNode::Kind_IsValid(kind) && kind != SceneNode::KIND_UNSPECIFIED;
}

SceneNode::PayloadCase payloadCaseOf(SceneGraph::Kind kind) {
  switch (kind) {
    case SceneNode::MODEL:
      return SceneNode::kModel;
    case SceneNode::ANNOTATION:
      return SceneNode::kAnnotation;
    case SceneNode::SKETCH:
      return SceneNode::kSketch;
    case SceneNode::AVATAR:
      return SceneNode::kAvatar;
    case SceneNode::VIDEO_INSET:
      return SceneNode::kVideoInset;
    case SceneNode::MEASUREMENT:
      return SceneNode::kMeasurement;
    case SceneNode::SELECTION:
      return SceneNode::kSelection;
    case SceneNode::CLIP:
      return SceneNode::kClip;
    default:
      return SceneNode::PAYLOAD_NOT_SET;
  }
}

Problem checkColor(const scene::Color& c, const std::string& field) {
  for (float v : {c.r(), c.g(), c.b()}) {
    if (!(v >= 0.0f && v <= 1.0f)) return field + ": components must be in [0, 1], got " + num(v);
  }
  return {};
}

static Problem checkNonNegative(float v, const std::string& field) {
  if (!(v >= 0.0f) || !std::isfinite(v)) return field + ": must be finite and >= 0, got " + num(v);
  return {};
}

/// A database place's fields (scene.proto AnnotationPayload 4..8).
static Problem checkAnnotation(const scene::AnnotationPayload& a) {
  if (!std::isfinite(a.radius()) || a.radius() < 0.0)
    return "annotation.radius: must be finite and >= 0, got " + num(a.radius());
  if (a.view_size() != 0 && a.view_size() != 10)
    return "annotation.view: needs eye, target, up and fovy (10 numbers) or none, got " +
           std::to_string(a.view_size());
  for (double v : a.view())
    if (!(std::abs(v) <= 1e12)) return std::string("annotation.view: numbers must be finite");
  if (a.view_size() == 10) {
    const auto& v = a.view();
    const glm::dvec3 eye(v[0], v[1], v[2]), target(v[3], v[4], v[5]), up(v[6], v[7], v[8]);
    if (const auto problem = viewProblem(eye, target, up))
      return describe(*problem, "annotation.view");
    if (!(v[9] > 0.0 && v[9] < 180.0))
      return "annotation.view: fovy must be in (0, 180) degrees, got " + num(v[9]);
  }
  if (a.items_size() > SceneGraph::kMaxAnnotationItems)
    return "annotation.items: at most " + std::to_string(SceneGraph::kMaxAnnotationItems) +
           ", got " + std::to_string(a.items_size());
  size_t picture_bytes = 0;
  for (int i = 0; i < a.items_size(); ++i) {
    const scene::AnnotationItem& it = a.items(i);
    const std::string field = "annotation.items[" + std::to_string(i) + "]";
    if (it.id() == 0) return field + ".id: must be > 0";
    if (it.kind() != "text" && it.kind() != "number" && it.kind() != "image" &&
        it.kind() != "link")
      return field + ".kind: must be text, number, image or link";
    if (it.title().size() > 1024)
      return field + ".title: at most 1024 bytes, got " + std::to_string(it.title().size());
    if (it.text().size() > SceneGraph::kMaxAnnotationText)
      return field + ".text: at most " + std::to_string(SceneGraph::kMaxAnnotationText) +
             " bytes, got " + std::to_string(it.text().size());
    for (const auto& [value, name] : {std::pair{&it.unit(), ".unit"}, {&it.author(), ".author"}})
      if (value->size() > 256) return field + name + ": at most 256 bytes";
    if (it.uri().size() > 4096) return field + ".uri: at most 4096 bytes";
    if (!std::isfinite(it.number())) return field + ".number: must be finite";
    if (it.revision() == 0) return field + ".revision: must be >= 1";
    if (it.picture_problem().size() > 256) return field + ".picture_problem: at most 256 bytes";
    if (it.picture().empty() && it.picture_width() == 0 && it.picture_height() == 0) continue;
    if (it.kind() != "image") return field + ".picture: only an image item has one";
    const uint32_t w = it.picture_width(), h = it.picture_height();
    if (w == 0 || h == 0 || w > SceneGraph::kMaxAnnotationPicturePx ||
        h > SceneGraph::kMaxAnnotationPicturePx)
      return field + ".picture_width, picture_height: each in [1, " +
             std::to_string(SceneGraph::kMaxAnnotationPicturePx) + "], got " + std::to_string(w) +
             "x" + std::to_string(h);
    if (it.picture().size() != size_t(w) * h * 4)
      return field + ".picture: " + std::to_string(w) + "x" + std::to_string(h) +
             " RGBA needs " + std::to_string(size_t(w) * h * 4) + " bytes, got " +
             std::to_string(it.picture().size());
    picture_bytes += it.picture().size();
    if (picture_bytes > SceneGraph::kMaxAnnotationPictureBytes)
      return field + ".picture: the payload's pictures exceed " +
             std::to_string(SceneGraph::kMaxAnnotationPictureBytes) + " bytes together";
  }
  return {};
}

/// Largest magnitude of a clip plane's numbers or a clip box's centre and extents (metres):
/// beyond it the cut is outside any scene (and squares overflow floats).
constexpr double kMaxClipValue = 1e9;

static Problem checkClip(const scene::ClipPayload& c) {
  const bool box = c.has_box_half_extents();
  if (c.planes_size() % 4 != 0)
    return "clip.planes: needs a b c d quadruples, got " + std::to_string(c.planes_size()) +
           " numbers";
  const int planes = c.planes_size() / 4;
  if (planes > SceneGraph::kMaxClipNodePlanes)
    return "clip.planes: at most " + std::to_string(SceneGraph::kMaxClipNodePlanes) +
           " planes, got " + std::to_string(planes);
  if (box && planes > 0)
    return std::string("clip.planes: a clip node holds planes or a box, not both");
  if (c.has_box_center() && !box)
    return std::string("clip.box_center: a box needs box_half_extents too");
  for (double v : c.planes())
    if (!(std::abs(v) <= kMaxClipValue))
      return "clip.planes: numbers must be finite, within +-" + num(kMaxClipValue) + ", got " +
             num(v);
  for (int i = 0; i < planes; ++i) {
    const double a = c.planes(4 * i), b = c.planes(4 * i + 1), cz = c.planes(4 * i + 2);
    // Relative to the plane's own numbers: (0, 0, 0, d) keeps everything or nothing.
    const double largest =
        std::max({std::abs(a), std::abs(b), std::abs(cz), std::abs(c.planes(4 * i + 3))});
    if (!(std::max({std::abs(a), std::abs(b), std::abs(cz)}) > 1e-12 * largest))
      return "clip.planes: plane " + std::to_string(i) + " has a zero normal (a, b, c)";
  }
  for (const auto& [v, field] : {std::pair{&c.box_center(), "clip.box_center"},
                                 {&c.box_half_extents(), "clip.box_half_extents"}})
    for (double x : {v->x(), v->y(), v->z()})
      if (!(std::abs(x) <= kMaxClipValue))
        return std::string(field) + ": numbers must be finite, within +-" + num(kMaxClipValue) +
               ", got " + num(x);
  if (box)
    for (double x : {c.box_half_extents().x(), c.box_half_extents().y(), c.box_half_extents().z()})
      if (!(x > 0.0)) return "clip.box_half_extents: each must be > 0, got " + num(x);
  if (c.models_size() > SceneGraph::kMaxClipModels)
    return "clip.models: at most " + std::to_string(SceneGraph::kMaxClipModels) + " models, got " +
           std::to_string(c.models_size());
  for (uint32_t m : c.models())
    if (m == 0) return std::string("clip.models: ids must name MODEL nodes (> 0)");
  if (!std::isfinite(c.outline()) || c.outline() < 0.0f || c.outline() > kMaxClipValue)
    return "clip.outline: must be finite and in [0, " + num(kMaxClipValue) + "], got " +
           num(c.outline());
  return {};
}

static Problem checkPayload(const SceneNode& n) {
  switch (n.payload_case()) {
    case SceneNode::kAnnotation: {
      const auto& a = n.annotation().anchor();
      if (!std::isfinite(a.x()) || !std::isfinite(a.y()) || !std::isfinite(a.z()))
        return std::string("annotation.anchor: numbers must be finite");
      return checkAnnotation(n.annotation());
    }
    case SceneNode::kSketch: {
      const auto& s = n.sketch();
      if (s.points_size() % 3 != 0)
        return "sketch.points: needs x y z triples, got " + std::to_string(s.points_size()) +
               " numbers";
      for (float v : s.points()) {
        if (!std::isfinite(v)) return std::string("sketch.points: numbers must be finite");
      }
      if (auto p = checkColor(s.color(), "sketch.color")) return p;
      return checkNonNegative(s.width(), "sketch.width");
    }
    case SceneNode::kAvatar: {
      const auto& a = n.avatar();
      if (auto p = checkColor(a.color(), "avatar.color")) return p;
      if (!(a.fovy_deg() >= 0.0f && a.fovy_deg() < 180.0f))
        return "avatar.fovy_deg: must be in [0, 180), got " + num(a.fovy_deg());
      if (auto p = checkNonNegative(a.aspect(), "avatar.aspect")) return p;
      if (a.aspect() > 100.0f) return "avatar.aspect: at most 100, got " + num(a.aspect());
      return checkNonNegative(a.reach(), "avatar.reach");
    }
    case SceneNode::kMeasurement: {
      const auto& m = n.measurement();
      if (!scene::MeasurementPayload::Type_IsValid(m.type()))
        return "measurement.type: unknown type " + std::to_string(int(m.type()));
      const int points = m.points_size() / 3;
      if (m.points_size() % 3 != 0)
        return "measurement.points: needs x y z triples, got " +
               std::to_string(m.points_size()) + " numbers";
      if (points > 1024) return "measurement.points: at most 1024, got " + std::to_string(points);
      const int need = m.type() == scene::MeasurementPayload::DISTANCE ? 2
                       : m.type() == scene::MeasurementPayload::ANGLE  ? 3
                                                                        : 0;
      const int least = m.type() == scene::MeasurementPayload::AREA ? 3 : 2;
      if ((need && points != need) || points < least)
        return "measurement.points: a " + scene::MeasurementPayload::Type_Name(m.type()) +
               " needs " + (need ? std::to_string(need) : "at least " + std::to_string(least)) +
               " points, got " + std::to_string(points);
      for (double v : m.points())
        if (!std::isfinite(v)) return std::string("measurement.points: numbers must be finite");
      for (const auto& [v, field] : {std::pair{m.value(), "measurement.value"},
                                     {m.uncertainty(), "measurement.uncertainty"}})
        if (!std::isfinite(v) || v < 0.0)
          return std::string(field) + ": must be finite and >= 0, got " + num(v);
      return checkColor(m.color(), "measurement.color");
    }
    case SceneNode::kSelection: {
      const auto& s = n.selection();
      if (s.model() == 0) return std::string("selection.model: must name a MODEL node (> 0)");
      if (s.lasso_clip_from_world_size() != 16)
        return "selection.lasso_clip_from_world: needs 16 numbers, got " +
               std::to_string(s.lasso_clip_from_world_size());
      for (double v : s.lasso_clip_from_world())
        if (!std::isfinite(v))
          return std::string("selection.lasso_clip_from_world: numbers must be finite");
      const bool has_mask = !s.mask().empty() || s.mask_width() != 0 || s.mask_height() != 0;
      if (has_mask) {  // a region mask instead of a lasso (lazy snapping)
        if (s.lasso_size() != 0)
          return std::string("selection.lasso: a selection with a mask has no lasso");
        if (auto p = decodeSelectionMask(s.mask(), s.mask_width(), s.mask_height(), nullptr))
          return p;
      } else if (s.lasso_size() % 2 != 0 || s.lasso_size() < 6 || s.lasso_size() > 8192) {
        return "selection.lasso: needs 3..4096 x y pairs (or a mask), got " +
               std::to_string(s.lasso_size()) + " numbers";
      }
      for (double v : s.lasso())
        if (!(std::abs(v) <= 1e6)) return std::string("selection.lasso: numbers must be finite, within 1e6");
      if (s.elements().size() > (size_t(16) << 20))
        return "selection.elements: " + std::to_string(s.elements().size()) +
               " bytes; at most 16 MiB";
      return checkColor(s.color(), "selection.color");
    }
    case SceneNode::kClip:
      return checkClip(n.clip());
    case SceneNode::kVideoInset: {
      const auto& v = n.video_inset();
      if (auto p = checkNonNegative(v.width(), "video_inset.width")) return p;
      if (auto p = checkNonNegative(v.height(), "video_inset.height")) return p;
      if (!v.screen()) return {};
      for (const auto& [value, field] : {std::pair{v.screen_x(), "video_inset.screen_x"},
                                         {v.screen_y(), "video_inset.screen_y"},
                                         {v.screen_width(), "video_inset.screen_width"},
                                         {v.screen_height(), "video_inset.screen_height"}})
        if (!(value >= 0.0f && value <= 1.0f))
          return std::string(field) + ": must be in [0, 1] (fractions of the wall), got " +
                 num(value);
      return {};
    }
    default:
      return {};
  }
}

/// A node transform: none, or 16 finite numbers (column-major) of an affine, invertible map
/// with every entry within kMaxTransformValue.
Problem checkTransform(std::span<const double> m) {
  if (m.size() != 0 && m.size() != 16)
    return "transform: needs 16 numbers (column-major 4x4) or none, got " +
           std::to_string(m.size());
  for (double v : m) {
    if (!std::isfinite(v)) return std::string("transform: numbers must be finite");
    if (std::abs(v) > kMaxTransformValue)
      return "transform: " + num(v) + " is beyond +-" + num(kMaxTransformValue) +
             " (the model would leave every view)";
  }
  if (m.size() == 16) {
    // Column-major: the last row is m[3], m[7], m[11], m[15].
    if (m[3] != 0.0 || m[7] != 0.0 || m[11] != 0.0 || m[15] != 1.0)
      return std::string("transform: the last row must be 0 0 0 1 (an affine transform)");
    const double det = m[0] * (m[5] * m[10] - m[9] * m[6]) - m[4] * (m[1] * m[10] - m[9] * m[2]) +
                       m[8] * (m[1] * m[6] - m[5] * m[2]);
    double largest = 0.0;
    for (int i : {0, 1, 2, 4, 5, 6, 8, 9, 10}) largest = std::max(largest, std::abs(m[i]));
    // Relative to the matrix's own scale, so a small uniform scale is still invertible.
    if (!(std::abs(det) > 1e-9 * largest * largest * largest))
      return "transform: singular (determinant " + num(det) +
             "): the model would collapse to a plane, a line or a point";
  }
  return {};
}

/// A node transform as it travels: none (identity), 16 numbers (checkTransform() above), or the
/// rigid form: a translation of 3 finite numbers within kMaxTransformValue and a rotation
/// quaternion of 4 finite numbers of length 1 within 1e-3 (sync/transform.h), never both forms.
Problem checkTransform(const scene::Transform& t) {
  const bool rigid = t.translation_size() != 0 || t.rotation_size() != 0;
  if (!rigid) return checkTransform(std::span<const double>(t.m().data(), size_t(t.m_size())));
  if (t.m_size() != 0)
    return std::string("transform: 16 numbers and the rigid form (translation, rotation) at once");
  if (t.translation_size() != 3 || t.rotation_size() != 4)
    return "transform: the rigid form needs a translation of 3 numbers and a rotation of 4, got " +
           std::to_string(t.translation_size()) + " and " + std::to_string(t.rotation_size());
  for (double v : t.translation()) {
    if (!std::isfinite(v)) return std::string("transform: translation must be finite");
    if (std::abs(v) > kMaxTransformValue)
      return "transform: translation " + num(v) + " is beyond +-" + num(kMaxTransformValue) +
             " (the model would leave every view)";
  }
  double length2 = 0.0;
  for (float v : t.rotation()) {
    if (!std::isfinite(v)) return std::string("transform: rotation must be finite");
    length2 += double(v) * double(v);
  }
  if (!(std::abs(std::sqrt(length2) - 1.0) <= 1e-3))
    return "transform: rotation must be a unit quaternion (w x y z), its length is " +
           num(std::sqrt(length2));
  return {};
}

/// The fields present in `n` (a full state or a delta) for a node of `kind`.
Problem checkNodeFields(const SceneNode& n, SceneGraph::Kind kind) {
  if (n.has_opacity() && !(n.opacity() >= 0.0f && n.opacity() <= 1.0f))
    return "opacity: " + num(n.opacity()) + " is not in [0, 1]";
  if (n.has_transform()) {
    if (auto p = checkTransform(n.transform())) return p;
  }
  if (n.has_shading() && !scene::Shading_IsValid(n.shading()))
    return "shading: unknown value " + std::to_string(int(n.shading()));
  if (n.has_lod_pixels()) {
    if (auto p = checkNonNegative(n.lod_pixels(), "lod_pixels")) return p;
  }
  if (n.has_author() && n.author().size() > SceneGraph::kMaxParticipantName)
    return "author: at most " + std::to_string(SceneGraph::kMaxParticipantName) + " bytes, got " +
           std::to_string(n.author().size());
  if (n.has_kind() && n.kind() != kind)
    return "kind: " + std::to_string(int(n.kind())) + " differs from the node's kind " +
           std::to_string(int(kind)) + " (a new kind is a delete and a create)";
  if (n.payload_case() != SceneNode::PAYLOAD_NOT_SET && n.payload_case() != payloadCaseOf(kind))
    return "payload: field " + std::to_string(int(n.payload_case())) + " does not belong to kind " +
           SceneNode::Kind_Name(kind);
  return checkPayload(n);
}

Problem checkAnalysis(const scene::Analysis& a) {
  if (a.relative_depth_radius() > 256)
    return "settings.analysis.relative_depth_radius: must be 0..256 px, got " +
           std::to_string(a.relative_depth_radius());
  if (a.has_relative_depth_lo() != a.has_relative_depth_hi())
    return "settings.analysis: relative_depth_lo and relative_depth_hi go together";
  if (a.has_relative_depth_lo() &&
      !(std::isfinite(a.relative_depth_lo()) && std::isfinite(a.relative_depth_hi()) &&
        a.relative_depth_lo() < a.relative_depth_hi()))
    return "settings.analysis: relative_depth_lo must be below relative_depth_hi, both finite, "
           "got " + num(a.relative_depth_lo()) + " and " + num(a.relative_depth_hi());
  if (!(std::isfinite(a.contour_interval()) && a.contour_interval() >= 0.0))
    return "settings.analysis.contour_interval: must be finite and >= 0 (0: off), got " +
           num(a.contour_interval());
  if (!std::isfinite(a.contour_phase()))
    return "settings.analysis.contour_phase: must be finite, got " + num(a.contour_phase());
  if (a.has_contour_axis()) {
    const auto& v = a.contour_axis();
    if (!(std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z())))
      return "settings.analysis.contour_axis: must be finite";
  }
  if (!(std::isfinite(a.ao_strength()) && a.ao_strength() >= 0.0f && a.ao_strength() <= 4.0f))
    return "settings.analysis.ao_strength: must be 0..4 (0: off), got " + num(a.ao_strength());
  if (!(std::isfinite(a.ao_radius()) && a.ao_radius() >= 0.0f))
    return "settings.analysis.ao_radius: must be finite and >= 0 metres (0: ao_radius_px), got " +
           num(a.ao_radius());
  if (a.has_ao_radius_px() && !(a.ao_radius_px() >= 1.0f && a.ao_radius_px() <= 128.0f))
    return "settings.analysis.ao_radius_px: must be 1..128 px, got " + num(a.ao_radius_px());
  if (!(std::isfinite(a.relative_depth_radius_m()) && a.relative_depth_radius_m() >= 0.0f))
    return "settings.analysis.relative_depth_radius_m: must be finite and >= 0 metres, got " +
           num(a.relative_depth_radius_m());
  if (!scene::Analysis::StoredAo_IsValid(a.stored_ao()))
    return "settings.analysis.stored_ao: unknown value " + std::to_string(int(a.stored_ao()));
  if (a.has_ao_slices() && (a.ao_slices() < 1 || a.ao_slices() > 64))
    return "settings.analysis.ao_slices: must be 1..64, got " + std::to_string(a.ao_slices());
  return std::nullopt;
}

Problem checkInsetPlacement(const scene::InsetPlacement& p) {
  if (p.centres_size() > 256)
    return "settings.inset.centres: at most 256, got " + std::to_string(p.centres_size());
  for (int i = 0; i < p.centres_size(); ++i) {
    const scene::InsetCentre& c = p.centres(i);
    const std::string f = "settings.inset.centres[" + std::to_string(i) + "]";
    if (c.name().empty() || c.name().size() > 64)
      return f + ".name: needs the inset's name (1..64 bytes)";
    if (!std::isfinite(c.x()) || !std::isfinite(c.y()))
      return f + " ('" + c.name() + "'): x and y must be finite (metres), got " + num(c.x()) +
             ", " + num(c.y());
    for (int j = 0; j < i; ++j)
      if (p.centres(j).name() == c.name()) return f + ".name: '" + c.name() + "' is placed twice";
  }
  return std::nullopt;
}

Problem checkHead(const scene::Head& h) {
  auto vec3 = [](const config::Vec3& v) {
    return "(" + num(v.x()) + ", " + num(v.y()) + ", " + num(v.z()) + ")";
  };
  if (!h.has_eye() || !finite(h.eye()))
    return "eye: needs finite x, y and z (metres, wall frame), got " +
           (h.has_eye() ? vec3(h.eye()) : std::string("none"));
  if (!h.has_right() || !finite(h.right()))
    return "right: needs finite x, y and z (the head's right axis), got " +
           (h.has_right() ? vec3(h.right()) : std::string("none"));
  const double len = std::sqrt(h.right().x() * h.right().x() + h.right().y() * h.right().y() +
                               h.right().z() * h.right().z());
  if (!(len > 1e-9) || !std::isfinite(len))
    return "right: the head's right axis must not be zero, got " + vec3(h.right());
  if (h.has_eye_separation() && !(h.eye_separation() > 0.0 && h.eye_separation() <= 1.0))
    return "eye_separation: must be in (0, 1] metres, got " + num(h.eye_separation());
  return std::nullopt;
}

/// A delta of the settings (or complete settings).
Problem checkSettings(const scene::Settings& s) {
  if (s.has_background()) {
    if (auto p = checkColor(s.background(), "settings.background")) return p;
  }
  if (s.has_shading() && s.shading() != scene::SHADING_COLOR && s.shading() != scene::SHADING_EDL)
    return "settings.shading: must be SHADING_COLOR or SHADING_EDL, got " +
           std::to_string(int(s.shading()));
  if (s.has_lod_pixels() && !(s.lod_pixels() > 0.0f && std::isfinite(s.lod_pixels())))
    return "settings.lod_pixels: must be finite and > 0, got " + num(s.lod_pixels());
  if (s.has_analysis()) {
    if (auto p = checkAnalysis(s.analysis())) return p;
  }
  if (s.has_inset()) {
    if (auto p = checkInsetPlacement(s.inset())) return p;
  }
  if (s.has_head()) {
    if (auto p = checkHead(s.head())) return "settings.head." + *p;
  }
  if (s.has_points_per_pixel() &&
      !(std::isfinite(s.points_per_pixel()) && s.points_per_pixel() >= 0.0f &&
        s.points_per_pixel() <= 1e6f))
    return "settings.points_per_pixel: must be finite and 0..1e6, got " + num(s.points_per_pixel());
  if (s.has_spbr_ensembles() && (s.spbr_ensembles() < 1 || s.spbr_ensembles() > 4096))
    return "settings.spbr_ensembles: must be 1..4096, got " + std::to_string(s.spbr_ensembles());
  if (s.has_leader() && s.leader().size() > SceneGraph::kMaxParticipantName)
    return "settings.leader: at most " + std::to_string(SceneGraph::kMaxParticipantName) +
           " bytes, got " + std::to_string(s.leader().size());
  return {};
}

/// A delta of the camera: each part absent or complete.
Problem checkCameraDelta(const scene::CameraState& c) {
  if (c.eye_size() != 0 && c.eye_size() != 3)
    return "camera.eye: needs 3 numbers, got " + std::to_string(c.eye_size());
  if (c.view_size() != 0 && c.view_size() != 3)
    return "camera.view: needs 3 numbers, got " + std::to_string(c.view_size());
  for (double v : c.eye()) {
    if (!std::isfinite(v)) return std::string("camera.eye: numbers must be finite");
  }
  double length2 = 0.0;
  for (float v : c.view()) {
    if (!std::isfinite(v)) return std::string("camera.view: numbers must be finite");
    length2 += double(v) * double(v);
  }
  if (c.view_size() == 3 && !(length2 > 0.0))
    return std::string("camera.view: eye and target coincide");
  if (c.has_roll() && !std::isfinite(c.roll())) return std::string("camera.roll: must be finite");
  return {};
}

Problem checkCommand(const scene::Command& c) {
  switch (c.command_case()) {
    case scene::Command::kScreenshot:
      if (c.screenshot().path().empty()) return std::string("screenshot.path: must not be empty");
      return {};
    case scene::Command::kQuit:
      return {};
    default:
      return std::string("empty or unknown command");
  }
}

}  // namespace tessera::sync::checks
