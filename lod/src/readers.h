// Constructors of the concrete readers behind openPointReader().
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <vector>

#include <tessera/lod/point_reader.h>

#include "byte_source.h"

namespace tessera::lod::detail {

/// Bytes looked at to recognise a PLY magic line (ByteSource::ensure() this many first).
constexpr size_t kPlyMagicProbe = 64;

/// The PLY magic line: "ply", optional blanks (some exporters write "ply "), the line's end.
inline bool isPlyMagic(const uint8_t* head, size_t n) {
  if (n < 4 || std::memcmp(head, "ply", 3) != 0) return false;
  for (size_t i = 3; i < n; ++i) {
    if (head[i] == '\n' || head[i] == '\r') return true;
    if (head[i] != ' ' && head[i] != '\t') return false;
  }
  return false;
}

std::unique_ptr<PointReader> openPly(ByteSource source);
/// LAS or LAZ; `decode_threads`: LAZ chunks decoded at once (0: one per core).
std::unique_ptr<PointReader> openLas(ByteSource source, unsigned decode_threads = 0);
struct LasRecordFormat;
/// The record layout of an uncompressed LAS file's reader, as openLas() parsed it (colour depth
/// included); nullptr for any other reader, LAZ too. Valid while the reader lives.
const LasRecordFormat* lasRecords(const PointReader& reader);
std::unique_ptr<PointReader> openText(ByteSource source);
std::unique_ptr<PointReader> openObj(ByteSource source);
std::unique_ptr<PointReader> openE57(ByteSource source);
/// A Stanford .conf file. `chain`: the .conf files being read around it, outermost first (a
/// .conf may list .conf files; one that lists itself, directly or not, is refused).
std::unique_ptr<PointReader> openStanfordConf(const std::filesystem::path& conf,
                                              std::vector<std::filesystem::path> chain = {});

/// A .conf listing from bytes (the fuzz target); its scans are found beside `conf`.
std::unique_ptr<PointReader> openStanfordConf(ByteSource listing,
                                              const std::filesystem::path& conf);

}  // namespace tessera::lod::detail
