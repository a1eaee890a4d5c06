#include <tessera/sync/mpi_link.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include <tessera/core/check.h>

namespace tessera::sync {

namespace {

// One tag per direction keeps each direction's messages in the order they were sent (MPI's
// non-overtaking rule holds per sender, receiver and tag).
constexpr int kTagToNode = 1;    // ToNode envelopes: welcome or refusal, frames, presents, quit
constexpr int kTagFromNode = 2;  // FromNode envelopes: the hello, reports
constexpr int kTagTimeout = 3;   // the master's --timeout in seconds (text), its first message

std::string seconds(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%g s", s);
  return text;
}

}  // namespace

MpiMasterLink::MpiMasterLink(MpiTransport& mpi) : mMpi(mpi) {
  TESSERA_CHECK(mpi.rank() == 0, "the master is rank 0");
  mRanks.resize(size_t(mpi.size()));
}

std::vector<int> MpiMasterLink::nodeRanks() const {
  std::vector<int> ranks;
  for (int r = 1; r < mMpi.size(); ++r) ranks.push_back(r);
  return ranks;
}

std::string MpiMasterLink::describe(int rank) const {
  const Rank& r = mRanks[size_t(rank)];
  const std::string number = "rank " + std::to_string(rank);
  if (!r.joined) return number + " (it never joined: its tile, host and pid are unknown)";
  return (r.tile.empty() ? std::string("the node") : "tile " + r.tile) + " (host " + r.host +
         ", pid " + std::to_string(r.pid) + ", " + number + ")";
}

void MpiMasterLink::abortHung(const std::vector<int>& ranks, const std::string& what) const {
  std::string why;
  for (int r : ranks)
    why += describe(r) + ": hung: " + what + " within " + seconds(mMpi.timeout()) + "; ";
  why += std::to_string(ranks.size()) + " of " + std::to_string(nodes()) +
         " render nodes hung; aborting the job";
  mMpi.abort(kExitRankHung, why);
}

std::vector<std::string> MpiMasterLink::receiveFromEveryNode(const char* what,
                                                             const char* missing) {
  const std::vector<int> ranks = nodeRanks();
  std::vector<std::optional<std::string>> got =
      mMpi.receiveEach(ranks, kTagFromNode, mMpi.timeout(), what);
  std::vector<int> late;
  for (size_t i = 0; i < ranks.size(); ++i)
    if (!got[i]) late.push_back(ranks[i]);
  if (!late.empty()) abortHung(late, missing);
  std::vector<std::string> out;
  for (std::optional<std::string>& bytes : got) {
    mCounters.bytes_received += bytes->size();
    mCounters.messages_received += 1;
    out.push_back(std::move(*bytes));
  }
  return out;
}

LinkEvents MpiMasterLink::poll(LinkClock::time_point deadline) {
  LinkEvents events;
  if (mJoined) {  // nothing comes between the frames: wait as asked, without spinning a core
    std::this_thread::sleep_until(deadline);
    return events;
  }
  mJoined = true;
  // First the master's timeout, so that every node waits for the master longer than the master
  // waits for a node: when a node hangs, the master is the one that notices and names it.
  char timeout[32];
  std::snprintf(timeout, sizeof timeout, "%.17g", mMpi.timeout());
  const auto timeout_bytes = std::make_shared<const std::string>(timeout);
  for (int r : nodeRanks()) mMpi.post(r, kTagTimeout, timeout_bytes, "the master's timeout");
  const std::vector<std::string> hellos = receiveFromEveryNode("every node's join", "no join");
  for (size_t i = 0; i < hellos.size(); ++i) {
    const PeerId peer = PeerId(i + 1);
    cluster::FromNode f;
    std::string why;
    if (!parseFromNode(hellos[i], f, why) || !f.has_hello()) {
      if (why.empty()) why = "the first message was not a join";
      events.faults.emplace_back(peer, why);
      refuse(peer, why);
      continue;
    }
    Rank& r = mRanks[peer];
    r.joined = true;
    r.host = f.hello().host().substr(0, 64);
    r.pid = f.hello().pid();
    events.joins.emplace_back(peer, std::move(*f.mutable_hello()));
  }
  return events;
}

void MpiMasterLink::send(PeerId peer, const cluster::ToNode& message, const char* what) {
  const auto bytes = std::make_shared<const std::string>(envelope(message));
  mMpi.post(int(peer), kTagToNode, bytes, what);
  mCounters.bytes_sent += bytes->size();
  mCounters.messages_sent += 1;
}

void MpiMasterLink::sendEach(const cluster::ToNode& message, const char* what) {
  const auto bytes = std::make_shared<const std::string>(envelope(message));
  for (int r : nodeRanks()) {
    mMpi.post(r, kTagToNode, bytes, what);
    mCounters.bytes_sent += bytes->size();
    mCounters.messages_sent += 1;
  }
}

void MpiMasterLink::welcome(PeerId peer, const cluster::ClusterSetup& setup) {
  TESSERA_CHECK(peer >= 1 && peer < mRanks.size(), "a node rank");
  mRanks[peer].tile = setup.tile();
  cluster::ToNode t;
  *t.mutable_welcome() = setup;
  send(peer, t, "the welcome");
}

void MpiMasterLink::refuse(PeerId peer, const std::string& reason) {
  TESSERA_CHECK(peer >= 1 && peer < mRanks.size(), "a node rank");
  cluster::ToNode t;
  t.mutable_refused()->set_reason(reason);
  send(peer, t, "the refusal");
}

void MpiMasterLink::publish(const cluster::FrameMessage& frame) {
  cluster::ToNode t;
  *t.mutable_frame() = frame;
  sendEach(t, "the frame");
}

LinkEvents MpiMasterLink::collect(uint64_t, const std::set<PeerId>&, LinkClock::duration,
                                  LinkClock::time_point) {
  LinkEvents events;
  const std::vector<std::string> parts = receiveFromEveryNode("every node's report", "no report");
  for (size_t i = 0; i < parts.size(); ++i) {
    const PeerId peer = PeerId(i + 1);
    cluster::FromNode f;
    std::string why;
    if (!parseFromNode(parts[i], f, why) || !f.has_report()) {
      events.faults.emplace_back(peer, why.empty() ? "expected a report" : why);
      continue;
    }
    events.reports.emplace_back(peer, std::move(*f.mutable_report()));
  }
  return events;
}

void MpiMasterLink::swap(uint64_t frame) {
  // Every report is in (collect()), so the present is the swap barrier's release.
  cluster::ToNode t;
  t.mutable_present()->set_frame(frame);
  sendEach(t, "the present");
}

void MpiMasterLink::drop(PeerId, const std::string&) {
  TESSERA_CHECK(false, "MpiMasterLink cannot drop a rank (canDropNodes() is false)");
}

void MpiMasterLink::quit(uint32_t code, const std::string& reason) {
  cluster::ToNode t;
  t.mutable_quit()->set_code(code);
  t.mutable_quit()->set_reason(reason);
  sendEach(t, "the quit");
  const std::vector<int> late = mMpi.flush(mMpi.timeout(), "the quit");
  if (!late.empty()) abortHung(late, "did not take the master's messages");
}

MpiNodeLink::MpiNodeLink(MpiTransport& mpi) : mMpi(mpi) {
  TESSERA_CHECK(mpi.rank() > 0, "nodes are ranks 1..K");
}

std::string MpiNodeLink::receiveFromMaster(int tag, double timeout_s, const char* what) {
  std::optional<std::string> got = std::move(mMpi.receiveEach({0}, tag, timeout_s, what)[0]);
  if (!got)
    mMpi.abort(cluster::NODE_MASTER_LOST, std::string("no ") + what + " from the master within " +
                                              seconds(timeout_s) +
                                              " (the master hung or died); aborting the job");
  return std::move(*got);
}

cluster::ClusterSetup MpiNodeLink::join(const cluster::Hello& hello, LinkClock::time_point) {
  if (mJoined) throw LinkError("sync::MpiNodeLink: an MPI job cannot be joined twice");
  mJoined = true;
  cluster::FromNode f;
  *f.mutable_hello() = hello;
  mMpi.post(0, kTagFromNode, std::make_shared<const std::string>(envelope(f)), "the join");
  // Until the master's first message, this rank's own --timeout (the master may be converting
  // scans before it listens); then twice the larger of both.
  const std::string timeout = receiveFromMaster(kTagTimeout, mMpi.timeout(), "answer to the join");
  char* end = nullptr;
  const double master_timeout_s = std::strtod(timeout.c_str(), &end);
  if (end == timeout.c_str() || *end != '\0' || !std::isfinite(master_timeout_s) ||
      master_timeout_s <= 0)
    mMpi.abort(cluster::NODE_BAD_FRAME,
               "the master's timeout '" + timeout.substr(0, 32) + "' is not a number of seconds");
  mMasterTimeoutS = master_timeout_s;
  cluster::ToNode t;
  receive(t, LinkClock::now());
  if (t.has_welcome()) return std::move(*t.mutable_welcome());
  const std::string reason = t.has_refused() ? t.refused().reason() : "no welcome";
  // The master takes the startup reports and then ends the job: follow it there.
  cluster::NodeReport r;
  r.mutable_status()->set_code(cluster::NODE_REFUSED);
  r.mutable_status()->set_message(reason);
  report(r);
  cluster::ToNode next;
  receive(next, LinkClock::now());  // the quit: the master does not start a wall it refused
  throw JoinRefused(reason);
}

bool MpiNodeLink::receive(cluster::ToNode& message, LinkClock::time_point) {
  const double wait_s = 2.0 * std::max(mMpi.timeout(), mMasterTimeoutS);
  const std::string bytes = receiveFromMaster(kTagToNode, wait_s, "message");
  std::string why;
  if (!parseToNode(bytes, message, why))
    mMpi.abort(cluster::NODE_BAD_FRAME, "the master's message: " + why);
  if (message.has_quit()) mQuitCode = int(message.quit().code());
  return true;
}

void MpiNodeLink::report(const cluster::NodeReport& report) {
  cluster::FromNode f;
  *f.mutable_report() = report;
  mMpi.post(0, kTagFromNode, std::make_shared<const std::string>(envelope(f)),
            "this node's report");
}

}  // namespace tessera::sync
