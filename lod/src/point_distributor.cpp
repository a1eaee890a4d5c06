#include "point_distributor.h"

#include "file_io.h"
#include "morton.h"
#include "readers.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <exception>
#include <limits>
#include <mutex>
#include <thread>
#include <tuple>

#include <tessera/core/parallel.h>
#include <tessera/core/progress.h>
#include <tessera/lod/point_store.h>

namespace tessera::lod {
namespace {

constexpr int kCountLevel = 7;  // 128^3 counting grid
constexpr uint32_t kCountRes = 1u << kCountLevel;

size_t gridIndex(uint32_t x, uint32_t y, uint32_t z) {
  return (size_t(z) * kCountRes + y) * kCountRes + x;
}

ReadError aoMismatchError(size_t given, const std::string& held) {
  return ReadError("lod::buildStore(): ambient occlusion is given for " + std::to_string(given) +
                   " points but the inputs hold " + held +
                   " (inputs changed since it was computed?)");
}

}  // namespace

uint64_t CellKey::morton() const {
  // Cells deeper than level 21 share codes with their neighbours; callers break ties by x, y, z.
  int shift = std::max(0, int(level) - 21);
  return mortonEncode(x >> shift, y >> shift, z >> shift);
}

bool CellKey::operator<(const CellKey& o) const {
  if (level != o.level) return level < o.level;
  uint64_t a = morton(), b = o.morton();
  if (a != b) return a < b;
  return std::tie(x, y, z) < std::tie(o.x, o.y, o.z);
}

namespace {

/// Writes blocks on a thread of its own, so reading the inputs goes on while a block is on its
/// way to the disk; buffers are recycled.
class BlockWriter {
 public:
  BlockWriter(int fd, std::string name) : mFd(fd), mName(std::move(name)) {
    mThread = std::thread([this] { run(); });
  }
  ~BlockWriter() { stop(); }
  /// A buffer of at least `n` bytes to fill and hand to write().
  AlignedBytes take(size_t n) {
    AlignedBytes b;
    {
      std::lock_guard lock(mMutex);
      if (!mFree.empty()) {
        b = std::move(mFree.back());
        mFree.pop_back();
      }
    }
    b.reserve(n);
    return b;
  }
  void write(AlignedBytes bytes, size_t n, uint64_t offset) {
    std::unique_lock lock(mMutex);
    mRoom.wait(lock, [&] { return mQueue.size() < kInFlight || mError; });
    if (mError) std::rethrow_exception(mError);
    mQueue.push_back({std::move(bytes), n, offset});
    mWake.notify_one();
  }
  /// Waits for every block to be written; rethrows a write's failure.
  void finish() {
    stop();
    if (mError) std::rethrow_exception(mError);
  }

