#include <tessera/master/script_player.h>

#include <gtest/gtest.h>

#include <tessera/sync/camera_path.h>

namespace {

using namespace tessera;

TEST(ScriptPlayer, CameraAndActionsOnceEachIntoTheGraph) {
  const config::CameraPath path = sync::parseCameraPath(R"({"keyframes": [
      {"time": 0, "eye": {"z": 2}, "target": {}, "up": {"y": 1}},
      {"time": 1, "eye": {"x": 1, "z": 2}, "target": {}, "up": {"y": 1}}],
      "actions": [{"time": 0.5, "setOpacity": {"model": "m", "opacity": 0.25}},
                  {"time": 0.5, "setShading": "edl"},
                  {"time": 0.6, "setAnalysis": {"aoStrength": 1, "contourInterval": 0.01}},
                  {"time": 0.75, "setVisible": {"model": "m", "visible": false}},
                  {"time": 1, "screenshot": "end.png"}]})",
                                                        "p.json");
  scene::SceneFile scene;
  scene::SceneNode& m = *scene.add_nodes();
  m.set_id(1);
  m.set_kind(scene::SceneNode::MODEL);
  m.set_name("m");
  m.mutable_model()->set_store("/x.tlod");
  scene.mutable_camera()->mutable_eye()->set_z(1.0);
  scene.mutable_camera()->mutable_up()->set_y(1.0);
  sync::SceneGraph graph = sync::SceneGraph::fromFile(scene);
  master::ScriptPlayer player(path);
  EXPECT_DOUBLE_EQ(player.duration(), 1.0);
  const auto id = *graph.findByName("m");

  EXPECT_TRUE(player.advance(graph, 0.25).empty());
  EXPECT_NEAR(graph.camera().eye().x(), sync::cameraAt(path, 0.25).eye().x(), 1e-9);
  EXPECT_EQ(graph.node(id).opacity(), 1.0f);
  EXPECT_TRUE(player.advance(graph, 0.5).empty());
  EXPECT_EQ(graph.node(id).opacity(), 0.25f);
  EXPECT_EQ(graph.settings().shading(), scene::SHADING_EDL);
  EXPECT_EQ(graph.settings().analysis().ao_strength(), 0.0f);
  EXPECT_TRUE(player.advance(graph, 0.6).empty());
  EXPECT_EQ(graph.settings().analysis().ao_strength(), 1.0f);
  EXPECT_EQ(graph.settings().analysis().contour_interval(), 0.01);
  EXPECT_TRUE(graph.node(id).visible());
  EXPECT_EQ(player.advance(graph, 1.0), std::vector<std::string>{"end.png"});
  EXPECT_FALSE(graph.node(id).visible());
  EXPECT_TRUE(player.advance(graph, 2.0).empty());  // nothing twice
}

}  // namespace
