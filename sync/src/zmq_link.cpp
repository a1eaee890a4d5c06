#include <tessera/sync/zmq_link.h>
#include <tessera/sync/zmq_poll.h>

#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstring>
#include <map>
#include <mutex>
#include <thread>

namespace tessera::sync {

namespace {

/// Each link's monitor needs its own inproc address within its context.
std::string monitorAddress(const char* who) {
  static std::atomic<uint64_t> counter{0};
  return std::string("inproc://tessera-") + who + "-monitor-" + std::to_string(counter++);
}

void setCommonOptions(zmq::socket_t& s, const ZmqLinkOptions& o) {
  s.set(zmq::sockopt::heartbeat_ivl, o.heartbeat_ivl_ms);
  s.set(zmq::sockopt::heartbeat_timeout, o.heartbeat_timeout_ms);
  s.set(zmq::sockopt::heartbeat_ttl, o.heartbeat_timeout_ms);
  s.set(zmq::sockopt::maxmsgsize, o.max_message_bytes);
  s.set(zmq::sockopt::sndhwm, 1000);
  s.set(zmq::sockopt::rcvhwm, 1000);
}

/// Milliseconds from now to `deadline`, rounded up, for zmq::poll (0 once it passed): a wait
/// that ends before its deadline would make its caller spin through the last millisecond.
std::chrono::milliseconds until(LinkClock::time_point deadline) {
  const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - LinkClock::now());
  return left.count() > 0 ? left : std::chrono::milliseconds(0);
}

/// How often a member is probed while a closed connection is being matched to its peer: each
/// probe is a message in the member's queue, read only between its frames.
constexpr auto kProbeInterval = std::chrono::milliseconds(20);

/// How long a node's hello waits for its answer on one connection before it goes out again on
/// a new one. A master answers a hello at its next frame or pacing wait: well within this.
constexpr auto kHelloRetry = std::chrono::milliseconds(2000);

/// Stops `s`'s monitor. Before the monitor's reader is closed: libzmq sends each event from its
/// I/O thread with a blocking send, so an event for a reader gone (a connection closed after
/// it) would stop that thread, and every connection of the context with it, for good.
void stopMonitor(zmq::socket_t& s) {
  zmq_socket_monitor(s.handle(), nullptr, 0);
}

/// Reads one monitor event: true when it says a connection closed; `fd` is then its socket.
bool readMonitorEvent(zmq::socket_t& monitor, int* fd = nullptr) {
  std::vector<zmq::message_t> parts;
  if (!zmq::recv_multipart(monitor, std::back_inserter(parts), zmq::recv_flags::dontwait))
    return false;
  if (parts.empty() || parts[0].size() < 6) return false;  // uint16 event, uint32 value
  uint16_t event = 0;
  uint32_t value = 0;
  std::memcpy(&event, parts[0].data(), sizeof event);
  std::memcpy(&value, static_cast<const char*>(parts[0].data()) + 2, sizeof value);
  if (fd) *fd = int(value);
  return event == ZMQ_EVENT_DISCONNECTED;
}

}  // namespace

// ---- master ----------------------------------------------------------------------------------

struct ZmqMasterLink::Impl {
  struct Peer {
    std::string routing;
    bool member = false;  // welcomed and not dropped: gets frames and swaps
    bool told = false;    // sent Dropped/Refused since its last join: stale reports are ignored
    int fd = -1;          // the TCP socket its last message came from (ZMQ_SRCFD)
    LinkClock::time_point probed{};  // its last probe
  };

  zmq::context_t ctx{1};
  zmq::socket_t router{ctx, zmq::socket_type::router};
  zmq::socket_t monitor{ctx, zmq::socket_type::pair};
  std::map<std::string, PeerId> by_routing;
  std::map<PeerId, Peer> peers;
  PeerId next = 1;
  LinkCounters counters;
  std::string endpoint;
  LinkClock::time_point probe_until{};  // after a closed connection: probe the members
  std::set<PeerId> stalled;             // members a message could not be queued for

  ~Impl() { stopMonitor(router); }  // before the members close: the monitor's reader first

  enum class Sent { kYes, kQueueFull, kGone };

