// A test suite over one point store of the bunny's registered scans (TESSERA_DATA_DIR
// stanford-bunny/scans/bun.conf, 362,272 points), built once per suite into a temporary folder,
// with a headless GL context current for the suite's whole run; BunnyMeshStoreTest adds the
// bunny's reconstruction as a mesh store beside it.
#pragma once

#include <string>

#include <gtest/gtest.h>

#include <tessera/lod/mesh_builder.h>
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

/// The bunny's reconstruction (69,451 triangles).
inline const std::string kBunnyMeshPly =
    std::string(TESSERA_DATA_DIR) + "/stanford-bunny/reconstruction/bun_zipper.ply";

/// BunnyStoreTest, and the reconstruction as a mesh store b.tmesh beside b.tlod (patches of
/// about 1024 triangles).
class BunnyMeshStoreTest : public BunnyStoreTest {
 public:
  static void SetUpTestSuite() {
    BunnyStoreTest::SetUpTestSuite();
    lod::MeshBuildOptions o;
    o.patch_triangles = 1024;
    o.quiet = true;
    lod::buildMeshStore(std::vector<std::filesystem::path>{kBunnyMeshPly}, *sDir / "b.tmesh", o);
  }
};

}  // namespace tessera::test
