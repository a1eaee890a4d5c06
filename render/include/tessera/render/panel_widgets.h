// Dear ImGui pieces that the console's panels (master/) and a site's window (collab/) share,
// drawn between render::Window::beginUi() and endUi().
#pragma once

#include <tessera/scene.pb.h>

namespace tessera::render {

/// A note's item as a panel lists it: its title and text wrapped at the panel's width, a
/// number with its unit, a link's target, and a greyed line with its kind, author and revision.
void noteItemLines(const scene::AnnotationItem& item);

}  // namespace tessera::render
