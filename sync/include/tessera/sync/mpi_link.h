// The cluster link inside one mpirun job (MPMD: `mpirun -np 1 tessera-master ... : -np K
// tessera-node`), on the collectives of mpi_transport.h. See cluster_link.h for the protocol.
//
// Every rank is known from the start and every call is collective, so the link's calls map to
// MPI's: the joins are one gather of Hellos and one scatter of the answers; publish() and quit()
// broadcast; collect() gathers every rank's report; swap() is the barrier. A rank that dies or
// hangs cannot be dropped: the transport's timeout aborts the whole job with a message
// (canDropNodes() is false). The master is rank 0; rank r's peer id is r.
#pragma once

#include <string>
#include <vector>

#include <tessera/sync/cluster_link.h>
#include <tessera/sync/mpi_transport.h>

namespace tessera::sync {

class MpiMasterLink final : public MasterLink {
 public:
  /// Precondition: mpi.rank() == 0.
  explicit MpiMasterLink(MpiTransport& mpi);

  /// The number of nodes in the job (ranks 1..size-1).
  int nodes() const { return mMpi.size() - 1; }

  const char* transport() const override { return "mpi"; }
  bool canDropNodes() const override { return false; }
  LinkEvents poll(LinkClock::time_point deadline) override;
  void welcome(PeerId peer, const cluster::ClusterSetup& setup) override;
  void refuse(PeerId peer, const std::string& reason) override;
  void publish(const cluster::FrameMessage& frame) override;
  LinkEvents collect(uint64_t frame, const std::set<PeerId>& awaited, LinkClock::duration quiet,
                     LinkClock::time_point cap) override;
  void swap(uint64_t frame) override;
  void drop(PeerId peer, const std::string& reason) override;
  bool connected(PeerId) override { return true; }
  void quit(uint32_t code, const std::string& reason) override;
  LinkCounters counters() const override { return mCounters; }

 private:
  void broadcast(const cluster::ToNode& message, const char* what);
  void answerIfComplete();

  MpiTransport& mMpi;
  bool mJoined = false;
  std::vector<std::string> mAnswers;  // per rank, envelope bytes; [0] unused
  size_t mAnswered = 0;
  LinkCounters mCounters;
};

class MpiNodeLink final : public NodeLink {
 public:
  /// Precondition: mpi.rank() > 0.
  explicit MpiNodeLink(MpiTransport& mpi);

  const char* transport() const override { return "mpi"; }
  /// Joins once (the job's start); a refusal is followed through the collectives the master
  /// makes next (the startup reports, the quit) before JoinRefused is thrown.
  cluster::ClusterSetup join(const cluster::Hello& hello, LinkClock::time_point deadline) override;
  bool receive(cluster::ToNode& message, LinkClock::time_point deadline) override;
  bool pending() override { return false; }
  void working(uint64_t) override {}
  void report(const cluster::NodeReport& report) override;

 private:
  MpiTransport& mMpi;
  bool mJoined = false;
  uint64_t mReportedFrame = 0;
  bool mSwapNext = false;  // the last report was a frame's: the next receive() is the barrier
};

}  // namespace tessera::sync
