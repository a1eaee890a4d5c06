// A node's join over ZeroMQ (sync/zmq_link.h), against a ROUTER socket on loopback that plays
// the master's side of the hello: a hello left unanswered goes out again on a new connection,
// well before the join's deadline, and a hello answered at once is said once.
#include <gtest/gtest.h>

#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <tessera/sync/cluster_link.h>
#include <tessera/sync/zmq_link.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

namespace {

using namespace tessera;
using namespace std::chrono_literals;

/// The master's end: a ROUTER on a free loopback port that records each hello's connection.
struct HelloCounter {
  zmq::context_t ctx{1};
  zmq::socket_t router{ctx, zmq::socket_type::router};
  std::string endpoint;
  std::vector<std::string> connections;  // the routing id each hello came on

  HelloCounter() {
    router.set(zmq::sockopt::linger, 0);
    router.bind("tcp://127.0.0.1:*");
    endpoint = router.get(zmq::sockopt::last_endpoint);
  }

  /// Waits up to `wait` for the next hello; answers it with a welcome when `answer`.
  bool next(std::chrono::milliseconds wait, bool answer) {
    zmq::pollitem_t item{router.handle(), 0, ZMQ_POLLIN, 0};
    if (zmq::poll(&item, 1, wait) <= 0) return false;
    std::vector<zmq::message_t> parts;
    if (!zmq::recv_multipart(router, std::back_inserter(parts)) || parts.size() != 2) return false;
    cluster::FromNode f;
    std::string why;
    if (!sync::parseFromNode(std::string_view(parts[1].data<char>(), parts[1].size()), f, why) ||
        !f.has_hello())
      return false;
    connections.push_back(parts[0].to_string());
    if (answer) {
      cluster::ToNode t;
      t.mutable_welcome()->set_tile(f.hello().tile());
      const std::string bytes = sync::envelope(t);
      router.send(parts[0], zmq::send_flags::sndmore);
      router.send(zmq::const_buffer(bytes.data(), bytes.size()));
    }
    return true;
  }
};

cluster::Hello helloFor(const std::string& tile) {
  cluster::Hello h;
  h.set_protocol(sync::kProtocolVersion);
  h.set_tile(tile);
  h.set_host("loopback");
  h.set_pid(4242);
  return h;
}

TEST(ZmqNodeLink, AnUnansweredHelloGoesOutAgainOnANewConnectionBeforeTheDeadline) {
  HelloCounter master;
  std::thread answers([&] {
    if (master.next(8000ms, false)) master.next(8000ms, true);  // the first is lost
  });
  sync::ZmqNodeLink link(master.endpoint);
  cluster::ClusterSetup setup;
  // Six seconds: one unanswered hello on a single connection would use them all.
  EXPECT_NO_THROW(setup = link.join(helloFor("left"), sync::LinkClock::now() + 6s));
  answers.join();
  EXPECT_EQ(setup.tile(), "left");
  ASSERT_EQ(master.connections.size(), 2u);
  EXPECT_NE(master.connections[0], master.connections[1]);
}

TEST(ZmqNodeLink, AHelloAnsweredAtOnceIsSaidOnce) {
  HelloCounter master;
  std::thread answers([&] { master.next(8000ms, true); });
  sync::ZmqNodeLink link(master.endpoint);
  EXPECT_NO_THROW(link.join(helloFor("right"), sync::LinkClock::now() + 6s));
  answers.join();
  // Longer than the retry: nothing more comes.
  EXPECT_FALSE(master.next(3000ms, false));
  EXPECT_EQ(master.connections.size(), 1u);
}

TEST(ZmqNodeLink, NoAnswerAtAllEndsTheJoinAtItsDeadline) {
  HelloCounter master;
  std::thread answers([&] {
    while (master.next(4000ms, false)) {
    }
  });
  sync::ZmqNodeLink link(master.endpoint);
  EXPECT_THROW(link.join(helloFor("left"), sync::LinkClock::now() + 2500ms), sync::MasterLost);
  answers.join();
  // The hello went out again on a new connection meanwhile, never more than the wait allows.
  EXPECT_EQ(master.connections.size(), 2u);
}

}  // namespace
