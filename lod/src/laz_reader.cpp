// LAZ chunks: the LASzip VLR, the chunk table, and chunks decoded on worker threads (see
// laz_reader.h).
#include "laz_reader.h"

#include <algorithm>
#include <cassert>
#include <thread>

#include "reader_util.h"

namespace tessera::lod::detail {
namespace {

constexpr uint32_t kVariableChunks = 0xFFFFFFFFu;
/// Decoded bytes one chunk may take: a larger chunk is refused rather than risking the memory.
constexpr uint64_t kMaxChunkBytes = uint64_t(1) << 30;

const char* compressorName(uint16_t c) {
  switch (c) {
    case 1:
      return "pointwise";
    case 2:
      return "pointwise chunked";
    case 3:
      return "layered chunked";
    default:
      return "unknown";
  }
}

}  // namespace

std::string parseLaszipVlr(const uint8_t* p, size_t n, LaszipVlr& out) {
  if (n < 34) return "LASzip VLR of " + std::to_string(n) + " bytes is shorter than 34";
  out.compressor = loadLE<uint16_t>(p);
  out.coder = loadLE<uint16_t>(p + 2);
  out.version_major = p[4];
  out.version_minor = p[5];
  out.chunk_size = loadLE<uint32_t>(p + 12);
  const uint16_t num_items = loadLE<uint16_t>(p + 32);
  if (34 + size_t(num_items) * 6 > n) {
    return "LASzip VLR lists " + std::to_string(num_items) + " items but holds " +
           std::to_string((n - 34) / 6);
  }
  out.items.clear();
  for (uint16_t i = 0; i < num_items; ++i) {
    const uint8_t* it = p + 34 + 6 * i;
    out.items.push_back({loadLE<uint16_t>(it), loadLE<uint16_t>(it + 2), loadLE<uint16_t>(it + 4)});
  }
  if (out.coder != 0) return "LASzip coder " + std::to_string(out.coder) + " is unknown";
  if (out.compressor < 1 || out.compressor > 3) {
    return "LASzip compressor " + std::to_string(out.compressor) + " is unknown";
  }
  if (out.chunk_size == 0) return "LASzip chunk size is 0";
  return {};
}

std::vector<uint8_t> laszipVlrPayload(const std::vector<laz::Item>& items, uint32_t chunk_size,
                                      bool layered) {
  std::vector<uint8_t> v(34 + 6 * items.size(), 0);
  auto put16 = [&](size_t at, uint16_t x) { std::memcpy(v.data() + at, &x, 2); };
  put16(0, layered ? 3 : 2);  // layered chunked or pointwise chunked
  put16(2, 0);                // arithmetic coder
  v[4] = 3;                   // the LASzip release whose format these chunks follow: 3.4
  v[5] = 4;
  std::memcpy(v.data() + 12, &chunk_size, 4);
  const int64_t none = -1;
  std::memcpy(v.data() + 16, &none, 8);  // no special EVLRs
  std::memcpy(v.data() + 24, &none, 8);
  put16(32, uint16_t(items.size()));
  for (size_t i = 0; i < items.size(); ++i) {
    put16(34 + 6 * i, items[i].type);
    put16(36 + 6 * i, items[i].size);
    put16(38 + 6 * i, items[i].version);
  }
  return v;
}

LazChunks::LazChunks(const ByteSource& src, const char* component, uint64_t data_offset,
                     uint64_t points, uint16_t record_length, const LaszipVlr& vlr,
                     unsigned threads)
    : mSrc(src),
      mComponent(component),
      mDataOffset(data_offset),
      mTotal(points),
      mRecordLength(record_length),
      mVlr(vlr) {
  const bool layered = vlr.compressor == 3;
  if (std::string why = laz::unsupportedItems(vlr.items, layered); !why.empty()) {
    fail("LASzip VLR", "cannot decode this LAZ file: " + why);
  }
  if (laz::recordSize(vlr.items) != record_length) {
    fail("LASzip VLR", "its items make " + std::to_string(laz::recordSize(vlr.items)) +
                           "-byte records but the header says " +
                           std::to_string(record_length));
  }
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  mThreads = std::min(threads, 16u);
  if (mTotal == 0) return;
  if (vlr.compressor == 1) {  // one chunk: every point in one stream, no table
    mPoints.push_back(mTotal);
    mStarts = {mDataOffset, mSrc.size()};
    return;
  }
  if (!readTable()) {
    if (vlr.chunk_size == kVariableChunks) {
      fail("chunk table", mTableNote + "; a file of variable-sized chunks cannot be read "
                                       "without it");
    }
    planFixed();
  }
  for (size_t i = 0; i < mPoints.size(); ++i) {
    if (mPoints[i] * record_length > kMaxChunkBytes) {
      fail("chunk " + std::to_string(i), "holds " + std::to_string(mPoints[i]) +
                                             " points, more than one chunk may decode to (1 GiB)");
    }
  }
}

LazChunks::~LazChunks() = default;

void LazChunks::fail(const std::string& where, const std::string& what) const {
  detail::fail(mComponent, mSrc.name(), where, what);
}

bool LazChunks::readTable() {
  const uint64_t chunks_at = mDataOffset + 8;
  uint8_t word[8];
  if (mSrc.readAt(mDataOffset, word, 8) < 8) fail(atByte(mDataOffset), "file ends before its chunk table offset");
  int64_t table_at = loadLE<int64_t>(word);
  if (table_at == -1 && mSrc.size() >= 8 && mSrc.readAt(mSrc.size() - 8, word, 8) == 8) {
    table_at = loadLE<int64_t>(word);  // a writer that could not seek put it at the end
  }
  auto refuse = [&](const std::string& why) {
    mTableNote = why;
    return false;
  };
  if (uint64_t(table_at) == chunks_at) return refuse("the writer stopped before its chunk table");
  if (table_at < int64_t(chunks_at) || uint64_t(table_at) + 8 > mSrc.size()) {
    return refuse("chunk table offset " + std::to_string(table_at) + " lies outside the file");
  }
  if (mSrc.readAt(uint64_t(table_at), word, 8) < 8) return refuse("file ends in the chunk table");
  const uint32_t version = loadLE<uint32_t>(word), count = loadLE<uint32_t>(word + 4);
  if (version != 0) return refuse("chunk table version " + std::to_string(version) + " is unknown");
  if (count == 0 || count > mTotal) {
    return refuse("chunk table lists " + std::to_string(count) + " chunks for " +
                  std::to_string(mTotal) + " points");
  }
  // Each entry codes in at most 18 bytes (two 32-bit corrections with their bit lengths).
  const uint64_t coded_at = uint64_t(table_at) + 8;
  std::vector<uint8_t> coded(size_t(std::min<uint64_t>(mSrc.size() - coded_at, uint64_t(count) * 18 + 64)));
  coded.resize(mSrc.readAt(coded_at, coded.data(), coded.size()));
  std::vector<uint32_t> points;
  std::vector<uint64_t> bytes;
  const bool variable = mVlr.chunk_size == kVariableChunks;
  try {
    laz::decodeChunkTable(coded, count, variable, points, bytes);
  } catch (const laz::CorruptData& e) {
    return refuse(std::string("chunk table does not decode (") + e.what() + ")");
  }
  mStarts.assign(1, chunks_at);
  for (uint32_t i = 0; i < count; ++i) {
    if (bytes[i] == 0 || mStarts.back() + bytes[i] > uint64_t(table_at)) {
      return refuse("chunk table gives chunk " + std::to_string(i) + " " +
                    std::to_string(bytes[i]) + " bytes, beyond the chunk table's own start");
    }
    mStarts.push_back(mStarts.back() + bytes[i]);
  }
  mPoints.clear();
  uint64_t sum = 0;
  for (uint32_t i = 0; i < count; ++i) {
    uint64_t n = variable ? points[i] : std::min<uint64_t>(mVlr.chunk_size, mTotal - sum);
    if (n == 0) {
      fail("chunk table", "chunk " + std::to_string(i) + " of " + std::to_string(count) +
                              " holds no point; the header declares " + std::to_string(mTotal));
    }
    mPoints.push_back(n);
    sum += n;
  }
  if (sum != mTotal) {
    fail("chunk table", "its chunks hold " + std::to_string(sum) + " points but the header declares " +
                            std::to_string(mTotal));
  }
  return true;
}

void LazChunks::planFixed() {
  mScanning = true;
  mScanAt = mDataOffset + 8;
  mPoints.clear();
  mStarts.clear();
  for (uint64_t left = mTotal; left;) {
    const uint64_t n = std::min<uint64_t>(mVlr.chunk_size, left);
    mPoints.push_back(n);
    left -= n;
  }
}

std::string LazChunks::describe() const {
  std::string s = "LASzip " + std::to_string(mVlr.version_major) + "." +
                  std::to_string(mVlr.version_minor) + " " + compressorName(mVlr.compressor);
  s += ", " + std::to_string(mPoints.size()) + (mPoints.size() == 1 ? " chunk" : " chunks");
  if (mScanning) s += " (" + mTableNote + ": chunks found by scanning)";
  s += ",";
  for (const laz::Item& it : mVlr.items) s += " " + laz::itemName(it);
  return s;
}

LazChunks::Result LazChunks::decodeChunk(size_t i) const {
  const uint64_t begin = mScanning ? mScanAt : mStarts[i];
  uint64_t length;
  if (mScanning) {  // a bound: coded points never take twice their raw size
    length = std::min<uint64_t>(mSrc.size() - std::min(begin, mSrc.size()),
                                mPoints[i] * mRecordLength * 2 + 65536);
  } else {
    length = mStarts[i + 1] - begin;
  }
  const std::string where = "chunk " + std::to_string(i) + " of " + std::to_string(mPoints.size()) +
                            " (bytes " + std::to_string(begin) + "-" +
                            std::to_string(begin + length) + ")";
  std::vector<uint8_t> bytes(static_cast<size_t>(length));
  if (mSrc.readAt(begin, bytes.data(), bytes.size()) < bytes.size() || length == 0) {
    fail(where, "file ends inside the chunk (truncated at byte " + std::to_string(mSrc.size()) + ")");
  }
  Result r;
  r.count = mPoints[i];
  r.records.resize(size_t(r.count * mRecordLength));
  laz::ChunkDecoder decoder(mVlr.items, mVlr.compressor == 3);
  size_t used = 0;
  try {
    used = decoder.decode(bytes, r.count, r.records.data());
  } catch (const laz::CorruptData& e) {
    if (begin + length >= mSrc.size() && std::string(e.what()).find("ends early") != std::string::npos) {
      fail(where, "file ends inside the chunk (truncated at byte " + std::to_string(mSrc.size()) + ")");
    }
    fail(where, std::string("corrupt: ") + e.what());
  }
  if (!mScanning && used != length) {
    fail(where, "corrupt: its points decode from " + std::to_string(used) +
                    " bytes but the chunk table gives " + std::to_string(length));
  }
  r.used = used;
  return r;
}

uint64_t LazChunks::decodeAt(size_t index, std::vector<uint8_t>& records, uint64_t& bytes) const {
  assert(!mScanning && index < mPoints.size());
  Result r = decodeChunk(index);
  records = std::move(r.records);
  bytes = r.used;
  return r.count;
}

void LazChunks::launch() {
  while (mInFlight.size() < mThreads && mNextLaunch < mPoints.size()) {
    const size_t i = mNextLaunch++;
    mInFlight.push_back(std::async(std::launch::async, [this, i] { return decodeChunk(i); }));
  }
}

bool LazChunks::next(std::vector<uint8_t>& records, uint64_t& count) {
  if (mScanning) {  // each chunk's start is known only once the one before it is decoded
    if (mNextDeliver >= mPoints.size()) return false;
    Result r = decodeChunk(mNextDeliver++);
    mScanAt += r.used;
    records = std::move(r.records);
    count = r.count;
    return true;
  }
  launch();
  if (mInFlight.empty()) return false;
  Result r = mInFlight.front().get();
  mInFlight.pop_front();
  ++mNextDeliver;
  launch();
  records = std::move(r.records);
  count = r.count;
  return true;
}

}  // namespace tessera::lod::detail
