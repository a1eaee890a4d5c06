// libFuzzer target: bytes read as LAS (format forced), see fuzz_reader.h.
#include "fuzz_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::readAll(data, size, tessera::lod::Format::kLas, "fuzz.las");
}
