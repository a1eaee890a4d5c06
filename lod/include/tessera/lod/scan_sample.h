// An even sample of a raw scan, read without parsing the whole file: what a first picture is
// drawn from while the scan's store builds (tessera-render --preview, the window).
//
// Formats with fixed-size records are sampled by record: LAS every k-th record (k = declared
// points / wanted points, rounded down, at least 1), read in spans of at most 4 MiB that skip
// whatever lies more than 64 KiB between two samples; binary PLY every k-th vertex the same way.
// LAZ is coded chunk by chunk, each chunk on its own: a spread of chunks (evenly through the
// file, as many as the wanted points need, at least 16 when the file has them) is decoded and
// every k-th record of each kept. ASCII PLY, XYZ/PTS/TXT/CSV, E57, OBJ and Stanford .conf files
// cannot be sampled this way; sampleScan() then says why and the caller builds the whole store.
//
// The file's header is parsed by the format's own reader first (openPointReader()), so a bad
// header gives the reader's error; a file that ends before its declared records gives the
// reader's "file ends inside point record N of M" (LAS) or "file ends inside vertex N of M"
// (PLY) with the byte where it ends, and a bad LAZ chunk the chunk reader's error. The sample is
// kept as a small file of the same kind (LAS for LAS and LAZ, binary PLY for PLY) holding the
// original header's bounds, scale and offset, so its reader gives the very points (same origin,
// same positions) the whole file's reader gives for those records.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <tessera/lod/point_reader.h>
#include <tessera/lod/store_builder.h>

namespace tessera::lod {

struct SampleOptions {
  /// About this many points (at least this many when the file holds them; at most twice as
  /// many). Precondition (TESSERA_CHECK): at least 1. The default is about half a point for
  /// each pixel of a 1280x720 view: its store builds in a fifth of a second, so a preview shows
  /// within a tenth of the time ParaView takes to its first picture of 10^7 points.
  uint64_t points = 500'000;
};

class ScanSample {
 public:
  /// Samples the scan at `path`. Returns nothing, with the reason in `why_not` when given, for
  /// a format that cannot be sampled (see above). Throws ReadError, naming the file and the
  /// byte, for a file its reader refuses or one shorter than its header declares.
  static std::optional<ScanSample> read(const std::filesystem::path& path,
                                        const SampleOptions& options = {},
                                        std::string* why_not = nullptr);
  /// The same over bytes in memory (fuzzing, tests); `name` names it in messages and gives the
  /// extension that detection uses. `bytes` need not outlive the sample.
  static std::optional<ScanSample> read(std::span<const uint8_t> bytes, const std::string& name,
                                        const SampleOptions& options = {},
                                        std::string* why_not = nullptr);

  /// The whole file's header as its reader gives it (format, declared points, header bounds).
  const SourceInfo& info() const { return mInfo; }
  /// Records kept: LAS and PLY record (or vertex) i * stride() for i = 0, 1, ...; LAZ every
  /// stride()-th record of each chunk decoded.
  uint64_t stride() const { return mStride; }
  /// Records in the sample.
  uint64_t points() const { return mPoints; }
  /// LAZ: the chunks decoded, in file order (empty for LAS and PLY); chunkCount() in all.
  const std::vector<uint64_t>& chunks() const { return mChunks; }
  uint64_t chunkCount() const { return mChunkCount; }
  /// Bytes of the file read or decoded to draw the sample (LAZ: compressed chunk bytes).
  uint64_t bytesRead() const { return mBytesRead; }

  /// The sample's points, as the format's reader gives them; the reader reads this object's
  /// bytes, so the sample must outlive it.
  std::unique_ptr<PointReader> reader() const;
  /// The sample as a file of its own (".las" or ".ply"; extension()). Throws WriteError
  /// (point_writer.h) naming the file when it cannot be written.
  void write(const std::filesystem::path& path) const;
  /// ".las" or ".ply": what write() makes and reader() reads.
  const std::string& extension() const { return mExtension; }

 private:
  ScanSample() = default;
  SourceInfo mInfo;
  std::vector<uint8_t> mBytes;
  std::string mName, mExtension;
  uint64_t mStride = 1, mPoints = 0, mChunkCount = 0, mBytesRead = 0;
  std::vector<uint64_t> mChunks;
  friend struct ScanSampler;
};

/// Builds a .tlod of `sample` at `output` (through a temporary file of the sample beside it,
/// removed at the end), quiet, with the build's settings for speed over size (zstd level 1).
/// Throws as buildStore() does.
BuildReport buildSampleStore(const ScanSample& sample, const std::filesystem::path& output,
                             int threads = 0);

}  // namespace tessera::lod
