// libFuzzer target: bytes read as E57 (format forced), see fuzz_reader.h. Start it from the
// files in ../shared/data/e57; most mutations fail a page's CRC-32C before the structure behind
// it is read.
#include "fuzz_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::readAll(data, size, tessera::lod::Format::kE57, "fuzz.e57");
}
