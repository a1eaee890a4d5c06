// Out-of-core distribution of input points into octree cells ("chunks") small enough to be
// worked on in memory: the first passes of building (and verifying) a point store.
#pragma once

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <tessera/core/parallel.h>
#include <tessera/lod/point_reader.h>

#include "build_point.h"
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
  uint64_t skipped() const { return mSkipped; }

  /// Pass 1: parses every input once into `raw_file` (TempLayout); bounds and count; sets
  /// the frame (origin: the first input's own local origin; cube around the box).
  void measure(const std::filesystem::path& raw_file);
  /// Pass 1 in a given frame (verification against an existing store).
  void measureInFrame(const CubeFrame& frame, const std::filesystem::path& raw_file);
  const CubeFrame& frame() const { return mFrame; }
  /// The temporary files' record layout, chosen by measure() / measureInFrame().
  const TempLayout& tempLayout() const { return mLayout; }
  uint64_t points() const { return mPoints; }
  glm::dvec3 boundsMin() const { return mMin; }
  glm::dvec3 boundsMax() const { return mMax; }

  /// Passes 2 and 3 over the raw file: counting grid, chunks of at most `chunk_max` points where
  /// the grid allows, and distribution into `temp_file`; the raw file is then removed.
  std::vector<Chunk> distribute(uint64_t chunk_max, const std::filesystem::path& temp_file,
                                int threads);

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
  /// The inputs that are uncompressed LAS files, each with its local origin; when they are all
  /// the inputs, the passes read their records directly (mDirect) instead of a raw file.
  std::vector<std::pair<LasDirect::Input, glm::dvec3>> mLas;
  std::unique_ptr<LasDirect> mDirect;
  unsigned mThreads = threadCount();
  bool mQuiet;
};

/// Reads points [first, first + count) of a temp file written in `layout`.
void readTempPoints(const TempLayout& layout, int fd, uint64_t first, uint64_t count,
                    BuildPoint* out, const std::string& name);
/// Writes points at index `first` of a temp file. Throws TempRangeError when a position does
/// not fit a compact record.
void writeTempPoints(const TempLayout& layout, int fd, uint64_t first, const BuildPoint* pts,
                     uint64_t count, const std::string& name);

}  // namespace tessera::lod
