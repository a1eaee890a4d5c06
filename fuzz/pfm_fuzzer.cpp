// libFuzzer target: bytes read as a projector's PFM warp or blend map (pfm_fuzz.h).
#include "pfm_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::readPfm(data, size);
}
