// The scene draw list (render/scene_draw_list.h) owns store lifetimes: a model removed while its
// chunks stream is forgotten by the loader before its store closes, and a model re-added draws
// exactly what it drew before. Built and run under AddressSanitizer too (scripts/test.sh), where
// a loader decoding into a closed store is a use-after-free.
#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

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
  const auto add = [&] {
    const auto id = graph.add(scene::SceneNode::MODEL, sync::SceneGraph::kRoot, "bunny");
    scene::ModelPayload p;
    p.set_store((dir / "b.tlod").string());
    graph.setPayload(id, p);
    (void)graph.takeFrame(graph.frameNumber() + 1, 0);
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
  std::vector<ModelInstance> instances = list.update(graph, streamers);
  ASSERT_EQ(instances.size(), 1u);
  const Image before = renderer->renderSettled(instances, view, options);

  // A cold start, then the model goes while the loader holds its requests.
  renderer = std::make_unique<ViewRenderer>(320, 240);
  streamers[0] = &renderer->streamer();
  instances = list.update(graph, streamers);
  renderer->draw(instances, view, options);  // queues the cut's chunks
  EXPECT_GT(renderer->streamer().stats().requested, 0u);
  graph.remove(id);
  (void)graph.takeFrame(graph.frameNumber() + 1, 0);
  instances = list.update(graph, streamers);  // forgets, then closes the store
  EXPECT_TRUE(instances.empty());
  EXPECT_EQ(list.storeBytes(), 0u);
  renderer->streamer().waitForLoader();
  renderer->draw(instances, view, options);
  EXPECT_EQ(renderer->streamer().stats().resident_bytes, 0u);

  // Back again: the same pixels as before it left.
  add();
  instances = list.update(graph, streamers);
  ASSERT_EQ(instances.size(), 1u);
  const Image after = renderer->renderSettled(instances, view, options);
  EXPECT_TRUE(after.rgba == before.rgba);
  list.clear(streamers);
}

}  // namespace
}  // namespace tessera::render
