// The cluster link's envelopes (sync/cluster_link.h): what a peer that speaks garbage, an old
// protocol or nothing at all gets told.
#include <gtest/gtest.h>

#include <tessera/sync/cluster_link.h>

namespace {

using namespace tessera;

TEST(ClusterLink, EnvelopesRoundTripWithTheProtocolVersion) {
  cluster::FromNode f;
  f.mutable_hello()->set_tile("left");
  const std::string bytes = sync::envelope(f);
  cluster::FromNode back;
  std::string why;
  ASSERT_TRUE(sync::parseFromNode(bytes, back, why)) << why;
  EXPECT_EQ(back.protocol(), sync::kProtocolVersion);
  EXPECT_EQ(back.hello().tile(), "left");

  cluster::ToNode t;
  t.mutable_present()->set_frame(12);
  cluster::ToNode t_back;
  ASSERT_TRUE(sync::parseToNode(sync::envelope(t), t_back, why)) << why;
  EXPECT_EQ(t_back.present().frame(), 12u);
}

TEST(ClusterLink, RefusesGarbageOtherVersionsAndEmptyEnvelopes) {
  std::string why;
  cluster::FromNode f;
  EXPECT_FALSE(sync::parseFromNode(std::string("\xff\xff\xff\xff garbage", 12), f, why));
  EXPECT_EQ(why.rfind("12 bytes are not a FromNode", 0), 0u) << why;

  cluster::FromNode old;
  old.set_protocol(1);
  old.mutable_hello();
  EXPECT_FALSE(sync::parseFromNode(old.SerializeAsString(), f, why));
  EXPECT_EQ(why.rfind("protocol version 1, this build speaks 2", 0), 0u) << why;

  cluster::ToNode empty;
  empty.set_protocol(sync::kProtocolVersion);
  cluster::ToNode t;
  EXPECT_FALSE(sync::parseToNode(empty.SerializeAsString(), t, why));
  EXPECT_NE(why.find("without a message kind"), std::string::npos) << why;
  EXPECT_FALSE(sync::parseToNode({}, t, why));  // no protocol field at all: version 0
}

}  // namespace
