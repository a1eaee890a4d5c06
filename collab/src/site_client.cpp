#include <tessera/collab/site_client.h>

#include <zmq.hpp>

#include <tessera/sync/cluster_link.h>
#include <tessera/sync/wire.h>
#include <tessera/sync/zmq_poll.h>

namespace tessera::collab {

using Why = SiteSessionEnded::Why;

struct SiteClient::Impl {
  SiteClientOptions opt;
  zmq::context_t context{1};
  zmq::socket_t socket{context, zmq::socket_type::dealer};
  Clock::time_point last_heard = Clock::now();
  uint64_t sent = 0, received = 0;

  /// The next message until `deadline`, or nothing.
  std::optional<site::ToSite> next(Clock::time_point deadline) {
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now());
    zmq::pollitem_t item{socket.handle(), 0, ZMQ_POLLIN, 0};
    if (sync::pollItems(
            &item, 1, std::max<std::chrono::milliseconds>(left, std::chrono::milliseconds(0))) <= 0)
      return std::nullopt;
    zmq::message_t msg;
    if (!socket.recv(msg, zmq::recv_flags::dontwait)) return std::nullopt;
    received += msg.size();
    last_heard = Clock::now();
    site::ToSite m;
    if (msg.more() || !m.ParseFromArray(msg.data(), int(msg.size())))
      throw SiteSessionEnded(Why::kBadMessage, "collab::SiteClient: " + std::to_string(msg.size()) +
                                                   " bytes from the master are not a site message");
    return m;
  }
};

SiteClient::SiteClient(SiteClientOptions options) : m(std::make_unique<Impl>()) {
  m->opt = std::move(options);
  curveClient(m->socket, m->opt.keys, m->opt.master_key);
  m->socket.set(zmq::sockopt::linger, 500);
  m->socket.set(zmq::sockopt::sndhwm, 1000);
  m->socket.set(zmq::sockopt::heartbeat_ivl, 1000);
  m->socket.set(zmq::sockopt::heartbeat_timeout, 5000);
  // A snapshot of a big scene: at most 256 MB from a master we trust.
  m->socket.set(zmq::sockopt::maxmsgsize, int64_t(256) << 20);
  try {
    m->socket.connect(m->opt.master);
  } catch (const zmq::error_t& e) {
    throw SiteSessionEnded(Why::kMasterLost,
                           "--master " + m->opt.master + ": not a ZeroMQ endpoint: " + e.what());
  }
}

SiteClient::~SiteClient() = default;

site::SiteWelcome SiteClient::join(sync::SceneGraph& graph, Clock::time_point deadline) {
  site::ToMaster hello;
  hello.mutable_hello()->set_protocol(sync::kProtocolVersion);
  hello.mutable_hello()->set_name(m->opt.name);
  send(hello);
  while (true) {
    std::optional<site::ToSite> reply = m->next(deadline);
    if (!reply)
      throw SiteSessionEnded(Why::kMasterLost,
                             "no welcome from the master at " + m->opt.master +
                                 " (not running, another server key, or this site's key is not "
                                 "on its allow list)");
    switch (reply->kind_case()) {
      case site::ToSite::kWelcome: {
        try {
          graph = sync::SceneGraph();
          graph.apply(sync::parseSnapshot(reply->welcome().snapshot()));
        } catch (const sync::SyncError& e) {
          throw SiteSessionEnded(Why::kBadMessage,
                                 std::string("the welcome's snapshot: ") + e.what());
        }
        return reply->welcome();
      }
      case site::ToSite::kRefused:
        throw SiteSessionEnded(Why::kRefused,
                               "the master refused this site: " + reply->refused().reason());
      case site::ToSite::kDropped:
        throw SiteSessionEnded(Why::kDropped,
                               "dropped by the master: " + reply->dropped().reason());
      case site::ToSite::kQuit:
        throw SiteSessionEnded(Why::kQuit,
                               "the master ended the session (" + reply->quit().reason() + ")");
      default:
        break;  // frames of an earlier session on this connection
    }
  }
}

sync::SceneChanges SiteClient::receive(sync::SceneGraph& graph, Clock::time_point deadline) {
  sync::SceneChanges all;
  auto merge = [&](const sync::SceneChanges& c) {
    all.everything |= c.everything;
    all.camera |= c.camera;
    all.settings |= c.settings;
    all.nodes.insert(all.nodes.end(), c.nodes.begin(), c.nodes.end());
  };
  for (bool first = true;; first = false) {
    std::optional<site::ToSite> msg = m->next(first ? deadline : Clock::now());
    if (!msg) break;
    try {
      switch (msg->kind_case()) {
        case site::ToSite::kFrame:
          merge(graph.apply(sync::parseFrame(msg->frame())));
          break;
        case site::ToSite::kSnapshot: {
          sync::SceneGraph fresh;
          fresh.apply(sync::parseSnapshot(msg->snapshot()));
          graph = std::move(fresh);
          merge(sync::SceneChanges::all());
          break;
        }
        case site::ToSite::kDropped:
          throw SiteSessionEnded(Why::kDropped,
                                 "dropped by the master: " + msg->dropped().reason());
        case site::ToSite::kQuit:
          throw SiteSessionEnded(Why::kQuit,
                                 "the master ended the session (" + msg->quit().reason() + ")");
        case site::ToSite::kVoice:
          if (m->opt.voice) m->opt.voice(msg->voice());
          break;
        case site::ToSite::kVideo:
          if (m->opt.video) m->opt.video(msg->video());
          break;
        case site::ToSite::kNote:
          if (m->opt.note) m->opt.note(msg->note());
          break;
        case site::ToSite::kRefused:
          throw SiteSessionEnded(Why::kRefused, "refused: " + msg->refused().reason());
        default:
          break;
      }
    } catch (const sync::SyncError& e) {
      throw SiteSessionEnded(Why::kBadMessage, std::string("a frame from the master: ") + e.what());
    }
  }
  if (Clock::now() - m->last_heard > std::chrono::duration<double>(m->opt.master_timeout_s))
    throw SiteSessionEnded(
        Why::kMasterLost,
        "no frame from the master for " + std::to_string(int(m->opt.master_timeout_s)) + " s");
  std::sort(all.nodes.begin(), all.nodes.end());
  all.nodes.erase(std::unique(all.nodes.begin(), all.nodes.end()), all.nodes.end());
  return all;
}

void SiteClient::send(const site::ToMaster& message) {
  const std::string bytes = message.SerializeAsString();
  if (m->socket.send(zmq::buffer(bytes), zmq::send_flags::dontwait)) m->sent += bytes.size();
}

uint64_t SiteClient::bytesSent() const {
  return m->sent;
}
uint64_t SiteClient::bytesReceived() const {
  return m->received;
}

}  // namespace tessera::collab
