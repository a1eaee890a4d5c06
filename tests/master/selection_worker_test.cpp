// The master's selection worker: requests answered off the loop become SELECTION nodes, and the
// stores it opened stay open only while a model of the scene names them or a job uses them.
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/store_builder.h>
#include <tessera/master/selection_worker.h>

#include "../support/temp_dir.h"

namespace {

using tessera::master::SelectionRequest;
using tessera::master::SelectionWorker;
namespace scene = tessera::scene;
namespace sync = tessera::sync;

const std::string kData = TESSERA_DATA_DIR;

/// A view of the bunny from the front, 320x240 pixels.
tessera::render::ViewSetup bunnyView() {
  tessera::render::ViewSetup v;
  v.view = glm::lookAt(glm::dvec3(-0.027, 0.12, 0.38), glm::dvec3(-0.027, 0.1, 0.0),
                       glm::dvec3(0, 1, 0));
  v.projection = glm::perspective(glm::radians(45.0), 320.0 / 240.0, 0.01, 10.0);
  v.width = 320;
  v.height = 240;
  v.eye_world = glm::dvec3(-0.027, 0.12, 0.38);
  return v;
}

/// Collects (bounded) until the worker has nothing queued, at work or uncollected: the
/// selections added.
int collectAll(SelectionWorker& w, sync::SceneGraph& graph) {
  int added = 0;
  for (int i = 0; i < 3000; ++i) {
    added += w.collect(graph);
    if (w.pending() == 0) return added;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return -1;
}

TEST(SelectionWorker, StoresCloseWhenNoModelNamesThem) {
  tessera::test::TempDir dir;
  tessera::lod::BuildOptions o;
  o.quiet = true;
  const std::string a = (dir / "a.tlod").string(), b = (dir / "b.tlod").string();
  tessera::lod::buildStore({kData + "/stanford-bunny/scans/bun000.ply"}, a, o);
  tessera::lod::buildStore({kData + "/stanford-bunny/scans/bun045.ply"}, b, o);

  sync::SceneGraph graph;
  auto model = [&](const std::string& name, const std::string& store) {
    scene::ModelPayload p;
    p.set_store(store);
    return graph.add(scene::SceneNode::MODEL, sync::SceneGraph::kRoot, name, std::move(p), "");
  };
  const auto ma = model("a", a), mb = model("b", b);
  std::vector<std::string> said;
  SelectionWorker worker([&](const std::string& s) { said.push_back(s); });
  auto lasso = [&](uint32_t m) {
    SelectionRequest r;
    r.model = m;
    r.view = bunnyView();
    r.pixels = {{0, 0}, {320, 0}, {320, 240}, {0, 240}};
    return worker.request(graph, 1, "console", r);
  };

  ASSERT_TRUE(lasso(ma));
  EXPECT_EQ(collectAll(worker, graph), 1);
  EXPECT_EQ(worker.openStores(), 1u);  // a's, kept for the next lasso on it
  ASSERT_TRUE(lasso(mb));
  EXPECT_EQ(collectAll(worker, graph), 1);
  EXPECT_EQ(worker.openStores(), 2u);

  // Model b goes: its store closes at the next collect; a's stays.
  graph.remove(mb);
  EXPECT_EQ(worker.collect(graph), 0);
  EXPECT_EQ(worker.openStores(), 1u);
  // Model a is pointed at b's store: a's old store closes, the next lasso opens b's.
  scene::ModelPayload p;
  p.set_store(b);
  graph.setPayload(ma, p);
  EXPECT_EQ(worker.collect(graph), 0);
  EXPECT_EQ(worker.openStores(), 0u);
  ASSERT_TRUE(lasso(ma));
  EXPECT_EQ(collectAll(worker, graph), 1);
  EXPECT_EQ(worker.openStores(), 1u);
  // A request on a node that is no model is refused, opening nothing.
  EXPECT_FALSE(lasso(mb));
  EXPECT_EQ(worker.openStores(), 1u);
  for (const std::string& s : said) EXPECT_EQ(s.find("failed"), std::string::npos) << s;
}

}  // namespace
