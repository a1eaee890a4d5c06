// The mesh pass and mesh LOD drawing (render/mesh_pass.h, ViewRenderer with mesh models) on the
// real bunny reconstruction: the full-resolution cut against the input mesh drawn directly, the
// coarser cuts within their error, no crack at any cut (whole view and stand-ins), points and
// triangles hiding each other, pick ids naming the triangle.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/mesh.h>
#include <tessera/lod/mesh_builder.h>
#include <tessera/render/mesh_pass.h>
#include <tessera/render/screen_passes.h>
#include <tessera/render/view_renderer.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/config.h>

#include "../support/bunny_store_test.h"

namespace tessera::render {
namespace {

const std::string kBunnyMesh = test::kBunnyMeshPly;

class MeshPassTest : public test::BunnyMeshStoreTest {
 protected:
  /// A view of the bunny from `distance` metres, w x h.
  static ViewSetup view(const lod::MeshStore& s, double distance, uint32_t w, uint32_t h) {
    const glm::dvec3 c = s.summary().origin + 0.5 * (s.summary().bbox_min + s.summary().bbox_max);
    ViewSetup v;
    v.eye_world = c + glm::dvec3(0.03, 0.02, distance);
    v.view = glm::lookAt(v.eye_world, c, glm::dvec3(0, 1, 0));
    v.projection = glm::perspective(glm::radians(40.0), double(w) / h, 0.01, 10.0);
    v.width = w;
    v.height = h;
    return v;
  }

  /// The store drawn as a mesh model, at its own place.
  static ModelInstance meshInstance(lod::MeshStore& s) {
    ModelInstance m;
    m.mesh = &s;
    m.model = storeModel(s);
    return m;
  }

  static bool covered(const Image& img, const glm::vec3& background, size_t i) {
    const glm::u8vec3 bg(background * 255.0f);
    return img.rgba[4 * i] != bg.r || img.rgba[4 * i + 1] != bg.g || img.rgba[4 * i + 2] != bg.b;
  }

  /// Background pixels whose 8 neighbours are all covered: holes the size of a crack.
  static size_t holes(const Image& img, const glm::vec3& background) {
    size_t n = 0;
    for (uint32_t y = 1; y + 1 < img.height; ++y)
      for (uint32_t x = 1; x + 1 < img.width; ++x) {
        if (covered(img, background, size_t(y) * img.width + x)) continue;
        bool closed = true;
        for (int dy = -1; dy <= 1 && closed; ++dy)
          for (int dx = -1; dx <= 1 && closed; ++dx)
            closed = covered(img, background, size_t(y + dy) * img.width + (x + dx));
        n += closed;
      }
    return n;
  }

  static double psnr(const Image& a, const Image& b) {
    double se = 0.0;
    for (size_t i = 0; i < a.rgba.size(); ++i) {
      if (i % 4 == 3) continue;
      const double d = double(a.rgba[i]) - double(b.rgba[i]);
      se += d * d;
    }
    const double mse = se / (double(a.rgba.size()) * 0.75);
    return mse == 0 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
  }

