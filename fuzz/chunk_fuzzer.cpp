// libFuzzer target: bytes decoded as one .tlod chunk payload (store_fuzz.h).
#include "store_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::decodeChunkBytes(data, size);
}
