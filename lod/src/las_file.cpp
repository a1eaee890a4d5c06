// LAS and LAZ files as records (see las_file.h). Header offsets: ASPRS LAS 1.4 R15, table 3.
#include "las_file.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <thread>

#include "reader_util.h"

namespace tessera::lod::detail {
namespace {

constexpr uint64_t kChunkPoints = 50000;  // LASzip's default chunk size
constexpr uint64_t kMaxEvlrBytes = uint64_t(1) << 30;
constexpr uint16_t kBaseRecord[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

template <typename T>
void put(std::vector<uint8_t>& v, size_t at, T x) {
  std::memcpy(v.data() + at, &x, sizeof x);
}

}  // namespace

LasParts readLasParts(const ByteSource& src, const char* component) {
  LasParts p;
  uint8_t h[375] = {};
  const size_t got = src.readAt(0, h, sizeof h);
  if (got < 227 || std::memcmp(h, "LASF", 4) != 0) {
    fail(component, src.name(), atByte(0), "not a LAS file (no 'LASF' and 227-byte header)");
  }
  p.minor = h[25];
  const uint16_t header_size = loadLE<uint16_t>(h + 94);
  p.data_offset = loadLE<uint32_t>(h + 96);
  const uint32_t vlr_count = loadLE<uint32_t>(h + 100);
  p.format = h[104] & 0x3F;
  p.record_length = loadLE<uint16_t>(h + 105);
  p.count = loadLE<uint32_t>(h + 107);
  if (p.minor >= 4 && got >= 255 && loadLE<uint64_t>(h + 247) != 0) {
    p.count = loadLE<uint64_t>(h + 247);
  }
  if (header_size < 227 || header_size > got || p.data_offset < header_size) {
    fail(component, src.name(), atByte(94), "header size or point data offset out of range");
  }
  p.header.assign(h, h + header_size);
  for (int i = 0; i < 3; ++i) {
    p.scale[i] = loadLE<double>(h + 131 + 8 * i);
    p.offset[i] = loadLE<double>(h + 155 + 8 * i);
  }
  uint64_t pos = header_size;
  for (uint32_t i = 0; i < vlr_count && pos + 54 <= p.data_offset; ++i) {
    uint8_t vh[54];
    if (src.readAt(pos, vh, 54) < 54) break;
    const uint16_t length = loadLE<uint16_t>(vh + 20);
    if (pos + 54 + length > p.data_offset) {
      fail(component, src.name(), atByte(pos), "VLR runs past the point data offset");
    }
    std::vector<uint8_t> vlr(size_t(54) + length);
    std::memcpy(vlr.data(), vh, 54);
    src.readAt(pos + 54, vlr.data() + 54, length);
    const bool laszip = loadLE<uint16_t>(vlr.data() + 18) == 22204 &&
                        std::strncmp(reinterpret_cast<const char*>(vlr.data() + 2),
                                     "laszip encoded", 16) == 0;
    if (laszip) {
      p.laszip.emplace();
      if (std::string why = parseLaszipVlr(vlr.data() + 54, length, *p.laszip); !why.empty()) {
        fail(component, src.name(), atByte(pos + 54), why);
      }
    } else {
      p.vlrs.push_back(std::move(vlr));
    }
    pos += 54 + length;
  }
  if (p.minor >= 4 && got >= 247) {
    uint64_t at = loadLE<uint64_t>(h + 235);
    const uint32_t n = loadLE<uint32_t>(h + 243);
    uint64_t total = 0;
    for (uint32_t i = 0; i < n && at; ++i) {
      uint8_t eh[60];
      if (src.readAt(at, eh, 60) < 60) {
        fail(component, src.name(), atByte(at), "file ends inside EVLR " + std::to_string(i));
      }
      const uint64_t length = loadLE<uint64_t>(eh + 20);
      total += length;
      if (length > src.size() - std::min(src.size(), at + 60) || total > kMaxEvlrBytes) {
        fail(component, src.name(), atByte(at + 20),
             "EVLR " + std::to_string(i) + " of " + std::to_string(length) +
                 " bytes runs past the end of the file");
      }
      std::vector<uint8_t> evlr(size_t(60 + length));
      std::memcpy(evlr.data(), eh, 60);
      src.readAt(at + 60, evlr.data() + 60, size_t(length));
      p.evlrs.push_back(std::move(evlr));
      at += 60 + length;
    }
  }
  return p;
}

void forEachRecordBlock(const std::filesystem::path& path, unsigned threads,
                        const std::function<void(const uint8_t*, uint64_t)>& fn) {
  constexpr const char* kComponent = "lod::readLasRecords()";
  ByteSource src = ByteSource::openFile(path, kComponent);
  LasParts p = readLasParts(src, kComponent);
  if (p.record_length == 0) fail(kComponent, src.name(), atByte(105), "record length is 0");
  if (p.laszip) {
    LazChunks chunks(src, kComponent, p.data_offset, p.count, p.record_length, *p.laszip,
                     threads);
    std::vector<uint8_t> records;
    uint64_t n = 0;
    while (chunks.next(records, n)) fn(records.data(), n);
    return;
  }
  const uint64_t block = std::max<uint64_t>(1, (uint64_t(4) << 20) / p.record_length);
  std::vector<uint8_t> buf(size_t(block * p.record_length));
  for (uint64_t at = 0; at < p.count; at += block) {
    const uint64_t n = std::min(block, p.count - at);
    const size_t want = size_t(n * p.record_length);
    if (src.readAt(p.data_offset + at * p.record_length, buf.data(), want) < want) {
      fail(kComponent, src.name(), atByte(src.size()),
           "file ends inside the point records (the header declares " +
               std::to_string(p.count) + ")");
    }
    fn(buf.data(), n);
  }
}

LasParts newLasParts(int format, uint16_t extra_bytes, const glm::dvec3& scale,
                     const glm::dvec3& offset, int minor) {
  LasParts p;
  p.format = format;
  p.minor = minor ? minor : format >= 6 ? 4 : 2;
  const uint16_t header_size = p.minor >= 4 ? 375 : p.minor == 3 ? 235 : 227;
  p.record_length = uint16_t(kBaseRecord[format] + extra_bytes);
  p.scale = scale;
  p.offset = offset;
  p.header.assign(header_size, 0);
  std::memcpy(p.header.data(), "LASF", 4);
  p.header[24] = 1;
  p.header[25] = uint8_t(p.minor);
  std::string sys = "tessera";
  std::memcpy(p.header.data() + 26, sys.data(), sys.size());  // system identifier
  std::memcpy(p.header.data() + 58, sys.data(), sys.size());  // generating software
  put<uint16_t>(p.header, 90, 1);
  put<uint16_t>(p.header, 92, 2026);
  put<uint16_t>(p.header, 94, header_size);
  for (int i = 0; i < 3; ++i) {
    put<double>(p.header, 131 + 8 * size_t(i), scale[i]);
    put<double>(p.header, 155 + 8 * size_t(i), offset[i]);
  }
  return p;
}

LasFileWriter::LasFileWriter(const std::filesystem::path& path, LasParts parts, bool laz,
                             unsigned threads, const char* component)
    : mFile(path, component), mParts(std::move(parts)), mLaz(laz), mComponent(component) {
  const int f = mParts.format;
  if (f < 0 || f > 10 || mParts.record_length < kBaseRecord[f]) {
    throw WriteError(std::string(component) + ": point format " + std::to_string(f) +
                     " with " + std::to_string(mParts.record_length) + "-byte records");
  }
  if (f >= 6 && mParts.minor < 4) {
    throw WriteError(std::string(component) + ": point format " + std::to_string(f) +
                     " needs LAS 1.4");
  }
  if (mLaz) {
    mItems = laz::itemsForFormat(f, uint16_t(mParts.record_length - kBaseRecord[f]));
    if (mItems.empty()) {
      throw WriteError(std::string(component) + ": " + path.string() + ": point format " +
                       std::to_string(f) +
                       " carries waveform packets, which LAZ output does not write (write .las)");
    }
  }
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  mThreads = std::min(threads, 16u);
  std::vector<std::vector<uint8_t>> vlrs = mParts.vlrs;
  if (mLaz) {
    std::vector<uint8_t> v(54, 0);
    std::memcpy(v.data() + 2, "laszip encoded", 14);
    put<uint16_t>(v, 18, 22204);
    const auto payload = laszipVlrPayload(mItems, uint32_t(kChunkPoints), f >= 6);
    put<uint16_t>(v, 20, uint16_t(payload.size()));
    std::memcpy(v.data() + 22, "tessera", 7);
    v.insert(v.end(), payload.begin(), payload.end());
    vlrs.push_back(std::move(v));
  }
  uint64_t offset = mParts.header.size();
  for (const auto& v : vlrs) offset += v.size();
  if (offset > 0xFFFFFFFFu) throw WriteError(std::string(component) + ": VLRs too large");
  put<uint32_t>(mParts.header, 96, uint32_t(offset));
  put<uint32_t>(mParts.header, 100, uint32_t(vlrs.size()));
  mParts.header[104] = uint8_t(f | (mLaz ? 0x80 : 0));
  put<uint16_t>(mParts.header, 105, mParts.record_length);
  mFile.write(mParts.header);
  for (const auto& v : vlrs) mFile.write(v);
  if (mLaz) {
    mTableOffsetAt = mFile.written();
    mFile.write(std::vector<uint8_t>(8, 0));
  }
  mLo = glm::dvec3(std::numeric_limits<double>::max());
  mHi = glm::dvec3(-std::numeric_limits<double>::max());
}

LasFileWriter::~LasFileWriter() {
  for (auto& f : mEncoding) f.wait();
}

void LasFileWriter::add(const uint8_t* records, uint64_t n) {
  const uint32_t rl = mParts.record_length;
  const bool extended = mParts.format >= 6;
  for (uint64_t i = 0; i < n; ++i) {
    const uint8_t* r = records + i * rl;
    const glm::dvec3 p(double(loadLE<int32_t>(r)) * mParts.scale.x + mParts.offset.x,
                       double(loadLE<int32_t>(r + 4)) * mParts.scale.y + mParts.offset.y,
                       double(loadLE<int32_t>(r + 8)) * mParts.scale.z + mParts.offset.z);
    mLo = glm::min(mLo, p);
    mHi = glm::max(mHi, p);
    const uint32_t ret = extended ? (r[14] & 15u) : (r[14] & 7u);
    if (ret >= 1 && ret <= 15) ++mReturns[ret - 1];
  }
  mCount += n;
  if (!mLaz) {
    mFile.write(records, size_t(n * rl));
    return;
  }
  for (uint64_t i = 0; i < n;) {
    const uint64_t room = kChunkPoints - mPending.size() / rl;
    const uint64_t take = std::min(room, n - i);
    mPending.insert(mPending.end(), records + i * rl, records + (i + take) * rl);
    i += take;
    if (mPending.size() / rl == kChunkPoints) flushChunk();
  }
}

void LasFileWriter::flushChunk() {
  if (mPending.empty()) return;
  const uint32_t points = uint32_t(mPending.size() / mParts.record_length);
  mEncodingPoints.push_back(points);
  mEncoding.push_back(std::async(
      std::launch::async, [records = std::move(mPending), points, items = mItems,
                           layered = mParts.format >= 6] {
        std::vector<uint8_t> out;
        laz::ChunkEncoder(items, layered).encode(records.data(), points, out);
        return out;
      }));
  mPending = {};
  writeReady(false);
}

void LasFileWriter::writeReady(bool all) {
  while (!mEncoding.empty() && (all || mEncoding.size() >= mThreads)) {
    const std::vector<uint8_t> bytes = mEncoding.front().get();
    mEncoding.pop_front();
    mFile.write(bytes);
    mChunkPoints.push_back(mEncodingPoints.front());
    mEncodingPoints.pop_front();
    mChunkBytes.push_back(bytes.size());
  }
}

void LasFileWriter::commit() {
  if (mLaz) {
    flushChunk();
    writeReady(true);
    const uint64_t table_at = mFile.written();
    std::vector<uint8_t> table(8, 0);
    put<uint32_t>(table, 4, uint32_t(mChunkBytes.size()));
    if (!mChunkBytes.empty()) laz::encodeChunkTable(mChunkPoints, mChunkBytes, false, table);
    mFile.write(table);
    mFile.patch(mTableOffsetAt, &table_at, 8);
  }
  std::vector<uint8_t>& h = mParts.header;
  const bool extended = mParts.format >= 6;
  const bool legacy_fits = !extended && mCount <= 0xFFFFFFFFu;
  put<uint32_t>(h, 107, legacy_fits ? uint32_t(mCount) : 0);
  for (int i = 0; i < 5; ++i) {
    put<uint32_t>(h, 111 + 4 * size_t(i), legacy_fits ? uint32_t(mReturns[i]) : 0);
  }
  if (mCount == 0) mLo = mHi = glm::dvec3(0.0);
  for (int i = 0; i < 3; ++i) {
    put<double>(h, 179 + 16 * size_t(i), mHi[i]);
    put<double>(h, 187 + 16 * size_t(i), mLo[i]);
  }
  if (mParts.minor >= 3 && h.size() >= 235) put<uint64_t>(h, 227, 0);  // no waveform data
  if (mParts.minor >= 4 && h.size() >= 375) {
    const uint64_t evlr_at = mParts.evlrs.empty() ? 0 : mFile.written();
    for (const auto& e : mParts.evlrs) mFile.write(e);
    put<uint64_t>(h, 235, evlr_at);
    put<uint32_t>(h, 243, uint32_t(mParts.evlrs.size()));
    put<uint64_t>(h, 247, mCount);
    for (int i = 0; i < 15; ++i) put<uint64_t>(h, 255 + 8 * size_t(i), mReturns[i]);
  }
  mFile.patch(0, h.data(), h.size());
  mFile.commit();
}

}  // namespace tessera::lod::detail
