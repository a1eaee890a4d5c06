// Compression of one node's points (Bettio et al. 2009, section 3.3: per-node quantisation
// relative to the node box, attribute streams, entropy coding).
//
// Positions are quantised on a grid of `step` relative to the node box minimum, sorted by Morton
// code, and coded as LEB128 Morton deltas. Colours are decorrelated with the reversible
// subtract-green transform (G, R-G, B-G mod 256), delta-coded along the Morton order, and stored
// as byte planes. Both go through zstd. Intensity, source id and classification form a second
// frame so the position + colour cost can be reported on its own; ambient occlusion joins it as
// byte deltas along the Morton order.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <tessera/lod/point_store.h>

#include "build_point.h"

namespace tessera::lod {

struct EncodedChunk {
  std::vector<uint8_t> bytes;
  uint32_t position_color_bytes = 0;  ///< compressed size of the position + colour frame
  double max_error = 0.0;             ///< largest distance of a decoded position from its input
  double step = 0.0;                  ///< quantisation step used (>= the one asked for)
};

/// Encodes `points` (reordered in place into Morton order). `box_min` is the node box minimum;
/// every point must lie within [box_min, box_min + extent]. `step` > 0 is the quantisation step.
EncodedChunk encodeChunk(std::span<BuildPoint> points, const glm::dvec3& box_min, double extent,
                         double step, AttributeMask attributes, int zstd_level);

/// Decodes a payload. Throws StoreError (with `what` naming the chunk) on any inconsistency.
void decodeChunk(std::span<const uint8_t> bytes, const glm::dvec3& box_min, ChunkPoints& out,
                 const std::string& what);

}  // namespace tessera::lod
