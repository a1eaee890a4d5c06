// What a site asks of the master: notes placed under a pixel, measurements, lasso and snap
// selections, strokes placed on the model, each checked as the master will check it; and the
// script's actions.
#include "site_session_impl.h"

namespace tessera::collab {

std::optional<SiteSession::Impl::Surface> SiteSession::Impl::surfaceAt(const std::vector<uint32_t>& depth,
                                        const render::ViewSetup& v, const glm::dmat4& unproject,
                                        glm::dvec2 pixel) {
  if (!(pixel.x >= 0 && pixel.y >= 0 && pixel.x < v.width && pixel.y < v.height))
    return std::nullopt;
  const uint32_t x = uint32_t(pixel.x), y = uint32_t(pixel.y);
  std::vector<uint32_t> around;
  for (uint32_t yy = y > 0 ? y - 1 : 0; yy <= std::min(y + 1, v.height - 1); ++yy)
    for (uint32_t xx = x > 0 ? x - 1 : 0; xx <= std::min(x + 1, v.width - 1); ++xx) {
      const uint32_t dd = depth[size_t(v.height - 1 - yy) * v.width + xx];
      if (dd != render::kEmptyDepth) around.push_back(dd);
    }
  if (around.size() < 5) return std::nullopt;
  std::nth_element(around.begin(), around.begin() + around.size() / 2, around.end());
  const uint32_t d = around[around.size() / 2];  // float bits order like the depths
  float z = 1.0f;
  std::memcpy(&z, &d, 4);
  const glm::dvec4 ndc((x + 0.5) / v.width * 2.0 - 1.0, 1.0 - (y + 0.5) / v.height * 2.0,
                       2.0 * z - 1.0, 1.0);
  const glm::dvec4 w = unproject * ndc;
  return Surface{glm::dvec3(w) / w.w, x, y, z};
}

void SiteSession::Impl::note(const site::NoteAction& a, const config::Camera& c) {
  site::ToMaster m;
  site::SiteNote& n = *m.mutable_note() = a.note();
  const uint64_t index = ++notes_sent;
  if (n.request() == 0) n.set_request(index);
  if (n.has_add() && n.add().place() == 0 && a.pixel_size() == 2) {
    if (!renderer) {
      say("note " + std::to_string(n.request()) + " skipped: pixels need rendering");
      return;
    }
    want_pick = true;
    (void)settled(c);
    want_pick = false;
    const render::ViewSetup v = view(c);
    const glm::dvec2 pixel(a.pixel(0), a.pixel(1));
    const std::optional<Surface> at =
        surfaceAt(renderer->readDepth(), v, glm::inverse(v.projection * v.view), pixel);
    if (!at) {
      say("note " + std::to_string(n.request()) + " skipped: no surface under its pixel");
      return;
    }
    site::NoteAdd& add = *n.mutable_add();
    add.clear_position();
    for (int k = 0; k < 3; ++k) add.add_position(at->world[k]);
    if (add.model().empty()) {
      const auto hit = renderer->pick(at->x, at->y);
      const std::vector<uint32_t>& nodes = models.instanceNodes();
      if (hit && hit->model < nodes.size() && graph.contains(nodes[hit->model]))
        add.set_model(graph.node(nodes[hit->model]).name());
    }
  }
  if (n.has_add() && n.add().radius() > 0.0 && n.add().view_size() == 0) {
    for (const config::Vec3& p : {c.eye(), c.target(), c.up()})
      for (double k : {p.x(), p.y(), p.z()}) n.mutable_add()->add_view(k);
    n.mutable_add()->add_view(script.fovy_deg());
  }
  if (const auto why = checkToMaster(m)) {
    say("note " + std::to_string(n.request()) + " not sent: " + *why);
    return;
  }
  say("note " + std::to_string(n.request()) + " sent");
  client->send(m);
}

void SiteSession::Impl::measure(const site::MeasureAction& a, const config::Camera& c) {
  const uint64_t index = ++measures_sent;
  const std::string what = "measurement " + std::to_string(index);
  if (!renderer) {
    say(what + " skipped: picking needs rendering");
    return;
  }
  want_pick = true;
  (void)settled(c);
  want_pick = false;
  const render::ViewSetup v = view(c);
  interact::MeasureTool tool;
  tool.setMode(
      a.type() == scene::MeasurementPayload::DISTANCE   ? interact::MeasureTool::Mode::kDistance
      : a.type() == scene::MeasurementPayload::ANGLE    ? interact::MeasureTool::Mode::kAngle
      : a.type() == scene::MeasurementPayload::POLYLINE ? interact::MeasureTool::Mode::kPath
                                                        : interact::MeasureTool::Mode::kArea);
  std::optional<interact::MeasureTool::Finished> done;
  try {
    for (int i = 0; i + 1 < a.pixels_size() && !done; i += 2) {
      const auto at =
          interact::pickUnderPixel(*renderer, instances, v, {a.pixels(i), a.pixels(i + 1)});
      if (!at) {
        say(what + " skipped: no surface under pixel " + std::to_string(int(a.pixels(i))) + "," +
            std::to_string(int(a.pixels(i + 1))));
        return;
      }
      done = tool.addPoint(*at, instances);
    }
    if (!done) done = tool.complete(instances);
  } catch (const std::exception& e) {  // annotate::MeasureError, a store that cannot be read
    say(what + " failed: " + e.what());
    return;
  }
  if (!done) {
    say(what + " skipped: too few points");
    return;
  }
  site::ToMaster m;
  site::SiteMeasure& me = *m.mutable_measure();
  me.set_type(done->type);
  for (const glm::dvec3& p : done->points)
    for (int k = 0; k < 3; ++k) me.add_points(p[k]);
  me.set_value(done->measured.value);
  me.set_uncertainty(done->measured.uncertainty);
  if (const auto why = checkToMaster(m)) {
    say(what + " not sent: " + *why);
    return;
  }
  say(what + " sent: " + tool.lastLabel());
  client->send(m);
}

uint32_t SiteSession::Impl::modelFor(const std::string& name, const std::string& what) {
  if (!name.empty()) {
    if (const auto id = graph.findByName(name);
        id && graph.node(*id).kind() == scene::SceneNode::MODEL)
      return *id;
  } else {
    for (uint32_t id : graph.ids())
      if (graph.node(id).kind() == scene::SceneNode::MODEL) return id;
  }
  say(what + " skipped: the scene has no model " +
      (name.empty() ? std::string() : "named \"" + name + "\""));
  return 0;
}

template <class M>
void SiteSession::Impl::setSentView(M& s, uint32_t model, const config::Camera& c) {
  const render::ViewSetup v = view(c);
  s.set_model(model);
  for (int k = 0; k < 16; ++k) {
    s.add_view(v.view[k / 4][k % 4]);
    s.add_projection(v.projection[k / 4][k % 4]);
  }
  s.set_width(v.width);
  s.set_height(v.height);
}

void SiteSession::Impl::sendChecked(const site::ToMaster& m, const std::string& what) {
  if (const auto why = checkToMaster(m)) {
    say(what + " not sent: " + *why);
    return;
  }
  say(what + " sent");
  client->send(m);
}

void SiteSession::Impl::lasso(const site::LassoAction& a, const config::Camera& c) {
  const std::string what = "lasso " + std::to_string(++lassos_sent);
  const uint32_t model = modelFor(a.model(), what);
  if (!model) return;
  site::ToMaster m;
  site::SiteSelect& s = *m.mutable_select();
  setSentView(s, model, c);
  for (float p : a.pixels()) s.add_lasso(p);
  sendChecked(m, what);
}

void SiteSession::Impl::snap(const site::SnapAction& a, const config::Camera& c) {
  const std::string what = "snap " + std::to_string(++snaps_sent);
  const uint32_t model = modelFor(a.model(), what);
  if (!model) return;
  site::ToMaster m;
  site::SiteSnap& s = *m.mutable_snap();
  setSentView(s, model, c);
  for (float p : a.foreground()) s.add_foreground(p);
  for (float p : a.background()) s.add_background(p);
  s.set_heavy_width(a.heavy_width());
  sendChecked(m, what);
}

void SiteSession::Impl::stroke(const site::StrokeAction& a, const config::Camera& c) {
  site::ToMaster m;
  site::SiteStroke& s = *m.mutable_stroke();
  *s.mutable_color() = a.color();
  s.set_width(a.width() > 0 ? a.width() : 4.0f);
  const uint64_t index = ++strokes;
  if (a.world_size() > 0) {
    for (double v : a.world()) s.add_points(v);
  } else {
    if (!renderer) {
      say("stroke " + std::to_string(index) + " skipped: pixels need rendering (--no-render)");
      return;
    }
    (void)settled(c);
    const render::ViewSetup v = view(c);
    const std::vector<uint32_t> depth = renderer->readDepth();
    const glm::dmat4 unproject = glm::inverse(v.projection * v.view);
    // The pixels the stroke passes, at most 2 px apart (as a mouse drag gives them), so the
    // polyline follows the surface between the samples given instead of cutting chords under
    // it.
    std::vector<glm::dvec2> path;
    for (int i = 0; i + 1 < a.pixels_size(); i += 2) {
      const glm::dvec2 p(a.pixels(i), a.pixels(i + 1));
      if (!path.empty()) {
        const int steps = int(std::min(4096.0, std::ceil(glm::length(p - path.back()) / 2.0)));
        const glm::dvec2 from = path.back();
        for (int k = 1; k < steps; ++k) path.push_back(glm::mix(from, p, double(k) / steps));
      }
      path.push_back(p);
    }
    if (path.size() > size_t(kMaxStrokePoints)) path.resize(size_t(kMaxStrokePoints));
    for (const glm::dvec2& pixel : path) {
      const std::optional<Surface> at = surfaceAt(depth, v, unproject, pixel);
      if (!at) continue;  // no surface under it: skipped
      const glm::dvec3 p = at->world;
      s.add_points(p.x);
      s.add_points(p.y);
      s.add_points(p.z);
      if (strokes_csv) {
        char line[256];
        std::snprintf(line, sizeof line, "%llu,%u,%u,%.17g,%.17g,%.17g,%.9g\n",
                      (unsigned long long)index, at->x, at->y, p.x, p.y, p.z, double(at->z));
        strokes_csv << line;
      }
    }
    strokes_csv.flush();
  }
  if (s.points_size() < 6) {
    say("stroke " + std::to_string(index) +
        " skipped: fewer than 2 of its pixels are on the model");
    return;
  }
  say("stroke " + std::to_string(index) + ": " + std::to_string(s.points_size() / 3) +
      " points placed on the model");
  client->send(m);
}

bool SiteSession::Impl::act(const site::SiteAction& a, double now) {
  site::ToMaster m;
  switch (a.action_case()) {
    case site::SiteAction::kCamera:
      own = asSent(a.camera());
      following = false;
      break;
    case site::SiteAction::kStroke:
      stroke(a.stroke(), asSent(camera(now)));
      break;
    case site::SiteAction::kNote:
      note(a.note(), asSent(camera(now)));
      break;
    case site::SiteAction::kMeasure:
      measure(a.measure(), asSent(camera(now)));
      break;
    case site::SiteAction::kLasso:
      lasso(a.lasso(), asSent(camera(now)));
      break;
    case site::SiteAction::kSnap:
      snap(a.snap(), asSent(camera(now)));
      break;
    case site::SiteAction::kShading:
      *m.mutable_shading() = a.shading();
      simple(m);
      break;
    case site::SiteAction::kHead:
      *m.mutable_head() = a.head();
      simple(m);
      break;
    case site::SiteAction::kUndo:
      m.mutable_undo();
      simple(m);
      break;
    case site::SiteAction::kClear:
      m.mutable_clear();
      simple(m);
      break;
    case site::SiteAction::kLead:
      m.mutable_lead();
      simple(m);
      following = false;
      say("leads the view");
      break;
    case site::SiteAction::kRelease:
      m.mutable_release();
      simple(m);
      break;
    case site::SiteAction::kFollow:
      following = true;
      follow_from = own;
      follow_start = now;
      say("follows the view");
      break;
    case site::SiteAction::kScreenshot: {
      if (!renderer) break;
      const std::string path = (fs::path(opt.out_dir) / a.screenshot()).string();
      const config::Camera c = asSent(camera(now));
      render::writePng(path, settled(c));
      char cam[320];
      std::snprintf(cam, sizeof cam, "eye=%.9g,%.9g,%.9g;target=%.9g,%.9g,%.9g;up=%.9g,%.9g,%.9g",
                    c.eye().x(), c.eye().y(), c.eye().z(), c.target().x(), c.target().y(),
                    c.target().z(), c.up().x(), c.up().y(), c.up().z());
      say("wrote " + path + " (scene version " + std::to_string(graph.version()) + "); camera " +
          cam);
      break;
    }
    case site::SiteAction::kBye:
      return false;
    default:
      break;
  }
  return true;
}

}  // namespace tessera::collab
