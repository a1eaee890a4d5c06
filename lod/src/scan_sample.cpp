// Even samples of raw scans (scan_sample.h): every k-th fixed-size record of LAS and binary PLY
// read in spans, a spread of LAZ chunks decoded, each sample kept as a small file of its kind.
#include <tessera/lod/scan_sample.h>

#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <cstring>
#include <fstream>

#include <tessera/core/check.h>
#include <tessera/core/parallel.h>
#include <tessera/lod/point_writer.h>

#include "byte_source.h"
#include "las_file.h"
#include "laz_reader.h"
#include "reader_util.h"

namespace tessera::lod {

namespace fs = std::filesystem;

/// Fills a ScanSample (a friend): one function per format.
struct ScanSampler {
  /// The sample of `src`, whose header `header` has read; nothing when it cannot be sampled.
  static std::optional<ScanSample> sample(ByteSource src, std::unique_ptr<PointReader> header,
                                          const SampleOptions& options, std::string* why_not,
                                          ScanSample s);
  static void las(const ByteSource& src, uint64_t want, ScanSample& s);
  static void laz(const ByteSource& src, uint64_t want, ScanSample& s, std::string* why_not,
                  bool& sampled);
  static void ply(ByteSource& src, uint64_t want, ScanSample& s, std::string* why_not,
                  bool& sampled);
};

namespace {

constexpr const char* kLasComponent = "lod::readLas()";
constexpr const char* kPlyComponent = "lod::readPly()";
// Two samples less than this far apart share one read; one read spans at most kMaxSpan.
constexpr uint64_t kMaxGap = uint64_t(64) << 10;
constexpr uint64_t kMaxSpan = uint64_t(4) << 20;
// LAZ: at least this many chunks are decoded when the file has them, so that the sample
// reaches every part of a file whose chunks are few and large.
constexpr uint64_t kMinLazChunks = 16;

template <typename T>
void put(std::vector<uint8_t>& v, size_t at, T x) {
  std::memcpy(v.data() + at, &x, sizeof x);
}

/// Copies records first + i * stride (i < count), each `length` bytes, of the records starting
/// at byte `base`, into `out` (count * length bytes), reading spans on `threads` workers.
/// Returns the bytes read. The caller has checked that every record lies in the source.
uint64_t gatherStrided(const ByteSource& src, uint64_t base, uint32_t length, uint64_t stride,
                       uint64_t count, uint8_t* out) {
  struct Span {
    uint64_t first = 0, n = 0;  // sample indices
  };
  std::vector<Span> spans;
  const uint64_t step = stride * length;
  for (uint64_t i = 0; i < count;) {
    Span s{i, 1};
    // Samples join the span while the gap to the next is small and the span stays bounded.
    if (step - length <= kMaxGap)
      s.n = std::min<uint64_t>(count - i, std::max<uint64_t>(1, kMaxSpan / step));
    spans.push_back(s);
    i += s.n;
  }
  std::atomic<uint64_t> read{0};
  parallelFor(spans.size(), threadCount(), [&](size_t k) {
    const Span& s = spans[k];
    const uint64_t at = base + s.first * step;
    if (s.n == 1 || step == length) {  // one record, or records back to back: straight in
      const size_t n = size_t(s.n == 1 ? length : s.n * length);
      if (src.readAt(at, out + s.first * length, n) != n)
        throw ReadError("lod::ScanSample: " + src.name() + ": " + detail::atByte(at) +
                        ": the file shrank while it was sampled");
      read += n;
      return;
    }
    std::vector<uint8_t> buffer(size_t((s.n - 1) * step + length));
    if (src.readAt(at, buffer.data(), buffer.size()) != buffer.size())
      throw ReadError("lod::ScanSample: " + src.name() + ": " + detail::atByte(at) +
                      ": the file shrank while it was sampled");
    for (uint64_t j = 0; j < s.n; ++j)
      std::memcpy(out + (s.first + j) * length, buffer.data() + j * step, length);
    read += buffer.size();
  });
  return read.load();
}

/// The public header of a LAS file holding `count` records right after it: no VLRs, no
/// compression bits, no EVLRs; bounds, scale and offset as the original's.
std::vector<uint8_t> sampleLasHeader(const detail::LasParts& parts, uint64_t count) {
  std::vector<uint8_t> h = parts.header;
  put<uint32_t>(h, 96, uint32_t(h.size()));  // point data right after the header
  put<uint32_t>(h, 100, 0);                  // no VLRs
  h[104] = uint8_t(parts.format);
  put<uint32_t>(h, 107, count <= 0xFFFFFFFFu ? uint32_t(count) : 0u);
  if (parts.minor >= 4 && h.size() >= 255) {
    put<uint64_t>(h, 235, 0);  // no EVLRs
    put<uint32_t>(h, 243, 0);
    put<uint64_t>(h, 247, count);
  }
  return h;
}

/// At most this many bytes of records in a sample, whatever their length.
constexpr uint64_t kMaxSampleBytes = uint64_t(256) << 20;

/// The points wanted, fewer where records are so long that they would pass kMaxSampleBytes.
uint64_t sampleLimit(uint64_t want, uint64_t record_length) {
  return std::max<uint64_t>(
      1, std::min(want, kMaxSampleBytes / std::max<uint64_t>(1, record_length) / 2));
}

/// Records (or vertices) k * stride that sample `total` to about `want`.
uint64_t strideFor(uint64_t total, uint64_t want) {
  return std::max<uint64_t>(1, total / want);
}

/// Sample indices of `total` records taken every `stride`.
uint64_t sampledCount(uint64_t total, uint64_t stride) {
  return total == 0 ? 0 : (total - 1) / stride + 1;
}

/// Bytes of one PLY scalar type; 0 for a name that is not one.
size_t plyTypeSize(std::string_view t) {
  if (t == "char" || t == "int8" || t == "uchar" || t == "uint8") return 1;
  if (t == "short" || t == "int16" || t == "ushort" || t == "uint16") return 2;
  if (t == "int" || t == "int32" || t == "uint" || t == "uint32" || t == "float" || t == "float32")
    return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

}  // namespace

void ScanSampler::las(const ByteSource& src, uint64_t want, ScanSample& s) {
  const detail::LasParts parts = detail::readLasParts(src, kLasComponent);
  const uint64_t length = parts.record_length;
  const uint64_t available =
      src.size() > parts.data_offset ? (src.size() - parts.data_offset) / length : 0;
  if (available < parts.count)  // the words the reader says when it reaches the end
    detail::fail(kLasComponent, src.name(), detail::atByte(parts.data_offset + available * length),
                 "file ends inside point record " + std::to_string(available) + " of " +
                     std::to_string(parts.count) + " declared by the header");
  s.mStride = strideFor(parts.count, sampleLimit(want, length));
  s.mPoints = sampledCount(parts.count, s.mStride);
  s.mBytes = sampleLasHeader(parts, s.mPoints);
  const size_t at = s.mBytes.size();
  s.mBytes.resize(at + size_t(s.mPoints * length));
  s.mBytesRead = gatherStrided(src, parts.data_offset, uint32_t(length), s.mStride, s.mPoints,
                               s.mBytes.data() + at);
  s.mExtension = ".las";
}

void ScanSampler::laz(const ByteSource& src, uint64_t want, ScanSample& s, std::string* why_not,
                      bool& sampled) {
  const detail::LasParts parts = detail::readLasParts(src, kLasComponent);
  if (!parts.laszip) detail::fail(kLasComponent, src.name(), "", "LAZ file without a LASzip VLR");
  const detail::LazChunks chunks(src, kLasComponent, parts.data_offset, parts.count,
                                 parts.record_length, *parts.laszip, 1);
  if (!chunks.seekable()) {
    if (why_not)
      *why_not = "its chunks cannot be found without decoding the file (" + chunks.describe() + ")";
    sampled = false;
    return;
  }
  // Chunks spread evenly through the file, enough to hold twice the points wanted; each keeps
  // every k-th record as it is decoded, so at most a chunk a worker is held whole.
  want = sampleLimit(want, parts.record_length);
  const uint64_t count = chunks.chunkCount();
  const uint64_t per_chunk = std::max<uint64_t>(1, parts.count / std::max<uint64_t>(1, count));
  const uint64_t decode = std::min<uint64_t>(
      count,
      std::max<uint64_t>(std::min(count, kMinLazChunks), (2 * want + per_chunk - 1) / per_chunk));
  s.mChunkCount = count;
  uint64_t decoded = 0;
  for (uint64_t j = 0; j < decode; ++j) {
    s.mChunks.push_back(j * count / decode);
    decoded += chunks.chunkPoints(size_t(s.mChunks.back()));
  }
  s.mStride = strideFor(decoded, want);
  const size_t length = parts.record_length;
  std::vector<uint64_t> first(decode + 1, 0);  // each chunk's first sample
  for (uint64_t j = 0; j < decode; ++j)
    first[j + 1] = first[j] + sampledCount(chunks.chunkPoints(size_t(s.mChunks[j])), s.mStride);
  s.mPoints = first[decode];
  s.mBytes = sampleLasHeader(parts, s.mPoints);
  const size_t at = s.mBytes.size();
  s.mBytes.resize(at + size_t(s.mPoints) * length);
  std::atomic<uint64_t> read{0};
  parallelFor(decode, threadCount(), [&](size_t j) {
    std::vector<uint8_t> records;
    uint64_t bytes = 0;
    const uint64_t n = chunks.decodeAt(size_t(s.mChunks[j]), records, bytes);
    read += bytes;
    uint8_t* out = s.mBytes.data() + at + first[j] * length;
    for (uint64_t i = 0; i < n; i += s.mStride, out += length)
      std::memcpy(out, records.data() + i * length, length);
  });
  s.mBytesRead = read.load();
  s.mExtension = ".las";
  sampled = true;
}

void ScanSampler::ply(ByteSource& src, uint64_t want, ScanSample& s, std::string* why_not,
                      bool& sampled) {
  sampled = false;
  // The reader has parsed this header already: here only where the vertices lie and how long
  // each is. Elements before the vertices must have fixed-size instances to be stepped over.
  std::string_view line;
  src.rewind();
  src.readLine(line);  // "ply"
  std::string format;
  struct Element {
    std::string name;
    uint64_t count = 0, size = 0;
    bool fixed = true;
    std::string properties;  // the property lines, as written
  };
  std::vector<Element> elements;
  bool ended = false;
  while (!ended && src.readLine(line, 1 << 16)) {
    std::string_view rest = line;
    const std::string_view key = detail::nextToken(rest);
    if (key == "end_header") ended = true;
    if (key == "format") format = std::string(detail::nextToken(rest));
    if (key == "element") {
      Element e;
      e.name = std::string(detail::nextToken(rest));
      if (!detail::parseUint(detail::nextToken(rest), e.count)) break;
      elements.push_back(std::move(e));
    }
    if (key == "property" && !elements.empty()) {
      const std::string_view type = detail::nextToken(rest);
      Element& e = elements.back();
      e.fixed = e.fixed && type != "list";
      e.size += plyTypeSize(type);
      if (e.properties.size() < (size_t(1) << 20)) e.properties += std::string(line) + "\n";
    }
  }
  if (!ended || format.empty())  // the reader refuses such a header first
    detail::fail(kPlyComponent, src.name(), "header", "no end_header or format line");
  if (format == "ascii") {
    if (why_not) *why_not = "ASCII PLY has vertices of varying length";
    return;
  }
  uint64_t offset = src.offset();
  const Element* vertex = nullptr;
  for (const Element& e : elements) {
    if (e.name == "vertex") {
      vertex = &e;
      break;
    }
    if (!e.fixed) {
      if (why_not) *why_not = "element '" + e.name + "' before the vertices holds lists";
      return;
    }
    // Elements that would reach past the end of any file end the walk: the file is short.
    if (e.size != 0 && e.count > (src.size() - std::min(offset, src.size())) / e.size)
      detail::fail(kPlyComponent, src.name(), detail::atByte(src.size()),
                   "file ends inside " + e.name + " (" + std::to_string(e.count) +
                       " declared by the header)");
    offset += e.count * e.size;
  }
  if (!vertex || !vertex->fixed || vertex->size == 0) {
    if (why_not) *why_not = "its vertices hold lists";
    return;
  }
  const uint64_t length = vertex->size;
  const uint64_t available = src.size() > offset ? (src.size() - offset) / length : 0;
  if (available < vertex->count)
    detail::fail(kPlyComponent, src.name(), detail::atByte(offset + available * length),
                 "file ends inside vertex " + std::to_string(available) + " of " +
                     std::to_string(vertex->count) + " declared by the header");
  s.mStride = strideFor(vertex->count, sampleLimit(want, length));
  s.mPoints = sampledCount(vertex->count, s.mStride);
  const std::string header = "ply\nformat " + format + " 1.0\nelement vertex " +
                             std::to_string(s.mPoints) + "\n" + vertex->properties + "end_header\n";
  s.mBytes.assign(header.begin(), header.end());
  const size_t at = s.mBytes.size();
  s.mBytes.resize(at + size_t(s.mPoints * length));
  s.mBytesRead =
      gatherStrided(src, offset, uint32_t(length), s.mStride, s.mPoints, s.mBytes.data() + at);
  s.mExtension = ".ply";
  sampled = true;
}

std::optional<ScanSample> ScanSampler::sample(ByteSource src, std::unique_ptr<PointReader> header,
                                              const SampleOptions& options, std::string* why_not,
                                              ScanSample s) {
  TESSERA_CHECK(options.points >= 1, "lod::ScanSample::read(): ask for at least one point");
  s.mInfo = header->info();
  header.reset();
  bool sampled = true;
  switch (s.mInfo.format) {
    case Format::kLas:
      ScanSampler::las(src, options.points, s);
      break;
    case Format::kLaz:
      ScanSampler::laz(src, options.points, s, why_not, sampled);
      break;
    case Format::kPly:
      ScanSampler::ply(src, options.points, s, why_not, sampled);
      break;
    default:
      if (why_not)
        *why_not = std::string(formatName(s.mInfo.format)) + " has no fixed-size records to sample";
      sampled = false;
  }
  if (!sampled) return std::nullopt;
  return s;
}

std::optional<ScanSample> ScanSample::read(const fs::path& path, const SampleOptions& options,
                                           std::string* why_not) {
  auto header = openPointReader(path);  // the reader's own checks and errors first
  ScanSample s;
  s.mName = "sample of " + path.filename().string();
  return ScanSampler::sample(ByteSource::openFile(path, "lod::ScanSample"), std::move(header),
                             options, why_not, std::move(s));
}

std::optional<ScanSample> ScanSample::read(std::span<const uint8_t> bytes, const std::string& name,
                                           const SampleOptions& options, std::string* why_not) {
  auto header = openPointReader(bytes, name);
  ScanSample s;
  s.mName = "sample of " + fs::path(name).filename().string();
  return ScanSampler::sample(ByteSource::fromMemory(bytes, name), std::move(header), options,
                             why_not, std::move(s));
}

std::unique_ptr<PointReader> ScanSample::reader() const {
  return openPointReader(std::span<const uint8_t>(mBytes), mName + mExtension);
}

void ScanSample::write(const fs::path& path) const {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(mBytes.data()), std::streamsize(mBytes.size()));
  f.close();
  if (!f) throw WriteError("lod::ScanSample::write(): " + path.string() + ": cannot write");
}

BuildReport buildSampleStore(const ScanSample& sample, const fs::path& output, int threads) {
  // The sample beside the output, under a name of this process, removed however the build ends.
  const fs::path input =
      output.parent_path() / (output.filename().string() + "." + std::to_string(::getpid()) +
                              ".sample" + sample.extension());
  struct Remove {
    fs::path path;
    ~Remove() {
      std::error_code ec;
      fs::remove(path, ec);
    }
  } remove{input};
  sample.write(input);
  BuildOptions o;
  o.quiet = true;
  o.threads = threads;
  o.zstd_level = 1;
  return buildStore({input}, output, o);
}

}  // namespace tessera::lod
