// Replays every input the fuzzers ever crashed on (fuzz/regressions/<format>/) through the same
// checks the fuzz targets make; under the asan preset this is the sanitizer regression suite.
#include <gtest/gtest.h>

#include <filesystem>

#include "../../fuzz/conf_fuzz.h"
#include "../../fuzz/fuzz_reader.h"
#include "../../fuzz/laz_fuzz.h"
#include "../../fuzz/store_fuzz.h"
#include "../../fuzz/tmesh_fuzz.h"
#include "../support/temp_dir.h"

namespace tessera::lod {
namespace {

const std::filesystem::path kRegressions = TESSERA_FUZZ_REGRESSIONS;

TEST(FuzzRegressions, EveryRecordedCrashInputIsHandled) {
  const std::pair<const char*, Format> formats[] = {{"ply", Format::kPly},
                                                    {"las", Format::kLas},
                                                    {"text", Format::kText},
                                                    {"obj", Format::kObj},
                                                    {"e57", Format::kE57}};
  size_t replayed = 0;
  for (auto [dir, format] : formats) {
    std::filesystem::path folder = kRegressions / dir;
    if (!std::filesystem::exists(folder)) continue;
    for (const auto& entry : std::filesystem::directory_iterator(folder)) {
      auto bytes = test::readBytes(entry.path());
      SCOPED_TRACE(entry.path().string());
      // Aborts (and fails the test binary) on a broken invariant; sanitizers report the rest.
      fuzz::readAll(bytes.data(), bytes.size(), format, entry.path().filename().c_str());
      ++replayed;
    }
  }
  EXPECT_GT(replayed, 0u) << "no regression inputs found in " << kRegressions;
}

TEST(FuzzRegressions, EveryRecordedConfStoreAndChunkInputIsHandled) {
  test::TempDir fixture;
  fuzz::writeConfFixture(fixture.path());
  const std::pair<const char*, int (*)(const uint8_t*, size_t, const std::filesystem::path&)>
      targets[] = {
          {"conf", [](const uint8_t* d, size_t n,
                      const std::filesystem::path& dir) { return fuzz::readConf(d, n, dir); }},
          {"tlod", [](const uint8_t* d, size_t n,
                      const std::filesystem::path&) { return fuzz::readStore(d, n); }},
          {"chunk", [](const uint8_t* d, size_t n,
                       const std::filesystem::path&) { return fuzz::decodeChunkBytes(d, n); }},
          {"tmesh", [](const uint8_t* d, size_t n, const std::filesystem::path&) {
             return fuzz::readMeshStore(d, n);
           }},
          {"laz", [](const uint8_t* d, size_t n,
                     const std::filesystem::path&) { return fuzz::decodeLaz(d, n); }}};
  size_t replayed = 0;
  for (auto [dir, replay] : targets) {
    const std::filesystem::path folder = kRegressions / dir;
    if (!std::filesystem::exists(folder)) continue;
    for (const auto& entry : std::filesystem::directory_iterator(folder)) {
      auto bytes = test::readBytes(entry.path());
      SCOPED_TRACE(entry.path().string());
      // Unguarded, the .conf cycles here would recurse until the stack overflowed (SIGSEGV).
      replay(bytes.data(), bytes.size(), fixture.path());
      ++replayed;
    }
  }
  EXPECT_GE(replayed, 3u) << "the .conf cycle inputs are missing from " << kRegressions;
}

}  // namespace
}  // namespace tessera::lod
