// The cluster's transport over MPI (plain C API, OpenMPI): what master (rank 0) and the render
// nodes (ranks 1..K) say to each other (DESIGN.md, "The frame"):
//
//   startup   gatherHosts()                  every rank's host name to the master (tile mapping)
//             broadcast(kSetup, ClusterSetup) the wall, tiles, snapshot (cluster.proto)
//             gatherStatus()                  each node: started, or an error code and text
//   per frame broadcast(kFrame, Frame)        master's scene changes (scene.proto, wire.h)
//             swapBarrier()                    after rendering, before presenting
//             gatherBytes()                    only on screenshot frames: each tile's pixels
//             gatherStats()                    a fixed NodeFrameStats per node
//   end       broadcast(kQuit) or, after a node failed mid-run, broadcast(kFailed) then
//             gatherStatus() so the master can say which node failed and why.
//
// Every call is collective: all ranks make the same calls in the same order. Waits are
// non-blocking MPI requests polled with short sleeps, so an idle rank yields its core to the
// renderers (this machine runs master + 8 nodes on 2 cores), and bounded: a wait longer than the
// transport's timeout (a rank hung or gone) prints what was awaited and aborts the whole job
// (MPI_Abort), so a broken cluster never hangs. Not thread-safe: one thread per process uses it.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::sync {

/// What the master broadcasts; nodes act on it.
enum class ClusterMessage : int32_t {
  kSetup = 1,   ///< bytes: a cluster::ClusterSetup
  kFrame = 2,   ///< bytes: a scene::Frame
  kQuit = 3,    ///< no bytes: leave the frame loop and exit
  kFailed = 4,  ///< no bytes: a node failed; everyone joins gatherStatus(), then exits
};

/// Broadcast flags of a kFrame, readable without parsing the frame (collectives depend on them).
constexpr uint32_t kFrameScreenshot = 1;  ///< every rank joins gatherBytes() after the barrier

/// Why a node cannot go on (NodeStatus::code, the node's exit code).
enum class NodeFailure : int32_t {
  kNone = 0,
  kNoGl = 10,      ///< no EGL / GL 4.5 context
  kBadStore = 11,  ///< a model's store cannot be opened or read
  kBadTile = 12,   ///< no tile for this rank, or a tile the renderer cannot take
  kBadFrame = 13,  ///< a frame or setup message could not be parsed or applied
  kRender = 14,    ///< rendering failed mid-run
  kInternal = 15,  ///< anything else
};

/// A node's word to the master: code and a message (NUL-terminated, truncated to fit).
struct NodeStatus {
  int32_t code = 0;  ///< NodeFailure
  char text[508] = {};
  void set(NodeFailure failure, std::string_view message);
  std::string message() const;
};
static_assert(sizeof(NodeStatus) == 512);

/// One node's figures for one frame, gathered to the master after the swap barrier. Plain data,
/// sent as bytes (all ranks run the same build).
struct NodeFrameStats {
  double render_ms = 0;         ///< apply the frame, select, stream, draw (and read back if asked)
  double barrier_ms = 0;        ///< waiting at the swap barrier for the slowest rank
  double present_ms = 0;        ///< window swap (0 headless)
  uint64_t points = 0;          ///< points drawn
  uint64_t nodes = 0;           ///< LOD nodes drawn
  uint64_t resident_bytes = 0;  ///< GPU bytes of resident chunks
  uint64_t resident_disk_bytes = 0;  ///< the same chunks' compressed size in their stores
  uint64_t store_bytes = 0;          ///< the open stores' file sizes together
  uint64_t chunks_queued = 0;        ///< handed to the loader and not done
  uint32_t frames = 0;               ///< frames drawn (renderSettled may draw several)
  int32_t failure = 0;               ///< NodeFailure: non-zero ends the run (kFailed)
};

/// MPI could not start, or a message broke the protocol.
class TransportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class MpiTransport {
 public:
  /// MPI_Init. `timeout_s` bounds every wait (seconds). `who` names this process in messages
  /// ("tessera-master", "tessera-node"). Throws TransportError if MPI is unusable.
  MpiTransport(int* argc, char*** argv, std::string who, double timeout_s);
  /// MPI_Finalize.
  ~MpiTransport();
  MpiTransport(const MpiTransport&) = delete;
  MpiTransport& operator=(const MpiTransport&) = delete;

  int rank() const { return mRank; }
  int size() const { return mSize; }
  /// MPI_Get_processor_name of this rank.
  const std::string& host() const { return mHost; }
  void setTimeout(double seconds) { mTimeoutS = seconds; }

  /// Rank 0 sends `kind`, `flags` and `bytes`; the others receive them into theirs. Returns the
  /// bytes moved. `what` names the wait in a timeout message.
  uint64_t broadcast(ClusterMessage& kind, uint32_t& flags, std::string& bytes, const char* what);
  /// The swap barrier: returns once every rank has called it; milliseconds waited.
  double swapBarrier();
  /// On rank 0 every rank's item in rank order (its own first); empty elsewhere.
  std::vector<NodeStatus> gatherStatus(const NodeStatus& mine);
  std::vector<NodeFrameStats> gatherStats(const NodeFrameStats& mine);
  std::vector<std::string> gatherHosts();
  /// Variable-size gather (tile pixels): rank 0 gets each rank's bytes (up to 2 GiB each).
  std::vector<std::string> gatherBytes(std::string_view mine);

  /// Prints "<who> (rank R on HOST): why" to stderr and ends every process of the job with
  /// `code` (MPI_Abort). For waits that cannot end otherwise.
  [[noreturn]] void abort(int code, const std::string& why) const;

 private:
  void wait(void* request, const char* what);  // MPI_Request*, polled until done or timeout
  template <class T>
  std::vector<T> gatherFixed(const T& mine, const char* what);

  std::string mWho;
  std::string mHost;
  int mRank = 0, mSize = 0;
  double mTimeoutS = 60.0;
};

}  // namespace tessera::sync