 private:
  /// Lets the thread write what is queued, then joins it.
  void stop() {
    if (!mThread.joinable()) return;
    {
      std::lock_guard lock(mMutex);
      mDone = true;
    }
    mWake.notify_all();
    mThread.join();
  }
  struct Job {
    AlignedBytes bytes;
    size_t n;
    uint64_t offset;
  };
  static constexpr size_t kInFlight = 16;
  void run() {
    for (;;) {
      Job job;
      {
        std::unique_lock lock(mMutex);
        mWake.wait(lock, [&] { return !mQueue.empty() || mDone; });
        if (mQueue.empty()) return;
        job = std::move(mQueue.front());
        mQueue.pop_front();
      }
      try {
        if (!mError) pwriteAll(mFd, job.bytes.data(), job.n, job.offset, mName);
      } catch (...) {
        std::lock_guard lock(mMutex);
        mError = std::current_exception();
      }
      {
        std::lock_guard lock(mMutex);
        mFree.push_back(std::move(job.bytes));
      }
      mRoom.notify_one();
    }
  }
  int mFd;
  std::string mName;
  std::thread mThread;
  std::mutex mMutex;
  std::condition_variable mWake, mRoom;
  std::deque<Job> mQueue;
  std::vector<AlignedBytes> mFree;
  std::exception_ptr mError;
  bool mDone = false;
};

}  // namespace

// A compact record: x, y, z as int32 multiples of the quantum, then rgb, classification,
// intensity, source, ao (little-endian, unaligned).
void encodeTemp(const TempLayout& layout, const BuildPoint* pts, uint64_t count, uint8_t* out) {
  if (!layout.compact()) {
    std::memcpy(out, pts, count * sizeof(BuildPoint));
    return;
  }
  constexpr size_t R = TempLayout::kCompactRecord;
  constexpr double kLimit = 2147483647.0;
  const double inv = 1.0 / layout.quantum;
  for (uint64_t i = 0; i < count; ++i) {
    const BuildPoint& p = pts[i];
    uint8_t* r = out + i * R;
    int32_t k[3];
    for (int a = 0; a < 3; ++a) {
      const double v = std::round(p.position[a] * inv);
      if (!(std::fabs(v) <= kLimit))
        throw TempRangeError("a position lies beyond 2^31 quanta of the origin");
      k[a] = int32_t(v);
    }
    std::memcpy(r, k, 12);
    r[12] = p.rgb.r;
    r[13] = p.rgb.g;
    r[14] = p.rgb.b;
    r[15] = p.classification;
    std::memcpy(r + 16, &p.intensity, 2);
    std::memcpy(r + 18, &p.source, 2);
    r[20] = p.ao;
  }
}

void decodeTemp(const TempLayout& layout, const uint8_t* in, uint64_t count, BuildPoint* out) {
  if (!layout.compact()) {
    std::memcpy(out, in, count * sizeof(BuildPoint));
    return;
  }
  constexpr size_t R = TempLayout::kCompactRecord;
  const double q = layout.quantum;
  for (uint64_t i = 0; i < count; ++i) {
    const uint8_t* r = in + i * R;
    int32_t k[3];
    std::memcpy(k, r, 12);
    BuildPoint& p = out[i];
    p.position = glm::dvec3(double(k[0]) * q, double(k[1]) * q, double(k[2]) * q);
    p.rgb = glm::u8vec3(r[12], r[13], r[14]);
    p.classification = r[15];
    std::memcpy(&p.intensity, r + 16, 2);
    std::memcpy(&p.source, r + 18, 2);
    p.ao = r[20];
  }
}

void readTempPoints(const TempLayout& layout, int fd, uint64_t first, uint64_t count,
                    BuildPoint* out, const std::string& name) {
  if (!layout.compact()) {
    preadAll(fd, out, count * sizeof(BuildPoint), first * sizeof(BuildPoint), name);
    return;
  }
  constexpr size_t R = TempLayout::kCompactRecord;
  thread_local std::vector<uint8_t> buf;
  buf.resize(count * R);
  preadAll(fd, buf.data(), buf.size(), first * R, name);
  decodeTemp(layout, buf.data(), count, out);
}

void writeTempPoints(const TempLayout& layout, int fd, uint64_t first, const BuildPoint* pts,
                     uint64_t count, const std::string& name) {
  if (!layout.compact()) {
    pwriteAll(fd, pts, count * sizeof(BuildPoint), first * sizeof(BuildPoint), name);
    return;
  }
  constexpr size_t R = TempLayout::kCompactRecord;
  thread_local std::vector<uint8_t> buf;
  buf.resize(count * R);
  encodeTemp(layout, pts, count, buf.data());
  pwriteAll(fd, buf.data(), buf.size(), first * R, name);
}

PointDistributor::PointDistributor(const std::vector<std::filesystem::path>& inputs, bool quiet)
    : mQuiet(quiet) {
  if (inputs.empty()) throw ReadError("lod::buildStore(): no input files");
  uint32_t next_source = 0;
  for (const auto& path : inputs) {
    auto reader = openPointReader(path);  // throws ReadError naming the file
    const SourceInfo& info = reader->info();
    if (mInputs.empty()) mFirstOrigin = info.origin;
    mInputs.push_back({path, uint16_t(next_source)});
    if (const detail::LasRecordFormat* las = detail::lasRecords(*reader))
      mLas.push_back({{path.string(), *las, glm::dvec3(0.0), uint16_t(next_source)}, info.origin});
    // A .conf's and an E57's scans are sources of their own (a scan's points carry its index).
    const bool per_scan = (info.format == Format::kStanfordConf || info.format == Format::kE57) &&
                          !info.scans.empty() && (info.attributes & kScanIndex);
    if (per_scan) {
      for (const ScanInfo& s : info.scans)
        mSourceNames.push_back(path.filename().string() + ":" + s.name);
      next_source += uint32_t(info.scans.size());
    } else {
      mSourceNames.push_back(path.filename().string());
      next_source += 1;
    }
    if (next_source > 65535)
      throw ReadError("lod::buildStore(): more than 65535 sources (files and scans)");
    mAttributes |= info.attributes & (kColor | kIntensity | kClassification);
    mDeclared += info.declared_points;
    if (mInputs.size() == 1 || mHeaderBox) {
      if (info.header_bbox) {
        auto [lo, hi] = *info.header_bbox;
        mHeaderBox = mInputs.size() == 1 ? std::make_pair(lo, hi)
                                         : std::make_pair(glm::min(mHeaderBox->first, lo),
                                                          glm::max(mHeaderBox->second, hi));
      } else {
        mHeaderBox.reset();
      }
    }
    // The finest declared resolution over all inputs; unknown (0) anywhere means unknown.
    double p = info.precision;
    mPrecision = mInputs.size() == 1               ? p
                 : (p == 0.0 || mPrecision == 0.0) ? 0.0
                                                   : std::min(mPrecision, p);
  }
}

void PointDistributor::setAmbientOcclusion(std::span<const uint8_t> ao) {
  mAo = ao;
  if (!ao.empty()) mAttributes |= kAmbientOcclusion;
}

void PointDistributor::forEachBatch(const std::string& label,
                                    const std::function<void(std::span<const BuildPoint>)>& fn) {
  Progress progress(label, mDeclared, " points", mQuiet);
  std::vector<BuildPoint> pts;
  PointBatch batch;
  uint64_t skipped = 0;
  uint64_t read = 0;
  auto aoMismatch = [&] {
    return aoMismatchError(mAo.size(), read > mAo.size() ? "more" : std::to_string(read));
  };
  for (const InputSource& in : mInputs) {
    auto reader = openPointReader(in.path);
    const glm::dvec3 shift = reader->info().origin - mFrame.origin;
    const AttributeMask a = reader->info().attributes;
    while (reader->next(batch, 1 << 16)) {
      pts.resize(batch.size());
      for (size_t i = 0; i < batch.size(); ++i) {
        BuildPoint& p = pts[i];
        p.position = batch.positions[i] + shift;
        p.rgb = a & kColor ? glm::u8vec3(batch.colors[i]) : glm::u8vec3(255);
        p.intensity = a & kIntensity ? uint16_t(std::clamp(batch.intensities[i], 0.f, 65535.f)) : 0;
        p.source = uint16_t(in.first_source + (a & kScanIndex ? batch.scan_indices[i] : 0));
        p.classification = a & kClassification ? batch.classifications[i] : 0;
        p.ao = 255;
      }
      if (!mAo.empty()) {
        if (read + pts.size() > mAo.size()) {
          read += pts.size();
          throw aoMismatch();
        }
        for (size_t i = 0; i < pts.size(); ++i) pts[i].ao = mAo[read + i];
      }
      read += pts.size();
      fn(pts);
      progress.add(batch.size());
    }
    skipped += reader->stats().skippedTotal();
  }
  if (!mAo.empty() && read != mAo.size()) throw aoMismatch();
  mSkipped = skipped;
}

TempLayout PointDistributor::chooseLayout() const {
  return TempLayout{mPrecision > 0.0 ? mPrecision / 16.0 : 0.0};
}

void PointDistributor::readInputsIn(TempLayout layout, const std::string& label,
                                    const std::filesystem::path& raw_file) {
  mLayout = layout;
  try {
    readInputs(label, raw_file);
  } catch (const TempRangeError&) {
    if (!mLayout.compact()) throw;
    mLayout = TempLayout{};
    readInputs(label + " (again, wide records: the inputs span more than compact ones hold)",
               raw_file);
  }
  // Inputs read in place write no raw file: their bounds decide.
  if (mLayout.compact() && mLas.size() == mInputs.size()) {
    const double reach = std::max({std::fabs(mMin.x), std::fabs(mMin.y), std::fabs(mMin.z),
                                   std::fabs(mMax.x), std::fabs(mMax.y), std::fabs(mMax.z)});
    if (!(reach * (1.0 / mLayout.quantum) <= 2147483646.0)) mLayout = TempLayout{};
  }
}

// Pass 1 parses the inputs once: bounds and count, and every point in the local frame goes to
// a raw temporary file so the later passes read fixed-size records instead of parsing again
// (ASCII PLY parses at ~2 M points/s, its raw records read at hundreds of M points/s).
void PointDistributor::readInputs(const std::string& label, const std::filesystem::path& raw_file) {
  if (mLas.size() == mInputs.size()) {
    readLasBounds(label);
    return;
  }
  mRawFile = raw_file;
  const std::string name = raw_file.string();
  ScopedFd file(raw_file, O_RDWR | O_CREAT | O_TRUNC, "temporary file");
  const int fd = file.get();
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  uint64_t n = 0;
  forEachBatch(label, [&](std::span<const BuildPoint> pts) {
    for (const BuildPoint& p : pts) {
      lo = glm::min(lo, p.position);
      hi = glm::max(hi, p.position);
    }
    writeTempPoints(mLayout, fd, n, pts.data(), pts.size(), name);
    n += pts.size();
  });
  mPoints = n;
  mMin = lo;
  mMax = hi;
}

void PointDistributor::readLasBounds(const std::string& label) {
  // Every input is an uncompressed LAS: its records are read where they are, no raw file.
  std::vector<LasDirect::Input> las;
  for (const auto& [in, origin] : mLas) {
    las.push_back(in);
    las.back().shift = origin - mFrame.origin;  // forEachBatch()'s shift
  }
  mDirect = std::make_unique<LasDirect>(std::move(las));
  mPoints = mDirect->points();
  mSkipped = 0;
  if (!mAo.empty() && mAo.size() != mPoints)
    throw aoMismatchError(mAo.size(), std::to_string(mPoints));
  Progress progress(label, mPoints, " points", mQuiet);
  mDirect->bounds(mThreads, mMin, mMax);
  progress.update(mPoints);
}

void PointDistributor::forEachRaw(const std::string& label, int parts,
                                  const std::function<void(int, std::span<const BuildPoint>)>& fn) {
  Progress progress(label, mPoints, " points", mQuiet);
  std::atomic<uint64_t> done{0};
  if (mDirect) {
    mDirect->forEachPart(parts, mAo, [&](int part, std::span<const BuildPoint> pts) {
      fn(part, pts);
      uint64_t total = done += pts.size();
      if (part == 0) progress.update(total);
    });
    progress.update(done);
    return;
  }
  // Contiguous parts of the raw file, one thread each: copying records in and out of the page
  // cache is a third of a build's CPU time, and it scales with cores.
  ScopedFd file(mRawFile, O_RDONLY, "temporary file");
  const int fd = file.get();
  // One part a worker; where the system starts fewer threads, the workers take the rest.
  parallelFor(size_t(parts), unsigned(parts), [&](size_t p) {
    const int part = int(p);
    std::vector<BuildPoint> pts;
    const uint64_t kBlock = 1 << 16;
    const uint64_t begin = mPoints * uint64_t(part) / uint64_t(parts);
    const uint64_t end = mPoints * uint64_t(part + 1) / uint64_t(parts);
    for (uint64_t i = begin; i < end; i += kBlock) {
      uint64_t n = std::min(kBlock, end - i);
      pts.resize(n);
      readTempPoints(mLayout, fd, i, n, pts.data(), mRawFile.string());
      fn(part, pts);
      uint64_t total = done += n;
      if (part == 0) progress.update(total);
    }
  });
  progress.update(done);
}

CubeFrame PointDistributor::cubeAround(const glm::dvec3& lo, const glm::dvec3& hi) const {
  // The root cube around the box, a hair larger so nothing sits on its far faces.
  CubeFrame f;
  f.origin = mFrame.origin;
  glm::dvec3 centre = 0.5 * (lo + hi);
  double size = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
  size = size > 0 ? size * (1.0 + 1e-6) : 1.0;
  f.cube_size = size;
  f.cube_min = centre - glm::dvec3(0.5 * size);
  return f;
}

std::optional<CubeFrame> PointDistributor::headerCube() const {
  if (!mHeaderBox) return std::nullopt;
  const glm::dvec3 lo = mHeaderBox->first - mFrame.origin;
  const glm::dvec3 hi = mHeaderBox->second - mFrame.origin;
  CubeFrame f = cubeAround(lo, hi);
  const glm::dvec3 far = f.cube_min + glm::dvec3(f.cube_size);
  if (!std::isfinite(f.cube_size) || !std::isfinite(f.cube_min.x) || !std::isfinite(f.cube_min.y) ||
      !std::isfinite(f.cube_min.z) || !std::isfinite(far.x) || !std::isfinite(far.y) ||
      !std::isfinite(far.z))
    return std::nullopt;
  return f;
}

bool PointDistributor::headerCubeFits(const CubeFrame& header) const {
  const glm::dvec3 far = header.cube_min + glm::dvec3(header.cube_size);
  const bool holds = glm::all(glm::greaterThanEqual(mMin, header.cube_min)) &&
                     glm::all(glm::lessThanEqual(mMax, far));
  return holds && header.cube_size <= 1.01 * cubeAround(mMin, mMax).cube_size;
}

void PointDistributor::measure(const std::filesystem::path& raw_file) {
  // The local frame's origin is the first input's own (a LAS file's local origin, 0 for
  // others): positions then carry the same arithmetic in build and verify.
  mFrame.origin = mFirstOrigin;
  const std::optional<CubeFrame> header = headerCube();
  const TempLayout layout = chooseLayout();
  // The root cube is the header boxes' when they hold every point and are tight (the usual
  // case, a writer computes them), else the points' own: the same rule on every route, so a
  // LAS and its LAZ twin make the same store.
  if (header && layout.compact() && mLas.size() != mInputs.size()) {
    mFrame = *header;
    mLayout = layout;
    try {
      if (readBuckets("build 1/3 reading", raw_file, true)) {
        if (mPoints == 0) throw ReadError("lod::buildStore(): the inputs hold no points");
        return;
      }
      if (!mQuiet)
        std::fprintf(stderr,
                     "build: the header's bounding box does not hold the points tightly; "
                     "reading again in the points' own box\n");
      readInputsIn(layout, "build 1/5 reading", raw_file);
    } catch (const TempRangeError&) {
      mBlocks.clear();
      mCounts.clear();
      readInputsIn(TempLayout{},
                   "build 1/5 reading (again, wide records: the inputs span more than compact "
                   "ones hold)",
                   raw_file);
    }
  } else {
    readInputsIn(layout, "build 1/5 reading", raw_file);
  }
  if (mPoints == 0) throw ReadError("lod::buildStore(): the inputs hold no points");
  mFrame = header && headerCubeFits(*header) ? *header : cubeAround(mMin, mMax);
}

namespace {
constexpr int kBucketLevel = 4;  // 16^3 buckets
constexpr uint32_t kBucketRes = 1u << kBucketLevel;
constexpr int kBucketShift = kCountLevel - kBucketLevel;

uint32_t bucketOf(const CellKey& count_cell) {
  return ((count_cell.z >> kBucketShift) * kBucketRes + (count_cell.y >> kBucketShift)) *
             kBucketRes +
         (count_cell.x >> kBucketShift);
}
}  // namespace

// Pass 1 of the bucketed route: each point counted in the 128^3 grid and appended to its
// level-4 bucket's buffer; full buffers go to the raw file as blocks (records, then each
// point's input index less the block's first as a uint32), so the file grows sequentially.
bool PointDistributor::readBuckets(const std::string& label,
                                   const std::filesystem::path& raw_file, bool fit) {
  mRawFile = raw_file;
  const size_t R = mLayout.recordSize();
  const size_t kBuckets = size_t(kBucketRes) * kBucketRes * kBucketRes;
  // Direct I/O where the records would outgrow the page cache anyway: buffered, the kernel
  // spends more time moving 10^9 points' records through its cache than the build spends on
  // them (and evicts everything else); where they fit, the cache serves the reads.
  const uint64_t memory = uint64_t(sysconf(_SC_PHYS_PAGES)) * uint64_t(sysconf(_SC_PAGE_SIZE));
  mDirectIo = mDirectIoMode > 0 ||
              (mDirectIoMode < 0 && mDeclared * (R + sizeof(uint32_t)) > memory / 2);
  const std::unique_ptr<ScopedFd> file =
      openMaybeDirect(raw_file, O_RDWR | O_CREAT | O_TRUNC, mDirectIo, "temporary file");
  BlockWriter writer(file->get(), file->name());
  // Every bucket may fill a buffer at once: a quarter of the memory over them all.
  const uint32_t block_points = uint32_t(std::clamp<uint64_t>(
      mMemory / 4 / (kBuckets * (R + sizeof(uint32_t))), 1024, 16384));
  struct Buffer {
    std::vector<uint8_t> records;
    std::vector<uint32_t> deltas;
    uint64_t first = 0;
  };
  std::vector<Buffer> buffers(kBuckets);
  mCounts.assign(size_t(kCountRes) * kCountRes * kCountRes, 0);
  mBlocks.clear();
  const CubeFrame::LevelGrid grid = mFrame.levelGrid(kCountLevel);
  uint64_t end = 0;
  uint64_t n = 0;
  auto flush = [&](uint32_t b) {
    Buffer& buf = buffers[b];
    const uint32_t count = uint32_t(buf.deltas.size());
    if (count == 0) return;
    const size_t used = size_t(count) * (R + sizeof(uint32_t));
    const size_t padded = (used + kDirectAlign - 1) / kDirectAlign * kDirectAlign;
    AlignedBytes bytes = writer.take(padded);
    std::memcpy(bytes.data(), buf.records.data(), size_t(count) * R);
    std::memcpy(bytes.data() + size_t(count) * R, buf.deltas.data(), count * sizeof(uint32_t));
    std::memset(bytes.data() + used, 0, padded - used);
    writer.write(std::move(bytes), padded, end);
    mBlocks.push_back({end, buf.first, count, uint32_t(padded), uint16_t(b)});
    end += padded;
    buf.records.clear();
    buf.deltas.clear();
  };
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  forEachBatch(label, [&](std::span<const BuildPoint> pts) {
    for (const BuildPoint& p : pts) {
      lo = glm::min(lo, p.position);
      hi = glm::max(hi, p.position);
      const CellKey c = grid.cellOf(p.position);
      ++mCounts[gridIndex(c.x, c.y, c.z)];
      const uint32_t b = bucketOf(c);
      Buffer& buf = buffers[b];
      if (!buf.deltas.empty() && n - buf.first > std::numeric_limits<uint32_t>::max()) flush(b);
      if (buf.deltas.empty()) {
        buf.first = n;
        buf.records.reserve(size_t(block_points) * R);
        buf.deltas.reserve(block_points);
      }
      const size_t at = buf.records.size();
      buf.records.resize(at + R);
      encodeTemp(mLayout, &p, 1, buf.records.data() + at);
      buf.deltas.push_back(uint32_t(n - buf.first));
      if (buf.deltas.size() == block_points) flush(b);
      ++n;
    }
  });
  for (uint32_t b = 0; b < kBuckets; ++b) flush(b);
  writer.finish();
  mPoints = n;
  mMin = lo;
  mMax = hi;
  if (fit && n > 0 && !headerCubeFits(mFrame)) {
    mBlocks.clear();
    mCounts.clear();
    mFrame.origin = mFirstOrigin;
    return false;
  }
  mBucketed = true;
  return true;
}

std::unique_ptr<ScopedFd> PointDistributor::openBlocks() const {
  return std::make_unique<ScopedFd>(mRawFile, O_RDONLY | (mDirectIo ? O_DIRECT : 0),
                                    "temporary file");
}

const uint8_t* PointDistributor::readBlock(const ScopedFd& file, const Block& b,
                                           AlignedBytes& buf) const {
  uint8_t* at = buf.reserve(b.bytes);
  preadAll(file.get(), at, b.bytes, b.offset, file.name());
  return at;
}

std::vector<ChunkGroup> PointDistributor::groups(const std::vector<Chunk>& chunks) const {
  std::vector<ChunkGroup> out;
  std::vector<int32_t> group_of(size_t(kBucketRes) * kBucketRes * kBucketRes, -1);
  std::vector<int32_t> bucket_group;
  for (size_t ci = 0; ci < chunks.size(); ++ci) {
    const CellKey& k = chunks[ci].key;
    if (k.level >= kBucketLevel) {
      const int down = k.level - kBucketLevel;
      const uint32_t b =
          ((k.z >> down) * kBucketRes + (k.y >> down)) * kBucketRes + (k.x >> down);
      if (group_of[b] < 0) {
        group_of[b] = int32_t(out.size());
        out.emplace_back();
      }
      ChunkGroup& g = out[size_t(group_of[b])];
      g.chunks.push_back(uint32_t(ci));
      g.points += chunks[ci].count;
      continue;
    }
    // A chunk above the buckets holds each bucket inside it whole.
    const int up = kBucketLevel - k.level;
    const uint32_t span = 1u << up;
    const int32_t gi = int32_t(out.size());
    out.emplace_back();
    out.back().chunks.push_back(uint32_t(ci));
    out.back().points = chunks[ci].count;
    out.back().merge = true;
    for (uint32_t z = 0; z < span; ++z)
      for (uint32_t y = 0; y < span; ++y)
        for (uint32_t x = 0; x < span; ++x) {
          const uint32_t b = (((k.z << up) + z) * kBucketRes + ((k.y << up) + y)) * kBucketRes +
                             ((k.x << up) + x);
          group_of[b] = gi;
        }
  }
  for (size_t bi = 0; bi < mBlocks.size(); ++bi) {
    const int32_t g = group_of[mBlocks[bi].bucket];
    if (g < 0) throw StoreError("lod::buildStore(): internal error: a bucket has no chunk");
    out[size_t(g)].blocks.push_back(uint32_t(bi));
  }
  return out;
}

namespace {
/// Where each level-7 cell of a bucket goes among a group's chunks (-1: none).
std::vector<int32_t> bucketOwners(const ChunkGroup& group, const std::vector<Chunk>& chunks) {
  constexpr uint32_t kSide = 1u << kBucketShift;
  std::vector<int32_t> owner(size_t(kSide) * kSide * kSide, -1);
  for (size_t j = 0; j < group.chunks.size(); ++j) {
    const CellKey& k = chunks[group.chunks[j]].key;
    const int shift = kCountLevel - k.level;
    const uint32_t span = 1u << shift;
    const uint32_t mask = kSide - 1;
    for (uint32_t z = 0; z < span; ++z)
      for (uint32_t y = 0; y < span; ++y)
        for (uint32_t x = 0; x < span; ++x) {
          const uint32_t cx = ((k.x << shift) + x) & mask, cy = ((k.y << shift) + y) & mask,
                         cz = ((k.z << shift) + z) & mask;
          owner[(size_t(cz) * kSide + cy) * kSide + cx] = int32_t(j);
        }
  }
  return owner;
}

size_t ownerIndex(const CellKey& count_cell) {
  constexpr uint32_t kSide = 1u << kBucketShift;
  constexpr uint32_t mask = kSide - 1;
  return (size_t(count_cell.z & mask) * kSide + (count_cell.y & mask)) * kSide +
         (count_cell.x & mask);
}
}  // namespace

void PointDistributor::readGroup(const ChunkGroup& group, const std::vector<Chunk>& chunks,
                                 std::vector<std::vector<BuildPoint>>& out) const {
  const std::unique_ptr<ScopedFd> file = openBlocks();
  const size_t R = mLayout.recordSize();
  std::vector<BuildPoint> pts(group.points);
  std::vector<uint64_t> index(group.merge ? group.points : 0);
  thread_local AlignedBytes bytes;
  uint64_t at = 0;
  for (uint32_t bi : group.blocks) {
    const Block& b = mBlocks[bi];
    if (at + b.count > pts.size())
      throw StoreError("lod::buildStore(): internal error: a group holds more than its chunks");
    const uint8_t* block = readBlock(*file, b, bytes);
    decodeTemp(mLayout, block, b.count, pts.data() + at);
    if (group.merge) {
      const uint8_t* d = block + size_t(b.count) * R;
      for (uint32_t i = 0; i < b.count; ++i) {
        uint32_t delta;
        std::memcpy(&delta, d + size_t(i) * sizeof(uint32_t), sizeof delta);
        index[at + i] = b.first_index + delta;
      }
    }
    at += b.count;
  }
  if (at != pts.size())
    throw StoreError("lod::buildStore(): internal error: a group holds fewer than its chunks");
  out.assign(group.chunks.size(), {});
  if (group.merge) {
    // Several buckets' blocks: back into input order, as the other route keeps a chunk.
    std::vector<uint32_t> order(pts.size());
    for (uint32_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(),
              [&](uint32_t a, uint32_t b) { return index[a] < index[b]; });
    out[0].resize(pts.size());
    for (size_t i = 0; i < order.size(); ++i) out[0][i] = pts[order[i]];
    return;
  }
  if (group.chunks.size() == 1) {
    out[0] = std::move(pts);
    return;
  }
  const std::vector<int32_t> owner = bucketOwners(group, chunks);
  const CubeFrame::LevelGrid grid = mFrame.levelGrid(kCountLevel);
  for (size_t j = 0; j < group.chunks.size(); ++j) out[j].reserve(chunks[group.chunks[j]].count);
  for (const BuildPoint& p : pts) {
    const int32_t j = owner[ownerIndex(grid.cellOf(p.position))];
    if (j < 0) throw StoreError("lod::buildStore(): internal error: a point has no chunk");
    out[size_t(j)].push_back(p);
  }
  for (size_t j = 0; j < group.chunks.size(); ++j) {
    if (out[j].size() != chunks[group.chunks[j]].count)
      throw StoreError("lod::buildStore(): internal error: chunk counts differ");
  }
}

void PointDistributor::spillGroup(const ChunkGroup& group, std::vector<Chunk>& chunks,
                                  int temp_fd, const std::string& temp_name,
                                  uint64_t& temp_end) const {
  if (group.merge)
    throw StoreError("lod::buildStore(): internal error: a merged group spilled");
  const std::unique_ptr<ScopedFd> file = openBlocks();
  const std::vector<int32_t> owner = bucketOwners(group, chunks);
  const CubeFrame::LevelGrid grid = mFrame.levelGrid(kCountLevel);
  std::vector<uint64_t> written(group.chunks.size(), 0);
  for (uint32_t ci : group.chunks) {
    chunks[ci].first = temp_end;
    temp_end += chunks[ci].count;
  }
  std::vector<std::vector<BuildPoint>> buffers(group.chunks.size());
  const size_t kFlush = size_t(1) << 16;
  auto flush = [&](size_t j) {
    auto& b = buffers[j];
    const Chunk& c = chunks[group.chunks[j]];
    if (written[j] + b.size() > c.count)
      throw StoreError("lod::buildStore(): internal error: chunk overflow");
    writeTempPoints(mLayout, temp_fd, c.first + written[j], b.data(), b.size(), temp_name);
    written[j] += b.size();
    b.clear();
  };
  AlignedBytes bytes;
  std::vector<BuildPoint> pts;
  for (uint32_t bi : group.blocks) {
    const Block& b = mBlocks[bi];
    pts.resize(b.count);
    decodeTemp(mLayout, readBlock(*file, b, bytes), b.count, pts.data());
    for (const BuildPoint& p : pts) {
      const int32_t j = owner[ownerIndex(grid.cellOf(p.position))];
      if (j < 0) throw StoreError("lod::buildStore(): internal error: a point has no chunk");
      buffers[size_t(j)].push_back(p);
      if (buffers[size_t(j)].size() >= kFlush) flush(size_t(j));
    }
  }
  for (size_t j = 0; j < buffers.size(); ++j) {
    flush(j);
    if (written[j] != chunks[group.chunks[j]].count)
      throw StoreError("lod::buildStore(): internal error: chunk counts differ");
  }
}

void PointDistributor::measureInFrame(const CubeFrame& frame,
                                      const std::filesystem::path& raw_file) {
  mFrame = frame;
  mVerifying = true;
  if (mLas.size() == mInputs.size()) {
    readInputsIn(chooseLayout(), "verify 1/4 reading", raw_file);
    return;
  }
  // The frame is the store's: any input goes the bucketed route, its points outside the cube
  // counted in the edge cells as the other route does (they then match nothing).
  mLayout = chooseLayout();
  try {
    readBuckets("verify 1/2 reading", raw_file, false);
  } catch (const TempRangeError&) {
    mLayout = TempLayout{};
    readBuckets("verify 1/2 reading (again, wide records: the inputs span more than compact ones "
                "hold)",
                raw_file, false);
  }
}

namespace {
/// Chunks over the 128^3 counts: octree cells of at most `chunk_max` points where the grid
/// allows, in depth-first order, each its range in a file of them all in that order.
std::vector<Chunk> chunkCells(const std::vector<uint64_t>& counts, uint64_t chunk_max) {
  // Count pyramid: level l has 2^l cells per axis.
  std::vector<std::vector<uint64_t>> pyramid(kCountLevel + 1);
  pyramid[kCountLevel] = counts;
  for (int l = kCountLevel - 1; l >= 0; --l) {
    uint32_t r = 1u << l;
    pyramid[l].assign(size_t(r) * r * r, 0);
    for (uint32_t z = 0; z < 2 * r; ++z)
      for (uint32_t y = 0; y < 2 * r; ++y)
        for (uint32_t x = 0; x < 2 * r; ++x) {
          pyramid[l][(size_t(z / 2) * r + y / 2) * r + x / 2] +=
              pyramid[l + 1][(size_t(z) * 2 * r + y) * 2 * r + x];
        }
  }
  std::vector<Chunk> chunks;
  std::function<void(CellKey)> split = [&](CellKey k) {
    uint32_t r = 1u << k.level;
    uint64_t n = pyramid[k.level][(size_t(k.z) * r + k.y) * r + k.x];
    if (n == 0) return;
    if (n <= chunk_max || k.level == kCountLevel) {
      chunks.push_back({k, 0, n});
      return;
    }
    for (int i = 0; i < 8; ++i) split(k.child(i));
  };
  split(CellKey{});
  pyramid.clear();

  uint64_t offset = 0;
  for (Chunk& c : chunks) {
    c.first = offset;
    offset += c.count;
  }
  return chunks;
}
}  // namespace

std::vector<Chunk> PointDistributor::distribute(uint64_t chunk_max,
                                                const std::filesystem::path& temp_file,
                                                int threads) {
  if (mBucketed) return chunkCells(mCounts, chunk_max);
  // Pass 2: counting grid, one per part of the raw file.
  const int parts = std::clamp(threads, 1, 16);
  const size_t cells = size_t(kCountRes) * kCountRes * kCountRes;
  const CubeFrame::LevelGrid count_grid = mFrame.levelGrid(kCountLevel);
  std::vector<std::vector<uint32_t>> part_counts(size_t(parts), std::vector<uint32_t>(cells, 0));
  forEachRaw(mVerifying ? "verify 2/4 counting" : "build 2/5 counting", parts, [&](int part, std::span<const BuildPoint> pts) {
    auto& counts = part_counts[size_t(part)];
    for (const BuildPoint& p : pts) {
      CellKey c = count_grid.cellOf(p.position);
      ++counts[gridIndex(c.x, c.y, c.z)];
    }
  });
  std::vector<uint64_t> counts(cells, 0);
  uint64_t counted = 0;
  for (const auto& pc : part_counts) {
    for (size_t i = 0; i < cells; ++i) counts[i] += pc[i];
  }
  for (uint64_t c : counts) counted += c;
  if (counted != mPoints)
    throw StoreError("lod::buildStore(): internal error: temporary file count differs");

  std::vector<Chunk> chunks = chunkCells(counts, chunk_max);

  // Chunk of every counting cell, and each chunk's contiguous range in the temp file.
  std::vector<int32_t> owner(counts.size(), -1);
  uint64_t offset = 0;
  for (size_t ci = 0; ci < chunks.size(); ++ci) {
    Chunk& c = chunks[ci];
    c.first = offset;
    offset += c.count;
    int shift = kCountLevel - c.key.level;
    uint32_t span = 1u << shift;
    for (uint32_t z = 0; z < span; ++z)
      for (uint32_t y = 0; y < span; ++y)
        for (uint32_t x = 0; x < span; ++x) {
          owner[gridIndex((c.key.x << shift) + x, (c.key.y << shift) + y, (c.key.z << shift) + z)] =
              int32_t(ci);
        }
  }
  counts.clear();
  counts.shrink_to_fit();
  // Where each part writes inside each chunk: parts in file order, so a chunk holds its points
  // in input order whatever the thread count (the build is deterministic).
  std::vector<std::vector<uint64_t>> start(size_t(parts), std::vector<uint64_t>(chunks.size(), 0));
  std::vector<std::vector<uint64_t>> part_chunk(size_t(parts),
                                                std::vector<uint64_t>(chunks.size(), 0));
  for (int part = 0; part < parts; ++part) {
    const auto& pc = part_counts[size_t(part)];
    for (size_t i = 0; i < cells; ++i) {
      if (pc[i]) part_chunk[size_t(part)][size_t(owner[i])] += pc[i];
    }
  }
  part_counts.clear();
  for (size_t ci = 0; ci < chunks.size(); ++ci) {
    uint64_t at = chunks[ci].first;
    for (int part = 0; part < parts; ++part) {
      start[size_t(part)][ci] = at;
      at += part_chunk[size_t(part)][ci];
    }
  }

  // Pass 3: distribution through per-chunk buffers into one preallocated file.
  const std::string name = temp_file.string();
  ScopedFd file(temp_file, O_RDWR | O_CREAT | O_TRUNC, "temporary file");
  const int fd = file.get();
  // Buffers: 64 MB in all whatever the chunk count (at least 64 points each).
  const size_t per_chunk =
      std::max<size_t>(64, (size_t(64) << 20) / sizeof(BuildPoint) /
                               std::max<size_t>(1, chunks.size() * size_t(parts)));
  struct PartState {
    std::vector<std::vector<BuildPoint>> buffers;
    std::vector<uint64_t> written;
  };
  std::vector<PartState> state(static_cast<size_t>(parts));
  for (auto& st : state) {
    st.buffers.resize(chunks.size());
    st.written.assign(chunks.size(), 0);
  }
  auto flush = [&](int part, size_t ci) {
    PartState& st = state[size_t(part)];
    auto& b = st.buffers[ci];
    if (b.empty()) return;
    if (st.written[ci] + b.size() > part_chunk[size_t(part)][ci]) {
      throw StoreError("lod::buildStore(): internal error: chunk overflow");
    }
    writeTempPoints(mLayout, fd, start[size_t(part)][ci] + st.written[ci], b.data(), b.size(),
                    name);
    st.written[ci] += b.size();
    b.clear();
  };
  forEachRaw(mVerifying ? "verify 3/4 distributing" : "build 3/5 distributing", parts, [&](int part, std::span<const BuildPoint> pts) {
    PartState& st = state[size_t(part)];
    for (const BuildPoint& p : pts) {
      CellKey c = count_grid.cellOf(p.position);
      int32_t ci = owner[gridIndex(c.x, c.y, c.z)];
      auto& b = st.buffers[size_t(ci)];
      if (b.capacity() == 0) b.reserve(per_chunk);
      b.push_back(p);
      if (b.size() >= per_chunk) flush(part, size_t(ci));
    }
  });
  for (int part = 0; part < parts; ++part) {
    for (size_t ci = 0; ci < chunks.size(); ++ci) {
      flush(part, ci);
      if (state[size_t(part)].written[ci] != part_chunk[size_t(part)][ci])
        throw StoreError("lod::buildStore(): internal error: chunk counts differ");
    }
  }
  std::error_code ec;
  std::filesystem::remove(mRawFile, ec);
  return chunks;
}

}  // namespace tessera::lod
