// LAS and LAZ files as records: the parts of a file a copy keeps (public header, VLRs, EVLRs),
// every record of a LAS or LAZ file in blocks, and a writer of LAS or LAZ from records. Export
// copies the records of a LAS or LAZ input this way, so every attribute the input had (GPS
// time, returns, flags, scan angle, source id, extra bytes, the CRS in its VLRs) reaches the
// output untouched.
#pragma once

#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "atomic_file.h"
#include "byte_source.h"
#include "laz_reader.h"

namespace tessera::lod::detail {

struct LasParts {
  std::vector<uint8_t> header;               ///< the public header as on disk
  std::vector<std::vector<uint8_t>> vlrs;    ///< whole VLRs (54-byte header + payload), not LASzip's
  std::vector<std::vector<uint8_t>> evlrs;   ///< whole EVLRs (60-byte header + payload)
  int minor = 2;
  int format = 0;
  uint16_t record_length = 0;
  uint64_t count = 0;
  uint64_t data_offset = 0;
  glm::dvec3 scale{0.001}, offset{0.0};
  std::optional<LaszipVlr> laszip;
};

/// The parts of a LAS or LAZ file. Throws ReadError naming the file and the byte.
LasParts readLasParts(const ByteSource& src, const char* component);

/// Calls `fn(records, n)` with every record of a LAS or LAZ file, in order, in blocks.
/// `threads`: LAZ chunks decoded at once (0: one per core). Throws ReadError.
void forEachRecordBlock(const std::filesystem::path& path, unsigned threads,
                        const std::function<void(const uint8_t*, uint64_t)>& fn);

/// A header for `format` (0-10) in LAS 1.`minor` (0: 1.2 for formats 0-5, 1.4 for 6-10) with
/// the given scale and offset and no VLRs: what a file made from other points starts from.
LasParts newLasParts(int format, uint16_t extra_bytes, const glm::dvec3& scale,
                     const glm::dvec3& offset, int minor = 0);

/// Writes LAS or LAZ from records laid out as `parts` says. The point count, bounding box,
/// return counts, offsets and format byte are recomputed from the records written; LAZ chunks
/// of 50,000 points are encoded on worker threads and the chunk table follows them.
class LasFileWriter {
 public:
  LasFileWriter(const std::filesystem::path& path, LasParts parts, bool laz, unsigned threads,
                const char* component);
  ~LasFileWriter();
  void add(const uint8_t* records, uint64_t n);
  /// Finishes the file and renames it into place.
  void commit();
  uint64_t points() const { return mCount; }
  uint16_t recordLength() const { return mParts.record_length; }

 private:
  void flushChunk();
  void writeReady(bool all);

  AtomicFile mFile;
  LasParts mParts;
  bool mLaz;
  unsigned mThreads;
  const char* mComponent;
  std::vector<laz::Item> mItems;
  uint64_t mCount = 0;
  uint64_t mReturns[15] = {};
  glm::dvec3 mLo{0.0}, mHi{0.0};
  std::vector<uint8_t> mPending;  // LAZ: records of the chunk being filled
  std::deque<std::future<std::vector<uint8_t>>> mEncoding;
  std::vector<uint32_t> mChunkPoints;
  std::vector<uint64_t> mChunkBytes;
  std::deque<uint32_t> mEncodingPoints;
  uint64_t mTableOffsetAt = 0;
};

}  // namespace tessera::lod::detail
