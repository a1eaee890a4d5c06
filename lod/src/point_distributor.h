// Out-of-core distribution of input points into octree cells ("chunks") small enough to be
// worked on in memory: the first passes of building (and verifying) a point store.
//
// Two routes. Bucketed, when every input states its bounding box (LAS, LAZ read through their
// reader): the root cube comes from the header boxes before any point is read, so the one pass
// over the inputs also counts the 128^3 grid and writes each point into the block file of its
// level-4 bucket; the chunk phase then reads each bucket once (ChunkGroup). Otherwise: the
// inputs into one raw file in reading order (or read in place, LasDirect), a counting pass, and a
// distribution pass into one temporary file where every chunk is contiguous. The bucketed route
// writes and reads each temporary record once, against three reads and two writes: at 10^9
// points the records outgrow the page cache and every pass runs at disk speed.
#pragma once

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <tessera/core/parallel.h>
#include <tessera/lod/point_reader.h>

#include "build_point.h"
#include "file_io.h"
#include "las_direct.h"

namespace tessera::lod {

/// Octree cell of the root cube.
struct CellKey {
  uint8_t level = 0;
  uint32_t x = 0, y = 0, z = 0;
  CellKey child(int i) const {
    return {uint8_t(level + 1), 2 * x + (i & 1), 2 * y + ((i >> 1) & 1), 2 * z + ((i >> 2) & 1)};
  }
  CellKey parent() const { return {uint8_t(level - 1), x / 2, y / 2, z / 2}; }
  int childIndex() const { return int(x & 1) | int(y & 1) << 1 | int(z & 1) << 2; }
  bool operator==(const CellKey&) const = default;
  /// Morton code of the cell within its level.
  uint64_t morton() const;
  /// Level first, then Morton order within the level: the payload order of a store.
  bool operator<(const CellKey& o) const;
};

struct CellKeyHash {
  size_t operator()(const CellKey& k) const {
    return size_t((uint64_t(k.x) * 0x9E3779B97F4A7C15ull) ^
                  (uint64_t(k.y) * 0xC2B2AE3D27D4EB4Full) ^
                  (uint64_t(k.z) * 0x165667B19E3779F9ull) ^ k.level);
  }
};

/// The store's local frame: world = origin + local; the root cube spans cube_min + [0, size]^3.
struct CubeFrame {
  glm::dvec3 origin{0.0};
  glm::dvec3 cube_min{0.0};
  double cube_size = 1.0;
  glm::dvec3 cellMin(const CellKey& k) const {
    return cube_min + glm::dvec3(k.x, k.y, k.z) * cellSize(k.level);
  }
  double cellSize(int level) const { return cube_size / double(uint64_t(1) << level); }
  /// The cell at `level` containing local point p (clamped into the cube).
  CellKey cellOf(const glm::dvec3& p, int level) const { return levelGrid(level).cellOf(p); }

  /// cellOf() at one level with its constants in registers: what loops over many points use
  /// (a copy, so stores to points cannot alias it).
  struct LevelGrid {
    glm::dvec3 cube_min;
    double inv;  ///< 1 / cube size
    double res;  ///< 2^level
    int level;
    CellKey cellOf(const glm::dvec3& p) const {
      // (p - min) * (1 / size) then an exact power-of-two scale: the cell at level l + 1 is
      // always a child of the cell at level l, and build and verify share this one function.
      auto axis = [&](double v) {
        double f = (v * inv) * res;
        return f <= 0.0 ? 0u : f >= res ? uint32_t(res - 1.0) : uint32_t(f);
      };
      return {uint8_t(level), axis(p.x - cube_min.x), axis(p.y - cube_min.y),
              axis(p.z - cube_min.z)};
    }
  };
  LevelGrid levelGrid(int level) const {
    return {cube_min, 1.0 / cube_size, double(uint64_t(1) << level), level};
  }
};

struct InputSource {
  std::filesystem::path path;
  uint16_t first_source = 0;  ///< source id of its first scan (a .conf has one source per scan)
};

/// One out-of-core work unit: a cell and the contiguous range of its points in the temp file.
struct Chunk {
  CellKey key;
  uint64_t first = 0;  ///< index of its first point in the temp file
  uint64_t count = 0;
};

/// How the build's temporary files hold points. Wide: a BuildPoint as it is, 40 bytes. Compact,
/// when every input declares its resolution (LAS, LAZ): each position as three int32 multiples of
/// `quantum`, a 16th of the finest declared resolution (so a position moves by at most a 32nd
/// of it and rounds back to the same input integer), and the attributes packed: 21 bytes. The
/// two temporary files of a 10^9-point build then take 42 GB instead of 80.
struct TempLayout {
  static constexpr size_t kCompactRecord = 21;
  double quantum = 0.0;  ///< 0: wide records
  bool compact() const { return quantum > 0.0; }
  size_t recordSize() const { return compact() ? kCompactRecord : sizeof(BuildPoint); }
};

/// The bucketed route's work unit: the chunks whose points one read brings in. Either one level-4
/// bucket and the chunks at level 4 or deeper inside it, or one chunk above level 4 and every
/// bucket inside it (`merge`: its blocks then interleave by input order).
struct ChunkGroup {
  std::vector<uint32_t> chunks;  ///< indices into distribute()'s chunk list
  std::vector<uint32_t> blocks;  ///< its blocks in file order
  uint64_t points = 0;
  bool merge = false;
};

/// A position too far from the origin for compact records (int32 multiples of the quantum):
/// the first pass starts again with wide records.
class TempRangeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class PointDistributor {
 public:
  /// Opens every input's header (so a bad input fails before any work) and assigns source ids.
  explicit PointDistributor(const std::vector<std::filesystem::path>& inputs, bool quiet);

