// A render node checks the numbers in the master's setup as the command line checks its own
// (every number from the wire). A fake link stands in for the master.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include <tessera/render_node/render_node.h>
#include <tessera/sync/cluster_link.h>

namespace tessera {
namespace {

/// Welcomes with `setup`, records the startup report, then tells the node to quit.
class FakeMasterLink final : public sync::NodeLink {
 public:
  explicit FakeMasterLink(cluster::ClusterSetup setup) : mSetup(std::move(setup)) {}
  const char* transport() const override { return "fake"; }
  cluster::ClusterSetup join(const cluster::Hello&, sync::LinkClock::time_point) override {
    return mSetup;
  }
  bool receive(cluster::ToNode& message, sync::LinkClock::time_point) override {
    message.Clear();
    message.set_protocol(sync::kProtocolVersion);
    message.mutable_quit()->set_code(7);
    message.mutable_quit()->set_reason("test over");
    return true;
  }
  bool pending() override { return false; }
  void working(uint64_t) override {}
  void report(const cluster::NodeReport& report) override { reports.push_back(report); }

  std::vector<cluster::NodeReport> reports;

 private:
  cluster::ClusterSetup mSetup;
};

cluster::ClusterSetup setupWithSplatScale(float scale) {
  cluster::ClusterSetup s;
  s.set_tile("a");
  s.set_splat_scale(scale);
  config::Tile* t = s.mutable_wall()->add_tiles();
  t->set_name("a");
  t->set_width(1);
  t->set_height(1);
  t->set_pixel_width(8);
  t->set_pixel_height(8);
  s.mutable_wall()->mutable_eye()->set_z(2);
  return s;
}

TEST(RenderNodeSetup, TheMastersSplatScaleMustBeARealOne) {
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                    -1.0f, 0.1f, 1e30f}) {
    FakeMasterLink link(setupWithSplatScale(bad));
    render_node::NodeOptions o;
    o.headless = true;
    render_node::RenderNode(link, o).run();
    ASSERT_FALSE(link.reports.empty()) << bad;
    const cluster::NodeStatus& st = link.reports.front().status();
    EXPECT_EQ(st.code(), cluster::NODE_BAD_FRAME) << bad << ": " << st.message();
    EXPECT_NE(st.message().find("splat scale"), std::string::npos) << st.message();
  }
}

}  // namespace
}  // namespace tessera
