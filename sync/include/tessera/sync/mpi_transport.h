// MPI primitives (plain C API, OpenMPI) under the cluster link's MPI transport (mpi_link.h):
// point-to-point messages between the master (rank 0) and each node, and nothing else.
//
// Why no collectives: a collective (gather, broadcast, barrier) cannot say which rank kept it
// waiting, and in OpenMPI a rank that stops inside one (SIGSTOP, a debugger, a stuck driver)
// also stalls the ranks it would have forwarded to. With one message at a time between the
// master and one node, a node only ever waits for the master and the master waits for named
// ranks: at a deadline it knows exactly which ones did not answer.
//
// Waits are non-blocking MPI requests polled with short sleeps, so an idle rank yields its core
// to the renderers (this machine runs master + 8 nodes on 2 cores), and bounded by a timeout
// the caller gives, which does not count time this process itself did not run (stopped by
// SIGSTOP or a debugger, then continued); what a missed deadline means is the caller's to say
// (mpi_link.h names the rank and ends the job with abort()). Not thread-safe: one thread per
// process uses it.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace tessera::sync {

/// MPI could not start, or a message broke the protocol.
class TransportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class MpiTransport {
 public:
  /// Exit code of a job aborted because MPI itself returned an error (abort()).
  static constexpr int kExitMpiFailed = 3;

  /// MPI_Init. `timeout_s` is timeout() (seconds; PreconditionError unless finite and > 0: NaN
  /// would switch hang detection off). `who` names this process in messages ("tessera-master",
  /// "tessera-node"). Throws TransportError if MPI is unusable.
  MpiTransport(int* argc, char*** argv, std::string who, double timeout_s);
  /// MPI_Finalize.
  ~MpiTransport();
  MpiTransport(const MpiTransport&) = delete;
  MpiTransport& operator=(const MpiTransport&) = delete;

  int rank() const { return mRank; }
  int size() const { return mSize; }
  /// MPI_Get_processor_name of this rank.
  const std::string& host() const { return mHost; }
  /// The --timeout of this process: how long the link waits for another rank (seconds).
  double timeout() const { return mTimeoutS; }
  /// As the constructor's `timeout_s`.
  void setTimeout(double seconds);

  /// Sends `bytes` to rank `to` with `tag` and returns at once; the transport holds the bytes
  /// until MPI is done with them (one buffer may go to many ranks). Messages from one rank to
  /// another with one tag arrive in the order they were sent. Up to 2 GiB (MPI's int count):
  /// larger ends the job with a message (abort(1)).
  void post(int to, int tag, std::shared_ptr<const std::string> bytes, const char* what);

  /// The next message with `tag` from each rank of `from`, waiting until all of them arrived or
  /// `timeout_s` passed (sends posted earlier progress meanwhile). One entry per rank of `from`,
  /// in its order; nullopt for a rank whose message did not arrive in time. A caller that got a
  /// nullopt must end the job (abort()): the message may still be in flight into a buffer the
  /// transport keeps for it.
  std::vector<std::optional<std::string>> receiveEach(const std::vector<int>& from, int tag,
                                                      double timeout_s, const char* what);

  /// Waits until every posted send completed or `timeout_s` passed. Returns the ranks whose
  /// messages were not taken (ascending, once each): small messages are buffered, so these are
  /// ranks that stopped taking large ones.
  std::vector<int> flush(double timeout_s, const char* what);

  /// Prints "<who> (rank R on HOST): why" to stderr and ends every process of the job with
  /// `code` (MPI_Abort; mpirun then exits with `code`). For waits that cannot end otherwise.
  [[noreturn]] void abort(int code, const std::string& why) const;

 private:
  struct Send;
  struct Buffer;
  bool progressSends(const char* what);  // true once every posted send completed
  void check(int mpi_result, const char* doing, const char* what) const;

  std::string mWho;
  std::string mHost;
  int mRank = 0, mSize = 0;
  double mTimeoutS = 60.0;
  std::vector<std::unique_ptr<Send>> mSends;  // posted, not yet completed
  // Receive buffers MPI may still write into (receiveEach() gave up on them): kept until the end.
  std::vector<std::unique_ptr<Buffer>> mAbandoned;
};

}  // namespace tessera::sync