  const std::vector<std::string>& sourceNames() const { return mSourceNames; }
  AttributeMask attributes() const { return mAttributes; }
  double inputPrecision() const { return mPrecision; }
  /// Each input point's ambient-occlusion byte in reading order (BuildOptions::
  /// ambient_occlusion); the store then carries kAmbientOcclusion. Call before measure().
  void setAmbientOcclusion(std::span<const uint8_t> ao);
  /// Threads for the passes over the inputs (default: the hardware's). Call before measure().
  void setThreads(unsigned threads) { mThreads = std::max(1u, threads); }
  /// Memory the bucketed route's write buffers may take (a quarter of it at most).
  void setMemory(uint64_t bytes) { mMemory = bytes; }
  /// Whether the bucketed route's block file bypasses the page cache (O_DIRECT): -1 when its
  /// records would outgrow half the machine's memory (BuildOptions::direct_io).
  void setDirectIo(int mode) { mDirectIoMode = mode; }
  /// Whether measure() chose direct I/O (the build writes its output so too).
  bool directIo() const { return mDirectIo; }
  uint64_t skipped() const { return mSkipped; }

  /// Pass 1: parses every input once into `raw_file` (TempLayout); bounds and count; sets
  /// the frame (origin: the first input's own local origin; cube around the box).
  void measure(const std::filesystem::path& raw_file);
  /// Pass 1 in a given frame (verification against an existing store): bucketed unless every
  /// input is an uncompressed LAS (read in place).
  void measureInFrame(const CubeFrame& frame, const std::filesystem::path& raw_file);
  const CubeFrame& frame() const { return mFrame; }
  /// The temporary files' record layout, chosen by measure() / measureInFrame().
  const TempLayout& tempLayout() const { return mLayout; }
  uint64_t points() const { return mPoints; }
  glm::dvec3 boundsMin() const { return mMin; }
  glm::dvec3 boundsMax() const { return mMax; }

  /// Passes 2 and 3 over the raw file: counting grid, chunks of at most `chunk_max` points where
  /// the grid allows, and distribution into `temp_file`; the raw file is then removed. Bucketed:
  /// the chunks from the counts pass 1 made, nothing written (Chunk::first is unused).
  std::vector<Chunk> distribute(uint64_t chunk_max, const std::filesystem::path& temp_file,
                                int threads);

  /// True when measure() took the bucketed route: the chunks' points are read by group.
  bool bucketed() const { return mBucketed; }
  /// The groups of the bucketed route covering `chunks` (distribute()'s list), each block once.
  std::vector<ChunkGroup> groups(const std::vector<Chunk>& chunks) const;
  /// A group's points, chunk by chunk (parallel to group.chunks), each in input order.
  void readGroup(const ChunkGroup& group, const std::vector<Chunk>& chunks,
                 std::vector<std::vector<BuildPoint>>& out) const;
  /// Streams a group too large for memory into `temp_fd` from record `temp_end` on, each of its
  /// chunks contiguous and in input order; sets their Chunk::first. Single-bucket groups only
  /// (a merged group is one chunk, within the chunk size).
  void spillGroup(const ChunkGroup& group, std::vector<Chunk>& chunks, int temp_fd,
                  const std::string& temp_name, uint64_t& temp_end) const;

