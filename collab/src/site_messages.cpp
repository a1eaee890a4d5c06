#include <tessera/collab/site_messages.h>

#include <cmath>
#include <cstdint>

#include <tessera/media/video_packet.h>
#include <tessera/media/voice_packet.h>
#include <tessera/sync/scene_graph.h>
#include <tessera/sync/vec3.h>
#include <tessera/sync/view.h>

namespace tessera::collab {

namespace {

using Problem = std::optional<std::string>;

Problem checkCoordinates(const google::protobuf::RepeatedField<double>& v, int count,
                         const std::string& field) {
  if (v.size() != count)
    return field + ": needs " + std::to_string(count) + " numbers, got " + std::to_string(v.size());
  for (double x : v) {
    if (!std::isfinite(x)) return field + ": numbers must be finite";
    if (std::abs(x) > kMaxCoordinate)
      return field + ": " + std::to_string(x) + " is beyond +-1e8 m";
  }
  return {};
}

glm::dvec3 vec(const google::protobuf::RepeatedField<double>& v) {
  return {v[0], v[1], v[2]};
}

Problem checkPose(const site::SitePose& p) {
  if (auto e = checkCoordinates(p.eye(), 3, "pose.eye")) return e;
  if (auto e = checkCoordinates(p.target(), 3, "pose.target")) return e;
  if (auto e = checkCoordinates(p.up(), 3, "pose.up")) return e;
  if (const auto problem = sync::viewProblem(vec(p.eye()), vec(p.target()), vec(p.up())))
    return sync::describe(*problem, "pose");
  if (!(p.fovy_deg() > 0.0f && p.fovy_deg() < 180.0f))
    return "pose.fovy_deg: must be in (0, 180), got " + std::to_string(p.fovy_deg());
  if (!(p.aspect() > 0.0f && p.aspect() <= 100.0f))
    return "pose.aspect: must be in (0, 100], got " + std::to_string(p.aspect());
  return {};
}

Problem checkColor(const scene::Color& c, const std::string& field) {
  for (float v : {c.r(), c.g(), c.b()})
    if (!(v >= 0.0f && v <= 1.0f)) return field + ": components must be in [0, 1]";
  return {};
}

Problem checkStroke(const site::SiteStroke& s) {
  const int n = s.points_size();
  if (n % 3 != 0)
    return "stroke.points: needs x y z triples, got " + std::to_string(n) + " numbers";
  if (n / 3 < 2 || n / 3 > kMaxStrokePoints)
    return "stroke.points: needs 2.." + std::to_string(kMaxStrokePoints) + " points, got " +
           std::to_string(n / 3);
  for (double x : s.points()) {
    if (!std::isfinite(x)) return std::string("stroke.points: numbers must be finite");
    if (std::abs(x) > kMaxCoordinate) return std::string("stroke.points: beyond +-1e8 m");
  }
  if (auto e = checkColor(s.color(), "stroke.color")) return e;
  if (!(s.width() > 0.0f && s.width() <= 64.0f))
    return "stroke.width: must be in (0, 64] pixels, got " + std::to_string(s.width());
  return {};
}

/// UTF-8: well-formed sequences, no overlongs or surrogates, no control characters (but line
/// breaks and tabs where `lines`).
Problem checkUtf8(std::string_view name, const std::string& field, bool lines) {
  for (size_t i = 0; i < name.size();) {
    const unsigned char c = static_cast<unsigned char>(name[i]);
    if ((c < 0x20 && !(lines && (c == '\n' || c == '\t'))) || c == 0x7F)
      return field + ": holds a control character";
    int extra = c < 0x80           ? 0
                : (c >> 5) == 0x6  ? 1
                : (c >> 4) == 0xE  ? 2
                : (c >> 3) == 0x1E ? 3
                                   : -1;
    if (extra < 0 || i + size_t(extra) >= name.size()) return field + ": not valid UTF-8";
    uint32_t cp = extra == 0 ? c : c & (0x3F >> extra);
    for (int k = 1; k <= extra; ++k) {
      const unsigned char d = static_cast<unsigned char>(name[i + size_t(k)]);
      if ((d >> 6) != 0x2) return field + ": not valid UTF-8";
      cp = (cp << 6) | (d & 0x3F);
    }
    static constexpr uint32_t kMin[] = {0, 0x80, 0x800, 0x10000};
    if (cp < kMin[extra] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
      return field + ": not valid UTF-8";
    if (cp >= 0x80 && cp < 0xA0) return field + ": holds a control character";
    i += size_t(extra) + 1;
  }
  return {};
}

Problem checkText(std::string_view text, size_t max, const std::string& field, bool lines) {
  if (text.size() > max)
    return field + ": at most " + std::to_string(max) + " bytes, got " +
           std::to_string(text.size());
  return checkUtf8(text, field, lines);
}

/// `keep_layer`: an update, whose empty layer keeps the item's own.
Problem checkNoteContent(const site::NoteContent& c, const std::string& field,
                         bool keep_layer = false) {
  if (c.layer().empty() && !keep_layer) return field + ".layer: empty";
  if (auto e = checkText(c.layer(), 256, field + ".layer", false)) return e;
  if (c.kind() != "text" && c.kind() != "number" && c.kind() != "link")
    return field + ".kind: must be text, number or link";
  if (c.title().empty()) return field + ".title: empty";
  if (auto e = checkText(c.title(), 1024, field + ".title", false)) return e;
  if (auto e = checkText(c.text(), kMaxNoteTextBytes, field + ".text", true)) return e;
  if (auto e = checkText(c.unit(), 256, field + ".unit", false)) return e;
  if (auto e = checkText(c.uri(), 4096, field + ".uri", false)) return e;
  if (!std::isfinite(c.number())) return field + ".number: must be finite";
  return {};
}

Problem checkNote(const site::SiteNote& n) {
  switch (n.edit_case()) {
    case site::SiteNote::kAdd: {
      const site::NoteAdd& a = n.add();
      if (a.place() == 0) {
        if (a.position_size() != 3)
          return "note.add.position: needs x y z, got " + std::to_string(a.position_size()) +
                 " numbers";
        for (double x : a.position())
          if (!(std::abs(x) <= kMaxCoordinate))
            return std::string("note.add.position: numbers must be finite, within 1e8 m");
        if (auto e = checkText(a.model(), 256, "note.add.model", false)) return e;
        if (!(a.radius() >= 0.0 && a.radius() <= kMaxCoordinate))
          return std::string("note.add.radius: must be finite, in [0, 1e8] m");
        if (a.view_size() != 0 && a.view_size() != 10)
          return "note.add.view: needs eye, target, up and fovy (10 numbers) or none, got " +
                 std::to_string(a.view_size());
        for (double x : a.view())
          if (!(std::abs(x) <= kMaxCoordinate))
            return std::string("note.add.view: numbers must be finite, within 1e8");
        if (a.radius() > 0.0 && a.view_size() != 10)
          return std::string("note.add.view: a hot spot (radius > 0) needs its view");
      }
      return checkNoteContent(a.item(), "note.add.item");
    }
    case site::SiteNote::kUpdate:
      if (n.update().item() == 0) return std::string("note.update.item: must be > 0");
      if (n.update().base_revision() == 0)
        return std::string("note.update.base_revision: must be > 0");
      return checkNoteContent(n.update().content(), "note.update.content", true);
    case site::SiteNote::kRemove:
      if (n.remove().item() == 0) return std::string("note.remove.item: must be > 0");
      if (n.remove().base_revision() == 0)
        return std::string("note.remove.base_revision: must be > 0");
      return {};
    case site::SiteNote::kLayer:
      if (n.layer().layer().empty()) return std::string("note.layer.layer: empty");
      return checkText(n.layer().layer(), 256, "note.layer.layer", false);
    case site::SiteNote::kOpen:
      if (n.open().place() == 0) return std::string("note.open.place: must be > 0");
      return {};
    default:
      return std::string("note: no edit (empty, or from a newer protocol)");
  }
}

Problem checkMeasure(const site::SiteMeasure& m) {
  if (!scene::MeasurementPayload::Type_IsValid(m.type()))
    return "measure.type: unknown type " + std::to_string(int(m.type()));
  const int n = m.points_size() / 3;
  if (m.points_size() % 3 != 0)
    return "measure.points: needs x y z triples, got " + std::to_string(m.points_size()) +
           " numbers";
  const auto type = m.type();
  const int exact = type == scene::MeasurementPayload::DISTANCE ? 2
                    : type == scene::MeasurementPayload::ANGLE  ? 3
                                                                : 0;
  const int least = type == scene::MeasurementPayload::AREA ? 3 : 2;
  if ((exact && n != exact) || n < least || n > kMaxMeasurePoints)
    return "measure.points: a " + scene::MeasurementPayload::Type_Name(type) + " needs " +
           (exact ? std::to_string(exact) : std::to_string(least) + ".." +
                                                 std::to_string(kMaxMeasurePoints)) +
           " points, got " + std::to_string(n);
  for (double x : m.points())
    if (!(std::abs(x) <= kMaxCoordinate))
      return std::string("measure.points: numbers must be finite, within 1e8 m");
  for (const auto& [v, field] :
       {std::pair{m.value(), "measure.value"}, {m.uncertainty(), "measure.uncertainty"}})
    if (!(v >= 0.0 && v <= 1e17)) return std::string(field) + ": must be finite and >= 0";
  // What the points alone give must be what the site says.
  auto at = [&](int i) {
    return glm::dvec3(m.points(3 * i), m.points(3 * i + 1), m.points(3 * i + 2));
  };
  double expected = -1.0;
  if (type == scene::MeasurementPayload::DISTANCE || type == scene::MeasurementPayload::POLYLINE) {
    expected = 0.0;
    for (int i = 1; i < n; ++i) expected += glm::length(at(i) - at(i - 1));
  } else if (type == scene::MeasurementPayload::ANGLE) {
    const glm::dvec3 a = at(0) - at(1), b = at(2) - at(1);
    if (!(glm::length(a) > 0.0 && glm::length(b) > 0.0))
      return std::string("measure.points: an angle's arms must not be of zero length");
    expected = std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
  }
  if (expected >= 0.0 && !(std::abs(m.value() - expected) <= 1e-9 * std::max(1.0, expected)))
    return "measure.value: " + std::to_string(m.value()) + " is not what its points give (" +
           std::to_string(expected) + ")";
  return {};
}

/// A view sent with a lasso or strokes: 16 + 16 finite numbers, an invertible projection of a
/// finite frustum, 16..16384 pixels a side. `what` names the message ("select", "snap").
template <class M>
Problem checkSentView(const M& m, const std::string& what) {
  if (m.model() == 0) return what + ".model: must name a MODEL node (> 0)";
  for (const auto& [matrix, field] :
       {std::pair{&m.view(), ".view"}, {&m.projection(), ".projection"}}) {
    if (matrix->size() != 16)
      return what + field + ": needs 16 numbers, got " + std::to_string(matrix->size());
    for (double v : *matrix)
      if (!(std::abs(v) <= 1e12)) return what + field + ": numbers must be finite";
  }
  for (const auto& [v, field] : {std::pair{m.width(), ".width"}, {m.height(), ".height"}})
    if (v < 16 || v > 16384) return what + field + ": 16..16384 pixels, got " + std::to_string(v);
  glm::dmat4 vp(1.0), view(1.0);
  for (int k = 0; k < 16; ++k) {
    vp[k / 4][k % 4] = m.projection(k);
    view[k / 4][k % 4] = m.view(k);
  }
  vp = vp * view;
  const double det = glm::determinant(vp);
  if (!std::isfinite(det) || std::abs(det) < 1e-300)
    return what + ".projection: with the view, not invertible";
  return {};
}

/// x y pairs of pixels, `least`..`most` of them, each within 1e6.
Problem checkPixels(const google::protobuf::RepeatedField<double>& px, int least, int most,
                    const std::string& field) {
  if (px.size() % 2 != 0 || px.size() < 2 * least || px.size() > 2 * most)
    return field + ": needs " + std::to_string(least) + ".." + std::to_string(most) +
           " x y pairs, got " + std::to_string(px.size()) + " numbers";
  for (double v : px)
    if (!(std::abs(v) <= 1e6)) return field + ": numbers must be finite, within 1e6";
  return {};
}

Problem checkSelect(const site::SiteSelect& m) {
  if (auto p = checkSentView(m, "select")) return p;
  return checkPixels(m.lasso(), 3, kMaxLassoPoints, "select.lasso");
}

Problem checkSnap(const site::SiteSnap& m) {
  if (auto p = checkSentView(m, "snap")) return p;
  if (!(m.heavy_width() >= 0.0f && m.heavy_width() <= kMaxHeavyStrokeWidth) ||
      (m.heavy_width() > 0.0f && m.heavy_width() < 1.0f))
    return "snap.heavy_width: 0 or 1.." + std::to_string(int(kMaxHeavyStrokeWidth)) + " pixels";
  const bool heavy = m.heavy_width() > 0.0f;
  if (auto p = checkPixels(m.foreground(), heavy ? 3 : 1, kMaxSnapStrokePoints, "snap.foreground"))
    return p;
  if (heavy) {
    if (m.background_size() != 0)
      return std::string("snap.background: the robust lasso (heavy_width > 0) has none");
    return {};
  }
  return checkPixels(m.background(), 1, kMaxSnapStrokePoints, "snap.background");
}

}  // namespace

Problem checkName(std::string_view name, const std::string& field) {
  if (name.empty() || name.size() > 64)
    return field + ": needs 1..64 bytes, got " + std::to_string(name.size());
  return checkUtf8(name, field, false);
}

Problem checkToMaster(const site::ToMaster& m) {
  switch (m.kind_case()) {
    case site::ToMaster::kHello:
      return checkName(m.hello().name(), "hello.name");
    case site::ToMaster::kPose:
      return checkPose(m.pose());
    case site::ToMaster::kStroke:
      return checkStroke(m.stroke());
    case site::ToMaster::kUndo:
    case site::ToMaster::kClear:
    case site::ToMaster::kLead:
    case site::ToMaster::kRelease:
    case site::ToMaster::kBye:
      return {};
    case site::ToMaster::kVoice: {
      media::VoicePacket packet;
      const std::string& v = m.voice();
      if (auto why =
              media::decodeVoicePacket({reinterpret_cast<const uint8_t*>(v.data()), v.size()}, packet))
        return "voice: " + *why;
      return {};
    }
    case site::ToMaster::kNote:
      return checkNote(m.note());
    case site::ToMaster::kMeasure:
      return checkMeasure(m.measure());
    case site::ToMaster::kSelect:
      return checkSelect(m.select());
    case site::ToMaster::kShading: {
      const site::SiteShading& s = m.shading();
      if (!s.has_shading() && !s.has_analysis()) return "shading: needs shading or analysis";
      if (s.has_shading() && s.shading() != scene::SHADING_COLOR &&
          s.shading() != scene::SHADING_EDL)
        return "shading.shading: must be SHADING_COLOR or SHADING_EDL, got " +
               std::to_string(int(s.shading()));
      if (s.has_analysis())
        if (auto why = sync::SceneGraph::analysisProblem(s.analysis())) return "shading: " + *why;
      return {};
    }
    case site::ToMaster::kHead:  // the wall's own check follows on the master (site_roster.h)
      if (!m.head().has_head()) return "head.head: needs the viewer's head";
      if (auto why = sync::SceneGraph::headProblem(m.head().head())) return "head.head." + *why;
      return {};
    case site::ToMaster::kSnap:
      return checkSnap(m.snap());
    case site::ToMaster::kVideo: {
      media::VideoPacket packet;
      const std::string& v = m.video();
      if (auto why =
              media::decodeVideoPacket({reinterpret_cast<const uint8_t*>(v.data()), v.size()}, packet))
        return "video: " + *why;
      return {};
    }
    default:
      return std::string("message: no known kind (empty, or from a newer protocol)");
  }
}

Problem parseToMaster(std::string_view bytes, site::ToMaster& out) {
  if (bytes.size() > kMaxSiteMessageBytes)
    return "message: " + std::to_string(bytes.size()) + " bytes, more than the " +
           std::to_string(kMaxSiteMessageBytes) + " a site may send";
  if (!out.ParseFromArray(bytes.data(), int(bytes.size())))
    return "message: " + std::to_string(bytes.size()) + " bytes are not a site message";
  out.DiscardUnknownFields();
  return checkToMaster(out);
}

Problem parseChunkRequest(std::string_view bytes, site::ChunkRequest& out) {
  if (bytes.size() > kMaxChunkRequestBytes)
    return "chunk request: " + std::to_string(bytes.size()) + " bytes, more than the " +
           std::to_string(kMaxChunkRequestBytes) + " a request may take";
  if (!out.ParseFromArray(bytes.data(), int(bytes.size())))
    return "chunk request: " + std::to_string(bytes.size()) + " bytes are not a chunk request";
  out.DiscardUnknownFields();
  if (out.cancel_size() > 0) {
    if (size_t(out.cancel_size()) > kMaxChunkCancelIds)
      return "chunk request.cancel: " + std::to_string(out.cancel_size()) +
             " ids, more than the " + std::to_string(kMaxChunkCancelIds) + " one cancel may name";
    if (!out.store().empty() || out.offset() != 0 || out.length() != 0)
      return std::string("chunk request: a cancel names no store, offset or length");
    return {};
  }
  if (out.store().empty() || out.store().size() > kMaxStorePathBytes)
    return "chunk request.store: needs 1.." + std::to_string(kMaxStorePathBytes) + " bytes, got " +
           std::to_string(out.store().size());
  if (out.store().find('\0') != std::string::npos)
    return std::string("chunk request.store: holds a NUL byte");
  if (out.length() > kMaxChunkRangeBytes)
    return "chunk request.length: " + std::to_string(out.length()) + " bytes, more than the " +
           std::to_string(kMaxChunkRangeBytes) + " one request may ask for";
  if (out.offset() > UINT64_MAX - out.length())
    return "chunk request.offset: " + std::to_string(out.offset()) + " + length overflows";
  return {};
}

Problem checkChunkRange(const site::ChunkRequest& r, uint64_t size) {
  if (r.offset() > size || r.length() > size - r.offset())
    return "bytes " + std::to_string(r.offset()) + ".." + std::to_string(r.offset() + r.length()) +
           " lie beyond the end of " + r.store() + " (" + std::to_string(size) + " bytes)";
  return {};
}

config::Camera poseCamera(const site::SitePose& p) {
  config::Camera c;
  auto set = [](config::Vec3* v, const google::protobuf::RepeatedField<double>& s) {
    v->set_x(s[0]);
    v->set_y(s[1]);
    v->set_z(s[2]);
  };
  set(c.mutable_eye(), p.eye());
  set(c.mutable_target(), p.target());
  set(c.mutable_up(), p.up());
  return c;
}

config::Camera blendCameras(const config::Camera& a, const config::Camera& b, double s) {
  const glm::dvec3 eye = glm::mix(sync::vec(a.eye()), sync::vec(b.eye()), s);
  const glm::dvec3 target = glm::mix(sync::vec(a.target()), sync::vec(b.target()), s);
  const glm::dvec3 up = glm::mix(sync::vec(a.up()), sync::vec(b.up()), s);
  if (sync::viewProblem(eye, target, up)) return b;
  config::Camera c;
  sync::set(c.mutable_eye(), eye);
  sync::set(c.mutable_target(), target);
  sync::set(c.mutable_up(), up);
  return c;
}

glm::dmat4 poseFrame(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up) {
  const glm::dvec3 f = glm::normalize(target - eye);
  const glm::dvec3 r = glm::normalize(glm::cross(f, up));
  const glm::dvec3 u = glm::cross(r, f);
  glm::dmat4 m(1.0);
  m[0] = glm::dvec4(r, 0.0);
  m[1] = glm::dvec4(u, 0.0);
  m[2] = glm::dvec4(-f, 0.0);
  m[3] = glm::dvec4(eye, 1.0);
  return m;
}

}  // namespace tessera::collab
