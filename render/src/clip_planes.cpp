#include <tessera/render/clip_planes.h>

#include <cmath>

#include "shared_layout.h"

namespace tessera::render {

static_assert(kMaxClipPlanes == TESSERA_MAX_CLIP_PLANES);
static_assert(kMaxClipPlanes <= 32, "groups are bits of a uint");

bool ClipPlanes::addGroup(std::span<const glm::dvec4> group, bool keep_outside) {
  if (group.empty() || count + group.size() > kMaxClipPlanes || group_count >= kMaxClipPlanes)
    return false;
  for (const glm::dvec4& p : group) {
    planes[count] = p;
    groups[count] = group_count;
    ++count;
  }
  if (keep_outside) invert |= 1u << group_count;
  ++group_count;
  return true;
}

ClipPlanes ClipPlanes::transformed(const glm::dmat4& this_from_other) const {
  ClipPlanes out = *this;
  for (uint32_t i = 0; i < count; ++i) {
    // A row vector times the matrix: plane . (M x) = (plane M) . x; glm's v * M is that.
    glm::dvec4 p = planes[i] * this_from_other;
    const double n = glm::length(glm::dvec3(p));
    if (n > 0.0 && std::isfinite(n)) p /= n;
    out.planes[i] = p;
  }
  return out;
}

bool ClipPlanes::keeps(const glm::dvec3& p) const {
  uint32_t present = 0, outside = 0;
  for (uint32_t i = 0; i < count; ++i) {
    const uint32_t bit = 1u << groups[i];
    present |= bit;
    if (glm::dot(glm::dvec3(planes[i]), p) + planes[i].w < 0.0) outside |= bit;
  }
  const uint32_t kept = (present & ~outside & ~invert) | (outside & invert);
  return kept == present;
}

std::array<glm::dvec4, 6> boxPlanes(const glm::dvec3& c, const glm::dvec3& h) {
  return {glm::dvec4(-1, 0, 0, c.x + h.x), glm::dvec4(1, 0, 0, -(c.x - h.x)),
          glm::dvec4(0, -1, 0, c.y + h.y), glm::dvec4(0, 1, 0, -(c.y - h.y)),
          glm::dvec4(0, 0, -1, c.z + h.z), glm::dvec4(0, 0, 1, -(c.z - h.z))};
}

GpuClipPlanes gpuClipPlanes(const ClipPlanes& world, const glm::dmat4& world_from_local) {
  GpuClipPlanes g;
  if (world.empty()) return g;
  const ClipPlanes local = world.transformed(world_from_local);
  g.count = local.count;
  g.invert = local.invert;
  for (uint32_t i = 0; i < local.count; ++i) {
    g.planes[i] = glm::vec4(local.planes[i]);
    g.groups[i] = local.groups[i];
  }
  return g;
}

}  // namespace tessera::render
