#include <tessera/lod/point_reader.h>

#include <algorithm>
#include <cctype>
#include <cstring>

#include "byte_source.h"
#include "reader_util.h"
#include "readers.h"

namespace tessera::lod {

std::vector<const char*> attributeNames(AttributeMask mask) {
  static constexpr const char* kNames[] = {"normal",        "color",         "alpha",
                                           "intensity",     "confidence",    "scan_index",
                                           "grid_position", "classification", "ambient_occlusion"};
  std::vector<const char*> out;
  for (unsigned i = 0; i < std::size(kNames); ++i) {
    if (mask & (1u << i)) out.push_back(kNames[i]);
  }
  return out;
}

const char* formatName(Format format) {
  switch (format) {
    case Format::kPly:
      return "ply";
    case Format::kStanfordConf:
      return "stanford-conf";
    case Format::kLas:
      return "las";
    case Format::kLaz:
      return "laz";
    case Format::kText:
      return "xyz";
    case Format::kObj:
      return "obj";
    case Format::kE57:
      return "e57";
  }
  return "unknown";
}

void PointBatch::reset(AttributeMask mask) {
  attributes = mask;
  positions.clear();
  normals.clear();
  colors.clear();
  intensities.clear();
  confidences.clear();
  scan_indices.clear();
  grid_positions.clear();
  classifications.clear();
  triangles.clear();
}

void PointBatch::resize(size_t n) {
  positions.resize(n);
  if (attributes & kNormal) normals.resize(n);
  if (attributes & kColor) colors.resize(n);
  if (attributes & kIntensity) intensities.resize(n);
  if (attributes & kConfidence) confidences.resize(n);
  if (attributes & kScanIndex) scan_indices.resize(n);
  if (attributes & kGridPosition) grid_positions.resize(n);
  if (attributes & kClassification) classifications.resize(n);
}

void PointBatch::appendFrom(const PointBatch& o, size_t i) {
  positions.push_back(o.positions[i]);
  if (attributes & kNormal) normals.push_back(o.normals[i]);
  if (attributes & kColor) colors.push_back(o.colors[i]);
  if (attributes & kIntensity) intensities.push_back(o.intensities[i]);
  if (attributes & kConfidence) confidences.push_back(o.confidences[i]);
  if (attributes & kScanIndex) scan_indices.push_back(o.scan_indices[i]);
  if (attributes & kGridPosition) grid_positions.push_back(o.grid_positions[i]);
  if (attributes & kClassification) classifications.push_back(o.classifications[i]);
}

void PointBatch::appendRange(const PointBatch& o, size_t first, size_t count) {
  auto append = [&](auto& dst, const auto& src) {
    dst.insert(dst.end(), src.begin() + ptrdiff_t(first), src.begin() + ptrdiff_t(first + count));
  };
  append(positions, o.positions);
  if (attributes & kNormal) append(normals, o.normals);
  if (attributes & kColor) append(colors, o.colors);
  if (attributes & kIntensity) append(intensities, o.intensities);
  if (attributes & kConfidence) append(confidences, o.confidences);
  if (attributes & kScanIndex) append(scan_indices, o.scan_indices);
  if (attributes & kGridPosition) append(grid_positions, o.grid_positions);
  if (attributes & kClassification) append(classifications, o.classifications);
}

uint64_t ReadStats::skippedTotal() const {
  uint64_t n = 0;
  for (auto& [reason, count] : skipped) n += count;
  return n;
}

void ReadStats::skip(const std::string& reason, const std::string& where) {
  if (skipped[reason]++ == 0) first_skip_at[reason] = where;
}

namespace {

std::string lowerExtension(const std::string& name) {
  std::string ext = std::filesystem::path(name).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext;
}

/// Magic bytes first (they cannot lie about a renamed file), then the extension.
std::optional<Format> detect(const uint8_t* head, size_t n, const std::string& name) {
  if (detail::isPlyMagic(head, n)) return Format::kPly;
  if (n >= 4 && std::memcmp(head, "LASF", 4) == 0) return Format::kLas;
  if (n >= 8 && std::memcmp(head, "ASTM-E57", 8) == 0) return Format::kE57;
  std::string ext = lowerExtension(name);
  if (ext == ".conf") return Format::kStanfordConf;
  if (ext == ".obj") return Format::kObj;
  if (ext == ".xyz" || ext == ".pts" || ext == ".txt" || ext == ".csv") return Format::kText;
  if (ext == ".ply" || ext == ".las" || ext == ".laz" || ext == ".e57")
    return std::nullopt;  // wrong magic
  return std::nullopt;
}

std::unique_ptr<PointReader> openWith(Format format, ByteSource src,
                                      const ReaderOptions& options) {
  switch (format) {
    case Format::kPly:
      return detail::openPly(std::move(src));
    case Format::kLas:
    case Format::kLaz:
      return detail::openLas(std::move(src), options.decode_threads);
    case Format::kText:
      return detail::openText(std::move(src));
    case Format::kObj:
      return detail::openObj(std::move(src));
    case Format::kE57:
      return detail::openE57(std::move(src));
    case Format::kStanfordConf:
      break;
  }
  detail::fail("lod::openPointReader()", src.name(), "",
               "a Stanford .conf names other files and cannot be read from memory");
}

[[noreturn]] void unknownFormat(ByteSource& src) {
  std::string ext = lowerExtension(src.name());
  std::string what;
  if (src.size() == 0) {
    what = "file is empty";
  } else if (ext == ".ply") {
    what = "not a PLY file (missing 'ply' magic line)";
  } else if (ext == ".las" || ext == ".laz") {
    what = "not a LAS file (missing 'LASF' signature)";
  } else if (ext == ".e57") {
    what = "not an E57 file (missing 'ASTM-E57' signature)";
  } else {
    what = "unknown point format (expected PLY, LAS, LAZ, E57, .conf, .xyz/.pts/.txt or .obj)";
  }
  detail::fail("lod::openPointReader()", src.name(), "byte 0", what);
}

std::unique_ptr<PointReader> openSource(ByteSource src, const ReaderOptions& options) {
  size_t n = src.ensure(detail::kPlyMagicProbe);
  auto format = options.format ? options.format : detect(src.data(), n, src.name());
  if (!format) unknownFormat(src);
  if (src.size() == 0)
    detail::fail("lod::openPointReader()", src.name(), "byte 0", "file is empty");
  return openWith(*format, std::move(src), options);
}

}  // namespace

std::unique_ptr<PointReader> openPointReader(const std::filesystem::path& path,
                                             const ReaderOptions& options) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    throw ReadError("lod::openPointReader(): " + path.string() + ": no such file");
  }
  bool conf = options.format ? *options.format == Format::kStanfordConf
                             : lowerExtension(path.string()) == ".conf";
  if (conf) return detail::openStanfordConf(path);
  return openSource(ByteSource::openFile(path, "lod::openPointReader()"), options);
}

std::vector<std::filesystem::path> filesRead(const std::filesystem::path& path) {
  std::vector<std::filesystem::path> files{path};
  if (lowerExtension(path.string()) != ".conf") return files;
  auto conf = openPointReader(path);  // a cycle of .confs is refused here
  for (const ScanInfo& s : conf->info().scans) {
    for (auto& f : filesRead(s.path)) files.push_back(std::move(f));
  }
  return files;
}

std::unique_ptr<PointReader> openPointReader(std::span<const uint8_t> bytes,
                                             const std::string& name,
                                             const ReaderOptions& options) {
  return openSource(ByteSource::fromMemory(bytes, name), options);
}

}  // namespace tessera::lod
