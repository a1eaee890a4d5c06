// One streaming reader interface over every scan format Tessera reads: PLY, Stanford range
// scans (.conf), LAS 1.0-1.4 and LAZ, XYZ/PTS/TXT point lists, OBJ meshes and E57 (every data3D scan,
// each a ScanInfo with its pose).
//
// A reader never holds the whole file in memory: it parses a small header on open and then
// hands out batches. Bad input is normal input: every problem throws `ReadError` whose message
// names the reader, the file and the byte offset or line; points that cannot be used
// (non-finite coordinates, ...) are skipped and counted in `stats()`.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include <tessera/lod/point_batch.h>

namespace tessera::lod {

/// A malformed, truncated, unsupported or unreadable input. The message starts with the
/// component (`lod::readLas()`), then the file and where in it.
class ReadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Format { kPly, kStanfordConf, kLas, kText, kObj, kE57, kLaz };
const char* formatName(Format format);

/// A rigid transform: world = rotation * local + translation (metres or file units).
struct RigidPose {
  glm::dvec3 translation{0.0};
  glm::dquat rotation{1.0, 0.0, 0.0, 0.0};  ///< glm order (w, x, y, z)
  glm::dvec3 apply(const glm::dvec3& p) const { return rotation * p + translation; }
};

/// The quaternion as a Stanford .conf writes it (i j k r order in the file) for a pose.
inline glm::dquat confQuaternion(const RigidPose& pose) {
  return glm::conjugate(pose.rotation);
}

/// One range scan of a Stanford-style .conf (or the single scan of a range-grid PLY).
struct ScanInfo {
  std::string name;            ///< file name as written in the .conf
  std::filesystem::path path;  ///< resolved path
  /// Scanner frame -> registered frame, from the `bmesh` line. Note the .conf stores the
  /// inverse rotation: conf quaternion = conjugate(pose.rotation); see confQuaternion().
  RigidPose pose;
  uint32_t grid_columns = 0;  ///< `obj_info num_cols` (0 when the file has no range grid)
  uint32_t grid_rows = 0;     ///< `obj_info num_rows`
  uint64_t points = 0;        ///< vertices declared by the scan's header
};

/// What a source declares about itself before any point is read.
struct SourceInfo {
  Format format = Format::kPly;
  std::string format_detail;         ///< "binary_little_endian 1.0", "LAS 1.2 format 3", ...
  uint64_t declared_points = 0;      ///< from the header (0 when the format has no count)
  bool has_declared_points = false;  ///< false for text formats without a count line
  uint64_t declared_triangles = 0;   ///< faces after triangulation where countable, else 0
  AttributeMask attributes = 0;      ///< attributes every batch will carry
  glm::dvec3 origin{0.0};            ///< world = origin + batch position
  /// Bounding box stated by the header (LAS), in file coordinates.
  std::optional<std::pair<glm::dvec3, glm::dvec3>> header_bbox;
  /// Coordinate resolution the file declares (LAS: the smallest scale factor); 0 when unknown.
  double precision = 0.0;
  std::vector<ScanInfo> scans;      ///< .conf: one per bmesh line; range-grid PLY: one
  std::optional<RigidPose> camera;  ///< .conf `camera` line, if any
};

/// Points skipped while reading, by reason ("non-finite coordinate" -> 3).
struct ReadStats {
  uint64_t points = 0;     ///< points delivered
  uint64_t triangles = 0;  ///< triangles delivered
  std::map<std::string, uint64_t> skipped;
  /// Where the first skip of each reason happened ("line 12", "byte 4096").
  std::map<std::string, std::string> first_skip_at;
  uint64_t skippedTotal() const;
  void skip(const std::string& reason, const std::string& where);
};

class PointReader {
 public:
  virtual ~PointReader() = default;
  const SourceInfo& info() const { return mInfo; }
  const ReadStats& stats() const { return mStats; }
  /// Fills `batch` (reset first) with up to `max_points` points and/or any triangles that
  /// follow. Returns false when the source is exhausted (batch then empty). Throws ReadError.
  virtual bool next(PointBatch& batch, size_t max_points = kDefaultBatch) = 0;

  static constexpr size_t kDefaultBatch = 1 << 16;

 protected:
  SourceInfo mInfo;
  ReadStats mStats;
};

struct ReaderOptions {
  /// Force a format instead of detecting it from magic bytes and extension.
  std::optional<Format> format;
  /// LAZ: chunks decoded at once on their own threads (0: one per core).
  unsigned decode_threads = 0;
};

/// Opens `path`, detects the format (magic bytes first, then extension) and parses its header.
/// Throws ReadError for a missing/unreadable file, an unknown format or a bad header.
std::unique_ptr<PointReader> openPointReader(const std::filesystem::path& path,
                                             const ReaderOptions& options = {});

/// Same over bytes in memory (fuzzing, tests, network). `name` is used in messages and, for
/// format detection, its extension. `bytes` must outlive the reader. A .conf cannot be read
/// from memory (it names other files).
std::unique_ptr<PointReader> openPointReader(std::span<const uint8_t> bytes,
                                             const std::string& name,
                                             const ReaderOptions& options = {});

/// Every file that reading `path` opens: `path` itself and, for a Stanford .conf, the scans it
/// lists (and theirs, for a nested .conf). What a writer must never write over. Throws
/// ReadError as openPointReader() does.
std::vector<std::filesystem::path> filesRead(const std::filesystem::path& path);

}  // namespace tessera::lod
