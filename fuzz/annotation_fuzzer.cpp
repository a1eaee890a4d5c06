// libFuzzer target: bytes imported as a JSON annotation export (annotation_fuzz.h).
#include "annotation_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::importAnnotations(data, size);
}
