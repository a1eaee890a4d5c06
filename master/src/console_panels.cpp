// The console's Dear ImGui panels: how they look and which edit each control makes.
// What a note edit does lives in console_notes.h (tested without a window). Every panel is a
// small collapsible window at the edges of the view, clear of its middle and of the
// navigation's bar on the right: Models, Tools and Layers down the left, Notes (the tallest)
// at the right.
#include "console.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <map>

#include <imgui.h>

#include <tessera/interact/wall_view.h>
#include <tessera/render/panel_widgets.h>
#include <tessera/render/scene_overlay.h>
#include <tessera/render/tile_frustum.h>
#include <tessera/render/view_renderer.h>

namespace tessera::master {

namespace {

constexpr const char* kAuthor = "console";  // notes' author in the database
constexpr float kPanelWidth = 250.0f;       // pixels
constexpr ImGuiWindowFlags kPanel = ImGuiWindowFlags_AlwaysAutoResize;
constexpr float kFieldWidth = -64.0f;  // text fields leave this much for their labels

/// A panel at `pos` (pixels from the window's top-left), `width` wide, its height following its
/// content up to `max_height`; false when collapsed (then only End()).
bool beginPanel(const char* title, ImVec2 pos, float width = kPanelWidth,
                float max_height = FLT_MAX) {
  ImGui::SetNextWindowPos(pos, ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowSizeConstraints(ImVec2(width, 0.0f), ImVec2(width, max_height));
  return ImGui::Begin(title, nullptr, kPanel);
}

/// `text` safe as an ImGui format string.
std::string literal(const std::string& text) {
  std::string out;
  for (char c : text) {
    out += c;
    if (c == '%') out += '%';
  }
  return out;
}

/// One row of the layer tree: a name, its visibility, its sublayers, and how to set it.
struct LayerRow {
  std::string name;
  bool visible = true;
  std::function<void(bool)> show;
  std::vector<LayerRow> children;
};

void layerTree(const std::vector<LayerRow>& rows) {
  for (const LayerRow& row : rows) {
    ImGui::PushID(row.name.c_str());
    bool visible = row.visible;
    if (ImGui::Checkbox("##shown", &visible)) row.show(visible);
    ImGui::SameLine();
    const ImGuiTreeNodeFlags flags =
        row.children.empty() ? ImGuiTreeNodeFlags_Leaf | ImGuiTreeNodeFlags_NoTreePushOnOpen
                             : ImGuiTreeNodeFlags_DefaultOpen;
    if (ImGui::TreeNodeEx(row.name.c_str(), flags) && !row.children.empty()) {
      layerTree(row.children);
      ImGui::TreePop();
    }
    ImGui::PopID();
  }
}

/// Text in `color`, wrapped at the panel's width.
void wrapped(const ImVec4& color, const std::string& text) {
  ImGui::PushStyleColor(ImGuiCol_Text, color);
  ImGui::TextWrapped("%s", text.c_str());
  ImGui::PopStyleColor();
}

/// Greyed text wrapped at the panel's width.
void disabledWrapped(const std::string& text) {
  wrapped(ImGui::GetStyleColorVec4(ImGuiCol_TextDisabled), text);
}

}  // namespace

void Console::panels(sync::SceneGraph& graph) {
  modelsPanel(graph);
  toolsPanel(graph);
  layersPanel(graph);
  notesPanel(graph);
  shadingPanel(graph);
  viewPanel(graph);
}

void Console::viewPanel(sync::SceneGraph& graph) {
  // Anchored by its bottom-right corner left of Shading, so it opens upwards.
  ImGui::SetNextWindowCollapsed(true, ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowPos(ImVec2(float(mWidth) - kPanelWidth - 16.0f, float(mHeight) - 8.0f),
                          ImGuiCond_Always, ImVec2(1.0f, 1.0f));
  ImGui::SetNextWindowSizeConstraints(ImVec2(kPanelWidth, 0.0f), ImVec2(kPanelWidth, FLT_MAX));
  if (ImGui::Begin("View", nullptr, kPanel)) {
    // Each control's edit passes the wall's checks (the head in front of every tile, the inset
    // on the wall) as a script's or a site's does; a refused one is said and changes nothing. A
    // slider or field says where it left the view once it is let go of.
    auto refused = [&](const std::optional<std::string>& why) {
      if (why) say("refused: " + *why);
      return why.has_value();
    };
    auto done = [&](const std::string& what) {
      if (ImGui::IsItemDeactivatedAfterEdit()) say(what);
    };
    char line[160];
    // Points a covered pixel the wall's cut holds each opaque model to (0: every level the
    // pixels ask for): coarser and faster to the left, finer to the right. First in the panel, so
    // the controls below keep their places on the screen whether it is there or not.
    float per_pixel = graph.settings().has_points_per_pixel()
                          ? graph.settings().points_per_pixel()
                          : float(render::RenderOptions{}.budget_per_covered_pixel);
    ImGui::SetNextItemWidth(kFieldWidth);
    if (ImGui::SliderFloat("points/px", &per_pixel, 0.0f, 8.0f,
                           per_pixel > 0.0f ? "%.1f" : "every level"))
      graph.setPointsPerPixel(per_pixel = std::clamp(per_pixel, 0.0f, 8.0f));
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("points drawn a pixel a model covers (0: every level, the slowest)");
    if (per_pixel > 0.0f)
      std::snprintf(line, sizeof line, "%.1f points a covered pixel", double(per_pixel));
    else
      std::snprintf(line, sizeof line, "every level the pixels ask for");
    done(line);
    const glm::dvec4 e = render::wallExtent(mWall);
    ImGui::TextUnformatted("Viewer's head (wall frame, m)");
    scene::Head head = interact::currentHead(mWall, graph.settings());
    double eye[3] = {head.eye().x(), head.eye().y(), head.eye().z()};
    ImGui::SetNextItemWidth(kFieldWidth);
    if (ImGui::InputScalarN("eye", ImGuiDataType_Double, eye, 3, nullptr, nullptr, "%.3f")) {
      head.mutable_eye()->set_x(eye[0]);
      head.mutable_eye()->set_y(eye[1]);
      head.mutable_eye()->set_z(eye[2]);
      (void)refused(interact::applyHead(graph, mWall, head));
    }
    const auto head_now = [&] { return interact::currentHead(mWall, graph.settings()); };
    std::snprintf(line, sizeof line, "head at (%.3f, %.3f, %.3f)", head_now().eye().x(),
                  head_now().eye().y(), head_now().eye().z());
    done(line);
    float yaw = float(interact::headYawDegrees(head));
    ImGui::SetNextItemWidth(kFieldWidth);
    if (ImGui::SliderFloat("turn deg", &yaw, -60.0f, 60.0f, "%.0f")) {
      interact::setHeadYaw(head, double(yaw));
      (void)refused(interact::applyHead(graph, mWall, head));
    }
    std::snprintf(line, sizeof line, "head turned %.0f degrees",
                  interact::headYawDegrees(head_now()));
    done(line);
    float separation = float(head.eye_separation() * 1000.0);
    ImGui::SetNextItemWidth(kFieldWidth);
    if (ImGui::SliderFloat("eyes mm", &separation, 40.0f, 80.0f, "%.0f")) {
      head.set_eye_separation(double(separation) / 1000.0);
      (void)refused(interact::applyHead(graph, mWall, head));
    }
    std::snprintf(line, sizeof line, "eyes %.0f mm apart", head_now().eye_separation() * 1000.0);
    done(line);
    const auto insetSaid = [&](int i) {
      const scene::InsetCentre now = interact::currentInset(mWall, graph.settings(), i);
      char at[128];
      std::snprintf(at, sizeof at, " at (%.3f, %.3f)", now.x(), now.y());
      return "inset " + now.name() + at;
    };
    for (int i = 0; i < mWall.insets_size(); ++i) {
      scene::InsetCentre c = interact::currentInset(mWall, graph.settings(), i);
      ImGui::PushID(i);
      bool shown = !c.hidden();
      const std::string label = "Inset " + literal(c.name());
      if (ImGui::Checkbox(label.c_str(), &shown)) {
        c.set_hidden(!shown);
        if (!refused(interact::applyInset(graph, mWall, c)))
          say("inset " + c.name() + (shown ? " shown" : " switched off"));
      }
      const config::Inset& in = mWall.insets(i);
      float x = float(c.x()), y = float(c.y());
      ImGui::SetNextItemWidth(kFieldWidth);
      if (ImGui::SliderFloat("x m", &x, float(e.x + 0.5 * in.width()),
                             float(e.z - 0.5 * in.width()), "%.3f")) {
        c.set_x(std::clamp(double(x), e.x + 0.5 * in.width(), e.z - 0.5 * in.width()));
        (void)refused(interact::applyInset(graph, mWall, c));
      }
      done(insetSaid(i));
      ImGui::SetNextItemWidth(kFieldWidth);
      if (ImGui::SliderFloat("y m", &y, float(e.y + 0.5 * in.height()),
                             float(e.w - 0.5 * in.height()), "%.3f")) {
        c.set_y(std::clamp(double(y), e.y + 0.5 * in.height(), e.w - 0.5 * in.height()));
        (void)refused(interact::applyInset(graph, mWall, c));
      }
      done(insetSaid(i));
      ImGui::PopID();
    }
  }
  ImGui::End();
}

void Console::applyShading(sync::SceneGraph& graph, const interact::SettingsEdit& edit) {
  if (edit.delta.has_shading()) graph.setShading(edit.delta.shading());
  if (edit.delta.has_analysis()) graph.setAnalysis(edit.delta.analysis());
  say(edit.said);
}

void Console::shadingPanel(sync::SceneGraph& graph) {
  // Anchored by its bottom-right corner, so it opens upwards from the window's corner.
  ImGui::SetNextWindowCollapsed(true, ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowPos(ImVec2(float(mWidth) - 8.0f, float(mHeight) - 8.0f), ImGuiCond_Always,
                          ImVec2(1.0f, 1.0f));
  ImGui::SetNextWindowSizeConstraints(ImVec2(kPanelWidth, 0.0f), ImVec2(kPanelWidth, FLT_MAX));
  if (ImGui::Begin("Shading", nullptr, kPanel)) {
    const scene::Settings& s = graph.settings();
    scene::Analysis a = s.analysis();
    bool changed = false;  // the analysis, applied once a control is let go of
    auto key = [&](interact::Command c) {
      if (const auto e = interact::shadingEdit(c, s, contourInterval())) applyShading(graph, *e);
    };
    if (bool edl = s.shading() == scene::SHADING_EDL;
        ImGui::Checkbox("Eye-dome lighting (E)", &edl))
      key(interact::Command::kShading);
    if (bool ao = a.ao_strength() > 0.0f; ImGui::Checkbox("Ambient occlusion (G)", &ao))
      key(interact::Command::kAmbientOcclusion);
    if (a.ao_strength() > 0.0f) {
      float strength = a.ao_strength(), radius = a.has_ao_radius_px() ? a.ao_radius_px() : 32.0f;
      ImGui::SetNextItemWidth(kFieldWidth);
      if (ImGui::SliderFloat("strength", &strength, 0.1f, 4.0f, "%.1f")) {
        a.set_ao_strength(std::clamp(strength, 0.1f, 4.0f));
        changed = true;
      }
      ImGui::SetNextItemWidth(kFieldWidth);
      if (ImGui::SliderFloat("radius px", &radius, 4.0f, 128.0f, "%.0f")) {
        a.set_ao_radius_px(std::clamp(radius, 4.0f, 128.0f));
        a.set_ao_radius(0.0f);
        changed = true;
      }
      if (bool half = !a.has_ao_half_resolution() || a.ao_half_resolution();
          ImGui::Checkbox("half resolution", &half)) {
        a.set_ao_half_resolution(half);
        changed = true;
      }
      ImGui::SameLine();
      if (bool grid = a.ao_grid(); ImGui::Checkbox("grid", &grid)) {
        a.set_ao_grid(grid);
        changed = true;
      }
      if (ImGui::IsItemHovered())
        ImGui::SetTooltip("gather the AO of every view drawn into a multi-view grid");
    }
    {  // points of stores carrying multi-view AO (tessera-lod ao)
      ImGui::TextUnformatted("Stored AO (tessera-lod ao)");
      const scene::Analysis::StoredAo modes[3] = {scene::Analysis::STORED_AO_MODULATE,
                                                  scene::Analysis::STORED_AO_OFF,
                                                  scene::Analysis::STORED_AO_ALONE};
      const char* names[3] = {"x colour", "off", "alone"};
      for (int i = 0; i < 3; ++i) {
        if (i > 0) ImGui::SameLine();
        if (ImGui::RadioButton(names[i], a.stored_ao() == modes[i]) && a.stored_ao() != modes[i]) {
          a.set_stored_ao(modes[i]);
          changed = true;
        }
      }
    }
    const bool relative = a.relative_depth_radius() > 0 || a.relative_depth_radius_m() > 0.0f;
    if (bool rd = relative; ImGui::Checkbox("Relative depth (D)", &rd))
      key(interact::Command::kRelativeDepth);
    if (relative && !(a.relative_depth_radius_m() > 0.0f)) {
      int radius = int(a.relative_depth_radius());
      ImGui::SetNextItemWidth(kFieldWidth);
      if (ImGui::SliderInt("blur px", &radius, 2, 256)) {
        a.set_relative_depth_radius(uint32_t(std::clamp(radius, 2, 256)));
        changed = true;
      }
    }
    if (bool lines = a.contour_interval() > 0.0; ImGui::Checkbox("Contour lines (T)", &lines))
      key(interact::Command::kContours);
    if (a.contour_interval() > 0.0) {
      double interval = a.contour_interval();
      ImGui::SetNextItemWidth(kFieldWidth);
      if (ImGui::InputDouble("every m", &interval, 0.0, 0.0, "%g") && interval > 0.0 &&
          std::isfinite(interval)) {
        a.set_contour_interval(interval);
        changed = true;
      }
      // Of the view depth, or heights along a world axis (a LiDAR scan's vertical: z).
      const auto& ax = a.contour_axis();
      int axis = ax.x() != 0.0 ? 1 : ax.y() != 0.0 ? 2 : ax.z() != 0.0 ? 3 : 0;
      const char* names[4] = {"depth", "x", "y", "z"};
      for (int i = 0; i < 4; ++i) {
        if (i > 0) ImGui::SameLine();
        if (ImGui::RadioButton(names[i], axis == i) && axis != i) {
          if (i == 0) {
            a.clear_contour_axis();
          } else {
            auto& v = *a.mutable_contour_axis();
            v.set_x(i == 1);
            v.set_y(i == 2);
            v.set_z(i == 3);
          }
          changed = true;
        }
      }
    }
    if (changed) {
      graph.setAnalysis(a);
      if (ImGui::IsItemDeactivatedAfterEdit() || !ImGui::IsAnyItemActive())
        say("shading: " + std::string(a.ao_strength() > 0.0f ? "ambient occlusion " : "") +
            (a.relative_depth_radius() > 0 ? "relative depth " : "") +
            (a.contour_interval() > 0.0 ? "contour lines " : "") + "changed");
    }
  }
  ImGui::End();
}

void Console::modelsPanel(sync::SceneGraph& graph) {
  if (beginPanel("Models", ImVec2(8, 8))) {
    size_t index = 0;
    for (auto id : graph.ids()) {
      if (graph.node(id).kind() != scene::SceneNode::MODEL) continue;
      const std::string name = graph.node(id).name();
      bool visible = graph.node(id).visible();
      float opacity = graph.node(id).opacity();
      ImGui::PushID(int(id));
      // The current model (1-9, the lasso's), shown, and its opacity.
      if (ImGui::RadioButton("##current", mSelected == index)) mSelected = index;
      if (ImGui::IsItemHovered()) ImGui::SetTooltip("the current model (keys 1-9, the lasso)");
      ImGui::SameLine();
      if (ImGui::Checkbox("##shown", &visible)) {
        graph.setVisible(id, visible);
        graph.setAuthor(id, "");
        say("model " + name + (visible ? " shown" : " hidden"));
      }
      ImGui::SameLine();
      ImGui::SetNextItemWidth(-FLT_MIN);
      const std::string format = literal(name.empty() ? "model" : name) + " %.2f";
      if (ImGui::SliderFloat("##opacity", &opacity, 0.0f, 1.0f, format.c_str())) {
        graph.setOpacity(id, std::clamp(opacity, 0.0f, 1.0f));
        graph.setAuthor(id, "");
      }
      if (ImGui::IsItemDeactivatedAfterEdit()) {
        char line[64];
        std::snprintf(line, sizeof line, ": opacity %.2f", graph.node(id).opacity());
        say("model " + name + line);
      }
      ImGui::PopID();
      ++index;
    }
    if (index == 0) ImGui::TextDisabled("no models");
  }
  ImGui::End();
}

void Console::toolsPanel(sync::SceneGraph& graph) {
  // At most down to where Layers begins (a long list of measurements scrolls with the wheel).
  if (beginPanel("Tools", ImVec2(8, float(mHeight) * 0.27f), kPanelWidth,
                 float(mHeight) * (0.64f - 0.27f) - 6.0f)) {
    ImGui::TextUnformatted("Measure (M)");
    using Mode = interact::MeasureTool::Mode;
    for (Mode m : {Mode::kOff, Mode::kDistance, Mode::kPath, Mode::kAngle, Mode::kArea}) {
      if (m != Mode::kOff && m != Mode::kAngle) ImGui::SameLine();
      if (ImGui::RadioButton(interact::MeasureTool::name(m), mTool.mode() == m) &&
          mTool.mode() != m) {
        mTools.choose(Tool::kMeasure, m);
        toolsChanged();
        say(std::string("measuring: ") + interact::MeasureTool::name(m));
      }
    }
    if (mTool.mode() == Mode::kPath || mTool.mode() == Mode::kArea) {
      if (ImGui::SmallButton("finish (Enter)"))
        measured([&] { return mTool.finish(graph, mInstances, kAuthor); });
      ImGui::SameLine();
      if (ImGui::SmallButton("drop last point")) (void)mTool.undoPoint();
    }
    if (bool lasso = on(Tool::kLasso); ImGui::Checkbox("Lasso (S)", &lasso)) {
      only(lasso ? Tool::kLasso : Tool::kNone);
      say(std::string("lasso ") + (lasso ? "on" : "off"));
    }
    if (ImGui::IsItemHovered()) ImGui::SetTooltip("drag around a region of the current model");
    ImGui::SameLine();
    if (bool snapping = on(Tool::kSnap); ImGui::Checkbox("Snap (N)", &snapping)) {
      only(snapping ? Tool::kSnap : Tool::kNone);
      say(std::string("snap ") + (snapping ? "on" : "off"));
    }
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip(
          "lazy snapping: a left drag over what to select, a right drag over what "
          "not to, then Enter");
    if (on(Tool::kSnap)) {
      ImGui::TextDisabled("left drag: select, right drag: not");
      if (ImGui::SmallButton("select (Enter)")) snap(graph);
      if (mSnaps && mSnaps->pending() > 0) {
        ImGui::SameLine();
        ImGui::TextUnformatted("selecting...");
      }
    }
    // Everyone's measurements and selections (the console's, sites', the database's).
    std::vector<sync::SceneGraph::NodeId> gone;
    for (auto id : graph.ids()) {
      const auto& n = graph.node(id);
      std::string line;
      if (n.kind() == scene::SceneNode::MEASUREMENT)
        line = n.name() + ": " + render::measurementLabel(n.measurement());
      else if (n.kind() == scene::SceneNode::SELECTION)
        line = n.name() + ": " + std::to_string(n.selection().count()) + " selected";
      else
        continue;
      ImGui::PushID(int(id));
      if (ImGui::SmallButton("x")) gone.push_back(id);
      if (ImGui::IsItemHovered()) ImGui::SetTooltip("delete");
      ImGui::SameLine();
      ImGui::TextUnformatted(line.c_str());
      ImGui::PopID();
    }
    for (auto id : gone) {
      say("removed " + graph.node(id).name());
      graph.remove(id);
    }
  }
  ImGui::End();
}

void Console::layersPanel(sync::SceneGraph& graph) {
  if (beginPanel("Layers", ImVec2(8, float(mHeight) * 0.64f))) {
    std::vector<LayerRow> rows;
    if (mAnnotations) {
      // The database's layers "a/b/c" as a tree: each under its parent path.
      std::vector<annotate::Layer> layers;
      try {
        layers = mAnnotations->db().layers();
      } catch (const annotate::AnnotationError& e) {
        ImGui::TextWrapped("%s", e.what());
      }
      std::map<std::string, std::vector<const annotate::Layer*>>
          under;  // parent path -> its layers
      for (const annotate::Layer& l : layers) {
        const size_t slash = l.path.rfind('/');
        under[slash == std::string::npos ? std::string() : l.path.substr(0, slash)].push_back(&l);
      }
      std::function<std::vector<LayerRow>(const std::string&)> rowsUnder =
          [&](const std::string& parent) {
            std::vector<LayerRow> out;
            for (const annotate::Layer* l : under[parent]) {
              const std::string path = l->path;
              out.push_back({path.substr(path.rfind('/') + 1), l->visible,
                             [this, &graph, path](bool v) {
                               try {
                                 mAnnotations->setLayerVisible(graph, path, v, "");
                                 say("layer " + path + (v ? " shown" : " hidden"));
                               } catch (const annotate::AnnotationError& e) {
                                 say(e.what());
                               }
                             },
                             rowsUnder(path)});
            }
            return out;
          };
      rows = rowsUnder("");
    } else {
      // The scene's GROUP nodes stand for layers.
      std::function<std::vector<LayerRow>(sync::SceneGraph::NodeId)> rowsUnder =
          [&](sync::SceneGraph::NodeId parent) {
            std::vector<LayerRow> out;
            for (auto id : graph.children(parent)) {
              const auto& n = graph.node(id);
              if (n.kind() != scene::SceneNode::GROUP) continue;
              out.push_back({n.name().empty() ? "group " + std::to_string(id) : n.name(),
                             n.visible(),
                             [this, &graph, id](bool v) {
                               graph.setVisible(id, v);
                               graph.setAuthor(id, "");
                               say("layer " + graph.node(id).name() + (v ? " shown" : " hidden"));
                             },
                             rowsUnder(id)});
            }
            return out;
          };
      rows = rowsUnder(sync::SceneGraph::kRoot);
      ImGui::TextWrapped("No --annotations: the scene's groups; notes are not kept.");
    }
    if (rows.empty()) ImGui::TextDisabled("no layers");
    layerTree(rows);
  }
  ImGui::End();
}

void Console::notesPanel(sync::SceneGraph& graph) {
  const float right =
      float(mWidth) * float(1.0 - interact::OneButtonNavigation::kBarFraction) - 8.0f;
  if (beginPanel("Notes", ImVec2(right - kPanelWidth, 8))) {
    if (!mAnnotations) {
      ImGui::TextWrapped("Notes need tessera-master --annotations FILE: they are not kept.");
      ImGui::End();
      return;
    }
    if (on(Tool::kNote)) {
      ImGui::TextWrapped("Click on the model where the note goes.");
      if (ImGui::SmallButton("cancel")) only(Tool::kNone);
    } else if (!mNoteForm && ImGui::Button("Add note")) {
      say(mTools.press(interact::Command::kAddNote));
      toolsChanged();
    }
    if (mNoteForm) noteForm(graph);

    // The notes, or those of the search's items (FTS5, best first).
    ImGui::SetNextItemWidth(-FLT_MIN);
    ImGui::InputTextWithHint("##search", "search: words, \"a phrase\", pre*", mSearch,
                             sizeof mSearch);
    if (mSearchRan != mSearch) {
      mSearchRan = mSearch;
      mHitPlaces.clear();
      mSearchError.clear();
      if (!mSearchRan.empty()) {
        try {
          for (const annotate::SearchHit& hit : mAnnotations->db().search(mSearchRan))
            for (int64_t place : mAnnotations->db().placesOf(hit.item))
              if (std::find(mHitPlaces.begin(), mHitPlaces.end(), place) == mHitPlaces.end())
                mHitPlaces.push_back(place);
        } catch (const annotate::AnnotationError& e) {  // a malformed query says why
          mSearchError = e.what();
          say("search: " + mSearchError);
        }
      }
    }
    if (!mSearchError.empty()) wrapped(ImVec4(1.0f, 0.5f, 0.4f, 1.0f), mSearchError);
    std::vector<sync::SceneGraph::NodeId> listed;
    if (mSearchRan.empty()) {
      for (auto id : graph.ids())
        if (graph.node(id).kind() == scene::SceneNode::ANNOTATION &&
            graph.node(id).annotation().place() != 0)
          listed.push_back(id);
    } else {
      for (int64_t place : mHitPlaces)
        for (auto id : mAnnotations->nodesOf(place))
          if (graph.contains(id)) listed.push_back(id);
    }
    ImGui::BeginChild("notes", ImVec2(0.0f, 90.0f), true);
    for (auto id : listed) {
      const auto& a = graph.node(id).annotation();
      ImGui::PushID(int(id));
      const std::string label = a.text() + "  [" + a.layer() + "]";
      if (ImGui::Selectable(label.c_str(), mShown == id)) {
        mShown = id;
        mEdit.reset();
      }
      ImGui::PopID();
    }
    if (listed.empty()) ImGui::TextDisabled(mSearchRan.empty() ? "no notes yet" : "no match");
    ImGui::EndChild();
    if (mShown && graph.contains(mShown) &&
        graph.node(mShown).kind() == scene::SceneNode::ANNOTATION)
      shownNote(graph);
    if (!mStatus.empty()) disabledWrapped(mStatus);
  }
  ImGui::End();
}

void Console::noteForm(sync::SceneGraph& graph) {
  NoteFormState& f = *mNoteForm;
  ImGui::Separator();
  ImGui::Text("New note on %s", f.draft.model.c_str());
  ImGui::PushItemWidth(kFieldWidth);
  ImGui::InputText("layer", f.layer, sizeof f.layer);
  if (f.focus) {  // typing goes to the title at once
    ImGui::SetKeyboardFocusHere();
    f.focus = false;
  }
  const bool enter =
      ImGui::InputText("title", f.title, sizeof f.title, ImGuiInputTextFlags_EnterReturnsTrue);
  ImGui::InputTextMultiline("text", f.text, sizeof f.text, ImVec2(0.0f, 40.0f));
  ImGui::Checkbox("number", &f.with_number);
  if (f.with_number) {
    ImGui::SetNextItemWidth(90.0f);
    ImGui::InputDouble("##number", &f.number);
    ImGui::SameLine();
    ImGui::SetNextItemWidth(50.0f);
    ImGui::InputText("unit", f.unit, sizeof f.unit);
  }
  ImGui::InputText("link", f.link, sizeof f.link);
  ImGui::InputFloat("radius m", &f.radius, 0.0f, 0.0f, "%.3f");
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("> 0: a hot spot with the current view");
  if (ImGui::Button("Add") || enter) {
    interact::NoteDraft d = f.draft;
    d.layer = f.layer;
    d.title = f.title;
    d.text = f.text;
    if (f.with_number) {
      d.number = f.number;
      d.unit = f.unit;
    }
    d.link = f.link;
    d.radius = std::max(0.0f, f.radius);
    try {
      const auto [item, place] = interact::addNote(*mAnnotations, graph, d, kAuthor);
      say("note " + std::to_string(place) + " added (item " + std::to_string(item) + ", layer " +
          d.layer + "): " + d.title);
      const auto nodes = mAnnotations->nodesOf(place);
      if (!nodes.empty()) mShown = nodes.front();
      mNoteForm.reset();
    } catch (const annotate::AnnotationError& e) {
      say(std::string("note not added: ") + e.what());
    }
  } else {
    ImGui::SameLine();
    if (ImGui::Button("Cancel")) mNoteForm.reset();
  }
  ImGui::PopItemWidth();
}

void Console::shownNote(sync::SceneGraph& graph) {
  const scene::AnnotationPayload a = graph.node(mShown).annotation();  // a copy: edits follow
  ImGui::Separator();
  ImGui::Text("%s %llu, layer %s", a.radius() > 0.0 ? "Hot spot" : "Point",
              (unsigned long long)a.place(), a.layer().c_str());
  if (ImGui::Button("Fly to")) graph.setCamera(interact::flyToNote(graph, mShown, graph.camera()));
  ImGui::SameLine();
  bool open = a.open();
  if (ImGui::Checkbox("open on the wall (O)", &open)) {
    try {
      mAnnotations->setOpen(graph, int64_t(a.place()), open, "");
    } catch (const annotate::AnnotationError& e) {
      say(e.what());
    }
  }
  for (const scene::AnnotationItem& it : a.items()) {
    ImGui::Separator();
    ImGui::PushID(int(it.id()));
    if (mEdit && mEdit->item == int64_t(it.id())) {
      ItemEditState& e = *mEdit;
      ImGui::PushItemWidth(kFieldWidth);
      ImGui::InputText("title", e.title, sizeof e.title);
      if (e.text_fits)
        ImGui::InputTextMultiline("text", e.text, sizeof e.text, ImVec2(0.0f, 40.0f));
      else
        ImGui::TextDisabled("(its text is too long to edit here; it is kept)");
      if (e.with_number) ImGui::InputDouble("number", &e.number);
      if (ImGui::SmallButton("save")) {
        try {
          std::optional<annotate::Item> item = mAnnotations->db().item(e.item);
          if (!item)
            throw annotate::AnnotationError(annotate::AnnotationError::Kind::kNotFound,
                                            "console: item " + std::to_string(e.item) + " is gone");
          item->title = e.title;
          if (e.text_fits) item->text = e.text;
          if (e.with_number) item->number = e.number;
          const int64_t revision = mAnnotations->updateItem(graph, *item, e.base_revision, kAuthor);
          say("item " + std::to_string(e.item) + " saved (revision " + std::to_string(revision) +
              ")");
          mEdit.reset();
        } catch (const annotate::AnnotationError& err) {
          if (err.kind() != annotate::AnnotationError::Kind::kConflict) {
            say(std::string("not saved: ") + err.what());
          } else {
            // Nothing overwritten; a second save, knowingly, replaces the newer revision.
            if (std::optional<annotate::Item> now = mAnnotations->db().item(e.item))
              e.base_revision = now->revision;
            say(std::string("not saved, changed meanwhile: ") + err.what() +
                " (save again to replace it, or cancel)");
          }
        }
      }
      ImGui::SameLine();
      if (ImGui::SmallButton("cancel")) mEdit.reset();
      ImGui::PopItemWidth();
    } else {
      render::noteItemLines(it);
      if (ImGui::SmallButton("edit")) {
        ItemEditState e;
        e.item = int64_t(it.id());
        // From the database: the scene carries at most 4 KiB of the text, and another
        // connection (tessera-annotate) may have changed the item since.
        const std::optional<annotate::Item> full = mAnnotations->db().item(e.item);
        e.base_revision = full ? full->revision : int64_t(it.revision());
        std::snprintf(e.title, sizeof e.title, "%s",
                      full ? full->title.c_str() : it.title().c_str());
        const std::string text = full ? full->text : it.text();
        e.text_fits = text.size() < sizeof e.text;
        std::snprintf(e.text, sizeof e.text, "%s", text.c_str());
        e.with_number = it.kind() == "number";
        e.number = it.number();
        mEdit = e;
      }
      ImGui::SameLine();
      if (ImGui::SmallButton("delete")) {
        try {
          mAnnotations->removeItem(graph, int64_t(it.id()), int64_t(it.revision()));
          say("item " + std::to_string(it.id()) + " deleted");
        } catch (const annotate::AnnotationError& err) {
          say(std::string("not deleted: ") + err.what());
        }
      }
    }
    ImGui::PopID();
  }
}

}  // namespace tessera::master
