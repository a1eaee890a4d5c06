// The builder's in-memory and temporary-file point record.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

namespace tessera::lod {

struct BuildPoint {
  glm::dvec3 position;  ///< store local frame (world - origin)
  glm::u8vec4 color;
  uint16_t intensity;
  uint16_t source;
  uint8_t classification;
  uint8_t pad[7];
};
static_assert(sizeof(BuildPoint) == 40);

}  // namespace tessera::lod
