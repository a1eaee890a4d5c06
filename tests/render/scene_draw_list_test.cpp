// The scene draw list (render/scene_draw_list.h) owns store lifetimes: a model removed while its
// chunks stream is forgotten by the loader before its store closes, and a model re-added draws
// exactly what it drew before. Built and run under AddressSanitizer too (scripts/test.sh), where
// a loader decoding into a closed store is a use-after-free.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/mesh_builder.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/scene_draw_list.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/scene_graph.h>

#include "../support/temp_dir.h"

namespace tessera::render {
namespace {

const std::string kData = TESSERA_DATA_DIR;

config::Camera bunnyCamera() {
  config::Camera cam;
  cam.mutable_eye()->set_x(-0.027);
  cam.mutable_eye()->set_y(0.12);
  cam.mutable_eye()->set_z(0.38);
  cam.mutable_target()->set_x(-0.027);
  cam.mutable_target()->set_y(0.1);
  cam.mutable_up()->set_y(1);
  return cam;
}

TEST(SceneDrawList, ModelRemovedMidStreamAndReAdded) {
  test::TempDir dir;
  lod::BuildOptions o;
  o.quiet = true;
  lod::buildStore({kData + "/stanford-bunny/scans/bun.conf"}, dir / "b.tlod", o);
  auto ctx = GlContext::createHeadless();

  sync::SceneGraph graph;
  graph.setCamera(bunnyCamera());
  sync::SceneChanges changes;  // of the last frame taken
  const auto take = [&] {
    changes = sync::SceneChanges::of(graph.takeFrame(graph.frameNumber() + 1, 0));
  };
  const auto add = [&] {
    const auto id = graph.add(scene::SceneNode::MODEL, sync::SceneGraph::kRoot, "bunny");
    scene::ModelPayload p;
    p.set_store((dir / "b.tlod").string());
    graph.setPayload(id, p);
    take();
    return id;
  };
  const auto id = add();

  ViewSetup view;
  view.view = cameraView(graph.camera());
  view.projection = glm::perspective(glm::radians(40.0), 320.0 / 240.0, 0.01, 10.0);
  view.width = 320;
  view.height = 240;
  RenderOptions options;
  options.lod_pixels = 0.5;

  SceneDrawList list;
  auto renderer = std::make_unique<ViewRenderer>(320, 240);
  ChunkStreamer* streamers[] = {&renderer->streamer()};
  std::vector<ModelInstance> instances = list.update(graph, changes, streamers);
  ASSERT_EQ(instances.size(), 1u);
  const Image before = renderer->renderSettled(instances, view, options);

  // A cold start, then the model goes while the loader holds its requests.
  renderer = std::make_unique<ViewRenderer>(320, 240);
  streamers[0] = &renderer->streamer();
  instances = list.update(graph, sync::SceneChanges::all(), streamers);
  renderer->draw(instances, view, options);  // queues the cut's chunks
  EXPECT_GT(renderer->streamer().stats().requested, 0u);
  graph.remove(id);
  take();
  instances = list.update(graph, changes, streamers);  // forgets, then closes the store
  EXPECT_TRUE(instances.empty());
  EXPECT_EQ(list.storeBytes(), 0u);
  renderer->streamer().waitForLoader();
  renderer->draw(instances, view, options);
  EXPECT_EQ(renderer->streamer().stats().resident_bytes, 0u);

  // Back again: the same pixels as before it left.
  add();
  instances = list.update(graph, changes, streamers);
  ASSERT_EQ(instances.size(), 1u);
  const Image after = renderer->renderSettled(instances, view, options);
  EXPECT_TRUE(after.rgba == before.rgba);
  list.clear(streamers);
}

bool sameInstances(std::span<const ModelInstance> a, std::span<const ModelInstance> b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].store->path() != b[i].store->path() || a[i].model != b[i].model ||
        a[i].opacity != b[i].opacity || a[i].color != b[i].color)
      return false;
  }
  return true;
}

