// The builder's in-memory and temporary-file point record.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

namespace tessera::lod {

/// 40 bytes: temporary files hold one per point (twice, briefly), so every byte counts. The
/// ambient-occlusion byte costs the 8 of alignment.
struct BuildPoint {
  glm::dvec3 position;  ///< store local frame (world - origin)
  glm::u8vec3 rgb;
  uint8_t classification;
  uint16_t intensity;
  uint16_t source;
  uint8_t ao;  ///< ambient-occlusion visibility 0..255 (kAmbientOcclusion), else 255
};
static_assert(sizeof(BuildPoint) == 40);

}  // namespace tessera::lod
