// A site's --window: the keyboard (interact/keys.h, as the console reads it), the tools' clicks
// and drags, the note form (Dear ImGui), one-button navigation.
#include "site_session_impl.h"

#include <imgui.h>

#include <tessera/render/panel_widgets.h>

namespace tessera::collab {

namespace {

/// The keys a site's window offers (interact/keys.h), as its title lists them.
constexpr interact::Command kSiteKeys[] = {
    interact::Command::kLead,       interact::Command::kRelease, interact::Command::kFollow,
    interact::Command::kUndoSketch, interact::Command::kClearSketches,
    interact::Command::kAddNote,    interact::Command::kMeasure, interact::Command::kLasso,
    interact::Command::kSnap,       interact::Command::kOpenNote, interact::Command::kPicture,
    interact::Command::kShading,    interact::Command::kAmbientOcclusion,
    interact::Command::kRelativeDepth, interact::Command::kContours};

}  // namespace

void SiteSession::Impl::toolInput(render::WindowInput& in, const glm::dvec2& scale, const glm::dvec2& cursor,
               double now) {
  auto record = [&](std::vector<float>& px, glm::dvec2 q) {
    const size_t n = px.size();
    if (n >= 2 && glm::length(q - glm::dvec2(px[n - 2], px[n - 1])) < 2.0) return;
    if (n >= 2 * 2048) return;  // the most a selection request takes
    px.push_back(float(q.x));
    px.push_back(float(q.y));
  };
  if (tools.tool() == Tool::kNote) {  // a click places the note: the form opens
    if (in.left_pressed) press_at = cursor;
    if (in.left_released && glm::length(cursor - press_at) <= 4.0) {
      note_pixel = cursor;
      note_focus = true;
      tools.choose(Tool::kNone);
      say("note at pixel " + std::to_string(int(cursor.x)) + "," + std::to_string(int(cursor.y)) +
          ": its title and text?");
    }
  } else if (tools.tool() == Tool::kMeasure) {
    if (in.left_pressed) press_at = cursor;
    if (in.left_released && glm::length(cursor - press_at) <= 4.0) {
      record(tool_px, cursor);
      const size_t n = tool_px.size() / 2;
      if ((tools.measureMode() == interact::MeasureTool::Mode::kDistance && n == 2) ||
          (tools.measureMode() == interact::MeasureTool::Mode::kAngle && n == 3))
        sendTool(now);
    }
  } else {
    std::vector<float>& fg = tool_px;
    if (in.left_pressed) fg.clear();
    for (const glm::dvec2& q : in.dragOf(render::WindowInput::kLeftHeld)) record(fg, q * scale);
    if (in.left) record(fg, cursor);
    if (tools.tool() == Tool::kLasso && in.left_released) sendTool(now);
    if (tools.tool() == Tool::kSnap) {  // the right button strokes what not to select
      if (in.right_pressed) snap_bg.clear();
      for (const glm::dvec2& q : in.dragOf(render::WindowInput::kRightHeld))
        record(snap_bg, q * scale);
      if (in.right) record(snap_bg, cursor);
      in.right = false;
    }
  }
  in.left = in.left_pressed = in.left_released = false;  // no navigation meanwhile
}

std::string SiteSession::Impl::modelNameAt(float x, float y) {
  if (renderer && x >= 0 && y >= 0 && x < float(script.width()) && y < float(script.height()))
    if (const auto hit = renderer->pick(uint32_t(x), uint32_t(y))) {
      const std::vector<uint32_t>& nodes = models.instanceNodes();
      if (hit->model < nodes.size() && graph.contains(nodes[hit->model]))
        return graph.node(nodes[hit->model]).name();
    }
  return {};
}

void SiteSession::Impl::sendTool(double now) {
  site::SiteAction a;
  if (tools.tool() == Tool::kMeasure) {
    a.mutable_measure()->set_type(interact::MeasureTool::typeOf(tools.measureMode()));
    for (float v : tool_px) a.mutable_measure()->add_pixels(v);
  } else if (tools.tool() == Tool::kLasso) {
    if (tool_px.size() < 6) return tool_px.clear();
    a.mutable_lasso()->set_model(modelNameAt(tool_px[0], tool_px[1]));
    for (float v : tool_px) a.mutable_lasso()->add_pixels(v);
  } else if (tools.tool() == Tool::kSnap) {
    if (tool_px.empty()) return say("snap: first stroke what to select (left drag)");
    site::SnapAction& sn = *a.mutable_snap();
    sn.set_model(modelNameAt(tool_px[0], tool_px[1]));
    for (float v : tool_px) sn.add_foreground(v);
    for (float v : snap_bg) sn.add_background(v);
    if (snap_bg.empty()) sn.set_heavy_width(16.0f);  // one stroke around: the robust lasso
  } else {
    return;
  }
  tool_px.clear();
  snap_bg.clear();
  act(a, now);
}

void SiteSession::Impl::noteForm(double now) {
  if (!note_pixel) return;
  bool open = true;
  ImGui::SetNextWindowPos(ImVec2(8.0f, 8.0f), ImGuiCond_Appearing);
  ImGui::SetNextWindowSizeConstraints(ImVec2(300.0f, 0.0f), ImVec2(300.0f, FLT_MAX));
  if (ImGui::Begin("New note", &open, ImGuiWindowFlags_AlwaysAutoResize)) {
    ImGui::PushItemWidth(-48.0f);
    ImGui::InputText("layer", note_layer, sizeof note_layer);
    if (note_focus) {
      ImGui::SetKeyboardFocusHere();
      note_focus = false;
    }
    const bool enter = ImGui::InputText("title", note_title, sizeof note_title,
                                        ImGuiInputTextFlags_EnterReturnsTrue);
    ImGui::InputTextMultiline("text", note_text, sizeof note_text, ImVec2(-48.0f, 54.0f));
    ImGui::PopItemWidth();
    if (ImGui::Button("Add (Enter)") || enter) {
      if (note_title[0] == '\0') {
        say("a note needs a title");
      } else {
        site::SiteAction a;
        site::NoteAction& na = *a.mutable_note();
        na.add_pixel(float(note_pixel->x));
        na.add_pixel(float(note_pixel->y));
        site::NoteContent& item = *na.mutable_note()->mutable_add()->mutable_item();
        item.set_layer(note_layer);
        item.set_kind("text");
        item.set_title(note_title);
        item.set_text(note_text);
        note_pixel.reset();
        note_title[0] = note_text[0] = '\0';
        act(a, now);
      }
    }
    ImGui::SameLine();
    if (ImGui::Button("Cancel")) open = false;
  }
  ImGui::End();
  if (!open) note_pixel.reset();
}

void SiteSession::Impl::notePanel(double now) {
  if (note_shown == 0) return;
  if (!graph.contains(note_shown) || graph.node(note_shown).kind() != scene::SceneNode::ANNOTATION) {
    note_shown = 0;  // removed meanwhile (its last item deleted, the master restarted)
    note_edit.reset();
    return;
  }
  const scene::AnnotationPayload n = graph.node(note_shown).annotation();  // a copy: edits follow
  bool open = true;
  // Top right, clear of the new note's form (top left); anchored, so it grows downwards.
  ImGui::SetNextWindowPos(ImVec2(float(script.width()) - 8.0f, 8.0f), ImGuiCond_Always,
                          ImVec2(1.0f, 0.0f));
  ImGui::SetNextWindowSizeConstraints(ImVec2(220.0f, 0.0f), ImVec2(220.0f, FLT_MAX));
  const std::string title = std::string(n.radius() > 0.0 ? "Hot spot " : "Point ") +
                            std::to_string(n.place()) + "###note";
  if (ImGui::Begin(title.c_str(), &open, ImGuiWindowFlags_AlwaysAutoResize)) {
    ImGui::PushItemWidth(-40.0f);
    for (const scene::AnnotationItem& it : n.items()) {
      ImGui::PushID(int(it.id()));
      if (note_edit && note_edit->item == it.id()) {
        NoteEdit& e = *note_edit;
        if (e.focus) {
          ImGui::SetKeyboardFocusHere();
          e.focus = false;
        }
        // Focused with its text selected: typing renames, End keeps and appends.
        bool save = ImGui::InputText(
            "title", e.title, sizeof e.title,
            ImGuiInputTextFlags_EnterReturnsTrue | ImGuiInputTextFlags_AutoSelectAll);
        ImGui::InputTextMultiline("text", e.text, sizeof e.text, ImVec2(-40.0f, 40.0f));
        if (e.kind == "number") ImGui::InputDouble("number", &e.number);
        save |= ImGui::SmallButton("save");
        ImGui::SameLine();
        if (ImGui::SmallButton("cancel")) {
          note_edit.reset();
        } else if (save && e.title[0] == '\0') {
          say("a note needs a title");
        } else if (save) {
          site::SiteAction a;
          site::NoteUpdate& u = *a.mutable_note()->mutable_note()->mutable_update();
          u.set_item(e.item);
          u.set_base_revision(e.base_revision);
          site::NoteContent& c = *u.mutable_content();  // its layer stays (empty: keep)
          c.set_kind(e.kind);
          c.set_title(e.title);
          c.set_text(e.text);
          c.set_number(e.number);
          c.set_unit(e.unit);
          c.set_uri(e.uri);
          c.set_link_item(e.link_item);
          note_edit.reset();
          act(a, now);
        }
      } else {
        render::noteItemLines(it);
        // The scene carries 4 KiB of a text (longer ones cut, ending "..."), the form 2 KiB:
        // a text it cannot hold whole is not rewritten here; images are the console's and
        // tessera-annotate's.
        const bool cut = it.text().size() >= sizeof NoteEdit::text - 1;
        if (it.kind() == "image" || cut) {
          ImGui::TextDisabled(it.kind() == "image" ? "(an image: edited at the console)"
                                                   : "(a long text: edited at the console)");
        } else if (ImGui::SmallButton("edit")) {
          NoteEdit e;
          e.item = it.id();
          e.base_revision = it.revision();
          e.kind = it.kind();
          e.unit = it.unit();
          e.uri = it.uri();
          e.link_item = it.link_item();
          e.number = it.number();
          std::snprintf(e.title, sizeof e.title, "%s", it.title().c_str());
          std::snprintf(e.text, sizeof e.text, "%s", it.text().c_str());
          note_edit = e;
        }
        if (it.kind() != "image" && !cut) ImGui::SameLine();
        if (ImGui::SmallButton("delete")) {
          site::SiteAction a;
          site::NoteRemove& r = *a.mutable_note()->mutable_note()->mutable_remove();
          r.set_item(it.id());
          r.set_base_revision(it.revision());
          if (note_edit && note_edit->item == it.id()) note_edit.reset();
          act(a, now);
        }
      }
      ImGui::Separator();
      ImGui::PopID();
    }
    ImGui::PopItemWidth();
  }
  ImGui::End();
  if (!open) {  // closes the panel; the note stays open on the wall (O closes it there)
    note_shown = 0;
    note_edit.reset();
  }
}

void SiteSession::Impl::key(interact::KeyPress press, const glm::dvec2& cursor, double now) {
  using interact::Command;
  site::SiteAction a;
  switch (press.command) {
    case Command::kAddNote:
    case Command::kMeasure:
    case Command::kLasso:
    case Command::kSnap:
      say(tools.press(press.command));
      tool_px.clear();
      snap_bg.clear();
      return;
    case Command::kEnd:
      sendTool(now);
      return;
    case Command::kBack:  // the last click, or the strokes
      if (tools.tool() == Tool::kMeasure && tool_px.size() >= 2) {
        tool_px.resize(tool_px.size() - 2);
      } else {
        tool_px.clear();
        snap_bg.clear();
      }
      return;
    case Command::kOpenNote: {  // open or close the note nearest the cursor
      const auto node = interact::noteNear(graph, last_view, cursor, 24.0);
      if (!node) {
        say("no note within 24 px of the cursor");
        return;
      }
      const scene::AnnotationPayload& n = graph.node(*node).annotation();
      if (n.place() == 0) {
        say("that note is not in the database: it cannot be opened");
        return;
      }
      site::PlaceOpen& open = *a.mutable_note()->mutable_note()->mutable_open();
      open.set_place(n.place());
      open.set_open(!n.open());
      note_shown = n.open() ? 0 : *node;  // its panel follows what the wall shows
      note_edit.reset();
      break;
    }
    case Command::kLead:
      a.set_lead(true);
      break;
    case Command::kRelease:
      a.set_release(true);
      break;
    case Command::kFollow:
      a.set_follow(true);
      break;
    case Command::kUndoSketch:
      a.set_undo(true);
      break;
    case Command::kClearSketches:
      a.set_clear(true);
      break;
    case Command::kPicture:
      a.set_screenshot("site-" + std::to_string(uint64_t(now * 1000)) + ".png");
      break;
    case Command::kShading:
    case Command::kAmbientOcclusion:
    case Command::kRelativeDepth:
    case Command::kContours: {  // for the whole wall: the master applies it
      double extent = 0.0;  // contour lines about 25 across the largest model
      for (const render::ModelInstance& m : instances) {
        const auto [lo, hi] = render::worldBounds(m);
        extent = std::max(extent, glm::length(hi - lo));
      }
      const auto e =
          interact::shadingEdit(press.command, graph.settings(), interact::roundContourInterval(extent));
      if (e->delta.has_shading()) a.mutable_shading()->set_shading(e->delta.shading());
      if (e->delta.has_analysis()) *a.mutable_shading()->mutable_analysis() = e->delta.analysis();
      say(e->said);
      break;
    }
    default:  // the console's own (section clip, models, opacity, lighting)
      return;
  }
  act(a, now);
}

bool SiteSession::Impl::interact(double now) {
  render::WindowInput in = window->poll();
  if (window->closing()) return false;
  // The note form first: what it takes (the mouse over it, the keyboard in a field) the view
  // does not also get.
  window->beginUi();
  noteForm(now);
  notePanel(now);
  window->endUi();
  window->withoutWhatUiTook(in, right_held);
  const auto t = Clock::now();
  const double dt = std::chrono::duration<double>(t - last_input).count();
  last_input = t;
  glm::dvec2 scale;
  interact::PointerInput p =
      interact::pointerInView(in, glm::dvec2(script.width(), script.height()), scale);
  if (tools.tool() != Tool::kNone) {
    toolInput(in, scale, p.cursor, now);
    p.down = p.pressed = p.released = false;
  }
  if (p.pressed || p.down || p.released || p.scroll != 0 || navigation.flying()) {
    if (following && (p.pressed || p.scroll != 0)) {
      following = false;  // taking control back
      say("stops following");
    }
    const glm::dmat4 clip_from_world = last_view.projection * last_view.view;
    const double fovy = glm::radians(double(script.fovy_deg()));
    auto pick = [&](glm::dvec2 px) -> std::optional<glm::dvec3> {
      if (!(px.x >= 0 && px.y >= 0 && px.x < script.width() && px.y < script.height()))
        return std::nullopt;
      if (auto hit = renderer->pick(uint32_t(px.x), uint32_t(px.y))) return hit->world;
      return std::nullopt;
    };
    auto project = [&](const glm::dvec3& w) -> std::optional<glm::dvec2> {
      const glm::dvec4 c = clip_from_world * glm::dvec4(w, 1.0);
      if (c.w <= 0) return std::nullopt;
      return glm::dvec2((c.x / c.w * 0.5 + 0.5) * script.width(),
                        (0.5 - c.y / c.w * 0.5) * script.height());
    };
    if (!following) own = navigation.update(own, p, dt, fovy, pick, project);
  }
  // A right-button drag draws a stroke, placed on the model when the button goes up.
  const glm::vec2 at(p.cursor);
  if (in.right) {
    if (drag.empty() || glm::length(at - glm::vec2(drag[drag.size() - 2], drag.back())) >= 1.0f) {
      drag.push_back(at.x);
      drag.push_back(at.y);
    }
  } else if (right_held) {
    if (drag.size() >= 4) {
      site::StrokeAction a;
      for (float v : drag) a.add_pixels(v);
      *a.mutable_color() = welcome.color();
      a.set_width(4.0f);
      stroke(a, asSent(camera(now)));
    }
    drag.clear();
  }
  right_held = in.right;
  for (int k : in.keys) key(interact::commandOf(k), p.cursor, now);
  const std::string& leader = graph.settings().leader();
  window->setTitle(
      "tessera-site: " + welcome.name() +
      (leader == welcome.name() ? " | leading the view"
       : following ? " | following " + (leader.empty() ? std::string("the wall") : leader)
                   : "") +
      " | left: navigate, right: draw; " + interact::keysHelp(kSiteKeys) + ", Esc quit");
  return true;
}

}  // namespace tessera::collab
