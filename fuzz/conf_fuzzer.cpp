// libFuzzer target: bytes read as a Stanford .conf listing whose scans are small files in a
// temporary folder (conf_fuzz.h).
#include <unistd.h>

#include <string>

#include "conf_fuzz.h"

namespace {

/// The folder of scans, written once and removed at exit.
struct Fixture {
  std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("tessera-conf-fuzz-" + std::to_string(::getpid()));
  Fixture() { tessera::fuzz::writeConfFixture(dir); }
  ~Fixture() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

const std::filesystem::path& fixtureDir() {
  static const Fixture fixture;
  return fixture.dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return tessera::fuzz::readConf(data, size, fixtureDir());
}
