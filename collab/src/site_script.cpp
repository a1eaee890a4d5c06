// The site script (site.proto SiteScript, JSON): loaded, checked field by field, defaults set.
#include "site_session_impl.h"

#include <tessera/collab/site_messages.h>

#include <google/protobuf/util/json_util.h>

namespace tessera::collab {

namespace {

[[noreturn]] void fail(const std::string& file, const std::string& field, const std::string& what) {
  throw sync::ConfigError("collab::loadSiteScript(): " + file + ": " +
                          (field.empty() ? "" : field + ": ") + what);
}

}  // namespace

/// The camera every process of the session would decode from it (the wire's rounding), so a
/// leader and its followers render the very same view.
config::Camera asSent(const config::Camera& c) {
  return sync::decodeCamera(sync::encodeCamera(c));
}

/// The script's defaults where it is silent: 30 frames a second, 640x480, 45 degrees.
void withDefaults(site::SiteScript& s) {
  if (s.fps() == 0) s.set_fps(30);
  if (s.width() == 0) s.set_width(640);
  if (s.height() == 0) s.set_height(480);
  if (s.fovy_deg() == 0) s.set_fovy_deg(45);
}

site::SiteScript loadSiteScript(const std::string& path) {
  if (const auto why = notRegularFile(path)) fail(path, "", "cannot open: " + *why);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "", "cannot open");
  std::ostringstream text;
  text << in.rdbuf();
  site::SiteScript s;
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = false;
  const auto status = google::protobuf::util::JsonStringToMessage(text.str(), &s, options);
  if (!status.ok()) fail(path, "", "not a valid SiteScript: " + std::string(status.message()));
  withDefaults(s);
  if (!(s.fps() > 0 && s.fps() <= 240)) fail(path, "fps", "must be in (0, 240]");
  if (s.width() < 16 || s.width() > 8192 || s.height() < 16 || s.height() > 8192)
    fail(path, "width/height", "16..8192 pixels each");
  if (!(s.fovy_deg() > 0 && s.fovy_deg() < 180)) fail(path, "fovyDeg", "must be in (0, 180)");
  uint32_t previous = 0;
  for (int i = 0; i < s.actions_size(); ++i) {
    const site::SiteAction& a = s.actions(i);
    const std::string field = "actions[" + std::to_string(i) + "]";
    if (a.frame() < previous) fail(path, field + ".frame", "actions must be in frame order");
    previous = a.frame();
    switch (a.action_case()) {
      case site::SiteAction::kCamera:
        if (auto why = sync::viewProblem(a.camera()))
          fail(path, field + (why->on_up ? ".camera.up" : ".camera"), why->what);
        break;
      case site::SiteAction::kStroke: {
        const site::StrokeAction& st = a.stroke();
        if (st.pixels_size() % 2 != 0 || st.world_size() % 3 != 0)
          fail(path, field + ".stroke", "pixels are x y pairs, world points x y z triples");
        if ((st.pixels_size() > 0) == (st.world_size() > 0))
          fail(path, field + ".stroke", "needs pixels or world points (one of them)");
        const int n = st.pixels_size() / 2 + st.world_size() / 3;
        if (n < 2 || n > kMaxStrokePoints)
          fail(path, field + ".stroke", "needs 2.." + std::to_string(kMaxStrokePoints) + " points");
        for (float v : st.pixels())
          if (!std::isfinite(v)) fail(path, field + ".stroke.pixels", "numbers must be finite");
        for (double v : st.world())
          if (!std::isfinite(v) || std::abs(v) > kMaxCoordinate)
            fail(path, field + ".stroke.world", "numbers must be finite, within 1e8 m");
        for (float v : {st.color().r(), st.color().g(), st.color().b()})
          if (!(v >= 0 && v <= 1)) fail(path, field + ".stroke.color", "components in [0, 1]");
        if (!(st.width() >= 0 && st.width() <= 64))
          fail(path, field + ".stroke.width", "must be in [0, 64] pixels");
        break;
      }
      case site::SiteAction::kNote: {
        const site::NoteAction& n = a.note();
        if (n.pixel_size() != 0 && n.pixel_size() != 2)
          fail(path, field + ".note.pixel", "x y, or none");
        for (float v : n.pixel())
          if (!std::isfinite(v)) fail(path, field + ".note.pixel", "numbers must be finite");
        if (n.note().edit_case() == site::SiteNote::EDIT_NOT_SET)
          fail(path, field + ".note.note", "names no edit (add, update, remove, layer, open)");
        if (n.note().has_add() && n.note().add().place() == 0 && n.pixel_size() == 0 &&
            n.note().add().position_size() != 3)
          fail(path, field + ".note", "a new place needs a pixel or a position");
        break;
      }
      case site::SiteAction::kMeasure: {
        const site::MeasureAction& me = a.measure();
        if (!scene::MeasurementPayload::Type_IsValid(me.type()))
          fail(path, field + ".measure.type", "unknown type");
        if (me.pixels_size() % 2 != 0 || me.pixels_size() / 2 > kMaxMeasurePoints)
          fail(path, field + ".measure.pixels",
               "x y pairs, at most " + std::to_string(kMaxMeasurePoints));
        for (float v : me.pixels())
          if (!std::isfinite(v)) fail(path, field + ".measure.pixels", "numbers must be finite");
        break;
      }
      case site::SiteAction::kLasso: {
        const site::LassoAction& l = a.lasso();
        if (l.pixels_size() % 2 != 0 || l.pixels_size() < 6 ||
            l.pixels_size() > 2 * kMaxLassoPoints)
          fail(path, field + ".lasso.pixels",
               "3.." + std::to_string(kMaxLassoPoints) + " x y pairs");
        for (float v : l.pixels())
          if (!std::isfinite(v)) fail(path, field + ".lasso.pixels", "numbers must be finite");
        break;
      }
      case site::SiteAction::kSnap: {
        const site::SnapAction& sn = a.snap();
        const bool heavy = sn.heavy_width() > 0.0f;
        if (!(sn.heavy_width() >= 0.0f && sn.heavy_width() <= kMaxHeavyStrokeWidth))
          fail(path, field + ".snap.heavy_width",
               "0 or up to " + std::to_string(int(kMaxHeavyStrokeWidth)) + " pixels");
        for (const auto& [px, name, least] :
             {std::tuple{&sn.foreground(), ".snap.foreground", heavy ? 3 : 1},
              {&sn.background(), ".snap.background", heavy ? 0 : 1}}) {
          const int most = heavy && least == 0 ? 0 : kMaxSnapStrokePoints;
          if (px->size() % 2 != 0 || px->size() < 2 * least || px->size() > 2 * most)
            fail(path, field + name,
                 std::to_string(least) + ".." + std::to_string(most) + " x y pairs");
          for (float v : *px)
            if (!std::isfinite(v)) fail(path, field + name, "numbers must be finite");
        }
        break;
      }
      case site::SiteAction::kShading: {  // as the master checks the message it becomes
        site::ToMaster m;
        *m.mutable_shading() = a.shading();
        if (auto why = checkToMaster(m)) fail(path, field, *why);
        break;
      }
      case site::SiteAction::kHead: {
        site::ToMaster m;
        *m.mutable_head() = a.head();
        if (auto why = checkToMaster(m)) fail(path, field, *why);
        break;
      }
      case site::SiteAction::kScreenshot:
        if (a.screenshot().empty() || a.screenshot().find('/') != std::string::npos)
          fail(path, field + ".screenshot", "a file name in the output folder");
        break;
      case site::SiteAction::ACTION_NOT_SET:
        fail(path, field, "names no action");
      default:
        break;
    }
  }
  return s;
}

}  // namespace tessera::collab
