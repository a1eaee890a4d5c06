// Compression of one node's points (Bettio et al. 2009, section 3.3: per-node quantisation
// relative to the node box, attribute streams, entropy coding).
//
// Positions are quantised on a grid of `step` (cell 0 at the node box minimum, or on the input's
// own lattice), sorted by the 2D Morton code of the two axes the points spread most along, and
// coded as Morton deltas and height differences, each split into a log-bucket symbol (entropy
// coded, rANS with the chunk's own table) and raw low bits. Colours are decorrelated with the
// reversible subtract-green transform (G, R-G, B-G mod 256) and delta-coded along the point
// order; the red and blue deltas are coded in three contexts of the green delta. Intensity,
// source id, classification and ambient occlusion form a second section, byte planes each coded
// by rANS or zstd, whichever is smaller, so the position + colour cost can be reported on its
// own. Format 1 chunks (Morton deltas as varints, zstd; stores of version 1-3) still decode.
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

/// Encodes `points` (reordered in place into the order decoding gives). `box_min` is the node box
/// minimum; every point must lie within [box_min, box_min + extent]. `step` > 0 is the
/// quantisation step. `lattice`: cell 0 is the multiple of `step` at or below `box_min` (in the
/// local frame) instead of `box_min`, so inputs declared on that lattice keep their integers
/// exactly (max_error ~ 1e-9 step).
EncodedChunk encodeChunk(std::span<BuildPoint> points, const glm::dvec3& box_min, double extent,
                         double step, AttributeMask attributes, int zstd_level,
                         bool lattice = false);

/// Encodes in format 1, what stores of version 1-3 hold (Morton deltas as LEB128 varints, zstd),
/// for the tests of older stores and the benchmark's baseline (bench/chunk_codec.cpp).
EncodedChunk encodeChunkFormat1(std::span<BuildPoint> points, const glm::dvec3& box_min,
                                double extent, double step, AttributeMask attributes,
                                int zstd_level);

/// Decodes a payload of either format (byte 25 tells them apart). Throws StoreError (with
/// `what` naming the chunk) on any inconsistency; never reads outside `bytes`.
/// `with_cells`: also fill out.cells.
void decodeChunk(std::span<const uint8_t> bytes, const glm::dvec3& box_min, ChunkPoints& out,
                 const std::string& what, bool with_cells = false);

}  // namespace tessera::lod