  /// Sends to one peer without blocking: a full queue is a connected node that does not read
  /// (hung), a gone pipe a closed connection (ZMQ_ROUTER_MANDATORY's EHOSTUNREACH).
  Sent send(PeerId id, const std::string& bytes) {
    auto it = peers.find(id);
    if (it == peers.end()) return Sent::kGone;
    try {
      zmq::const_buffer route(it->second.routing.data(), it->second.routing.size());
      if (!router.send(route, zmq::send_flags::sndmore | zmq::send_flags::dontwait))
        return Sent::kQueueFull;
      if (!router.send(zmq::const_buffer(bytes.data(), bytes.size()), zmq::send_flags::dontwait))
        return Sent::kQueueFull;
    } catch (const zmq::error_t&) {
      return Sent::kGone;
    }
    counters.bytes_sent += bytes.size() + it->second.routing.size();
    counters.messages_sent += 1;
    return Sent::kYes;
  }

  /// Whether `id`'s connection is still open, by sending it a ToNode{ping} (nodes ignore it).
  bool reachable(PeerId id) {
    static const std::string ping = [] {
      cluster::ToNode t;
      t.mutable_ping();
      return envelope(t);
    }();
    return send(id, ping) != Sent::kGone;
  }

  void sendTo(PeerId id, const cluster::ToNode& message) { send(id, envelope(message)); }

  void tell(PeerId id, const std::string& reason, bool refused) {
    cluster::ToNode t;
    if (refused)
      t.mutable_refused()->set_reason(reason);
    else
      t.mutable_dropped()->set_reason(reason);
    sendTo(id, t);
    Peer& p = peers[id];
    p.member = false;
    p.told = true;
  }

  /// One message from the router into `events`. False when none was waiting.
  bool receiveOne(LinkEvents& events) {
    std::vector<zmq::message_t> parts;
    zmq::recv_result_t got;
    try {
      got = zmq::recv_multipart(router, std::back_inserter(parts), zmq::recv_flags::dontwait);
    } catch (const zmq::error_t&) {
      return false;
    }
    if (!got || parts.empty()) return false;
    const std::string routing = parts[0].to_string();
    auto [it, is_new] = by_routing.emplace(routing, next);
    if (is_new) peers[next++].routing = routing;
    const PeerId id = it->second;
    try {
      peers[id].fd = parts.back().get(ZMQ_SRCFD);
    } catch (const zmq::error_t&) {
    }
    counters.messages_received += 1;
    for (const auto& p : parts) counters.bytes_received += p.size();

    cluster::FromNode message;
    std::string why;
    if (parts.size() != 2) {
      why = std::to_string(parts.size() - 1) + " frames in one message (a Tessera node sends 1)";
    } else if (parseFromNode(std::string_view(parts[1].data<char>(), parts[1].size()), message,
                             why)) {
      Peer& peer = peers[id];
      if (message.has_hello()) {
        peer.told = false;
        events.joins.emplace_back(id, std::move(*message.mutable_hello()));
        return true;
      }
      // A report: from a member it counts; from anyone else (dropped, or a new connection of a
      // node the master never welcomed) it is stale, and the node is told once to join again.
      if (peer.member) {
        events.reports.emplace_back(id, std::move(*message.mutable_report()));
      } else if (!peer.told) {
        tell(id,
             "this connection is not a member of the wall (dropped, or reconnected): join again",
             false);
      }
      return true;
    }
    // One refusal and one fault per connection: the rest of a flood is read and let go.
    if (!peers[id].told) {
      tell(id, why, true);
      events.faults.emplace_back(id, why);
    }
    return true;
  }

  /// Drains the monitor. A closed connection's socket names its peer (the fd its messages came
  /// from, ZMQ_SRCFD). As a second way, the pipe of a closed connection leaves the socket a
  /// moment after the event, so for a while after one every member is probed (a send to a gone
  /// pipe fails: ZMQ_ROUTER_MANDATORY) and the unreachable ones are reported gone.
  void checkDisconnects(LinkEvents& events) {
    while (true) {
      zmq::pollitem_t item{monitor.handle(), 0, ZMQ_POLLIN, 0};
      if (pollItems(&item, 1, std::chrono::milliseconds(0)) <= 0) break;
      int fd = -1;
      if (!readMonitorEvent(monitor, &fd)) continue;
      probe_until = LinkClock::now() + std::chrono::milliseconds(300);
      for (auto& [id, peer] : peers) {
        if (fd < 0 || peer.fd != fd) continue;
        peer.fd = -1;
        if (peer.member) {
          peer.member = false;
          events.gone.insert(id);
        }
      }
    }
    takeStalled(events);
    const auto now = LinkClock::now();
    if (now >= probe_until) return;
    for (auto& [id, peer] : peers) {
      if (!peer.member || now - peer.probed < kProbeInterval) continue;
      peer.probed = now;
      if (!reachable(id)) {
        peer.member = false;
        events.gone.insert(id);
      }
    }
  }

