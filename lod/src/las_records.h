// How the records of a LAS file decode into points: one definition that the LAS reader and the
// store builder's direct passes (las_direct.h) share, so both give the same positions, colours
// and attributes bit for bit.
#pragma once

#include <algorithm>
#include <cstdint>

#include <glm/glm.hpp>

#include "reader_util.h"

namespace tessera::lod::detail {

/// The layout and scaling of one file's point records (ASPRS LAS 1.4 R15, section 2.6).
struct LasRecordFormat {
  uint64_t data_offset = 0;    ///< byte offset of the first record
  uint64_t count = 0;          ///< records the header declares
  uint16_t record_length = 0;  ///< bytes a record (extra bytes included)
  int format = 0;              ///< point data format 0-10
  int rgb = -1;                ///< byte offset of the RGB triple in a record, -1: none
  bool color16 = true;         ///< colours use 16 bits (else 8-bit values in 16-bit fields)
  glm::dvec3 scale{1.0};       ///< the header's scale factors
  glm::dvec3 delta{0.0};       ///< the header's offset minus the reader's local origin

  /// Coordinate `axis` of a record's integer `v` relative to the reader's local origin:
  /// v * scale + (offset - origin). Monotonic in v (rising where scale > 0, else falling).
  double coordinate(int axis, int32_t v) const { return double(v) * scale[axis] + delta[axis]; }
  glm::dvec3 position(const uint8_t* p) const {
    return glm::dvec3(coordinate(0, loadLE<int32_t>(p)), coordinate(1, loadLE<int32_t>(p + 4)),
                      coordinate(2, loadLE<int32_t>(p + 8)));
  }
  uint16_t intensity(const uint8_t* p) const { return loadLE<uint16_t>(p + 12); }
  uint8_t classification(const uint8_t* p) const { return format < 6 ? (p[15] & 0x1F) : p[16]; }
  /// 8-bit RGB (16-bit channels rounded to the nearest 8-bit value). Precondition: rgb >= 0.
  glm::u8vec3 color(const uint8_t* p) const {
    const uint8_t* c = p + rgb;
    const uint16_t r = loadLE<uint16_t>(c), g = loadLE<uint16_t>(c + 2),
                   b = loadLE<uint16_t>(c + 4);
    if (color16) return glm::u8vec3((r + 128) / 257, (g + 128) / 257, (b + 128) / 257);
    return glm::u8vec3(std::min<uint16_t>(r, 255), std::min<uint16_t>(g, 255),
                       std::min<uint16_t>(b, 255));
  }
};

}  // namespace tessera::lod::detail