 private:
  /// Streams every input, calling `fn` per batch of points in the local frame.
  void forEachBatch(const std::string& label,
                    const std::function<void(std::span<const BuildPoint>)>& fn);
  void readInputs(const std::string& label, const std::filesystem::path& raw_file);
  /// readInputs() where every input is an uncompressed LAS: the bounds pass of LasDirect.
  void readLasBounds(const std::string& label);
  /// The compact layout when every input declares its resolution, else the wide one.
  TempLayout chooseLayout() const;
  /// readInputs() in `layout`, again in the wide layout when a position does not fit it.
  void readInputsIn(TempLayout layout, const std::string& label,
                    const std::filesystem::path& raw_file);
  /// The root cube around a box: centred, its largest side a hair larger.
  CubeFrame cubeAround(const glm::dvec3& lo, const glm::dvec3& hi) const;
  /// The cube of the inputs' header boxes in the local frame, when every input states one.
  std::optional<CubeFrame> headerCube() const;
  /// Whether the header cube serves as the root cube: it holds the points' box and is no more
  /// than 1% larger than the cube around it.
  bool headerCubeFits(const CubeFrame& header) const;
  /// Pass 1 of the bucketed route in mFrame; false when `fit` and the header cube does not fit.
  bool readBuckets(const std::string& label, const std::filesystem::path& raw_file, bool fit);
  /// Streams the raw file written by pass 1 in `parts` contiguous parts, one thread each;
  /// `fn(part, points)` is called from that part's thread.
  void forEachRaw(const std::string& label, int parts,
                  const std::function<void(int, std::span<const BuildPoint>)>& fn);

  std::vector<InputSource> mInputs;
  std::vector<std::string> mSourceNames;
  AttributeMask mAttributes = kScanIndex;
  std::span<const uint8_t> mAo;
  double mPrecision = 0.0;
  uint64_t mDeclared = 0;
  uint64_t mPoints = 0;
  uint64_t mSkipped = 0;
  glm::dvec3 mMin{0.0}, mMax{0.0};
  CubeFrame mFrame;
  TempLayout mLayout;
  glm::dvec3 mFirstOrigin{0.0};  ///< the first input's local origin (the store's origin)
  std::filesystem::path mRawFile;
  /// What the passes' progress labels begin with: "build 2/5" or "verify 2/4" for counting.
  bool mVerifying = false;
  /// The inputs that are uncompressed LAS files, each with its local origin; when they are all
  /// the inputs, the passes read their records directly (mDirect) instead of a raw file.
  std::vector<std::pair<LasDirect::Input, glm::dvec3>> mLas;
  std::unique_ptr<LasDirect> mDirect;
  /// Union of the inputs' header boxes in world coordinates, when all state one.
  std::optional<std::pair<glm::dvec3, glm::dvec3>> mHeaderBox;
  bool mBucketed = false;
  /// Bucketed route: the level-7 counts and the blocks of the raw file.
  struct Block {
    uint64_t offset = 0;       ///< bytes into the raw file
    uint64_t first_index = 0;  ///< input index of its first point (the others: + a uint32)
    uint32_t count = 0;
    uint32_t bytes = 0;  ///< on disk: the records and deltas, padded to kDirectAlign
    uint16_t bucket = 0;
  };
  /// Opens the block file for reading, directly when it was written so.
  std::unique_ptr<ScopedFd> openBlocks() const;
  /// Reads block `b`'s bytes (records, then deltas) into `buf`.
  const uint8_t* readBlock(const ScopedFd& file, const Block& b, AlignedBytes& buf) const;
  bool mDirectIo = false;
  int mDirectIoMode = -1;
  std::vector<uint64_t> mCounts;
  std::vector<Block> mBlocks;
  uint64_t mMemory = uint64_t(2048) << 20;
  unsigned mThreads = threadCount();
  bool mQuiet;
};

/// `count` points as temporary records of `layout` at `out` (recordSize() bytes each). Throws
/// TempRangeError when a position does not fit a compact record.
void encodeTemp(const TempLayout& layout, const BuildPoint* pts, uint64_t count, uint8_t* out);
/// The inverse of encodeTemp().
void decodeTemp(const TempLayout& layout, const uint8_t* in, uint64_t count, BuildPoint* out);
/// Reads points [first, first + count) of a temp file written in `layout`.
void readTempPoints(const TempLayout& layout, int fd, uint64_t first, uint64_t count,
                    BuildPoint* out, const std::string& name);
/// Writes points at index `first` of a temp file. Throws TempRangeError when a position does
/// not fit a compact record.
void writeTempPoints(const TempLayout& layout, int fd, uint64_t first, const BuildPoint* pts,
                     uint64_t count, const std::string& name);

}  // namespace tessera::lod
