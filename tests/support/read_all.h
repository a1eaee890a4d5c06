// Drains a reader into one batch (tests only: real code streams).
#pragma once

#include <tessera/lod/point_reader.h>

namespace tessera::test {

struct ReadResult {
  lod::PointBatch points;
  lod::ReadStats stats;
  lod::SourceInfo info;
};

inline ReadResult readAll(lod::PointReader& reader, size_t batch_size = 1000) {
  ReadResult r;
  r.info = reader.info();
  r.points.reset(r.info.attributes);
  lod::PointBatch b;
  while (reader.next(b, batch_size)) {
    for (size_t i = 0; i < b.size(); ++i) r.points.appendFrom(b, i);
    r.points.triangles.insert(r.points.triangles.end(), b.triangles.begin(), b.triangles.end());
  }
  r.stats = reader.stats();
  return r;
}

inline ReadResult readAll(const std::filesystem::path& path, size_t batch_size = 1000) {
  auto reader = lod::openPointReader(path);
  return readAll(*reader, batch_size);
}

inline ReadResult readAllMemory(const std::string& bytes, const std::string& name) {
  auto reader = lod::openPointReader(
      std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()), name);
  return readAll(*reader);
}

/// The message of the ReadError `fn` throws ("" if none).
template <typename Fn>
std::string readErrorOf(Fn&& fn) {
  try {
    fn();
  } catch (const lod::ReadError& e) {
    return e.what();
  }
  return "";
}

}  // namespace tessera::test