  /// Sends `bytes` to every member. A member whose queue is full (it stopped reading) would
  /// silently miss the message: it stops being a member and the next wait reports it stalled.
  void sendToMembers(const std::string& bytes) {
    for (auto& [id, peer] : peers) {
      if (peer.member && send(id, bytes) == Sent::kQueueFull) {
        peer.member = false;
        stalled.insert(id);
      }
    }
  }

  void takeStalled(LinkEvents& events) {
    events.stalled.insert(stalled.begin(), stalled.end());
    stalled.clear();
  }

  /// Waits for traffic until `deadline` or until `done(events)`.
  template <class Done>
  LinkEvents wait(LinkClock::time_point deadline, Done done) {
    LinkEvents events;
    while (true) {
      while (receiveOne(events)) {
      }
      checkDisconnects(events);
      if (done(events)) return events;
      auto left = until(deadline);
      if (left.count() == 0) return events;
      if (LinkClock::now() < probe_until) left = std::min(left, std::chrono::milliseconds(5));
      zmq::pollitem_t items[] = {{router.handle(), 0, ZMQ_POLLIN, 0},
                                 {monitor.handle(), 0, ZMQ_POLLIN, 0}};
      pollItems(items, 2, left);
    }
  }
};

ZmqMasterLink::ZmqMasterLink(const std::string& endpoint, const ZmqLinkOptions& options)
    : m(std::make_unique<Impl>()) {
  try {
    setCommonOptions(m->router, options);
    m->router.set(zmq::sockopt::router_mandatory, 1);
    m->router.set(zmq::sockopt::linger, 200);
    const std::string address = monitorAddress("master");
    if (zmq_socket_monitor(m->router.handle(), address.c_str(), ZMQ_EVENT_DISCONNECTED) != 0)
      throw zmq::error_t();
    m->monitor.connect(address);
    m->router.bind(endpoint);
    m->endpoint = m->router.get(zmq::sockopt::last_endpoint);
  } catch (const zmq::error_t& e) {
    throw LinkError("sync::ZmqMasterLink: cannot listen on " + endpoint + ": " + e.what());
  }
}

ZmqMasterLink::~ZmqMasterLink() = default;

std::string ZmqMasterLink::endpoint() const {
  return m->endpoint;
}

LinkEvents ZmqMasterLink::poll(LinkClock::time_point deadline) {
  LinkEvents events = m->wait(deadline, [](const LinkEvents& e) { return !e.empty(); });
  // Signs of work belong to collect(); between frames they are stale.
  std::erase_if(events.reports, [](const auto& r) { return r.second.working(); });
  return events;
}

void ZmqMasterLink::welcome(PeerId peer, const cluster::ClusterSetup& setup) {
  cluster::ToNode t;
  *t.mutable_welcome() = setup;
  if (m->send(peer, envelope(t)) == Impl::Sent::kYes) {
    m->peers[peer].member = true;
    m->peers[peer].told = false;
  }
}

void ZmqMasterLink::refuse(PeerId peer, const std::string& reason) {
  m->tell(peer, reason, true);
}

void ZmqMasterLink::publish(const cluster::FrameMessage& frame) {
  cluster::ToNode t;
  *t.mutable_frame() = frame;
  m->sendToMembers(envelope(t));
}

