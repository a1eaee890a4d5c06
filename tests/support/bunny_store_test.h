// A test suite over one point store of the bunny's registered scans (TESSERA_DATA_DIR
// stanford-bunny/scans/bun.conf, 362,272 points), built once per suite into a temporary folder,
// with a headless GL context current for the suite's whole run.
#pragma once

#include <string>

#include <gtest/gtest.h>

#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>

#include "temp_dir.h"

namespace tessera::test {

class BunnyStoreTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sDir = new TempDir();
    lod::BuildOptions o;
    o.quiet = true;
    lod::buildStore({std::string(TESSERA_DATA_DIR) + "/stanford-bunny/scans/bun.conf"},
                    *sDir / "b.tlod", o);
    sContext = render::GlContext::createHeadless().release();
  }
  static void TearDownTestSuite() {
    delete sContext;
    delete sDir;
  }
  static inline TempDir* sDir = nullptr;  ///< holds b.tlod
  static inline render::GlContext* sContext = nullptr;
};

}  // namespace tessera::test
