// libFuzzer target: bytes sampled as a raw scan's preview (lod/scan_sample.h). The first byte
// picks the name the bytes go by (.las, .laz or .ply: detection then reads the magic bytes), the
// second how many points the sample asks for (1 to 256); the rest is the file. The sampler's own
// reading (the LAS parts, the LAZ chunk spread, the PLY header walk and the strided gather) runs,
// then the sample's reader is drained under the reader contract (fuzz_reader.h). ReadError is
// the only failure allowed.
#include <tessera/lod/scan_sample.h>

#include "fuzz_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  static const char* const kNames[] = {"fuzz.las", "fuzz.laz", "fuzz.ply"};
  const std::string name = kNames[data[0] % 3];
  const tessera::lod::SampleOptions options{uint64_t(data[1]) + 1};
  try {
    std::string why_not;
    const auto sample =
        tessera::lod::ScanSample::read(std::span(data + 2, size - 2), name, options, &why_not);
    if (!sample) {
      tessera::fuzz::require(!why_not.empty(), "a sample refused without a reason");
      return 0;
    }
    tessera::fuzz::require(sample->stride() >= 1, "a stride of 0");
    auto reader = sample->reader();
    tessera::fuzz::checkReader(*reader);
  } catch (const tessera::lod::ReadError&) {
  }
  return 0;
}