LinkEvents ZmqMasterLink::collect(uint64_t frame, const std::set<PeerId>& awaited,
                                  LinkClock::duration quiet, LinkClock::time_point cap) {
  // Each awaited peer's own deadline: `quiet` after its last sign of work on this frame.
  std::map<PeerId, LinkClock::time_point> left;
  const auto start = LinkClock::now();
  for (PeerId id : awaited) left[id] = std::min(cap, start + quiet);
  LinkEvents events;
  while (true) {
    LinkEvents more;
    while (m->receiveOne(more)) {
    }
    m->checkDisconnects(more);
    const auto now = LinkClock::now();
    for (auto& [id, r] : more.reports) {
      auto it = left.find(id);
      if (r.working()) {
        // Any frame: a node behind is still rendering an older one, and renders the newest next.
        if (it != left.end()) it->second = std::min(cap, now + quiet);
        continue;
      }
      if (it != left.end() && (r.frame() == frame || r.status().code() != cluster::NODE_OK))
        left.erase(it);
      events.reports.emplace_back(id, std::move(r));
    }
    more.reports.clear();
    for (PeerId id : more.gone) left.erase(id);
    for (PeerId id : more.stalled) left.erase(id);
    for (const auto& [id, why] : more.faults) left.erase(id);
    events.append(std::move(more));
    LinkClock::time_point until_next = LinkClock::time_point::min();
    for (auto it = left.begin(); it != left.end();) {
      if (it->second <= now) {
        it = left.erase(it);  // missed: the caller names it
      } else {
        until_next = std::max(until_next, it->second);
        ++it;
      }
    }
    if (left.empty()) return events;
    auto wait = until(until_next);
    if (now < m->probe_until) wait = std::min(wait, std::chrono::milliseconds(5));
    wait = std::min(wait, std::chrono::milliseconds(100));  // deadlines move with progress
    zmq::pollitem_t items[] = {{m->router.handle(), 0, ZMQ_POLLIN, 0},
                               {m->monitor.handle(), 0, ZMQ_POLLIN, 0}};
    pollItems(items, 2, wait);
  }
}

void ZmqMasterLink::swap(uint64_t frame) {
  cluster::ToNode t;
  t.mutable_present()->set_frame(frame);
  m->sendToMembers(envelope(t));
}

void ZmqMasterLink::drop(PeerId peer, const std::string& reason) {
  if (m->peers.count(peer)) m->tell(peer, reason, false);
}

bool ZmqMasterLink::connected(PeerId peer) {
  return m->reachable(peer);
}

void ZmqMasterLink::quit(uint32_t code, const std::string& reason) {
  cluster::ToNode t;
  t.mutable_quit()->set_code(code);
  t.mutable_quit()->set_reason(reason);
  m->sendToMembers(envelope(t));
}

LinkCounters ZmqMasterLink::counters() const {
  return m->counters;
}

// ---- node ------------------------------------------------------------------------------------

struct ZmqNodeLink::Impl {
  std::mutex socket_mutex;  // the dealer: the caller's thread or the sign-of-life thread
  std::mutex beat_mutex;    // what the sign-of-life thread does
  std::condition_variable beat_wake;
  bool beating = false, stopping = false;
  uint64_t beat_frame = 0;
  std::thread beat;
  std::string endpoint;
  ZmqLinkOptions options;
  zmq::context_t ctx{1};
  std::unique_ptr<zmq::socket_t> dealer, monitor;
  bool lost = false;
  bool joined = false;  // join() was called before: the next one starts a new connection

  void open() {
    if (dealer) {
      stopMonitor(*dealer);
      dealer->set(zmq::sockopt::linger, 0);  // what it still queues is stale
    }
    monitor.reset();
    dealer.reset();
    dealer = std::make_unique<zmq::socket_t>(ctx, zmq::socket_type::dealer);
    monitor = std::make_unique<zmq::socket_t>(ctx, zmq::socket_type::pair);
    try {
      setCommonOptions(*dealer, options);
      // The last report (a failure, say) still reaches the master when the node exits.
      dealer->set(zmq::sockopt::linger, 1000);
      const std::string address = monitorAddress("node");
      if (zmq_socket_monitor(dealer->handle(), address.c_str(), ZMQ_EVENT_DISCONNECTED) != 0)
        throw zmq::error_t();
      monitor->connect(address);
      dealer->connect(endpoint);
    } catch (const zmq::error_t& e) {
      throw LinkError("sync::ZmqNodeLink: cannot connect to " + endpoint + ": " + e.what());
    }
    lost = false;
  }

  void send(const std::string& bytes) {
    try {
      dealer->send(zmq::const_buffer(bytes.data(), bytes.size()), zmq::send_flags::dontwait);
    } catch (const zmq::error_t&) {
      // The connection is gone; the monitor says so at the next receive().
    }
  }