  static double silhouetteIoU(const Image& a, const Image& b, const glm::vec3& bg) {
    size_t both = 0, either = 0;
    for (size_t i = 0; i < size_t(a.width) * a.height; ++i) {
      const bool ca = covered(a, bg, i), cb = covered(b, bg, i);
      both += ca && cb;
      either += ca || cb;
    }
    return either ? double(both) / double(either) : 1.0;
  }
};

TEST_F(MeshPassTest, FullResolutionCutEqualsTheInputMeshDrawnDirectly) {
  auto store = lod::MeshStore::open(*sDir / "b.tmesh");
  const ViewSetup v = view(*store, 0.3, 320, 240);
  RenderOptions o;
  o.lod_pixels = 1e-6;  // every leaf
  ViewRenderer r(v.width, v.height);
  const ModelInstance m = meshInstance(*store);
  RenderStats st;
  const Image lod_image = r.renderSettled({&m, 1}, v, o, &st);
  EXPECT_EQ(st.triangles, 69451u);
  const std::vector<uint32_t> lod_depth = r.readDepth();

  // The input mesh, as one batch, on the store's grid (what the leaves hold, exactly).
  const lod::Mesh mesh = lod::readMesh(kBunnyMesh);
  const lod::MeshSummary& s = store->summary();
  std::vector<GpuMeshVertex> verts(mesh.positions.size());
  std::vector<glm::dvec3> q(mesh.positions.size());
  for (size_t i = 0; i < q.size(); ++i)
    q[i] = glm::round((mesh.positions[i] + mesh.origin - s.origin) / s.step) * s.step;
  std::vector<glm::dvec3> normals(q.size(), glm::dvec3(0.0));
  std::vector<uint32_t> idx;
  for (const lod::Triangle& t : mesh.triangles) {
    const glm::dvec3 f = glm::cross(q[t.y] - q[t.x], q[t.z] - q[t.x]);
    for (int k = 0; k < 3; ++k) normals[t[k]] += f;
    idx.insert(idx.end(), {t.x, t.y, t.z});
  }
  for (size_t i = 0; i < q.size(); ++i) {
    const uint32_t n = packNormal1010102(glm::vec3(glm::normalize(normals[i])));
    verts[i] = {glm::vec3(q[i]), n, 0xFFC8C8C8u, glm::vec3(q[i]), n};
  }
  GlBuffer vb(verts.size() * sizeof(GpuMeshVertex), verts.data());
  GlBuffer ib(idx.size() * 4, idx.data());
  MeshBatch b;
  b.vertices = vb.name();
  b.indices = ib.name();
  b.index_count = uint32_t(idx.size());
  const glm::dmat4 world_from_local = storeModel(*store);
  b.clip_from_local = glm::mat4(v.projection * v.view * world_from_local);
  b.eye_local = glm::vec3(glm::inverse(world_from_local) * glm::dvec4(v.eye_world, 1.0));
  FrameTarget target(v.width, v.height);
  target.clearGeometry(false);
  MeshPass pass;
  pass.draw(target, {&b, 1}, MeshShading{});
  ResolvePass resolve;
  resolve.run(target, o.background, 0);
  const Image direct = target.readImage();

  const std::vector<uint32_t> direct_depth = target.readDepth();
  // The same triangles at the same floats: the same pixels covered, at the same depth up to
  // llvmpipe's interpolation from another vertex order (a few float steps).
  size_t covered_px = 0, same = 0;
  float worst = 0.0f;
  for (size_t i = 0; i < direct_depth.size(); ++i) {
    covered_px += direct_depth[i] != kEmptyDepth;
    same += (direct_depth[i] == kEmptyDepth) == (lod_depth[i] == kEmptyDepth);
    if (direct_depth[i] != kEmptyDepth && lod_depth[i] != kEmptyDepth) {
      float da, db;
      std::memcpy(&da, &direct_depth[i], 4);
      std::memcpy(&db, &lod_depth[i], 4);
      worst = std::max(worst, std::abs(da - db));
    }
  }
  EXPECT_GT(covered_px, 10000u);
  EXPECT_EQ(same, direct_depth.size());
  EXPECT_LT(worst, 1e-6f);
  // Colours differ only by the stored normals' 8-bit octahedral encoding.
  EXPECT_GT(psnr(lod_image, direct), 40.0);
  EXPECT_EQ(holes(lod_image, o.background), holes(direct, o.background));
}

TEST_F(MeshPassTest, CoarserCutsStayWithinTheirErrorAndNeverCrack) {
  auto store = lod::MeshStore::open(*sDir / "b.tmesh");
  const ViewSetup v = view(*store, 0.3, 320, 240);
  const ModelInstance m = meshInstance(*store);
  ViewRenderer r(v.width, v.height);
  RenderOptions o;
  o.lod_pixels = 1e-6;
  RenderStats full_st;
  const Image full = r.renderSettled({&m, 1}, v, o, &full_st);
  EXPECT_EQ(holes(full, o.background), 0u);
  double last_triangles = double(full_st.triangles);
  for (double px : {0.5, 1.0, 4.0, 1000.0}) {
    SCOPED_TRACE("threshold " + std::to_string(px) + " px");
    o.lod_pixels = px;
    RenderStats st;
    const Image img = r.renderSettled({&m, 1}, v, o, &st);
    EXPECT_LE(double(st.triangles), last_triangles);
    last_triangles = double(st.triangles);
    EXPECT_EQ(holes(img, o.background), 0u);
    if (px <= 1.0) {
      // A cut within a pixel of the surface: the silhouette and shading hold.
      EXPECT_GT(silhouetteIoU(img, full, o.background), 0.985);
      EXPECT_GT(psnr(img, full), 26.0);
    }
  }
  EXPECT_LT(last_triangles, 0.1 * double(full_st.triangles));  // the root alone
}

TEST_F(MeshPassTest, AncestorsStandInWithoutCracksWhilePatchesLoad) {
  // Small patches: a wide tree, so a narrow view holds whole subtrees.
  lod::MeshBuildOptions bo;
  bo.patch_triangles = 256;
  bo.quiet = true;
  lod::buildMeshStore(std::vector<std::filesystem::path>{kBunnyMesh}, *sDir / "small.tmesh", bo);
  auto store = lod::MeshStore::open(*sDir / "small.tmesh");
  const ViewSetup whole = view(*store, 0.3, 320, 240);
  const ModelInstance m = meshInstance(*store);
  ViewRenderer r(whole.width, whole.height);
  RenderOptions o;
  // The inner levels resident (coarser cuts of the whole view)...
  for (double px : {64.0, 16.0, 8.0, 4.0, 2.0}) {
    o.lod_pixels = px;
    r.renderSettled({&m, 1}, whole, o);
  }
  o.lod_pixels = 1e-6;
  // ...every leaf of the left of the bunny (a narrow view that culls the right)...
  ViewSetup left = whole;
  left.projection = glm::frustum(-0.012, -0.004, -0.0075, 0.0075, 0.02, 10.0) ;
  RenderStats st;
  r.renderSettled({&m, 1}, left, o, &st);
  ASSERT_GT(st.nodes, 1u);
  // ...then the whole view with the loader held: leaves on the left, ancestors standing in on
  // the right, levels mixed along their borders.
  r.streamer().pauseLoader(true);
  const Image held = r.render({&m, 1}, whole, o, &st);
  r.streamer().pauseLoader(false);
  EXPECT_GT(st.fallback_nodes, 0u);
  EXPECT_LT(st.fallback_nodes, st.nodes);
  EXPECT_EQ(holes(held, o.background), 0u);
  // The held frame covers what the settled one does (a stand-in covers its whole region).
  const Image settled = r.renderSettled({&m, 1}, whole, o);
  EXPECT_GT(silhouetteIoU(held, settled, o.background), 0.97);
}

TEST_F(MeshPassTest, PointsAndTrianglesHideEachOther) {
  auto mesh = lod::MeshStore::open(*sDir / "b.tmesh");
  auto points = lod::PointStore::open(*sDir / "b.tlod");
  const ViewSetup v = view(*mesh, 0.3, 320, 240);
  const ModelInstance mm = meshInstance(*mesh);
  // The registered scans lie within a millimetre of the reconstruction, on both sides of it.
  ModelInstance pm{points.get(), storeModel(*points)};
  ViewRenderer r(v.width, v.height);
  RenderOptions o;
  r.renderSettled({&mm, 1}, v, o);
  const auto dm = r.readDepth();
  r.renderSettled({&pm, 1}, v, o);
  const auto dp = r.readDepth();
  const ModelInstance both[2] = {mm, pm};
  r.renderSettled(both, v, o);
  const auto d = r.readDepth();
  size_t agree = 0, mesh_wins = 0, points_win = 0;
  for (size_t i = 0; i < d.size(); ++i) {
    agree += d[i] == std::min(dm[i], dp[i]);
    mesh_wins += dm[i] < dp[i];
    points_win += dp[i] < dm[i];
  }
  EXPECT_EQ(agree, d.size());
  EXPECT_GT(mesh_wins, 1000u);  // each hides the other somewhere
  EXPECT_GT(points_win, 1000u);
}

TEST_F(MeshPassTest, FlatShadingShowsFacetsOverTheSamePixels) {
  auto store = lod::MeshStore::open(*sDir / "b.tmesh");
  const ViewSetup v = view(*store, 0.3, 320, 240);
  const ModelInstance m = meshInstance(*store);
  ViewRenderer r(v.width, v.height);
  RenderOptions o;
  o.lod_pixels = 8.0;  // coarse patches: facets several pixels wide
  const Image smooth = r.renderSettled({&m, 1}, v, o);
  const auto smooth_depth = r.readDepth();
  o.flat_shading = true;
  const Image flat = r.renderSettled({&m, 1}, v, o);
  EXPECT_EQ(r.readDepth(), smooth_depth);  // the same surface
  EXPECT_EQ(silhouetteIoU(flat, smooth, o.background), 1.0);
  // Facets: within a triangle every pixel of a flat picture has one colour, so neighbouring
  // pixels are equal far more often than in the smooth one.
  auto equalNeighbours = [&](const Image& img) {
    size_t n = 0;
    for (size_t i = 4; i < img.rgba.size(); i += 4)
      n += covered(img, o.background, i / 4) &&
           std::equal(&img.rgba[i], &img.rgba[i] + 3, &img.rgba[i - 4]);
    return n;
  };
  EXPECT_GT(equalNeighbours(flat), equalNeighbours(smooth) * 3 / 2);
  EXPECT_GT(psnr(flat, smooth), 20.0);  // the same lighting, faceted
}

TEST_F(MeshPassTest, PickIdsNameTheTriangleUnderThePixel) {
  auto store = lod::MeshStore::open(*sDir / "b.tmesh");
  const ViewSetup v = view(*store, 0.3, 320, 240);
  const ModelInstance m = meshInstance(*store);
  ViewRenderer r(v.width, v.height);
  RenderOptions o;
  o.lod_pixels = 1e-6;
  o.pick_ids = true;
  r.renderSettled({&m, 1}, v, o);
  size_t checked = 0;
  for (uint32_t y = 60; y < 200; y += 20)
    for (uint32_t x = 80; x < 260; x += 20) {
      const auto hit = r.pick(x, y);
      if (!hit) continue;
      ASSERT_TRUE(hit->triangle);
      const lod::MeshPatch p = store->readPatch(hit->node);
      ASSERT_LT(hit->point, p.triangles());
      // The pixel's world position lies on that triangle's plane, within the depth's precision.
      glm::dvec3 c[3];
      for (int k = 0; k < 3; ++k)
        c[k] = store->summary().origin + p.offset + glm::dvec3(p.positions[p.indices[3 * hit->point + k]]);
      const glm::dvec3 n = glm::normalize(glm::cross(c[1] - c[0], c[2] - c[0]));
      EXPECT_LT(std::abs(glm::dot(hit->world - c[0], n)), 2e-4) << x << "," << y;
      ++checked;
    }
  EXPECT_GT(checked, 20u);
}

TEST_F(MeshPassTest, TheTwoByTwoWallShowsTheWholeViewWithoutCracksOrSeams) {
  auto store = lod::MeshStore::open(*sDir / "b.tmesh");
  const config::WallConfig wall =
      sync::loadWallConfig(std::string(TESSERA_CONFIG_DIR) + "/walls/2x2.json");
  const glm::dvec3 c = store->summary().origin + 0.5 * store->summary().bbox_max;
  config::Camera cam;
  cam.mutable_eye()->set_x(c.x + 0.03);
  cam.mutable_eye()->set_y(c.y + 0.02);
  cam.mutable_eye()->set_z(c.z + 0.45);
  cam.mutable_target()->set_x(c.x);
  cam.mutable_target()->set_y(c.y);
  cam.mutable_target()->set_z(c.z);
  cam.mutable_up()->set_y(1);
  const ModelInstance m = meshInstance(*store);
  RenderOptions o;  // 1 px: each tile cuts the hierarchy for itself
  const ViewSetup whole_view = wholeWallView(wall, cam);
  ViewRenderer whole_r(whole_view.width, whole_view.height);
  const Image whole = whole_r.renderSettled({&m, 1}, whole_view, o);
  size_t differ = 0, compared = 0, covered_px = 0;
  for (const auto& tile : wall.tiles()) {
    const ViewSetup tv = tileView(wall, tile, cam);
    ViewRenderer tr(tv.width, tv.height);
    const Image img = tr.renderSettled({&m, 1}, tv, o);
    EXPECT_EQ(holes(img, o.background), 0u) << tile.name();
    const glm::ivec2 off = tileOffsetInWhole(wall, tile);
    for (uint32_t y = 0; y < img.height; ++y)
      for (uint32_t x = 0; x < img.width; ++x) {
        const uint8_t* a = &img.rgba[(size_t(y) * img.width + x) * 4];
        const uint8_t* b = &whole.rgba[(size_t(off.y + y) * whole.width + off.x + x) * 4];
        ++compared;
        covered_px += covered(img, o.background, size_t(y) * img.width + x);
        // Shading may round one grey level apart where llvmpipe bins triangles per tile.
        differ += std::abs(int(a[0]) - int(b[0])) > 1 || std::abs(int(a[1]) - int(b[1])) > 1 ||
                  std::abs(int(a[2]) - int(b[2])) > 1;
      }
  }
  EXPECT_GT(covered_px, 100000u);
  EXPECT_LE(double(differ) / double(compared), 1e-3) << differ << " of " << compared;
}

/// Mean absolute difference of the RGB channels between two frames, grey levels.
double meanChange(const Image& a, const Image& b) {
  double sum = 0.0;
  for (size_t i = 0; i < a.rgba.size(); ++i)
    if (i % 4 != 3) sum += std::abs(double(a.rgba[i]) - double(b.rgba[i]));
  return sum / (double(a.rgba.size()) * 0.75);
}

TEST_F(MeshPassTest, GeomorphingKeepsASlowZoomFromPopping) {
  // A pop is a jump in how far the picture is from the full-resolution one: along a slow zoom
  // that distance drifts with the camera, and drops at once where a patch replaces its parent
  // without morphing. The measure: the largest change of that distance between two frames.
  auto store = lod::MeshStore::open(*sDir / "b.tmesh");
  const ModelInstance m = meshInstance(*store);
  ViewRenderer r(320, 240), full_r(320, 240);
  RenderOptions o, full_o;
  o.lod_pixels = 3.0;  // coarse enough that the zoom crosses several levels
  full_o.lod_pixels = 1e-6;
  std::vector<Image> full;
  for (double d = 0.9; d > 0.2; d *= 0.985)
    full.push_back(full_r.renderSettled({&m, 1}, view(*store, d, 320, 240), full_o));
  auto zoom = [&](double range, size_t* switches) {
    o.geomorph_range = range;
    double last_error = -1.0, worst = 0.0;
    size_t last_patches = 0, k = 0;
    *switches = 0;
    for (double d = 0.9; d > 0.2; d *= 0.985, ++k) {
      RenderStats st;
      const Image img = r.renderSettled({&m, 1}, view(*store, d, 320, 240), o, &st);
      const double error = meanChange(img, full[k]);
      if (last_error >= 0.0) {
        worst = std::max(worst, std::abs(error - last_error));
        *switches += st.mesh_patches != last_patches;
      }
      last_error = error;
      last_patches = st.mesh_patches;
    }
    return worst;
  };
  size_t switches_off = 0, switches_on = 0;
  const double off = zoom(0.0, &switches_off);
  const double on = zoom(1.0, &switches_on);
  std::printf("slow zoom: largest jump of the error against full resolution between frames %.3f "
              "grey levels without geomorphing, %.3f with (%zu and %zu level changes)\n",
              off, on, switches_off, switches_on);
  EXPECT_GE(switches_on, 3u);  // the zoom did change levels
  // Measured: 0.414 without, 0.106 with (positions and normals morphed).
  EXPECT_LT(on, 0.4 * off);
}

}  // namespace
}  // namespace tessera::render
