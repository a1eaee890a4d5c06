// MPI primitives (plain C API, OpenMPI) under the cluster link's MPI transport (mpi_link.h):
// broadcast from the master (rank 0), gathers to it and a scatter from it, and the swap barrier.
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

/// MPI could not start, or a message broke the protocol.
class TransportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class MpiTransport {
 public:
  /// MPI_Init. `timeout_s` bounds every wait (seconds; PreconditionError unless finite and > 0:
  /// NaN would switch hang detection off). `who` names this process in messages
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
  /// As the constructor's `timeout_s`.
  void setTimeout(double seconds);

  /// Rank 0 sends `bytes`; the others receive them into theirs. Returns the bytes moved. `what`
  /// names the wait in a timeout message.
  uint64_t broadcast(std::string& bytes, const char* what);
  /// The swap barrier: returns once every rank has called it; milliseconds waited.
  double swapBarrier();
  /// Variable-size gather: rank 0 gets each rank's bytes in rank order (its own first; up to
  /// 2 GiB in all); empty elsewhere.
  std::vector<std::string> gatherBytes(std::string_view mine, const char* what);
  /// Variable-size scatter: rank r gets `parts[r]` (`parts` is read on rank 0 only, one per rank).
  std::string scatterBytes(const std::vector<std::string>& parts, const char* what);

  /// Prints "<who> (rank R on HOST): why" to stderr and ends every process of the job with
  /// `code` (MPI_Abort). For waits that cannot end otherwise.
  [[noreturn]] void abort(int code, const std::string& why) const;

 private:
  void wait(void* request, const char* what);  // MPI_Request*, polled until done or timeout

  std::string mWho;
  std::string mHost;
  int mRank = 0, mSize = 0;
  double mTimeoutS = 60.0;
};

}  // namespace tessera::sync
