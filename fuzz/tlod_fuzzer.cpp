// libFuzzer target: bytes read as a .tlod store, checksums fixed first (store_fuzz.h).
#include "store_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::readStore(data, size);
}
