#include <tessera/sync/mpi_link.h>

#include <tessera/core/check.h>

namespace tessera::sync {

MpiMasterLink::MpiMasterLink(MpiTransport& mpi) : mMpi(mpi) {
  TESSERA_CHECK(mpi.rank() == 0, "the master is rank 0");
  mAnswers.resize(size_t(mpi.size()));
}

LinkEvents MpiMasterLink::poll(LinkClock::time_point) {
  LinkEvents events;
  if (mJoined) return events;
  mJoined = true;
  const std::vector<std::string> hellos = mMpi.gatherBytes({}, "every node's join");
  for (size_t r = 1; r < hellos.size(); ++r) {
    mCounters.bytes_received += hellos[r].size();
    mCounters.messages_received += 1;
    cluster::FromNode f;
    std::string why;
    if (!parseFromNode(hellos[r], f, why) || !f.has_hello()) {
      if (why.empty()) why = "the first message was not a join";
      events.faults.emplace_back(PeerId(r), why);
      refuse(PeerId(r), why);
      continue;
    }
    events.joins.emplace_back(PeerId(r), std::move(*f.mutable_hello()));
  }
  return events;
}

void MpiMasterLink::answerIfComplete() {
  if (mAnswered + 1 < mAnswers.size()) return;
  for (const std::string& a : mAnswers) mCounters.bytes_sent += a.size();
  mCounters.messages_sent += mAnswers.size() - 1;
  (void)mMpi.scatterBytes(mAnswers, "the answers to the joins");
}

void MpiMasterLink::welcome(PeerId peer, const cluster::ClusterSetup& setup) {
  TESSERA_CHECK(peer >= 1 && peer < mAnswers.size() && mAnswers[peer].empty(),
                "one answer per joined rank");
  cluster::ToNode t;
  *t.mutable_welcome() = setup;
  mAnswers[peer] = envelope(t);
  ++mAnswered;
  answerIfComplete();
}

void MpiMasterLink::refuse(PeerId peer, const std::string& reason) {
  TESSERA_CHECK(peer >= 1 && peer < mAnswers.size() && mAnswers[peer].empty(),
                "one answer per joined rank");
  cluster::ToNode t;
  t.mutable_refused()->set_reason(reason);
  mAnswers[peer] = envelope(t);
  ++mAnswered;
  answerIfComplete();
}

void MpiMasterLink::broadcast(const cluster::ToNode& message, const char* what) {
  std::string bytes = envelope(message);
  mCounters.bytes_sent += mMpi.broadcast(bytes, what);
  mCounters.messages_sent += 1;
}

void MpiMasterLink::publish(const cluster::FrameMessage& frame) {
  cluster::ToNode t;
  *t.mutable_frame() = frame;
  broadcast(t, "frame broadcast");
}

LinkEvents MpiMasterLink::collect(uint64_t, const std::set<PeerId>&, LinkClock::duration,
                                  LinkClock::time_point) {
  LinkEvents events;
  const std::vector<std::string> parts = mMpi.gatherBytes({}, "every node's report");
  for (size_t r = 1; r < parts.size(); ++r) {
    mCounters.bytes_received += parts[r].size();
    mCounters.messages_received += 1;
    cluster::FromNode f;
    std::string why;
    if (!parseFromNode(parts[r], f, why) || !f.has_report()) {
      events.faults.emplace_back(PeerId(r), why.empty() ? "expected a report" : why);
      continue;
    }
    events.reports.emplace_back(PeerId(r), std::move(*f.mutable_report()));
  }
  return events;
}

void MpiMasterLink::swap(uint64_t) {
  mMpi.swapBarrier();
}

void MpiMasterLink::drop(PeerId, const std::string&) {
  TESSERA_CHECK(false, "MpiMasterLink cannot drop a rank (canDropNodes() is false)");
}

void MpiMasterLink::quit(uint32_t code, const std::string& reason) {
  cluster::ToNode t;
  t.mutable_quit()->set_code(code);
  t.mutable_quit()->set_reason(reason);
  broadcast(t, "quit");
}

MpiNodeLink::MpiNodeLink(MpiTransport& mpi) : mMpi(mpi) {
  TESSERA_CHECK(mpi.rank() > 0, "nodes are ranks 1..K");
}

cluster::ClusterSetup MpiNodeLink::join(const cluster::Hello& hello, LinkClock::time_point) {
  if (mJoined) throw LinkError("sync::MpiNodeLink: an MPI job cannot be joined twice");
  mJoined = true;
  cluster::FromNode f;
  *f.mutable_hello() = hello;
  (void)mMpi.gatherBytes(envelope(f), "joining the master");
  const std::string answer = mMpi.scatterBytes({}, "the master's answer to the join");
  cluster::ToNode t;
  std::string why;
  if (!parseToNode(answer, t, why))
    throw LinkError("sync::MpiNodeLink: the master's answer: " + why);
  if (t.has_welcome()) return std::move(*t.mutable_welcome());
  const std::string reason = t.has_refused() ? t.refused().reason() : "no welcome";
  // The master gathers the startup reports and then ends the job: follow it there.
  cluster::NodeReport r;
  r.mutable_status()->set_code(cluster::NODE_REFUSED);
  r.mutable_status()->set_message(reason);
  report(r);
  cluster::ToNode next;
  receive(next, LinkClock::now());  // the quit: the master does not start a wall it refused
  throw JoinRefused(reason);
}

bool MpiNodeLink::receive(cluster::ToNode& message, LinkClock::time_point) {
  message.Clear();
  if (mSwapNext) {
    mSwapNext = false;
    mMpi.swapBarrier();
    message.set_protocol(kProtocolVersion);
    message.mutable_present()->set_frame(mReportedFrame);
    return true;
  }
  std::string bytes;
  mMpi.broadcast(bytes, "the master's next message");
  std::string why;
  if (!parseToNode(bytes, message, why)) mMpi.abort(5, "the master's message: " + why);
  return true;
}

void MpiNodeLink::report(const cluster::NodeReport& report) {
  cluster::FromNode f;
  *f.mutable_report() = report;
  (void)mMpi.gatherBytes(envelope(f), "sending this node's report");
  // Frame reports are followed by the barrier; the startup report (frame 0) by a broadcast.
  mReportedFrame = report.frame();
  mSwapNext = report.frame() > 0;
}

}  // namespace tessera::sync
