#include "las_direct.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <limits>
#include <mutex>

#include <tessera/core/parallel.h>

#include "reader_util.h"

namespace tessera::lod {
namespace {

// Records read and converted at once: 64 Ki records (2.2 MB of format 3) keep a block and its
// converted points (2.6 MB) in the cache of a core.
constexpr uint64_t kBlock = uint64_t(1) << 16;
// Points a bounds task covers: enough tasks to share two to sixteen threads evenly.
constexpr uint64_t kBoundsTask = uint64_t(1) << 22;

}  // namespace

LasDirect::LasDirect(std::vector<Input> inputs) : mInputs(std::move(inputs)) {
  for (const Input& in : mInputs) {
    mFiles.push_back(std::make_unique<ScopedFd>(in.path, O_RDONLY, "input"));
    const detail::LasRecordFormat& r = in.records;
    const off_t size = ::lseek(mFiles.back()->get(), 0, SEEK_END);
    const uint64_t bytes =
        size > 0 && uint64_t(size) > r.data_offset ? uint64_t(size) - r.data_offset : 0;
    const uint64_t whole = bytes / r.record_length;
    if (whole < r.count) {
      // What the reader says when it reaches the end: the same words and byte.
      detail::fail("lod::readLas()", in.path,
                   detail::atByte(r.data_offset + whole * r.record_length),
                   "file ends inside point record " + std::to_string(whole) + " of " +
                       std::to_string(r.count) + " declared by the header");
    }
    ::posix_fadvise(mFiles.back()->get(), 0, 0, POSIX_FADV_SEQUENTIAL);
    mFirst.push_back(mPoints);
    mPoints += r.count;
  }
}

void LasDirect::forEachBlock(
    uint64_t begin, uint64_t end, std::vector<uint8_t>& buffer,
    const std::function<void(size_t, uint64_t, uint64_t, const uint8_t*)>& fn) const {
  size_t i = size_t(std::upper_bound(mFirst.begin(), mFirst.end(), begin) - mFirst.begin()) - 1;
  for (uint64_t at = begin; at < end && i < mInputs.size(); ++i) {
    const detail::LasRecordFormat& r = mInputs[i].records;
    const uint64_t stop = std::min(end, mFirst[i] + r.count);
    while (at < stop) {
      const uint64_t n = std::min(kBlock, stop - at);
      buffer.resize(size_t(n * r.record_length));
      preadAll(mFiles[i]->get(), buffer.data(), buffer.size(),
               r.data_offset + (at - mFirst[i]) * r.record_length, mInputs[i].path);
      fn(i, at, n, buffer.data());
      at += n;
    }
  }
}

void LasDirect::bounds(unsigned threads, glm::dvec3& lo, glm::dvec3& hi) const {
  // Integer extremes per input and axis: min x, y, z then max x, y, z.
  using Extremes = std::array<int32_t, 6>;
  const Extremes none{std::numeric_limits<int32_t>::max(), std::numeric_limits<int32_t>::max(),
                      std::numeric_limits<int32_t>::max(), std::numeric_limits<int32_t>::min(),
                      std::numeric_limits<int32_t>::min(), std::numeric_limits<int32_t>::min()};
  std::vector<Extremes> all(mInputs.size(), none);
  std::mutex mutex;
  const size_t tasks = size_t((mPoints + kBoundsTask - 1) / kBoundsTask);
  parallelFor(tasks, threads, [&](size_t t) {
    std::vector<Extremes> mine(mInputs.size(), none);
    std::vector<uint8_t> buffer;
    forEachBlock(t * kBoundsTask, std::min(mPoints, (t + 1) * kBoundsTask), buffer,
                 [&](size_t i, uint64_t, uint64_t n, const uint8_t* rec) {
                   Extremes& e = mine[i];
                   const size_t len = mInputs[i].records.record_length;
                   for (uint64_t k = 0; k < n; ++k, rec += len) {
                     for (int a = 0; a < 3; ++a) {
                       const int32_t v = detail::loadLE<int32_t>(rec + 4 * a);
                       e[size_t(a)] = std::min(e[size_t(a)], v);
                       e[size_t(a) + 3] = std::max(e[size_t(a) + 3], v);
                     }
                   }
                 });
    std::lock_guard lock(mutex);
    for (size_t i = 0; i < all.size(); ++i) {
      for (size_t a = 0; a < 3; ++a) {
        all[i][a] = std::min(all[i][a], mine[i][a]);
        all[i][a + 3] = std::max(all[i][a + 3], mine[i][a + 3]);
      }
    }
  });
  lo = glm::dvec3(std::numeric_limits<double>::max());
  hi = glm::dvec3(-std::numeric_limits<double>::max());
  for (size_t i = 0; i < mInputs.size(); ++i) {
    if (mInputs[i].records.count == 0) continue;
    const detail::LasRecordFormat& r = mInputs[i].records;
    for (int a = 0; a < 3; ++a) {
      // The decoded coordinate is monotonic in the integer: its extremes are the integers'.
      const double c0 = r.coordinate(a, all[i][size_t(a)]) + mInputs[i].shift[a];
      const double c1 = r.coordinate(a, all[i][size_t(a) + 3]) + mInputs[i].shift[a];
      lo[a] = std::min({lo[a], c0, c1});
      hi[a] = std::max({hi[a], c0, c1});
    }
  }
}

void LasDirect::forEachPart(int parts, std::span<const uint8_t> ao,
                            const std::function<void(int, std::span<const BuildPoint>)>& fn) const {
  parallelFor(size_t(parts), unsigned(parts), [&](size_t part) {
    const uint64_t begin = mPoints * part / uint64_t(parts);
    const uint64_t end = mPoints * (part + 1) / uint64_t(parts);
    std::vector<uint8_t> buffer;
    auto pts = std::make_unique_for_overwrite<BuildPoint[]>(size_t(kBlock));
    forEachBlock(begin, end, buffer, [&](size_t i, uint64_t first, uint64_t n, const uint8_t* rec) {
      const Input& in = mInputs[i];
      const detail::LasRecordFormat& r = in.records;
      const bool color = r.rgb >= 0;
      for (uint64_t k = 0; k < n; ++k, rec += r.record_length) {
        BuildPoint& p = pts[k];
        p.position = r.position(rec) + in.shift;
        p.rgb = color ? r.color(rec) : glm::u8vec3(255);
        p.classification = r.classification(rec);
        p.intensity = r.intensity(rec);
        p.source = in.source;
        p.ao = ao.empty() ? 255 : ao[first + k];
      }
      fn(int(part), std::span<const BuildPoint>(pts.get(), size_t(n)));
    });
  });
}

}  // namespace tessera::lod
