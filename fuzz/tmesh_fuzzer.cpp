// libFuzzer target: bytes read as a .tmesh mesh store, checksums fixed first (tmesh_fuzz.h).
#include "tmesh_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::readMeshStore(data, size);
}
