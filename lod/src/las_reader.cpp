// LAS 1.0-1.4 reader, point data formats 0-10, uncompressed or LAZ-compressed. Coordinates are
// integers scaled and offset in double, then expressed relative to a local origin (the header
// box centre) so georeferenced data keeps its precision. Extra bytes are skipped by the record
// length. A LAZ file's chunks decode to the same records an uncompressed file holds
// (laz_reader.h), several chunks at a time.
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "byte_source.h"
#include "las_records.h"
#include "laz_reader.h"
#include "reader_util.h"
#include "readers.h"

namespace tessera::lod::detail {
namespace {

constexpr const char* kComponent = "lod::readLas()";
constexpr size_t kMinHeader = 227;
// Minimum record length of each point data format (ASPRS LAS 1.4 R15, section 2.6).
constexpr uint16_t kMinRecord[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

int rgbOffset(int fmt) {
  switch (fmt) {
    case 2:
      return 20;
    case 3:
    case 5:
      return 28;
    case 7:
    case 8:
    case 10:
      return 30;
    default:
      return -1;
  }
}

class LasReader final : public PointReader {
 public:
  LasReader(ByteSource source, unsigned threads) : mSrc(std::move(source)), mThreads(threads) {
    parseHeader();
  }
  bool next(PointBatch& batch, size_t max_points) override;
  /// The record layout; nullptr for LAZ (its records are compressed).
  const LasRecordFormat* records() const { return mLaz ? nullptr : &mRec; }

 private:
  void parseHeader();
  void detectColorDepth();
  bool nextLaz(PointBatch& batch, size_t max_points);
  /// Decodes `n` records at `p` into batch points at, at + 1, ...
  void decodeRecords(const uint8_t* p, size_t n, PointBatch& batch, size_t at);

  ByteSource mSrc;
  LasRecordFormat mRec;  // layout, scaling and colour depth of the records
  uint64_t mNext = 0;    // next record index
  unsigned mThreads;
  std::unique_ptr<LazChunks> mLaz;
  std::vector<uint8_t> mChunk;  // LAZ: the decoded records of the current chunk
  uint64_t mChunkCount = 0, mChunkNext = 0;
};

void LasReader::parseHeader() {
  uint8_t h[375] = {};
  size_t got = mSrc.readAt(0, h, sizeof h);
  if (got < 4 || std::memcmp(h, "LASF", 4) != 0) {
    fail(kComponent, mSrc.name(), atByte(0), "not a LAS file (missing 'LASF' signature)");
  }
  if (got < kMinHeader) {
    fail(kComponent, mSrc.name(), atByte(got),
         "file ends inside the " + std::to_string(kMinHeader) + "-byte public header");
  }
  int major = h[24], minor = h[25];
  uint16_t header_size = loadLE<uint16_t>(h + 94);
  mRec.data_offset = loadLE<uint32_t>(h + 96);
  uint32_t vlr_count = loadLE<uint32_t>(h + 100);
  uint8_t fmt_byte = h[104];
  mRec.record_length = loadLE<uint16_t>(h + 105);
  uint64_t legacy_count = loadLE<uint32_t>(h + 107);
  std::string version = std::to_string(major) + "." + std::to_string(minor);
  if (major != 1 || minor > 4) {
    fail(kComponent, mSrc.name(), atByte(24), "unsupported LAS version " + version);
  }
  // LASzip marks compressed records by setting bit 7 (and 6) of the format byte.
  const bool compressed = fmt_byte & 0xC0;
  mRec.format = fmt_byte & 0x3F;
  if (mRec.format > 10) {
    fail(kComponent, mSrc.name(), atByte(104),
         "unknown point data format " + std::to_string(mRec.format));
  }
  size_t need_header = minor >= 4 ? 375 : minor == 3 ? 235 : kMinHeader;
  if (header_size < need_header) {
    fail(kComponent, mSrc.name(), atByte(94),
         "header size " + std::to_string(header_size) + " is smaller than LAS " + version +
             " requires (" + std::to_string(need_header) + ")");
  }
  if (got < need_header) {
    fail(kComponent, mSrc.name(), atByte(got), "file ends inside the public header");
  }
  if (mRec.data_offset < header_size) {
    fail(kComponent, mSrc.name(), atByte(96),
         "offset to point data " + std::to_string(mRec.data_offset) + " lies inside the header");
  }
  if (mRec.record_length < kMinRecord[mRec.format]) {
    fail(kComponent, mSrc.name(), atByte(105),
         "point record length " + std::to_string(mRec.record_length) + " is shorter than format " +
             std::to_string(mRec.format) + " needs (" + std::to_string(kMinRecord[mRec.format]) +
             ")");
  }
  mRec.count = legacy_count;
  if (minor >= 4) {
    uint64_t count64 = loadLE<uint64_t>(h + 247);
    if (count64 != 0) mRec.count = count64;
  }
  for (int i = 0; i < 3; ++i) {
    mRec.scale[i] = loadLE<double>(h + 131 + 8 * i);
    if (!std::isfinite(mRec.scale[i]) || mRec.scale[i] == 0.0) {
      fail(kComponent, mSrc.name(), atByte(131 + 8 * i), "scale factor is zero or not finite");
    }
  }
  glm::dvec3 offset, lo, hi;
  for (int i = 0; i < 3; ++i) {
    offset[i] = loadLE<double>(h + 155 + 8 * i);
    hi[i] = loadLE<double>(h + 179 + 16 * i);
    lo[i] = loadLE<double>(h + 187 + 16 * i);
  }
  if (!finite3(offset.x, offset.y, offset.z)) {
    fail(kComponent, mSrc.name(), atByte(155), "offset is not finite");
  }
  bool box_ok = finite3(lo.x, lo.y, lo.z) && finite3(hi.x, hi.y, hi.z) &&
                glm::all(glm::lessThanEqual(lo, hi));
  if (box_ok) mInfo.header_bbox = std::make_pair(lo, hi);
  // Local origin: the header box centre snapped to the coordinate grid, else the offset.
  glm::dvec3 origin = offset;
  if (box_ok) origin = offset + glm::round((0.5 * (lo + hi) - offset) / mRec.scale) * mRec.scale;
  // A box or scale at the edge of the double range overflows: keep the offset then.
  if (!finite3(origin.x, origin.y, origin.z)) origin = offset;
  mInfo.origin = origin;
  mInfo.precision =
      std::min({std::abs(mRec.scale.x), std::abs(mRec.scale.y), std::abs(mRec.scale.z)});
  mRec.delta = offset - origin;
  for (int i = 0; i < 3; ++i) {
    // Every int32 coordinate must give a finite position.
    if (!std::isfinite(2147483648.0 * std::abs(mRec.scale[i]) + std::abs(mRec.delta[i]))) {
      fail(kComponent, mSrc.name(), atByte(131 + 8 * i),
           "scale factor and offset make coordinates overflow (not finite)");
    }
  }

  // Variable length records: the LASzip VLR says how the records are compressed.
  std::optional<LaszipVlr> laszip;
  uint64_t pos = header_size;
  for (uint32_t i = 0; i < vlr_count && pos + 54 <= mRec.data_offset; ++i) {
    uint8_t vh[54];
    if (mSrc.readAt(pos, vh, 54) < 54) break;
    std::string user(reinterpret_cast<const char*>(vh + 2),
                     strnlen(reinterpret_cast<const char*>(vh + 2), 16));
    uint16_t record_id = loadLE<uint16_t>(vh + 18);
    uint16_t length = loadLE<uint16_t>(vh + 20);
    if (user == "laszip encoded" && record_id == 22204) {
      std::vector<uint8_t> payload(length);
      if (pos + 54 + length > mRec.data_offset ||
          mSrc.readAt(pos + 54, payload.data(), length) < length) {
        fail(kComponent, mSrc.name(), atByte(pos), "LASzip VLR runs past the point data offset");
      }
      laszip.emplace();
      if (std::string why = parseLaszipVlr(payload.data(), length, *laszip); !why.empty()) {
        fail(kComponent, mSrc.name(), atByte(pos + 54), why);
      }
    }
    pos += 54 + length;
  }
  if (compressed && !laszip) {
    fail(kComponent, mSrc.name(), atByte(104),
         "point format byte marks LAZ compression but the file has no LASzip VLR");
  }

  mRec.rgb = rgbOffset(mRec.format);
  mInfo.format = laszip ? Format::kLaz : Format::kLas;
  mInfo.format_detail =
      (laszip ? "LAZ " : "LAS ") + version + " format " + std::to_string(mRec.format);
  mInfo.declared_points = mRec.count;
  mInfo.has_declared_points = true;
  mInfo.attributes = kIntensity | kClassification | (mRec.rgb >= 0 ? kColor : 0u);
  if (laszip) {
    mLaz = std::make_unique<LazChunks>(mSrc, kComponent, mRec.data_offset, mRec.count,
                                       mRec.record_length, *laszip, mThreads);
    mInfo.format_detail += " (" + mLaz->describe() + ")";
    return;  // colour depth: from the first chunk, once decoded
  }
  if (mRec.rgb >= 0) detectColorDepth();
  mSrc.seek(mRec.data_offset);
}

// Some writers put 8-bit colours in the 16-bit fields. Look at up to 64k records spread over
// the whole file: if no channel exceeds 255, the values are 8-bit and are used as they are.
void LasReader::detectColorDepth() {
  uint64_t available =
      mSrc.size() > mRec.data_offset ? (mSrc.size() - mRec.data_offset) / mRec.record_length : 0;
  uint64_t n = std::min(mRec.count, available);
  if (n == 0) return;
  uint64_t samples = std::min<uint64_t>(n, 65536);
  auto record = [&](uint64_t s) { return s * n / samples; };
  // Samples less than a page apart share one read (a small file is read in a few), instead of
  // one pread() per sample: that made opening a small file cost more than reading it.
  constexpr uint64_t kMaxGap = 4096, kMaxSpan = uint64_t(1) << 20;
  std::vector<uint8_t> chunk;
  uint16_t max_value = 0;
  bool short_read = false;
  for (uint64_t s = 0; s < samples && !short_read;) {
    const uint64_t first = record(s);
    uint64_t end = s + 1, last = first;
    while (end < samples && (record(end) - last) * mRec.record_length <= kMaxGap &&
           (record(end) - first) * mRec.record_length <= kMaxSpan) {
      last = record(end++);
    }
    chunk.resize(size_t((last - first) * mRec.record_length + 6));
    size_t got = mSrc.readAt(mRec.data_offset + first * mRec.record_length + uint64_t(mRec.rgb),
                             chunk.data(), chunk.size());
    for (; s < end; ++s) {
      size_t at = size_t((record(s) - first) * mRec.record_length);
      short_read = at + 6 > got;
      if (short_read) break;
      for (int c = 0; c < 3; ++c) {
        max_value = std::max(max_value, loadLE<uint16_t>(chunk.data() + at + 2 * c));
      }
    }
  }
  mRec.color16 = max_value > 255;
}

bool LasReader::nextLaz(PointBatch& batch, size_t max_points) {
  if (mChunkNext == mChunkCount) {
    const bool first = mChunkCount == 0;
    if (!mLaz->next(mChunk, mChunkCount)) {
      fail(kComponent, mSrc.name(), "",
           "the chunks hold " + std::to_string(mNext) + " points but the header declares " +
               std::to_string(mRec.count));
    }
    mChunkNext = 0;
    // Colours that never exceed 255 in the first chunk are 8-bit values in 16-bit fields.
    if (first && mRec.rgb >= 0) {
      uint16_t max_value = 0;
      for (uint64_t i = 0; i < mChunkCount; ++i) {
        for (int c = 0; c < 3; ++c) {
          max_value = std::max(max_value, loadLE<uint16_t>(mChunk.data() + i * mRec.record_length +
                                                           mRec.rgb + 2 * c));
        }
      }
      mRec.color16 = max_value > 255;
    }
  }
  size_t n = size_t(std::min<uint64_t>(
      {std::max<size_t>(1, max_points), mRec.count - mNext, mChunkCount - mChunkNext}));
  batch.resize(n);
  decodeRecords(mChunk.data() + mChunkNext * mRec.record_length, n, batch, 0);
  mChunkNext += n;
  mNext += n;
  mStats.points += n;
  return true;
}

bool LasReader::next(PointBatch& batch, size_t max_points) {
  batch.reset(mInfo.attributes);
  if (mNext >= mRec.count) return false;
  if (mLaz) return nextLaz(batch, max_points);
  size_t n = size_t(std::min<uint64_t>(std::max<size_t>(1, max_points), mRec.count - mNext));
  batch.resize(n);
  // Blocks of about 64 KiB: a refill then moves at most a block's tail to the buffer front.
  const size_t block = std::max<size_t>(1, (size_t(64) << 10) / mRec.record_length);
  size_t done = 0;
  while (done < n) {
    size_t want = std::min(n - done, block);
    size_t whole = mSrc.ensure(want * mRec.record_length) / mRec.record_length;
    decodeRecords(mSrc.data(), whole, batch, done);
    mSrc.consume(whole * mRec.record_length);
    done += whole;
    if (whole < want) break;  // the file ends early: deliver the whole records, fail next call
  }
  if (done == 0) {
    fail(kComponent, mSrc.name(), atByte(mSrc.offset()),
         "file ends inside point record " + std::to_string(mNext) + " of " +
             std::to_string(mRec.count) + " declared by the header");
  }
  batch.resize(done);
  mNext += done;
  mStats.points += done;
  return true;
}

void LasReader::decodeRecords(const uint8_t* p, size_t n, PointBatch& batch, size_t at) {
  const bool color = mRec.rgb >= 0;
  for (size_t i = at; i < at + n; ++i, p += mRec.record_length) {
    batch.positions[i] = mRec.position(p);
    batch.intensities[i] = float(mRec.intensity(p));
    batch.classifications[i] = mRec.classification(p);
    if (color) batch.colors[i] = glm::u8vec4(mRec.color(p), 255);
  }
}

}  // namespace

std::unique_ptr<PointReader> openLas(ByteSource source, unsigned decode_threads) {
  return std::make_unique<LasReader>(std::move(source), decode_threads);
}

const LasRecordFormat* lasRecords(const PointReader& reader) {
  const auto* las = dynamic_cast<const LasReader*>(&reader);
  return las ? las->records() : nullptr;
}

}  // namespace tessera::lod::detail
