// METIS k-way partitions in worker processes, so that the mesh builder's threads partition in
// parallel and every call's result depends only on its input.
//
// Why processes: METIS 5.1 draws its random numbers from one process-wide generator (GKlib's
// Mersenne twister, seeded per call from METIS_OPTION_SEED), so concurrent calls in one process
// take each other's numbers and the same mesh made different stores from run to run.
// Serialising the calls made builds reproducible but cost the partition phase its threads. A
// worker forked from the builder has a generator of its own: one call at a time per worker,
// any number of workers at once.
#pragma once

#include <sys/types.h>

#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include <metis.h>

namespace tessera::lod {

class MetisPool {
 public:
  /// Graphs with fewer vertices are partitioned in this process (one call at a time): a worker's
  /// round trip would cost more than the call.
  static constexpr idx_t kInProcessBelow = 1024;

  /// Forks `workers` processes (0: every call runs in this process, one at a time). Call it
  /// before starting threads that may hold locks a child would need (glibc's malloc and stdio
  /// are fork-safe). Each worker closes every descriptor but stdin/stdout/stderr and its socket,
  /// resets caught signals to their defaults, gives back its copy of the parent's free heap
  /// (malloc_trim), and leaves with _exit() when its socket closes (no atexit handlers, no stdio
  /// flush). Memory: about 45 MB a worker besides pages shared with the parent, for leaf blocks
  /// of 262,144 triangles. A worker that cannot be forked is left out (a message on
  /// stderr); with none, calls run in this process.
  explicit MetisPool(uint32_t workers);
  /// Closes the sockets and reaps every worker (no zombies, also after a worker died).
  ~MetisPool();
  MetisPool(const MetisPool&) = delete;
  MetisPool& operator=(const MetisPool&) = delete;

  /// METIS_PartGraphKway of the CSR graph (0-based; xadj has n + 1 entries; vwgt, if given, n;
  /// adjwgt, if given, as many as adjncy) into `parts` with METIS_OPTION_SEED `seed`, other
  /// options METIS's defaults. `part` gets n part ids; returns METIS's return code (METIS_OK, ...).
  /// The same input gives the same `part` whichever worker (or this process) runs it.
  /// Thread-safe: waits for a free worker and holds it for the call; costs the graph's bytes
  /// twice through a socket (about 1 ms for a 250,000-vertex graph) besides METIS.
  /// Throws std::runtime_error naming the worker, its pid and its fate (killed, exited, or its
  /// socket failed) when the worker died during the call; such a worker is reaped and left out
  /// of later calls, which throw once every worker died.
  int partGraphKway(const std::vector<idx_t>& xadj, const std::vector<idx_t>& adjncy,
                    const std::vector<idx_t>* vwgt, const std::vector<idx_t>* adjwgt, idx_t parts,
                    idx_t seed, std::vector<idx_t>& part);

  /// The workers' process ids, in order (tests).
  std::vector<pid_t> pids() const;

 private:
  struct Worker {
    pid_t pid = -1;
    int fd = -1;
    bool busy = false;
    bool dead = false;
    std::string fate;  ///< how it died, once dead
  };
  int remote(Worker& w, size_t index, const std::vector<idx_t>& xadj,
             const std::vector<idx_t>& adjncy, const std::vector<idx_t>* vwgt,
             const std::vector<idx_t>* adjwgt, idx_t parts, idx_t seed, std::vector<idx_t>& part);

  std::vector<Worker> mWorkers;
  std::mutex mMutex;
  std::condition_variable mFree;
};

}  // namespace tessera::lod