TEST(SceneDrawList, IncrementalUpdatesEqualAFullRebuildAndEmptyFramesCostNothing) {
  // A master mutates a scene of groups and models at random; a replica applies the frames and
  // its draw list updates from what apply() returns. After every frame the list equals one
  // rebuilt from scratch, and a frame without node changes visits no node.
  test::TempDir dir;
  lod::BuildOptions o;
  o.quiet = true;
  lod::buildStore({kData + "/stanford-bunny/scans/bun.conf"}, dir / "a.tlod", o);
  std::filesystem::copy_file(dir / "a.tlod", dir / "b.tlod");
  const std::string stores[] = {(dir / "a.tlod").string(), (dir / "b.tlod").string()};

  sync::SceneGraph master, replica;
  std::mt19937 rng(7);
  auto pick = [&](size_t n) { return size_t(rng() % n); };
  SceneDrawList incremental;
  size_t visited_on_camera_frames = 0, camera_frames = 0, models_seen = 0;
  for (int frame = 1; frame <= 300; ++frame) {
    const std::vector<sync::SceneGraph::NodeId> ids = master.ids();
    const int op = int(pick(10));
    if (ids.size() < 3 || op == 0) {
      const bool group = pick(3) == 0;
      const auto parent = ids.empty() || pick(2) ? sync::SceneGraph::kRoot : ids[pick(ids.size())];
      if (parent != sync::SceneGraph::kRoot &&
          master.node(parent).kind() != scene::SceneNode::GROUP) {
        continue;
      }
      const auto id =
          master.add(group ? scene::SceneNode::GROUP : scene::SceneNode::MODEL, parent, "n");
      if (!group) {
        scene::ModelPayload p;
        p.set_store(stores[pick(2)]);
        master.setPayload(id, p);
      }
    } else {
      const auto id = ids[pick(ids.size())];
      switch (op) {
        case 1:
          master.setOpacity(id, float(pick(11)) / 10.0f);
          break;
        case 2:
          master.setVisible(id, pick(2) == 0);
          break;
        case 3: {
          std::vector<double> m(16, 0.0);
          m[0] = m[5] = m[10] = m[15] = 1.0;
          m[12] = double(pick(5)) * 0.1;
          master.setTransform(id, m);
          break;
        }
        case 4:
          master.remove(id);
          break;
        case 5: {
          if (master.node(id).kind() == scene::SceneNode::MODEL) {
            scene::ModelPayload p;
            p.set_store(stores[pick(2)]);
            master.setPayload(id, p);
          }
          break;
        }
        default: {  // the camera only
          config::Camera cam;
          cam.mutable_eye()->set_z(1.0 + frame * 0.01);
          cam.mutable_up()->set_y(1.0);
          master.setCamera(cam);
          break;
        }
      }
    }
    const sync::SceneChanges changes = replica.apply(master.takeFrame(uint64_t(frame), 0));
    const std::vector<ModelInstance> got = incremental.update(replica, changes);
    if (changes.nodes.empty()) {
      ++camera_frames;
      visited_on_camera_frames += incremental.lastVisited();
    }
    SceneDrawList full;
    const std::vector<ModelInstance> want = full.update(replica, sync::SceneChanges::all());
    ASSERT_TRUE(sameInstances(got, want)) << "frame " << frame;
    models_seen += want.size();
  }
  EXPECT_GT(camera_frames, 50u);
  EXPECT_EQ(visited_on_camera_frames, 0u);
  EXPECT_GT(models_seen, 300u) << "the scenes had models to compare";
}

