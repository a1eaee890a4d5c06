#include <tessera/render/panel_widgets.h>

#include <imgui.h>

#include <string>

namespace tessera::render {

void noteItemLines(const scene::AnnotationItem& it) {
  if (!it.title().empty()) ImGui::TextWrapped("%s", it.title().c_str());
  if (!it.text().empty()) ImGui::TextWrapped("%s", it.text().c_str());
  if (it.kind() == "number") ImGui::Text("%g %s", it.number(), it.unit().c_str());
  if (it.kind() == "link" && !it.uri().empty()) ImGui::TextWrapped("link: %s", it.uri().c_str());
  if (it.kind() == "link" && it.link_item() != 0)
    ImGui::Text("link: item %llu", (unsigned long long)it.link_item());
  const std::string line = it.kind() + ", by " +
                           (it.author().empty() ? "the master" : it.author()) + ", revision " +
                           std::to_string(it.revision());
  ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyleColorVec4(ImGuiCol_TextDisabled));
  ImGui::TextWrapped("%s", line.c_str());
  ImGui::PopStyleColor();
}

}  // namespace tessera::render
