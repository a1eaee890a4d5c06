// The builder's in-memory and temporary-file point record.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

namespace tessera::lod {

/// 32 bytes: temporary files hold one per point (twice, briefly), so every byte counts.
struct BuildPoint {
  glm::dvec3 position;  ///< store local frame (world - origin)
  glm::u8vec3 rgb;
  uint8_t classification;
  uint16_t intensity;
  uint16_t source;
};
static_assert(sizeof(BuildPoint) == 32);

}  // namespace tessera::lod