TEST(SceneDrawList, AMeshIsDrawnAsTrianglesOpaqueAndAsPointsOnItsTrianglesSeeThrough) {
  test::TempDir dir;
  ::setenv("XDG_CACHE_HOME", (dir / "cache").c_str(), 1);  // the sampled store's cache
  lod::MeshBuildOptions o;
  o.quiet = true;
  o.patch_triangles = 4096;
  const std::string mesh_path = (dir / "bunny.tmesh").string();
  lod::buildMeshStore(
      std::vector<std::filesystem::path>{kData + "/stanford-bunny/reconstruction/bun_zipper.ply"},
      mesh_path, o);
  sync::SceneGraph graph;
  const auto group = graph.add(scene::SceneNode::GROUP, sync::SceneGraph::kRoot, "g");
  const auto id = graph.add(scene::SceneNode::MODEL, group, "mesh");
  scene::ModelPayload p;
  p.set_store(mesh_path);
  graph.setPayload(id, p);
  SceneDrawList list;
  auto models = list.update(graph, sync::SceneChanges::all());
  ASSERT_EQ(models.size(), 1u);
  EXPECT_NE(models[0].mesh, nullptr);
  EXPECT_EQ(models[0].store, nullptr);
  const uint64_t mesh_bytes = list.storeBytes();
  // The group turns see-through: the mesh is drawn from points sampled on its triangles. They
  // are built off the frame (the cache is empty): meanwhile the mesh is drawn opaque.
  graph.setOpacity(group, 0.5f);
  models = list.update(graph, sync::SceneChanges::all());
  ASSERT_TRUE(list.sampling());
  ASSERT_EQ(models.size(), 1u);
  EXPECT_NE(models[0].mesh, nullptr);
  EXPECT_FLOAT_EQ(models[0].opacity, 1.0f);
  models = list.finishSampling(graph);  // what a settled frame does
  EXPECT_FALSE(list.sampling());
  ASSERT_EQ(models.size(), 1u);
  ASSERT_NE(models[0].store, nullptr);
  EXPECT_EQ(models[0].mesh, nullptr);
  EXPECT_FLOAT_EQ(models[0].opacity, 0.5f);
  const double samples = double(models[0].store->summary().points);
  EXPECT_NEAR(samples, 4.0 * 69451, 0.02 * 4.0 * 69451);  // 4 a triangle on average
  // The samples lie where the mesh is: the two boxes agree to a fraction of a millimetre.
  const auto [plo, phi] = worldBounds(models[0]);
  ModelInstance mesh_instance;
  auto mesh = lod::MeshStore::open(mesh_path);
  mesh_instance.mesh = mesh.get();
  mesh_instance.model = storeModel(*mesh);
  const auto [mlo, mhi] = worldBounds(mesh_instance);
  EXPECT_LT(glm::length(plo - mlo), 5e-4);
  EXPECT_LT(glm::length(phi - mhi), 5e-4);
  // Opaque again: triangles, and the point store is closed.
  graph.setOpacity(group, 1.0f);
  models = list.update(graph, sync::SceneChanges::all());
  ASSERT_EQ(models.size(), 1u);
  EXPECT_NE(models[0].mesh, nullptr);
  EXPECT_EQ(list.storeBytes(), mesh_bytes);
  // See-through again: the samples are in the cache now, so this frame draws them at once.
  graph.setOpacity(group, 0.25f);
  models = list.update(graph, sync::SceneChanges::all());
  EXPECT_FALSE(list.sampling());
  ASSERT_EQ(models.size(), 1u);
  EXPECT_NE(models[0].store, nullptr);
  EXPECT_FLOAT_EQ(models[0].opacity, 0.25f);
  // A second list whose mesh turns see-through and back before the build ends lets the build go
  // (nothing waits for it) and draws the mesh.
  ::setenv("XDG_CACHE_HOME", (dir / "cache2").c_str(), 1);
  SceneDrawList other;
  graph.setOpacity(group, 1.0f);
  other.update(graph, sync::SceneChanges::all());
  graph.setOpacity(group, 0.5f);
  other.update(graph, sync::SceneChanges::all());
  ASSERT_TRUE(other.sampling());
  graph.setOpacity(group, 1.0f);
  models = other.update(graph, sync::SceneChanges::all());
  EXPECT_NE(models[0].mesh, nullptr);
  EXPECT_FLOAT_EQ(models[0].opacity, 1.0f);
  models = other.finishSampling(graph);
  EXPECT_FALSE(other.sampling());
  EXPECT_NE(models[0].mesh, nullptr);
  ::unsetenv("XDG_CACHE_HOME");
}

}  // namespace
TEST(SceneDrawList, TheAnalysisSettingsBecomeEveryTilesRenderOptions) {
  sync::SceneGraph g;
  RenderOptions o = SceneDrawList::options(g, 2.0f);
  EXPECT_FALSE(o.relative_depth.enabled);
  // The pixel budget: the renderer's default until the scene sets one; 0 turns it off.
  EXPECT_EQ(o.budget_per_covered_pixel, RenderOptions{}.budget_per_covered_pixel);
  g.setPointsPerPixel(0.0f);
  EXPECT_EQ(SceneDrawList::options(g, 2.0f).budget_per_covered_pixel, 0.0);
  g.setPointsPerPixel(3.5f);
  EXPECT_EQ(SceneDrawList::options(g, 2.0f).budget_per_covered_pixel, 3.5);
  EXPECT_THROW(g.setPointsPerPixel(-1.0f), std::exception);
  EXPECT_THROW(g.setPointsPerPixel(std::nanf("")), std::exception);
  EXPECT_FALSE(o.contours.enabled);
  scene::Analysis a;
  a.set_relative_depth_radius(40);
  a.set_relative_depth_lo(-0.2f);
  a.set_relative_depth_hi(0.3f);
  a.set_contour_interval(2.5);
  a.set_contour_phase(0.5);
  a.mutable_contour_axis()->set_z(2.0);
  g.setAnalysis(a);
  o = SceneDrawList::options(g, 2.0f);
  EXPECT_TRUE(o.relative_depth.enabled);
  EXPECT_EQ(o.relative_depth.radius, 40);
  ASSERT_TRUE(o.relative_depth.range.has_value());
  EXPECT_EQ(*o.relative_depth.range, glm::vec2(-0.2f, 0.3f));
  EXPECT_TRUE(o.contours.enabled);
  EXPECT_EQ(o.contours.interval, 2.5);
  EXPECT_EQ(o.contours.phase, 0.5);
  EXPECT_TRUE(o.contours.height);
  EXPECT_EQ(o.contours.axis, glm::dvec3(0.0, 0.0, 2.0));
  a.clear_contour_axis();  // no axis: lines of the view depth
  g.setAnalysis(a);
  EXPECT_FALSE(SceneDrawList::options(g, 2.0f).contours.height);
  // Ambient occlusion and the stored AO's mode.
  EXPECT_FALSE(o.ao.enabled);
  EXPECT_EQ(o.stored_ao, StoredAo::kModulate);
  a.set_ao_strength(1.5f);
  a.set_ao_radius(0.02f);
  a.set_ao_slices(4);
  a.set_ao_half_resolution(false);
  a.set_stored_ao(scene::Analysis::STORED_AO_ALONE);
  g.setAnalysis(a);
  o = SceneDrawList::options(g, 2.0f);
  EXPECT_TRUE(o.ao.enabled);
  EXPECT_EQ(o.ao.strength, 1.5f);
  EXPECT_EQ(o.ao.radius, 0.02f);
  EXPECT_EQ(o.ao.slices, 4);
  EXPECT_FALSE(o.ao.half_resolution);
  EXPECT_EQ(o.stored_ao, StoredAo::kAlone);
  // A blur in metres, taken at the camera's distance to its target.
  a.set_relative_depth_radius(0);
  a.set_relative_depth_radius_m(0.005f);
  g.setAnalysis(a);
  o = SceneDrawList::options(g, 2.0f);
  EXPECT_TRUE(o.relative_depth.enabled);
  EXPECT_EQ(o.relative_depth.radius_m, 0.005f);
  const config::Camera& c = g.camera();
  EXPECT_NEAR(o.relative_depth.radius_depth,
              glm::length(glm::dvec3(c.target().x() - c.eye().x(), c.target().y() - c.eye().y(),
                                     c.target().z() - c.eye().z())),
              1e-9);
  // Out of range: refused by name.
  a.set_ao_strength(std::nanf(""));
  EXPECT_THROW(g.setAnalysis(a), std::exception);
  a.set_ao_strength(1.0f);
  a.set_relative_depth_radius_m(-1.0f);
  EXPECT_THROW(g.setAnalysis(a), std::exception);
}

// A blur given in metres covers the pixels those metres span at the reference depth.
TEST(SceneDrawList, ARelativeDepthRadiusInMetresIsPixelsAtItsDepth) {
  ViewSetup v;
  v.width = 800;
  v.height = 600;
  v.projection = glm::perspective(glm::radians(60.0), 800.0 / 600.0, 0.1, 100.0);
  RelativeDepthOptions r;
  r.radius = 7;
  EXPECT_EQ(relativeDepthRadiusPx(r, v), 7);
  r.radius_m = 0.1f;
  r.radius_depth = 2.0;
  // 600 px span 2 tan(30 deg) x 2 m: 0.1 m is 0.1 / (2 tan 30 * 2) * 600 = 25.98 px.
  EXPECT_EQ(relativeDepthRadiusPx(r, v), 26);
  r.radius_depth = 1e-6;  // up close: the largest blur
  EXPECT_EQ(relativeDepthRadiusPx(r, v), kMaxRelativeDepthRadius);
  r.radius_m = std::nanf("");
  EXPECT_THROW(relativeDepthRadiusPx(r, v), std::exception);
}

}  // namespace tessera::render
