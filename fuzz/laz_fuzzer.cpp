// libFuzzer target for LAZ: files and bare chunks (laz_fuzz.h).
#include "laz_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::decodeLaz(data, size);
}
