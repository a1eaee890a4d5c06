// tile_scan: tiles a LAS or LAZ file side by side into one LAS or LAZ file of exactly N points,
// the inputs of the scale benchmarks (10^7 to 10^9 points of real LiDAR). The copies are laid
// out as bench/tile_las.py lays them: shifted in x and y by the input's extent in its own integer
// units plus one unit (so seams never hold duplicate positions), on a square grid, row by row,
// the last copy cut short. Every record is copied with all its attributes; the header, VLRs and
// scale are the input's, the counts and bounds recomputed. LAZ output is coded on worker threads
// in chunks of 50,000 points, so 10^9 points take about 5.5 GB where LAS takes 34 GB.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <vector>

#include <CLI/CLI.hpp>

#include <tessera/core/progress.h>

#include "../lod/src/las_file.h"

namespace {

namespace fs = std::filesystem;
using namespace tessera::lod;
constexpr const char* kComponent = "tile_scan";

// LAS records are little-endian, as is every machine this runs on.
int32_t loadI32(const uint8_t* p) {
  int32_t v;
  std::memcpy(&v, p, 4);
  return v;
}
void storeI32(uint8_t* p, int64_t v) {
  const auto w = int32_t(v);
  std::memcpy(p, &w, 4);
}

int run(const fs::path& in, const fs::path& out, uint64_t n_out, unsigned threads, bool quiet) {
  ByteSource src = ByteSource::openFile(in, kComponent);
  detail::LasParts parts = detail::readLasParts(src, kComponent);
  const uint16_t rl = parts.record_length;
  std::vector<uint8_t> records;
  records.reserve(size_t(parts.count) * rl);
  detail::forEachRecordBlock(in, threads, [&](const uint8_t* r, uint64_t n) {
    records.insert(records.end(), r, r + n * rl);
  });
  const uint64_t n_in = records.size() / rl;
  if (n_in == 0) throw std::runtime_error(in.string() + ": the file holds no points");
  int64_t lo_x = std::numeric_limits<int64_t>::max(), hi_x = std::numeric_limits<int64_t>::min();
  int64_t lo_y = lo_x, hi_y = hi_x;
  for (uint64_t i = 0; i < n_in; ++i) {
    const int64_t x = loadI32(&records[i * rl]);
    const int64_t y = loadI32(&records[i * rl + 4]);
    lo_x = std::min(lo_x, x), hi_x = std::max(hi_x, x);
    lo_y = std::min(lo_y, y), hi_y = std::max(hi_y, y);
  }
  const int64_t step_x = hi_x - lo_x + 1, step_y = hi_y - lo_y + 1;
  const uint64_t tiles = (n_out + n_in - 1) / n_in;
  const uint64_t side = uint64_t(std::ceil(std::sqrt(double(tiles))));
  if (hi_x + int64_t(side - 1) * step_x > std::numeric_limits<int32_t>::max() ||
      hi_y + int64_t((tiles - 1) / side) * step_y > std::numeric_limits<int32_t>::max())
    throw std::runtime_error("tiled coordinates overflow int32 at " + in.string() +
                             "'s scale; ask for fewer points");
  if (n_out > 0xFFFFFFFFull && parts.minor < 4)
    throw std::runtime_error("more than 2^32-1 points need a LAS 1.4 input");

  const bool laz = out.extension() == ".laz" || out.extension() == ".LAZ";
  detail::LasFileWriter writer(out, std::move(parts), laz, threads, kComponent);
  tessera::Progress progress("tiling", n_out, " points", quiet);
  std::vector<uint8_t> copy(records.size());
  for (uint64_t tile = 0, written = 0; written < n_out; ++tile) {
    const uint64_t m = std::min(n_in, n_out - written);
    const int64_t dx = int64_t(tile % side) * step_x, dy = int64_t(tile / side) * step_y;
    std::copy(records.begin(), records.begin() + ptrdiff_t(m * rl), copy.begin());
    for (uint64_t i = 0; i < m; ++i) {
      uint8_t* r = &copy[i * rl];
      storeI32(r, loadI32(r) + dx);
      storeI32(r + 4, loadI32(r + 4) + dy);
    }
    writer.add(copy.data(), m);
    written += m;
    progress.add(m);
  }
  writer.commit();
  progress.finish();
  if (!quiet)
    std::cerr << "tile_scan: " << out.string() << ": " << n_out << " points, " << tiles
              << " copies of " << in.filename().string() << " on a " << side << "-wide grid, "
              << fs::file_size(out) << " bytes\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "tile_scan: tile a LAS or LAZ file side by side (copies shifted in x and y by its extent, "
      "on a square grid) into one LAS or LAZ file (by OUT's extension) of exactly N points"};
  fs::path in, out;
  double points = 0;
  unsigned threads = 0;
  bool quiet = false;
  app.add_option("input", in, "Input LAS or LAZ")->required()->check(CLI::ExistingFile);
  app.add_option("-o,--output", out, "Output .las or .laz")->required();
  app.add_option("-n,--points", points, "Points in the output (1e9 works)")
      ->required()
      ->check(CLI::Range(1.0, 1e12));
  app.add_option("--threads", threads, "Threads decoding and coding LAZ (0: one per core)")
      ->check(CLI::Range(0u, 256u));
  app.add_flag("--quiet", quiet, "No progress output");
  CLI11_PARSE(app, argc, argv);
  if (points != std::floor(points)) {
    std::cerr << "tile_scan: error: --points must be a whole number, got " << points << "\n";
    return 2;
  }
  try {
    return run(in, out, uint64_t(points), threads, quiet);
  } catch (const std::exception& e) {
    std::cerr << "tile_scan: error: " << e.what() << "\n";
    return 1;
  }
}
