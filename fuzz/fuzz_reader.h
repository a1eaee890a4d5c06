// The body shared by the reader fuzz targets: open the bytes as one forced format, drain every
// batch with a small batch size and check what the PointBatch contract promises (checkReader(),
// also used by the .conf target, conf_fuzz.h). ReadError is
// the only failure a reader may report; anything else escapes and libFuzzer reports it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>

#include <tessera/lod/point_reader.h>

namespace tessera::fuzz {

inline void require(bool ok, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "reader fuzz: broken invariant: %s\n", what);
  std::abort();
}

inline bool finite(const glm::dvec3& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

/// Drains `reader` in batches of 7 points, checking what the PointBatch contract promises.
/// ReadError propagates.
inline void checkReader(lod::PointReader& reader_ref) {
  using namespace tessera::lod;
  PointReader* reader = &reader_ref;
  {
    require(finite(reader->info().origin), "non-finite origin");
    PointBatch batch;
    uint64_t points = 0, triangles = 0;
    uint32_t max_index = 0;
    while (reader->next(batch, 7)) {
      size_t n = batch.size();
      AttributeMask a = batch.attributes;
      require(a == reader->info().attributes, "batch attributes differ from info().attributes");
      require(!(a & kNormal) || batch.normals.size() == n, "normals.size() != size()");
      require(!(a & kColor) || batch.colors.size() == n, "colors.size() != size()");
      require(!(a & kIntensity) || batch.intensities.size() == n, "intensities.size() != size()");
      require(!(a & kConfidence) || batch.confidences.size() == n, "confidences.size() != size()");
      require(!(a & kGridPosition) || batch.grid_positions.size() == n, "grid_positions.size()");
      require(!(a & kClassification) || batch.classifications.size() == n,
              "classifications.size()");
      for (const glm::dvec3& p : batch.positions) require(finite(p), "non-finite position");
      for (const Triangle& t : batch.triangles) {
        max_index = std::max({max_index, t.x, t.y, t.z});
      }
      points += n;
      triangles += batch.triangles.size();
    }
    require(triangles == 0 || max_index < points, "triangle names a vertex never delivered");
    require(reader->stats().points == points, "stats().points != points delivered");
    require(reader->stats().triangles == triangles, "stats().triangles != triangles delivered");
  }
}

inline int readAll(const uint8_t* data, size_t size, lod::Format format, const char* name) {
  using namespace tessera::lod;
  try {
    ReaderOptions options;
    options.format = format;
    auto reader = openPointReader(std::span<const uint8_t>(data, size), name, options);
    checkReader(*reader);
  } catch (const ReadError&) {
  }
  return 0;
}

}  // namespace tessera::fuzz
