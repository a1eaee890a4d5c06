// libFuzzer target: bytes read as a serialised selection (annotate/selection.h), as given and with
// the checksum fixed (selection_fuzz.h).
#include "selection_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::readSelection(data, size);
}
