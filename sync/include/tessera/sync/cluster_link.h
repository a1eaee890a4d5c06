// The cluster link ("The seams"): what the master and the render nodes say to each
// other, independent of the transport. The master and node loops (master/master.h,
// render_node/render_node.h) are written once against it; MpiMasterLink / MpiNodeLink
// (mpi_link.h) carry it inside one mpirun job, ZmqMasterLink / ZmqNodeLink (zmq_link.h) over
// ZeroMQ for walls whose nodes come and go. The messages are cluster.proto's ToNode and FromNode.
//
// A frame on the master:  publish(frame) -> collect(frame, deadline) -> swap(frame)
// and on a node:          receive() a frame -> render -> report() -> receive() the swap -> present.
//
// Transports differ in what they can survive, not in what they say:
//   MPI  every rank is known at start; one message at a time between the master and each node;
//        a node that hangs ends the whole job after the master's timeout, named (MPI cannot drop
//        a rank), and every rank exits with one code (mpi_link.h).
//   ZMQ  nodes join at any time, any order; a node that misses the deadline is dropped and may
//        join again; the master's death is noticed by every node within the heartbeat timeout.
//
// Not thread-safe: one thread per process uses its link. Every wait has a deadline.
#pragma once

#include <chrono>
#include <cstdint>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <tessera/cluster.pb.h>

namespace tessera::sync {

/// The version every envelope carries (cluster.proto, ProtocolVersion).
constexpr uint32_t kProtocolVersion = cluster::PROTOCOL_CURRENT;

using LinkClock = std::chrono::steady_clock;

/// A node on the master's side of the link: a number the link gives each connection (a node that
/// reconnects is a new peer). Tiles, not peers, are what the master reasons about.
using PeerId = uint64_t;

/// The transport cannot work: a bind or connect failed, MPI is unusable, the master is gone. The
/// message starts with the component and names the endpoint.
class LinkError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The master refused this node's join (tile taken or unknown, protocol version). what() is the
/// master's reason.
class JoinRefused : public LinkError {
 public:
  using LinkError::LinkError;
};

/// The master died, hung past the heartbeat timeout, or closed the connection.
class MasterLost : public LinkError {
 public:
  using LinkError::LinkError;
};

/// What arrived at the master while it waited.
struct LinkEvents {
  std::vector<std::pair<PeerId, cluster::Hello>> joins;         ///< in arrival order
  std::vector<std::pair<PeerId, cluster::NodeReport>> reports;  ///< any frame, arrival order
  /// Bytes refused (not a FromNode, another protocol version, too large): the link already
  /// answered the peer with ToNode{refused}; the master only says so.
  std::vector<std::pair<PeerId, std::string>> faults;
  /// Peers whose connection closed (ZMQ: TCP closed or heartbeats stopped).
  std::set<PeerId> gone;
  /// Members a frame or swap could not be queued for: connected, but they stopped reading and
  /// their queue is full (ZMQ_SNDHWM). They are no longer members; the master drops their tiles.
  std::set<PeerId> stalled;

  bool empty() const {
    return joins.empty() && reports.empty() && faults.empty() && gone.empty() && stalled.empty();
  }
  void append(LinkEvents&& more);
};

/// Per-transport byte counts, for the benchmarks (bytes on the wire, payload and envelopes).
struct LinkCounters {
  uint64_t bytes_sent = 0;
  uint64_t bytes_received = 0;
  uint64_t messages_sent = 0;
  uint64_t messages_received = 0;
};

class MasterLink {
 public:
  virtual ~MasterLink() = default;
  /// "mpi" or "zmq".
  virtual const char* transport() const = 0;
  /// Whether a node may miss a deadline and be dropped (ZMQ), or a miss ends the job (MPI).
  virtual bool canDropNodes() const = 0;

