// The point records of a LAZ file, chunk by chunk: the LASzip VLR, the chunk table (at the end
// of the file, found through the offset at the start of the point data, or rebuilt by scanning
// the chunks when a writer was interrupted before writing it), and chunks decoded several at a
// time on worker threads. The LAS reader turns the records into points as it does for LAS.
#pragma once

#include <cstdint>
#include <deque>
#include <future>
#include <string>
#include <vector>

#include "byte_source.h"
#include "laz_items.h"

namespace tessera::lod::detail {

/// The LASzip VLR (user "laszip encoded", record 22204).
struct LaszipVlr {
  uint16_t compressor = 0;  ///< 1 pointwise, 2 pointwise chunked, 3 layered chunked
  uint16_t coder = 0;       ///< 0: arithmetic, the only one
  uint8_t version_major = 0, version_minor = 0;
  uint32_t chunk_size = 0;  ///< points per chunk; 0xFFFFFFFF: variable (from the chunk table)
  std::vector<laz::Item> items;
};

/// Parses the VLR's payload. Returns an empty string on success, else what is wrong.
std::string parseLaszipVlr(const uint8_t* data, size_t n, LaszipVlr& out);

/// Builds the VLR's payload (34 bytes + 6 per item) for the chunk size given.
std::vector<uint8_t> laszipVlrPayload(const std::vector<laz::Item>& items, uint32_t chunk_size,
                                      bool layered);

class LazChunks {
 public:
  /// `component` and the source's name start every message. `threads`: chunks decoded at once
  /// (0: one per core). Throws ReadError for a bad VLR, items that cannot be decoded, or a chunk
  /// table that does not match the header's point count.
  LazChunks(const ByteSource& src, const char* component, uint64_t data_offset, uint64_t points,
            uint16_t record_length, const LaszipVlr& vlr, unsigned threads);
  ~LazChunks();

  /// Decodes the next chunk into `records` (count * record length bytes). False at the end.
  bool next(std::vector<uint8_t>& records, uint64_t& count);
  /// "pointwise chunked, 3 chunks, POINT10 v2 + GPSTIME11 v2 + RGB12 v2" and the like.
  std::string describe() const;
  size_t chunkCount() const { return mPoints.size(); }
  /// Whether chunks can be decoded out of order (the chunk table was read): decodeAt().
  bool seekable() const { return !mScanning; }
  /// Points in chunk `index` (< chunkCount()).
  uint64_t chunkPoints(size_t index) const { return mPoints[index]; }
  /// Decodes chunk `index` (< chunkCount()) into `records`, its coded size into `bytes`;
  /// returns its point count. Any thread, several at once. Precondition (assert): seekable().
  uint64_t decodeAt(size_t index, std::vector<uint8_t>& records, uint64_t& bytes) const;

 private:
  struct Result {
    std::vector<uint8_t> records;
    uint64_t count = 0;
    uint64_t used = 0;  // bytes the chunk occupies
  };
  bool readTable();
  void planFixed();
  Result decodeChunk(size_t index) const;
  void launch();
  [[noreturn]] void fail(const std::string& where, const std::string& what) const;

  const ByteSource& mSrc;
  const char* mComponent;
  uint64_t mDataOffset, mTotal;
  uint16_t mRecordLength;
  LaszipVlr mVlr;
  unsigned mThreads;
  bool mScanning = false;        // no chunk table: chunks found one after another
  std::string mTableNote;        // why the table was not used
  std::vector<uint64_t> mPoints;  // per chunk
  std::vector<uint64_t> mStarts;  // per chunk (+ the end when known)
  size_t mNextLaunch = 0, mNextDeliver = 0;
  uint64_t mScanAt = 0;  // scanning: where the next chunk starts
  std::deque<std::future<Result>> mInFlight;
};

}  // namespace tessera::lod::detail
