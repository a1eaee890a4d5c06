#include "console.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/interact/point_pick.h>
#include <tessera/interact/select_tool.h>
#include <tessera/interact/surface_pick.h>
#include <tessera/render/gl_context.h>
#include <tessera/sync/scene_edits.h>

#include <tessera/sync/vec3.h>

namespace tessera::master {

namespace {

/// The robust lasso's stroke width when the console snaps with a foreground stroke only, pixels.
constexpr double kHeavyStrokePx = 16.0;
/// How near the cursor a note must be for O to open it, pixels.
constexpr double kNoteReachPx = 24.0;

/// The console's own name as a participant (sketch layer, author, leader).
constexpr const char* kConsole = "console";

std::vector<sync::SceneGraph::NodeId> modelIds(const sync::SceneGraph& graph) {
  std::vector<sync::SceneGraph::NodeId> ids;
  for (auto id : graph.ids())
    if (graph.node(id).kind() == scene::SceneNode::MODEL) ids.push_back(id);
  return ids;
}

}  // namespace

Console::Console(const config::WallConfig& wall, uint32_t max_width, float splat_scale)
    : mWall(wall), mSplatScale(splat_scale) {
  config::Camera any;
  any.mutable_eye()->set_z(1.0);
  any.mutable_up()->set_y(1.0);
  const render::ViewSetup whole = render::wholeWallView(mWall, any);
  const double s = std::min(1.0, double(max_width) / whole.width);
  mWidth = std::max(1u, uint32_t(std::lround(whole.width * s)));
  mHeight = std::max(1u, uint32_t(std::lround(whole.height * s)));
  mWindow = render::Window::open(mWidth, mHeight, "tessera-master: " + mWall.name());
  mWindow->enableUi();  // the panels (console_panels.cpp)
  mRenderer = std::make_unique<render::ViewRenderer>(mWidth, mHeight);
  mVideos = std::make_unique<render::VideoTextures>();
  // Screen-pinned insets: the console shows the whole wall.
  render::SceneOverlayOptions so;
  so.screen_wall = so.screen_view = render::wallExtent(mWall);
  so.view_px = glm::dvec2(mWidth, mHeight);
  so.video_texture = [this](uint32_t source) { return mVideos->texture(source); };
  mSceneOverlay.setOptions(so);
}

Console::~Console() {
  mVideos.reset();  // while the window's context is still current
  mRenderer.reset();
}

void Console::video(const sync::SceneGraph& graph,
                    const google::protobuf::RepeatedPtrField<std::string>& packets) {
  if (packets.empty()) return;
  // The insets the console shows, from the camera of the frame just taken.
  mVideos->setShown(
      render::shownVideoSources(graph, view(graph.camera()), mSceneOverlay.options()));
  for (const std::string& p : packets)
    (void)mVideos->receive({reinterpret_cast<const uint8_t*>(p.data()), p.size()});
  if (mVideos->upload()) mSceneOverlay.invalidate();
}

double Console::contourInterval() const {
  // A round interval (1, 2 or 5 times a power of ten) near a 25th of the largest model's extent.
  double extent = 0.0;
  for (const render::ModelInstance& m : mInstances) {
    if (m.store) {
      const lod::StoreSummary& s = m.store->summary();
      extent = std::max(extent, glm::length(s.bbox_max - s.bbox_min));
    }
  }
  return interact::roundContourInterval(extent);
}

render::ViewSetup Console::view(const config::Camera& camera) const {
  // The whole wall's frustum at a lower pixel count: the same picture, smaller.
  render::ViewSetup v = render::wholeWallView(mWall, camera);
  v.width = mWidth;
  v.height = mHeight;
  return v;
}

void Console::draw(const sync::SceneGraph& graph, const sync::SceneChanges& changes) {
  render::ChunkStreamer* streamers[] = {&mRenderer->streamer()};
  mInstances = mModels.update(graph, changes, streamers);
  mLastView = view(graph.camera());
  render::RenderOptions options = render::SceneDrawList::options(graph, mSplatScale);
  options.pick_ids = true;  // the navigation's picks read the frame's ids
  const render::Overlay marks = overlay(mSceneOverlay.update(graph, changes));
  options.highlights = mSceneOverlay.highlights();
  mRenderer->draw(mInstances, mLastView, options, nullptr, &marks);
  mWindow->present(mRenderer->imageBuffer(), mWidth, mHeight);
}

void Console::save(const std::string& path) const {
  render::Image shown;
  shown.rgba = mWindow->readFramebuffer(shown.width, shown.height);
  render::writePng(path, shown);
  std::printf("tessera-master: wrote %s (%ux%u, the console)\n", path.c_str(), shown.width,
              shown.height);
}

void Console::say(const std::string& text) {
  std::printf("tessera-master: console: %s\n", text.c_str());
  std::fflush(stdout);
  mStatus = text;
}

void Console::measured(const std::function<std::optional<sync::SceneGraph::NodeId>()>& make) {
  try {
    if (auto id = make()) {
      mMeasurements.push_back(*id);
      say(std::string(interact::MeasureTool::name(mTool.mode())) + " " + mTool.lastLabel());
    }
  } catch (const std::exception& e) {
    say(std::string("no measurement: ") + e.what());
  }
}

void Console::toolsChanged() {
  if (mTool.mode() != mTools.measureMode()) mTool.setMode(mTools.measureMode());
  if (!on(Tool::kLasso)) mLasso.clear();
  if (!on(Tool::kSnap)) {
    mSnapFg.clear();
    mSnapBg.clear();
  }
}

void Console::back(sync::SceneGraph& graph) {
  if (on(Tool::kSnap)) {
    if (!mSnapFg.empty() || !mSnapBg.empty()) {
      mSnapFg.clear();
      mSnapBg.clear();
      return;
    }
    sync::SceneGraph::NodeId newest = 0;  // the newest selection the console snapped
    for (auto id : graph.ids())
      if (graph.node(id).kind() == scene::SceneNode::SELECTION &&
          graph.node(id).author() == kConsole)
        newest = std::max(newest, id);
    if (newest) graph.remove(newest);
  } else if (on(Tool::kLasso)) {
    std::erase_if(mSelections, [&](auto id) { return !graph.contains(id); });
    if (!mSelections.empty()) {
      graph.remove(mSelections.back());
      mSelections.pop_back();
    }
  } else if (!mTool.undoPoint()) {  // no point: the newest measurement
    std::erase_if(mMeasurements, [&](auto id) { return !graph.contains(id); });
    if (!mMeasurements.empty()) {
      graph.remove(mMeasurements.back());
      mMeasurements.pop_back();
    }
  }
}

std::optional<std::pair<sync::SceneGraph::NodeId, size_t>> Console::currentModel(
    const sync::SceneGraph& graph) const {
  const auto models = modelIds(graph);
  if (models.empty()) return std::nullopt;
  const auto node = models[std::min(mSelected, models.size() - 1)];
  const auto& nodes = mModels.instanceNodes();
  const auto at = std::find(nodes.begin(), nodes.end(), node);
  if (at == nodes.end() || size_t(at - nodes.begin()) >= mInstances.size()) return std::nullopt;
  return std::pair{node, size_t(at - nodes.begin())};
}

void Console::snap(const sync::SceneGraph& graph) {
  const auto model = currentModel(graph);
  if (!model) return say("snap: the current model is not drawn");
  if (mSnapFg.empty()) return say("snap: first stroke what to select (left drag)");
  SelectionRequest r;
  r.model = model->first;
  r.view = mLastView;
  r.pixels = mSnapFg;
  if (!mSnapBg.empty()) {
    r.kind = SelectionRequest::Kind::kSnap;
    r.background = mSnapBg;
  } else {
    r.kind = SelectionRequest::Kind::kRobustLasso;
    r.heavy_width = kHeavyStrokePx;
    if (r.pixels.size() < 3)
      return say("snap: stroke what not to select (right drag), or around the region");
  }
  if (!mSnaps)
    mSnaps = std::make_unique<SelectionWorker>([this](const std::string& line) {
      const std::string own = std::string(kConsole) + ": ";
      say(line.rfind(own, 0) == 0 ? line.substr(own.size()) : line);
    });
  if (mSnaps->request(graph, 0, kConsole, std::move(r)))
    say(std::string("snap: selecting on model ") + std::to_string(model->first) + " (" +
        (mSnapBg.empty() ? "robust lasso" : "lazy snapping") + ")");
  mSnapFg.clear();
  mSnapBg.clear();
}

render::Overlay Console::overlay(const render::Overlay& scene) const {
  // The right-hand bar of the navigation, lightened (a quarter white over the scene), and a ring
  // where the target is, after the scene's own (so on top of them).
  render::Overlay o = scene;
  const float bar_x = float(mWidth * (1.0 - interact::OneButtonNavigation::kBarFraction));
  o.rects.push_back({{bar_x, 0.0f}, {float(mWidth), float(mHeight)}, {255, 255, 255, 64}});
  // The lasso being drawn, and the unfinished measurement's points and lines, on top.
  auto stroke = [&](const std::vector<glm::dvec2>& px, glm::u8vec4 color) {
    for (size_t i = 1; i < px.size(); ++i)
      o.rects.push_back({glm::vec2(px[i]) - 1.5f, glm::vec2(px[i]) + 1.5f, color});
  };
  stroke(mLasso, {255, 190, 0, 230});
  stroke(mSnapFg, {60, 230, 90, 230});  // what to select
  stroke(mSnapBg, {240, 60, 60, 230});  // what not to
  const auto& pts = mTool.points();
  for (size_t i = 0; i < pts.size(); ++i) {
    o.points.push_back({pts[i].point.world, {90, 230, 255, 255}, 7.0f, 1.5f});
    if (i > 0)
      o.lines.push_back({pts[i - 1].point.world, pts[i].point.world, {90, 230, 255, 200}, 1.5f});
  }
  if (const auto& target = mNavigation.target()) {
    render::OverlayPoint ring;
    ring.at = *target;
    ring.color = {255, 200, 40, 255};
    ring.size_px = float(interact::OneButtonNavigation::kTargetRadiusPx);
    ring.ring_px = 2.0f;
    o.points.push_back(ring);
  }
  return o;
}

bool Console::handleInput(sync::SceneGraph& graph) {
  render::WindowInput in = mWindow->poll();
  if (mWindow->closing()) return false;
  // The panels first: what they take (the mouse over them, the keyboard in a text field) the
  // view does not also get.
  mWindow->beginUi();
  panels(graph);
  mWindow->endUi();
  mWindow->withoutWhatUiTook(in, mRightHeld);  // a sketch begun on the model goes on
  const auto now = std::chrono::steady_clock::now();
  const double dt = std::chrono::duration<double>(now - mLastInput).count();
  mLastInput = now;

  glm::dvec2 scale;
  interact::PointerInput p = interact::pointerInView(in, glm::dvec2(mWidth, mHeight), scale);
  const glm::dmat4 clip_from_world = mLastView.projection * mLastView.view;
  const glm::dmat4 world_from_clip = glm::inverse(clip_from_world);
  const double fovy = 2.0 * std::atan(1.0 / mLastView.projection[1][1]);
  auto ray = [&](glm::dvec2 px) {
    const double nx = px.x / mWidth * 2.0 - 1.0, ny = 1.0 - px.y / mHeight * 2.0;
    glm::dvec4 a = world_from_clip * glm::dvec4(nx, ny, -1.0, 1.0);
    glm::dvec4 b = world_from_clip * glm::dvec4(nx, ny, 1.0, 1.0);
    const glm::dvec3 from = glm::dvec3(a) / a.w, to = glm::dvec3(b) / b.w;
    return std::pair{from, glm::normalize(to - from)};
  };
  interact::PickOptions pick_options;
  pick_options.pixel_angle = fovy / mHeight;
  auto pick = [&](glm::dvec2 px) -> std::optional<glm::dvec3> {
    // The frame's pick ids name the point under the pixel; a see-through frame has none: then
    // a ray through the points (point_pick.h).
    if (px.x >= 0 && px.y >= 0 && px.x < mWidth && px.y < mHeight) {
      if (auto hit = mRenderer->pick(uint32_t(px.x), uint32_t(px.y))) return hit->world;
    }
    const auto [from, dir] = ray(px);
    return interact::pickPoint(mInstances, from, dir, pick_options);
  };
  // Measuring and placing notes: a click picks the surface under the pixel in the
  // full-resolution data of the model the frame's pick ids name (surface_pick.h), not the
  // coarse cut on screen.
  auto surfaceAt = [&](glm::dvec2 px) {
    return interact::pickUnderPixel(*mRenderer, mInstances, mLastView, px);
  };
  auto measureAt = [&](glm::dvec2 px) {
    if (const auto at = surfaceAt(px))
      measured([&] { return mTool.add(*at, graph, mInstances, kConsole); });
  };
  // "Add note": the place is the point clicked; the form then asks for the rest, and a hot
  // spot's view is the console's camera as it is now.
  auto placeNoteAt = [&](glm::dvec2 px) {
    const auto at = surfaceAt(px);
    const auto& nodes = mModels.instanceNodes();
    if (!at || at->model >= nodes.size() || !graph.contains(nodes[at->model])) {
      say("no model under the click: click on the model to place the note");
      return;
    }
    NoteFormState form;
    form.draft.position = at->point.world;
    form.draft.model = graph.node(nodes[at->model]).name();
    const config::Camera camera = graph.camera();
    form.draft.view.eye = sync::vec(camera.eye());
    form.draft.view.target = sync::vec(camera.target());
    form.draft.view.up = sync::vec(camera.up());
    form.draft.view.fovy_deg = glm::degrees(fovy);
    mNoteForm = form;
    only(Tool::kNone);
    char line[256];
    std::snprintf(line, sizeof line, "note at %.4f %.4f %.4f on model %s: its title and text?",
                  at->point.world.x, at->point.world.y, at->point.world.z,
                  form.draft.model.c_str());
    say(line);
  };
  if (mSnaps) mSnaps->collect(graph);  // snaps finished since: SELECTION nodes
  auto record = [&](std::vector<glm::dvec2>& stroke, glm::dvec2 q) {
    if (stroke.empty() || glm::length(q - stroke.back()) >= 2.0) stroke.push_back(q);
  };
  if (on(Tool::kSnap)) {
    // Left drag: what to select; right drag: what not to (not a sketch). A new drag replaces
    // its stroke. Every cursor position the window reported, as the lasso.
    if (in.left_pressed) mSnapFg.clear();
    for (const glm::dvec2& q : in.dragOf(render::WindowInput::kLeftHeld)) record(mSnapFg, q * scale);
    if (in.left) record(mSnapFg, p.cursor);
    if (in.right_pressed) mSnapBg.clear();
    for (const glm::dvec2& q : in.dragOf(render::WindowInput::kRightHeld)) record(mSnapBg, q * scale);
    if (in.right) record(mSnapBg, p.cursor);
    in.right = false;
    p.down = p.pressed = p.released = false;
  } else if (on(Tool::kNote)) {  // as measuring: a click places the note; the wheel still moves the view
    if (in.left_pressed) mPressAt = p.cursor;
    if (in.left_released && glm::length(p.cursor - mPressAt) <= 4.0) placeNoteAt(p.cursor);
    p.down = p.pressed = p.released = false;
  } else if (on(Tool::kLasso)) {
    // A left drag draws the lasso (every cursor position the window reported, so a fast drag
    // over slow frames keeps its shape); letting go selects what of the current model it
    // encloses.
    for (const glm::dvec2& q : in.dragOf(render::WindowInput::kLeftHeld)) record(mLasso, q * scale);
    if (in.left) record(mLasso, p.cursor);
    if (!in.left && !mLasso.empty()) {
      const auto model = currentModel(graph);
      if (mLasso.size() >= 3 && model) {
        const auto [node, index] = *model;
        try {
          const interact::LassoSelectResult r =
              interact::selectWithLasso(graph, mInstances[index], node, mLastView, mLasso, kConsole);
          if (r.node) mSelections.push_back(r.node);
          std::printf("tessera-master: console: lasso on model %u: %llu %s selected%s\n", node,
                      (unsigned long long)r.count, mInstances[index].mesh ? "triangles" : "points",
                      r.corrupt ? " (some chunks could not be read)" : "");
        } catch (const std::exception& e) {  // a selection over 16 MiB, ...
          std::printf("tessera-master: console: no selection: %s\n", e.what());
        }
        std::fflush(stdout);
      }
      mLasso.clear();
    }
    p.down = p.pressed = p.released = false;
  } else if (on(Tool::kMeasure)) {
    // Clicks measure; the wheel still moves the view.
    if (in.left_pressed) mPressAt = p.cursor;
    if (in.left_released && glm::length(p.cursor - mPressAt) <= 4.0) measureAt(p.cursor);
    p.down = p.pressed = p.released = false;
  }
  auto project = [&](const glm::dvec3& w) -> std::optional<glm::dvec2> {
    const glm::dvec4 c = clip_from_world * glm::dvec4(w, 1.0);
    if (c.w <= 0) return std::nullopt;
    return glm::dvec2((c.x / c.w * 0.5 + 0.5) * mWidth, (0.5 - c.y / c.w * 0.5) * mHeight);
  };
  if (p.pressed || p.down || p.released || p.scroll != 0 || mNavigation.flying()) {
    const config::Camera before = graph.camera();
    const config::Camera after = mNavigation.update(before, p, dt, fovy, pick, project);
    if (after.SerializeAsString() != before.SerializeAsString()) graph.setCamera(after);
  }

  // A right-button drag draws a sketch, placed on the model through the frame's depth (the
  // point under each pixel) when the button goes up; pixels without a model are skipped.
  if (in.right) {
    const glm::dvec2 at = p.cursor;
    if (mDrag.empty() || glm::length(at - mDrag.back()) >= 1.0) mDrag.push_back(at);
  } else if (mRightHeld) {
    std::vector<glm::dvec3> points;
    for (const glm::dvec2& px : mDrag) {
      if (points.size() >= 3000) break;
      if (!(px.x >= 0 && px.y >= 0 && px.x < mWidth && px.y < mHeight)) continue;
      if (auto hit = mRenderer->pick(uint32_t(px.x), uint32_t(px.y))) points.push_back(hit->world);
    }
    if (points.size() >= 2) {
      scene::Color pink;  // the console's colour: no site's (collab/site_roster.cpp)
      pink.set_r(0.95f);
      pink.set_g(0.30f);
      pink.set_b(0.75f);
      const auto layer = sync::layerGroup(graph, std::string("sketches/") + kConsole, kConsole);
      mSketches.push_back(sync::addSketch(graph, layer, kConsole, points, pink, 4.0f));
      std::printf("tessera-master: console: sketch of %zu points placed on the model\n",
                  points.size());
      std::fflush(stdout);
    }
    mDrag.clear();
  }
  mRightHeld = in.right;

  const auto models = modelIds(graph);
  using interact::Command;
  for (int key : in.keys) {
    const interact::KeyPress press = interact::commandOf(key);
    std::erase_if(mSketches, [&](auto id) { return !graph.contains(id); });
    switch (press.command) {
      case Command::kLead: {  // the wall's console leads (sites' poses no longer move the view)
        const bool leads = graph.settings().leader() == kConsole;
        graph.setLeader(leads ? "" : kConsole);
        say(leads ? "gave the view back" : "leads the view");
        break;
      }
      case Command::kUndoSketch:
        if (!mSketches.empty()) {
          graph.remove(mSketches.back());
          mSketches.pop_back();
        }
        break;
      case Command::kClearSketches:
        for (auto id : mSketches) graph.remove(id);
        mSketches.clear();
        break;
      case Command::kAddNote:
      case Command::kMeasure:
      case Command::kLasso:
      case Command::kSnap:
        if (press.command == Command::kAddNote && !mAnnotations) {
          say("notes need tessera-master --annotations FILE");
          break;
        }
        say(mTools.press(press.command));
        toolsChanged();
        break;
      case Command::kEnd:
        if (on(Tool::kSnap))
          snap(graph);
        else
          measured([&] { return mTool.finish(graph, mInstances, kConsole); });
        break;
      case Command::kBack:
        back(graph);
        break;
      case Command::kClip:  // a section: a clip plane through the surface under the cursor
        std::erase_if(mClips, [&](auto id) { return !graph.contains(id); });
        if (!mClips.empty()) {
          for (auto id : mClips) graph.remove(id);
          mClips.clear();
          say("clip removed");
        } else if (const auto at = surfaceAt(p.cursor)) {
          mClips.push_back(
              interact::addSectionClip(graph, at->point.world, graph.camera(), kConsole));
          say("clip: everything nearer than the surface under the cursor is cut away (K again "
              "removes it)");
        } else {
          say("clip: no model under the cursor");
        }
        break;
      case Command::kOpenNote:  // the note nearest the cursor, open on the wall or not
        if (!mAnnotations) break;
        if (const auto note = interact::noteNear(graph, mLastView, p.cursor, kNoteReachPx)) {
          const auto& a = graph.node(*note).annotation();
          try {
            mAnnotations->setOpen(graph, int64_t(a.place()), !a.open(), "");
            say(std::string(a.open() ? "closed" : "opened") + " note " +
                std::to_string(a.place()) + " on the wall");
          } catch (const std::exception& e) {
            say(std::string("cannot open the note: ") + e.what());
          }
        }
        break;
      case Command::kModel:
        if (size_t(press.model) < models.size()) mSelected = size_t(press.model);
        break;
      case Command::kOpacityUp:
      case Command::kOpacityDown:
      case Command::kHide: {
        if (models.empty()) break;
        const auto id = models[std::min(mSelected, models.size() - 1)];
        const float opacity = graph.node(id).opacity();
        if (press.command == Command::kOpacityUp)
          graph.setOpacity(id, std::min(1.0f, std::round(opacity * 10.0f + 1.0f) / 10.0f));
        else if (press.command == Command::kOpacityDown)
          graph.setOpacity(id, std::max(0.1f, std::round(opacity * 10.0f - 1.0f) / 10.0f));
        else
          graph.setVisible(id, !graph.node(id).visible());
        break;
      }
      case Command::kShading:
      case Command::kAmbientOcclusion:
      case Command::kRelativeDepth:
      case Command::kContours:  // contour lines: about 25 across the largest model
        if (const auto e = interact::shadingEdit(press.command, graph.settings(), contourInterval()))
          applyShading(graph, *e);
        break;
      default:  // release, follow, picture: a site's
        break;
    }
  }
  char title[256];
  const auto& target = mNavigation.target();
  std::snprintf(title, sizeof title, "tessera-master: %s | model %zu of %zu%s",
                mWall.name().c_str(),
                models.empty() ? 0 : std::min(mSelected, models.size() - 1) + 1, models.size(),
                target ? " | target set (click it to fly there)" : "");
  mWindow->setTitle(title);
  return true;
}

}  // namespace tessera::master
