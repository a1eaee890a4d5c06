// Writers for PLY, LAS and LAZ: export, test fixtures and benchmark inputs. Output is written to a
// temporary file beside the target and renamed into place, so a failed write leaves nothing.
#pragma once

#include <filesystem>
#include <stdexcept>

#include <tessera/lod/point_batch.h>

namespace tessera::lod {

/// A file could not be written (disk full, no permission). Names the file.
class WriteError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class PlyEncoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

struct PlyWriteOptions {
  PlyEncoding encoding = PlyEncoding::kBinaryLittleEndian;
  bool double_positions = false;  ///< `double x` instead of `float x`
  bool ushort_colors = false;     ///< colours as ushort (value * 257) instead of uchar
};

/// Writes the points (positions + origin as world coordinates) with every attribute of the
/// batch that PLY can hold (normals, colour, alpha, intensity, confidence) and its triangles.
void writePly(const std::filesystem::path& path, const PointBatch& points, const glm::dvec3& origin,
              const PlyWriteOptions& options = {});

struct LasWriteOptions {
  int minor_version = 2;          ///< 2, 3 or 4
  int point_format = 3;           ///< 0..10
  glm::dvec3 scale{0.001};        ///< coordinate resolution
  bool eight_bit_colors = false;  ///< store 0..255 in the 16-bit fields (as some writers do)
  uint16_t extra_bytes = 0;       ///< zero bytes appended to each record (record length grows)
  bool laz = false;               ///< LAZ-compressed (formats 0-3 and 6-8)
};

/// Writes a LAS or LAZ file. Coordinates are world = origin + position, quantised by `scale`
/// around an offset at the box centre. Colour, intensity and classification come from the batch
/// when set.
void writeLas(const std::filesystem::path& path, const PointBatch& points, const glm::dvec3& origin,
              const LasWriteOptions& options = {});

}  // namespace tessera::lod
