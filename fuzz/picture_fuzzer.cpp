// libFuzzer target: bytes decoded as an image item's picture (picture_fuzz.h).
#include "picture_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::decodePicture(data, size);
}
