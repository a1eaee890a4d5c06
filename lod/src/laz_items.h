// The LAZ point items and the chunks they make (LASzip's format, Isenburg 2013). A point record
// of a LAS file is a sequence of items (POINT10 + GPSTIME11 + RGB12 + BYTE for point formats
// 0-5, POINT14 + RGB14 / RGBNIR14 + BYTE14 for 6-10); a LAZ chunk holds its first record raw and
// the others coded against their predecessors:
//  - pointwise (item versions 1 and 2): one arithmetic-coded stream, item after item;
//  - layered (versions 3 and 4, LAS 1.4): the record count, then one stream per field group
//    ("layer"), each with its byte count up front, so a reader may skip fields.
// Chunks are independent: ChunkDecoder turns one chunk's bytes into raw LAS records, exactly the
// bytes an uncompressed LAS file holds; ChunkEncoder is its mirror (versions 2 and 3).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "laz_codec.h"

namespace tessera::lod::laz {

enum ItemType : uint16_t {
  kByte = 0,
  kPoint10 = 6,
  kGpsTime11 = 7,
  kRgb12 = 8,
  kWavePacket13 = 9,
  kPoint14 = 10,
  kRgb14 = 11,
  kRgbNir14 = 12,
  kWavePacket14 = 13,
  kByte14 = 14,
};

struct Item {
  uint16_t type = 0;
  uint16_t size = 0;
  uint16_t version = 0;
};

/// "POINT10 v2" and the like, for messages.
std::string itemName(const Item& item);

/// Why `items` cannot be decoded (an empty string when they can): unknown or unsupported item
/// types and versions (wave packets), sizes that do not match the type, items of the other
/// compressor. `layered`: the LAS 1.4 layered compressor.
std::string unsupportedItems(const std::vector<Item>& items, bool layered);

/// Sum of the item sizes: the LAS record length the items describe.
uint32_t recordSize(const std::vector<Item>& items);

class ItemCoder;

/// Decodes chunks of one file (one instance per thread: it holds the models of a chunk).
class ChunkDecoder {
 public:
  ChunkDecoder(std::vector<Item> items, bool layered);
  ~ChunkDecoder();
  /// Decodes `count` (>= 1) records from `bytes` into `out` (count * recordSize() bytes).
  /// Returns the bytes the chunk occupies. Throws CorruptData.
  size_t decode(std::span<const uint8_t> bytes, uint64_t count, uint8_t* out);
  uint32_t recordSize() const { return mRecordSize; }

 private:
  size_t decodePointwise(std::span<const uint8_t> bytes, uint64_t count, uint8_t* out);
  size_t decodeLayered(std::span<const uint8_t> bytes, uint64_t count, uint8_t* out);

  std::vector<Item> mItems;
  bool mLayered;
  uint32_t mRecordSize;
};

/// Encodes chunks: item versions 2 (point formats 0-3, pointwise) and 3 (6-8, layered).
class ChunkEncoder {
 public:
  ChunkEncoder(std::vector<Item> items, bool layered);
  /// Appends the chunk of `count` (>= 1) raw records to `out`.
  void encode(const uint8_t* records, uint64_t count, std::vector<uint8_t>& out);

 private:
  void encodeLayered(const uint8_t* records, uint64_t count, std::vector<uint8_t>& out);

  std::vector<Item> mItems;
  bool mLayered;
  uint32_t mRecordSize;
};

/// The items LASzip writes for LAS point format `format` with `extra` extra bytes, in the
/// versions ChunkEncoder writes. Empty for the formats with wave packets (4, 5, 9, 10).
std::vector<Item> itemsForFormat(int format, uint16_t extra);

/// The chunk table: each chunk's point count (variable chunks) and byte count, coded with an
/// IntegerCoder(32, 2) after a version word and the count.
void encodeChunkTable(const std::vector<uint32_t>& points, const std::vector<uint64_t>& bytes,
                      bool variable, std::vector<uint8_t>& out);
/// Decodes `count` entries from `coded` (the bytes after the version word and the count).
void decodeChunkTable(std::span<const uint8_t> coded, uint32_t count, bool variable,
                      std::vector<uint32_t>& points, std::vector<uint64_t>& bytes);

}  // namespace tessera::lod::laz
