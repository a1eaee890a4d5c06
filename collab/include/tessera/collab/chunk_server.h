// The master's chunk server ("chunks on demand"; Bettio et al. 2009, section 4): the
// byte ranges of the scene's stores for sites that do not have them (collab/chunk_client.h).
// A CURVE ROUTER socket of its own beside the site hub, in the hub's ZeroMQ context, so the
// hub's ZAP handler admits the same keys (one handler per context, curve.h), served by a thread
// of its own: the master's loop never waits for it.
//
// Requests (site.proto ChunkRequest) are checked as site messages are (site_messages.h
// parseChunkRequest()), then against the stores: only a path the scene's MODEL nodes name
// (setStores()) is served, never any other file; the range must lie within the store. What
// does not check gets a ChunkReply.refused with the reason; nothing a site sends stops the
// server or the wall.
//
// Bandwidth: each site (by its CURVE key, so reconnecting does not reset it) has a token bucket
// of `bytes_per_s` with `burst_s` seconds of burst; a reply is sent when the bucket is not in
// debt, and its bytes taken from it. Sites with requests waiting are served in turn, one reply
// each, so one site's burst does not hold the others back; `total_bytes_per_s` caps all sites
// together (the master's uplink), shared in turn. A site may have `queue_per_site`
// requests waiting; more are refused at once ("too many requests waiting"). A site withdraws
// requests it no longer needs (its view moved on) by id: those still waiting are dropped, so
// the link carries what the site's present view needs.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace zmq {
class context_t;
}  // namespace zmq

namespace tessera::collab {

struct KeyPair;

struct ChunkServerOptions {
  std::string endpoint = "tcp://*:7402";
  /// Per site, bytes per second of replies (tessera-master --chunk-rate, in Mbit/s).
  double bytes_per_s = 100e6 / 8;
  double burst_s = 0.05;  ///< small: the rate holds from the first reply on
  /// All sites together, bytes per second of replies (tessera-master --chunk-total-rate); 0:
  /// no cap beyond each site's.
  double total_bytes_per_s = 0;
  size_t queue_per_site = 256;
  /// Requests per second a site may send (refusals included) before the excess is discarded
  /// unanswered.
  double requests_per_s = 4000, requests_burst_s = 2.0;
};

struct ChunkServerCounters {
  uint64_t requests = 0, replies = 0, refused = 0, discarded = 0;
  uint64_t cancelled = 0;  ///< requests withdrawn by their site while waiting: never sent
  uint64_t bytes_out = 0;  ///< range bytes sent
};

class ChunkServer {
 public:
  /// Binds a CURVE server socket with `keys` in `context` (whose ZAP handler must exist and
  /// outlive the server) and starts the server thread. Throws std::runtime_error naming the
  /// endpoint when it cannot bind.
  ChunkServer(zmq::context_t& context, const KeyPair& keys, ChunkServerOptions options);
  /// Stops the thread and closes the socket (before the context goes).
  ~ChunkServer();
  ChunkServer(const ChunkServer&) = delete;
  ChunkServer& operator=(const ChunkServer&) = delete;

  /// The bound endpoint with its real port ("tcp://0.0.0.0:7402").
  std::string endpoint() const;
  /// The store paths the scene names now (any thread). Requests for others are refused; a
  /// store is opened on its first request and closed when it leaves the list.
  void setStores(std::vector<std::string> paths);
  ChunkServerCounters counters() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

/// The identity of a store's bytes as ChunkStoreInfo carries it: FNV-1a (64 bit) over its size
/// (8 bytes, little-endian) and its first min(size, 4096) bytes. `head` holds those bytes.
uint64_t storeIdentity(uint64_t size, const void* head, size_t head_bytes);
constexpr size_t kIdentityHeadBytes = 4096;

}  // namespace tessera::collab
