// The body of the Stanford .conf fuzz target and its regression replay: the bytes are a .conf
// listing read from memory, its scans found in a folder of small files (writeConfFixture) that
// includes .conf files naming themselves and each other, so mutations reach nesting and
// cycles. The scans are drained and checked as every reader's batches are (fuzz_reader.h).
#pragma once

#include <filesystem>
#include <fstream>
#include <span>

#include "../lod/src/byte_source.h"
#include "../lod/src/readers.h"
#include "fuzz_reader.h"

namespace tessera::fuzz {

/// Writes into `dir`: a.ply (3 points, one face), b.xyz (2 points), self.conf (lists itself),
/// ping.conf and pong.conf (list each other), nest.conf (lists a.ply), empty.conf.
inline void writeConfFixture(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  auto write = [&](const char* name, const char* text) { std::ofstream(dir / name) << text; };
  write("a.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  write("b.xyz", "1 2 3\n4 5 6\n");
  write("self.conf", "bmesh self.conf 0 0 0 0 0 0 1\n");
  write("ping.conf", "bmesh pong.conf 0 0 0 0 0 0 1\n");
  write("pong.conf", "bmesh ping.conf 1 0 0 0 0 0 1\n");
  write("nest.conf", "camera 0 0 0 0 0 0 1\nbmesh a.ply 0 0 1 0 0 0.7071068 0.7071068\n");
  write("empty.conf", "");
}

/// Reads `data` as the listing `dir`/fuzz.conf. ReadError is the only failure allowed.
inline int readConf(const uint8_t* data, size_t size, const std::filesystem::path& dir) {
  const std::filesystem::path conf = dir / "fuzz.conf";
  try {
    auto reader = lod::detail::openStanfordConf(
        lod::ByteSource::fromMemory(std::span<const uint8_t>(data, size), conf.string()), conf);
    require(reader->info().format == lod::Format::kStanfordConf, "format is not .conf");
    require(!reader->info().scans.empty(), "a .conf opened without scans");
    checkReader(*reader);
  } catch (const lod::ReadError&) {
  }
  return 0;
}

}  // namespace tessera::fuzz
