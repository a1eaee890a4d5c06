// The .tlod point store file format, version 4 (versions 1-3 are read too: version 1 lacks the
// source table's checksum, versions 1-3 hold chunks of format 1). Little-endian, every structure
// checksummed.
//
//   [Header, 4096 bytes at offset 0]
//   [Payload: one compressed chunk per node, ordered by (level, Morton key of the node cell):
//    coarse levels first, spatial neighbours adjacent, so a cut reads mostly sequential ranges]
//   [Hierarchy pages: each holds a subtree of up to kPageLevels levels; nodes on a page's last
//    level that have children point to their own page, loaded only when a traversal gets there]
//   [Source table: one name per source (input file, or scan of a .conf)]
//
// A node's box is the octree cell (level, x, y, z) of the root cube. Every input point is stored
// once, in the leaf containing it. An inner node holds a spatially even copy of the points below
// it: one point per cell of a kGrid^3 grid over its box, the one nearest the cell centre. Nodes
// are self-contained (Bettio et al. 2009): a cut is drawn from its own nodes only, so a coarse
// node's quantisation (a quarter of its spacing) never shows next to finer data. Leaves keep the
// input's declared resolution, their cells the input's own integers (kExactLeaves), unless the
// store was built lossy (a quarter of the spacing there too).
#pragma once

#include <cstdint>

namespace tessera::lod::store {

constexpr char kMagic[4] = {'T', 'L', 'O', 'D'};
/// 2: source_table_crc (reserved in 1); 3: chunks may carry kAmbientOcclusion; 4: chunks of
/// format 2 (chunk_codec.h: entropy-coded streams, cells on the input's lattice) and `flags`.
constexpr uint32_t kVersion = 4;
constexpr uint32_t kHeaderSize = 4096;
constexpr int kGrid = 48;  ///< sampling grid per node and axis: inner nodes hold <= kGrid^3 points
/// An inner node holds at most this fraction of the input points below it (a coarser sampling
/// grid where needed): each level of inner nodes adds at most f of the input. Not a geometric
/// bound (nodes sample the input, not their children's samples): volumes reach 1.4x.
constexpr double kMaxInnerFraction = 0.2;
constexpr int kPageLevels = 4;  ///< levels per hierarchy page
constexpr int kMaxLevel = 30;   ///< deepest node level (duplicates stop subdividing there)
/// FileHeader::flags: every leaf keeps the input's integers (its cells are the input's own
/// coordinates at input_precision; a leaf's stated error is kLatticeTolerance of its step).
constexpr uint32_t kExactLeaves = 1;
/// Largest distance, in steps, of an exact leaf's stored point from its input (double
/// rounding): far below half a step, so the stored integer is the input's.
constexpr double kLatticeTolerance = 1e-3;

/// Fixed-size file header. All offsets are absolute byte offsets in the file.
struct FileHeader {
  char magic[4];
  uint32_t version;
  uint32_t header_size;
  uint32_t attributes;  ///< AttributeMask of what chunks carry (kColor, kIntensity, ...)
  double origin[3];     ///< world = origin + local
  double cube_min[3];   ///< root cube, local frame
  double cube_size;     ///< edge length of the root cube
  double bbox_min[3];   ///< tight bounds of all points, local frame
  double bbox_max[3];
  uint64_t points;
  uint64_t nodes;
  uint32_t depth;  ///< deepest level + 1
  uint32_t sources;
  uint64_t payload_offset;
  uint64_t payload_size;
  uint64_t root_page_offset;
  uint32_t root_page_size;
  uint32_t reserved0;
  uint64_t source_table_offset;
  uint32_t source_table_size;
  uint32_t source_table_crc;  ///< CRC-32C of the source table (version >= 2; 0 in version 1)
  double input_precision;     ///< finest coordinate resolution the inputs declared (0: unknown)
  double spacing_root;
  double spacing_finest;                  ///< smallest node spacing
  uint64_t payload_position_color_bytes;  ///< bytes of the position + colour streams
  uint64_t stored_points;  ///< points in all nodes (leaves hold each input point once; inner
                           ///< nodes hold sampled copies): stored_points / points = overhead
  uint32_t header_crc;     ///< CRC-32C of this struct with header_crc = 0
  uint32_t flags;          ///< kExactLeaves (version >= 4; 0 before)
};

/// One node on a hierarchy page (56 bytes, no padding).
struct NodeRecord {
  uint64_t payload_offset;
  uint64_t page_offset;  ///< kHasPage: the page holding this node's children
  uint32_t x, y, z;      ///< cell coordinates at `level`
  uint32_t points;
  float spacing;      ///< mean distance between the node's samples (local units)
  float error_bound;  ///< max distance of a stored position from its input point
  uint32_t payload_size;
  uint32_t payload_crc;  ///< CRC-32C of the payload bytes
  uint32_t page_size;
  uint8_t level;
  uint8_t child_mask;  ///< bit i: child i exists (i = x | y << 1 | z << 2)
  uint8_t flags;       ///< kHasPage: children are on the page at page_offset
  uint8_t reserved;
};
static_assert(sizeof(NodeRecord) == 56);
static_assert(sizeof(FileHeader) == 240);

constexpr uint8_t kHasPage = 1;

/// A hierarchy page: this header, then `nodes` NodeRecords in breadth-first order.
struct PageHeader {
  char magic[4];  ///< "TPAG"
  uint32_t nodes;
  uint32_t crc;  ///< CRC-32C of the records
  uint32_t reserved;
};

}  // namespace tessera::lod::store
