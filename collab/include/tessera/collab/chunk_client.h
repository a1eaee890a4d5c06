// A site's end of chunks on demand (Bettio et al. 2009, section 4): the stores the
// scene names, read as byte ranges from the master's chunk server (chunk_server.h) over CURVE,
// kept in a disk cache between sessions. Each store is a lod::RangeSource (range_source.h) that
// lod::PointStore reads through, so every range is checked by the store's own CRC-32C on use:
// a cached copy that fails it is dropped and fetched again (RangeSource::refetch()), never
// decoded.
//
// One DEALER socket per client, shared by its stores and driven by a network thread of its
// own; the loader threads (render/chunk_streamer.h) each wait for their own request, so as many
// requests are in flight as loaders are reading, answered in the order the server takes them
// (the loaders' order: coarse and near first). A loader whose chunk no frame wants any more
// (the view moved on) stops its read's token (range_source.h): the request is withdrawn from
// the server, which drops it if it still waits for the site's bandwidth, and the loader moves
// on to what the present view needs. A request unanswered for `timeout_s` is sent
// once more; a second timeout or a refusal is a lod::RangeError naming the store, the range and
// why, which PointStore turns into a StoreError (the chunk is then drawn by its ancestor).
//
// Disk cache (`cache_dir`): a folder per store named by a hash of its path and its identity
// (ChunkStoreInfo: its size and first 4 KiB), so a store changed on the master is never read
// from an old copy; a file per range ("OFFSET+LENGTH"), written to a temporary file and renamed
// into place, so a reader sees a whole range or none. A cache file of the wrong size is
// dropped and fetched again. Loader threads that read one broken copy at once all read again;
// the copy is dropped (and counted in `refetched`) once, never a good one written since. The folder holds at most `cache_limit_bytes` over all its stores,
// least recently used ranges removed first (chunk_cache.h).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include <tessera/collab/curve.h>
#include <tessera/lod/range_source.h>

namespace tessera::collab {

struct ChunkClientOptions {
  std::string endpoint;     ///< the chunk server, "tcp://HOST:7402"
  std::string master_key;   ///< the master's public key, Z85
  KeyPair keys;             ///< this site's
  std::string cache_dir;    ///< "" : no disk cache (every range from the server)
  uint64_t cache_limit_bytes = uint64_t(4) << 30;  ///< the disk cache's bound, all stores
  double timeout_s = 30.0;  ///< per request, then sent once more
};

struct ChunkClientCounters {
  uint64_t requests = 0;                     ///< range and info requests sent (retries included)
  uint64_t fetched_bytes = 0;                ///< range bytes received
  uint64_t retries = 0;                      ///< requests sent again after a timeout
  uint64_t cancelled = 0;  ///< requests withdrawn unanswered (the reader's cancel was stopped)
  uint64_t cache_hits = 0, cache_bytes = 0;  ///< ranges read from the disk cache
  uint64_t refetched = 0;     ///< cached ranges that failed the store's checksum (or size)
  uint64_t cache_errors = 0;  ///< ranges that could not be written to the cache
  uint64_t cache_evicted_files = 0, cache_evicted_bytes = 0;  ///< removed to keep the bound
};

class ChunkClient {
 public:
  /// Connects (ZeroMQ connects in the background) and starts the network thread. Throws
  /// lod::RangeError for an endpoint that is not one.
  explicit ChunkClient(ChunkClientOptions options);
  /// Stops the network thread; reads still waiting fail with a RangeError.
  ~ChunkClient();
  ChunkClient(const ChunkClient&) = delete;
  ChunkClient& operator=(const ChunkClient&) = delete;

  /// The store `path` (exactly as the scene names it) as a source: asks the server for its
  /// size and identity (blocks up to twice the timeout) and prepares its cache folder. Throws
  /// lod::RangeError (refused, no answer, a cache folder that cannot be made is only reported
  /// in cacheProblem()). Any thread.
  std::unique_ptr<lod::RangeSource> open(const std::string& path);

  ChunkClientCounters counters() const;
  /// Why the disk cache is not used or not written, "" when it is fine.
  std::string cacheProblem() const;

 private:
  struct Impl;
  std::shared_ptr<Impl> m;
};

/// The chunk endpoint a site connects to: `announced` (SiteWelcome.chunks, as the master bound
/// it) with a wildcard host ("*", "0.0.0.0", "::", "[::]") replaced by the host of `master`
/// (the site endpoint it joined). "" when nothing was announced.
std::string chunkEndpointFor(const std::string& announced, const std::string& master);

}  // namespace tessera::collab