  /// Waits until `deadline` for anything from the nodes (joins first of all), returning early
  /// once something arrived. MPI: the first call waits for every rank's Hello (up to the
  /// transport's timeout, then ends the job naming the missing ranks); later calls wait until
  /// `deadline` and return nothing.
  virtual LinkEvents poll(LinkClock::time_point deadline) = 0;

  /// Answers a join. welcome: the peer is a member from now on and gets every publish() and
  /// swap().
  virtual void welcome(PeerId peer, const cluster::ClusterSetup& setup) = 0;
  virtual void refuse(PeerId peer, const std::string& reason) = 0;

  /// Sends the frame to every member. Never blocks on a slow node (ZMQ: a member whose queue is
  /// full is reported stalled by the next collect() or poll()).
  virtual void publish(const cluster::FrameMessage& frame) = 0;

  /// Waits until every peer in `awaited` reported `frame`, or was silent for `quiet` (since the
  /// call, or since its last NodeReport{working}, which is not returned), or `cap`
  /// passed; returns all that arrived meanwhile (reports of other frames and joins too). Peers in
  /// `awaited` that disconnect end the wait for them early (they are in `gone`). MPI: the next
  /// report of every rank (`awaited`, `quiet` and `cap` are not used: a rank silent for the
  /// transport's timeout ends the job, named).
  virtual LinkEvents collect(uint64_t frame, const std::set<PeerId>& awaited,
                             LinkClock::duration quiet, LinkClock::time_point cap) = 0;

  /// Every member may present `frame` (the swap barrier's release).
  virtual void swap(uint64_t frame) = 0;

  /// Stops sending to `peer` and tells it why (ZMQ: it may join again). MPI: not supported
  /// (precondition: canDropNodes()).
  virtual void drop(PeerId peer, const std::string& reason) = 0;

  /// Whether `peer`'s connection is still open: after a missed deadline, tells a hung node
  /// (connected, silent) from a dead one.
  virtual bool connected(PeerId peer) = 0;

  /// Tells every member to exit with `code`.
  virtual void quit(uint32_t code, const std::string& reason) = 0;

  virtual LinkCounters counters() const = 0;
};

class NodeLink {
 public:
  virtual ~NodeLink() = default;
  virtual const char* transport() const = 0;

  /// Asks for a tile (hello.tile, or the first free one when empty) and waits for the answer
  /// until `deadline`. Returns the setup; throws JoinRefused with the master's reason, MasterLost
  /// when no master answered in time. May be called again after ToNode{dropped} (rejoin).
  virtual cluster::ClusterSetup join(const cluster::Hello& hello,
                                     LinkClock::time_point deadline) = 0;

  /// The next message from the master, or false when `deadline` passed first. Throws MasterLost
  /// when the master is gone. MPI: after report() the next message is the present (the swap).
  virtual bool receive(cluster::ToNode& message, LinkClock::time_point deadline) = 0;

  /// True when a message from the master is waiting now (a node behind applies the frames that
  /// wait and renders only the newest). MPI: always false.
  virtual bool pending() = 0;

  /// The node renders `frame` from now until its next report(): ZMQ sends NodeReport{working}
  /// every 100 ms meanwhile, from a thread of its own (so even one long GL call is covered; a
  /// stopped or dead process sends nothing). MPI: nothing (the master waits its --timeout for a
  /// report).
  virtual void working(uint64_t frame) = 0;

  /// Sends a report (a frame done, or a startup failure).
  virtual void report(const cluster::NodeReport& report) = 0;
};

/// Serialized envelopes, protocol version set. Bytes from outside are parsed with
/// parseFromNode / parseToNode: false (and `why` set: "N bytes are not a FromNode", "protocol
/// version 1, this build speaks 2") on anything this build cannot take. Never throws.
std::string envelope(cluster::ToNode message);
std::string envelope(cluster::FromNode message);
bool parseFromNode(std::string_view bytes, cluster::FromNode& out, std::string& why);
bool parseToNode(std::string_view bytes, cluster::ToNode& out, std::string& why);

}  // namespace tessera::sync
