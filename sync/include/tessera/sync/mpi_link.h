// The cluster link inside one mpirun job (MPMD: `mpirun -np 1 tessera-master ... : -np K
// tessera-node`), on the point-to-point messages of mpi_transport.h. See cluster_link.h for the
// protocol.
//
// Every rank is known from the start: the master is rank 0, rank r's peer id is r. Each
// ToNode goes from the master to each node as one message (the frame, the present that releases
// the swap, the quit), each FromNode from a node to the master (the hello, the reports), so a
// node only ever waits for the master, and the master for named ranks. A rank that dies or hangs
// cannot be dropped (canDropNodes() is false), and the job ends, with one exit code whichever
// rank noticed (README, "Exit codes"):
//   - a node rank hangs: at the end of the master's --timeout the master prints each rank that
//     did not join, report or take a message, with its tile, host and pid, and aborts the job
//     with kExitRankHung;
//   - the master hangs: the nodes wait for it twice as long as it would wait for them (so the
//     master always decides first when a node hangs), then abort with NODE_MASTER_LOST (17);
//   - anything the master decides (a node reported a failure, the wall cannot start, the end):
//     it sends every node the quit with its exit code, and every rank exits with that code
//     (MpiNodeLink::quitCode()), so mpirun's code is the master's.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <tessera/sync/cluster_link.h>
#include <tessera/sync/mpi_transport.h>

namespace tessera::sync {

/// The MPI job's exit code when a node rank hung (it did not join, report or take a message
/// within the master's --timeout).
constexpr int kExitRankHung = 4;

class MpiMasterLink final : public MasterLink {
 public:
  /// Precondition: mpi.rank() == 0.
  explicit MpiMasterLink(MpiTransport& mpi);

  /// The number of nodes in the job (ranks 1..size-1).
  int nodes() const { return mMpi.size() - 1; }

  const char* transport() const override { return "mpi"; }
  bool canDropNodes() const override { return false; }
  /// The first call waits up to the transport's timeout for every rank's Hello (a rank missing
  /// then ends the job, named); later calls wait until `deadline` and return nothing.
  LinkEvents poll(LinkClock::time_point deadline) override;
  void welcome(PeerId peer, const cluster::ClusterSetup& setup) override;
  void refuse(PeerId peer, const std::string& reason) override;
  void publish(const cluster::FrameMessage& frame) override;
  /// The next report of every rank, waiting up to the transport's timeout (`awaited`, `quiet`
  /// and `cap` are not used): a rank whose report did not come ends the job, named.
  LinkEvents collect(uint64_t frame, const std::set<PeerId>& awaited, LinkClock::duration quiet,
                     LinkClock::time_point cap) override;
  void swap(uint64_t frame) override;
  void drop(PeerId peer, const std::string& reason) override;
  bool connected(PeerId) override { return true; }
  /// Sends the quit to every rank and waits up to the transport's timeout for them to take it.
  void quit(uint32_t code, const std::string& reason) override;
  LinkCounters counters() const override { return mCounters; }

 private:
  struct Rank {  // what the master knows of a node rank, for messages
    bool joined = false;
    std::string tile, host;
    uint32_t pid = 0;
  };
  void sendEach(const cluster::ToNode& message, const char* what);
  void send(PeerId peer, const cluster::ToNode& message, const char* what);
  std::vector<int> nodeRanks() const;
  /// The next FromNode of every node rank (index r - 1), waiting up to the transport's timeout;
  /// ranks that sent nothing are named with "hung: `missing` within T s" and end the job.
  std::vector<std::string> receiveFromEveryNode(const char* what, const char* missing);
  /// "tile right (host vm, pid 4242, rank 2)", or what is known of it.
  std::string describe(int rank) const;
  /// Names each of `ranks` with "hung: `what` within T s" and aborts the job (kExitRankHung).
  [[noreturn]] void abortHung(const std::vector<int>& ranks, const std::string& what) const;

  MpiTransport& mMpi;
  bool mJoined = false;
  std::vector<Rank> mRanks;  // [0] unused
  LinkCounters mCounters;
};

class MpiNodeLink final : public NodeLink {
 public:
  /// Precondition: mpi.rank() > 0.
  explicit MpiNodeLink(MpiTransport& mpi);

  const char* transport() const override { return "mpi"; }
  /// Joins once (the job's start); a refusal is followed through the messages the master sends
  /// next (it takes the startup report, then quits) before JoinRefused is thrown.
  cluster::ClusterSetup join(const cluster::Hello& hello, LinkClock::time_point deadline) override;
  /// The master's next message. Waits twice the larger of this rank's and the master's timeout
  /// (the master's from its first message), then ends the job (NODE_MASTER_LOST): the master hung.
  bool receive(cluster::ToNode& message, LinkClock::time_point deadline) override;
  bool pending() override { return false; }
  void working(uint64_t) override {}
  void report(const cluster::NodeReport& report) override;

  /// The code of the master's quit, once received: every rank of the job exits with it.
  std::optional<int> quitCode() const { return mQuitCode; }

 private:
  std::string receiveFromMaster(int tag, double timeout_s, const char* what);

  MpiTransport& mMpi;
  bool mJoined = false;
  double mMasterTimeoutS = 0;  // the master's --timeout, from its first message
  std::optional<int> mQuitCode;
};

}  // namespace tessera::sync
