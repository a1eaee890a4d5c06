// The cluster link over ZeroMQ (libzmq 4.3 + cppzmq): walls whose nodes come and go, die, hang
// and come back. See cluster_link.h for the protocol.
//
// One ROUTER socket on the master, one DEALER per node, for everything: the master knows each
// node by its connection, and a snapshot and the frames after it travel on one ordered pipe, so a
// node that joins can never miss the frame between them (PUB/SUB's "slow joiner"), while PUB
// over TCP would copy each frame per subscriber anyway. ZMTP heartbeats (ZMQ_HEARTBEAT_IVL,
// _TIMEOUT, _TTL) close the connection of a peer that stops answering; a socket monitor turns
// closed connections into events: a node notices its master's death within the heartbeat
// timeout (1.5 s), the master a node's at once (TCP closed) or at the frame deadline (hung).
// Sends never block: a node that stops reading fills its queue (ZMQ_SNDHWM) and misses the
// deadline. Received messages are bounded (ZMQ_MAXMSGSIZE: a node cannot make the master
// allocate more than the largest tile's read-back).
#pragma once

#include <memory>
#include <string>

#include <tessera/sync/cluster_link.h>

namespace tessera::sync {

struct ZmqLinkOptions {
  int heartbeat_ivl_ms = 250;       ///< ZMTP PING interval
  int heartbeat_timeout_ms = 1500;  ///< no traffic for this long: the connection is closed
  /// The largest message accepted from the other side, bytes (master: a tile's read-back plus
  /// envelope; node: a snapshot).
  int64_t max_message_bytes = int64_t(256) << 20;
};

class ZmqMasterLink final : public MasterLink {
 public:
  /// Binds `endpoint` ("tcp://*:7400", "tcp://127.0.0.1:0" for any free port). Throws LinkError
  /// "sync::ZmqMasterLink: cannot listen on ENDPOINT: why".
  ZmqMasterLink(const std::string& endpoint, const ZmqLinkOptions& options = {});
  ~ZmqMasterLink() override;

  /// The bound endpoint with its real port (ZMQ_LAST_ENDPOINT), e.g. "tcp://0.0.0.0:7400".
  std::string endpoint() const;

  const char* transport() const override { return "zmq"; }
  bool canDropNodes() const override { return true; }
  LinkEvents poll(LinkClock::time_point deadline) override;
  void welcome(PeerId peer, const cluster::ClusterSetup& setup) override;
  void refuse(PeerId peer, const std::string& reason) override;
  void publish(const cluster::FrameMessage& frame) override;
  LinkEvents collect(uint64_t frame, const std::set<PeerId>& awaited, LinkClock::duration quiet,
                     LinkClock::time_point cap) override;
  void swap(uint64_t frame) override;
  void drop(PeerId peer, const std::string& reason) override;
  bool connected(PeerId peer) override;
  void quit(uint32_t code, const std::string& reason) override;
  LinkCounters counters() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

/// The socket is used by the caller's thread and, while working(), by the link's sign-of-life
/// thread; a mutex hands it over between them (a ZeroMQ socket may change threads behind a full
/// memory barrier, never be used by two at once).
class ZmqNodeLink final : public NodeLink {
 public:
  /// Connects (lazily, as ZeroMQ does) to the master at `endpoint` ("tcp://HOST:7400").
  /// Throws LinkError on a malformed endpoint.
  ZmqNodeLink(const std::string& endpoint, const ZmqLinkOptions& options = {});
  ~ZmqNodeLink() override;

  const char* transport() const override { return "zmq"; }
  /// After MasterLost, starts over on a fresh connection (a restarted master).
  cluster::ClusterSetup join(const cluster::Hello& hello, LinkClock::time_point deadline) override;
  bool receive(cluster::ToNode& message, LinkClock::time_point deadline) override;
  bool pending() override;
  void working(uint64_t frame) override;
  void report(const cluster::NodeReport& report) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace tessera::sync