  /// The next message, or false at the deadline. Throws MasterLost.
  bool next(cluster::ToNode& out, LinkClock::time_point deadline) {
    while (true) {
      zmq::message_t msg;
      if (dealer->recv(msg, zmq::recv_flags::dontwait)) {
        std::string why;
        if (parseToNode(std::string_view(msg.data<char>(), msg.size()), out, why)) return true;
        throw MasterLost("sync::ZmqNodeLink: the peer at " + endpoint +
                         " is not a Tessera master: " + why);
      }
      zmq::pollitem_t mon{monitor->handle(), 0, ZMQ_POLLIN, 0};
      while (pollItems(&mon, 1, std::chrono::milliseconds(0)) > 0) {
        if (readMonitorEvent(*monitor)) {
          lost = true;
          throw MasterLost("sync::ZmqNodeLink: lost the master at " + endpoint +
                           " (connection closed, or no heartbeat for " +
                           std::to_string(options.heartbeat_timeout_ms) + " ms)");
        }
      }
      const auto left = until(deadline);
      if (left.count() == 0) return false;
      zmq::pollitem_t items[] = {{dealer->handle(), 0, ZMQ_POLLIN, 0},
                                 {monitor->handle(), 0, ZMQ_POLLIN, 0}};
      pollItems(items, 2, left);
    }
  }
};

ZmqNodeLink::ZmqNodeLink(const std::string& endpoint, const ZmqLinkOptions& options)
    : m(std::make_unique<Impl>()) {
  m->endpoint = endpoint;
  m->options = options;
  m->open();
  m->beat = std::thread([impl = m.get()] {
    std::unique_lock lock(impl->beat_mutex);
    while (!impl->stopping) {
      impl->beat_wake.wait_for(lock, std::chrono::milliseconds(100));
      if (!impl->beating || impl->stopping) continue;
      cluster::FromNode f;
      f.mutable_report()->set_frame(impl->beat_frame);
      f.mutable_report()->set_working(true);
      std::lock_guard socket(impl->socket_mutex);
      impl->send(envelope(f));
    }
  });
}

ZmqNodeLink::~ZmqNodeLink() {
  {
    std::lock_guard lock(m->beat_mutex);
    m->stopping = true;
  }
  m->beat_wake.notify_all();
  m->beat.join();
  stopMonitor(*m->dealer);
  m->monitor.reset();
  m->dealer.reset();
}

void ZmqNodeLink::working(uint64_t frame) {
  {
    std::lock_guard lock(m->beat_mutex);
    m->beating = true;
    m->beat_frame = frame;
  }
  m->beat_wake.notify_one();  // the first sign at once, then one every 100 ms
}

cluster::ClusterSetup ZmqNodeLink::join(const cluster::Hello& hello,
                                        LinkClock::time_point deadline) {
  std::lock_guard socket(m->socket_mutex);
  cluster::FromNode f;
  *f.mutable_hello() = hello;
  const std::string bytes = envelope(f);
  for (bool first = true;; first = false) {
    // A join after the first starts on a new connection: the old one may be closed under the
    // node's feet (a node stopped past the heartbeat timeout reads its queued "dropped" before
    // the close), and a hello on it would be answered twice. A hello unanswered for
    // kHelloRetry goes out again on a new connection too (the old one and what it still queues
    // are let go): a connection that does not come up costs one retry, not the whole wait.
    if (!first || m->lost || m->joined) m->open();
    m->joined = true;
    m->send(bytes);
    const auto retry = std::min(deadline, LinkClock::now() + kHelloRetry);
    cluster::ToNode t;
    while (m->next(t, retry)) {
      if (t.has_welcome()) return std::move(*t.mutable_welcome());
      if (t.has_refused()) throw JoinRefused(t.refused().reason());
      if (t.has_quit()) throw MasterLost("the master ended the session: " + t.quit().reason());
      // Anything else is from before this join (a frame, a swap, a ping): not ours any more.
    }
    if (LinkClock::now() >= deadline) break;
  }
  throw MasterLost("sync::ZmqNodeLink: no master answered at " + m->endpoint + " in time");
}

bool ZmqNodeLink::receive(cluster::ToNode& message, LinkClock::time_point deadline) {
  std::lock_guard socket(m->socket_mutex);
  while (m->next(message, deadline))
    if (!message.has_ping()) return true;
  return false;
}

bool ZmqNodeLink::pending() {
  std::lock_guard socket(m->socket_mutex);
  zmq::pollitem_t item{m->dealer->handle(), 0, ZMQ_POLLIN, 0};
  return pollItems(&item, 1, std::chrono::milliseconds(0)) > 0;
}

void ZmqNodeLink::report(const cluster::NodeReport& report) {
  {
    std::lock_guard lock(m->beat_mutex);
    m->beating = false;
  }
  std::lock_guard socket(m->socket_mutex);
  cluster::FromNode f;
  *f.mutable_report() = report;
  m->send(envelope(f));
}

}  // namespace tessera::sync
