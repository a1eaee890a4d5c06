// The store builder's passes straight over uncompressed LAS records: a LAS file is already an
// array of fixed-size records, so bounds, counting and distribution read it in parallel parts
// and convert each record once into the builder's point, with no parsed copy of the input on
// disk. Positions, colours and attributes come from las_records.h, the LAS reader's own
// decoding, so a store built this way is the one the reader's points make, byte for byte.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "build_point.h"
#include "file_io.h"
#include "las_records.h"

namespace tessera::lod {

class LasDirect {
 public:
  /// One uncompressed LAS input: its reader's record layout, the shift from its local origin to
  /// the store's frame and the source id its points carry.
  struct Input {
    std::string path;
    detail::LasRecordFormat records;
    glm::dvec3 shift{0.0};
    uint16_t source = 0;
  };

  /// Opens every input. Throws ReadError naming the file and byte when a file ends before the
  /// records its header declares.
  explicit LasDirect(std::vector<Input> inputs);

  uint64_t points() const { return mPoints; }
  /// The exact bounds of every position in the store's frame (what min/max over the decoded
  /// points gives), from each file's integer extremes. Reads every record once on `threads`.
  void bounds(unsigned threads, glm::dvec3& lo, glm::dvec3& hi) const;
  /// Calls `fn(part, points)` on `parts` threads, part p with the points
  /// [points() * p / parts, points() * (p + 1) / parts) of the inputs in order, in blocks.
  /// `ao`: each point's ambient-occlusion byte (empty: 255), points() of them.
  void forEachPart(int parts, std::span<const uint8_t> ao,
                   const std::function<void(int, std::span<const BuildPoint>)>& fn) const;

 private:
  /// Calls `fn(input, first, count, records)` for every block of records in [begin, end) of the
  /// inputs in order; `buffer` holds the block.
  void forEachBlock(
      uint64_t begin, uint64_t end, std::vector<uint8_t>& buffer,
      const std::function<void(size_t, uint64_t, uint64_t, const uint8_t*)>& fn) const;

  std::vector<Input> mInputs;
  std::vector<std::unique_ptr<ScopedFd>> mFiles;
  std::vector<uint64_t> mFirst;  ///< index of each input's first point over all inputs
  uint64_t mPoints = 0;
};

}  // namespace tessera::lod
