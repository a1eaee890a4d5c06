// The master's CURVE ROUTER sockets for sites (the site hub's, the chunk server's): the same
// options, bound to an endpoint.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

#include <zmq.hpp>

#include <tessera/collab/curve.h>

namespace tessera::collab {

/// A CURVE server ROUTER in `context` (whose ZapHandler admits the sites), bound to
/// `endpoint`: unroutable sends fail (EHOSTUNREACH), `send_queue` messages per peer, messages
/// over `max_message_bytes` close their connection in libzmq, heartbeats notice a dead link in
/// 5 s. Throws std::runtime_error "COMPONENT: cannot listen on ENDPOINT: why".
inline zmq::socket_t bindSiteServer(zmq::context_t& context, const KeyPair& keys,
                                    const std::string& endpoint, int send_queue,
                                    int64_t max_message_bytes, const std::string& component) {
  zmq::socket_t socket(context, zmq::socket_type::router);
  curveServer(socket, keys);
  socket.set(zmq::sockopt::router_mandatory, 1);
  socket.set(zmq::sockopt::sndhwm, send_queue);
  socket.set(zmq::sockopt::rcvhwm, 10000);
  socket.set(zmq::sockopt::maxmsgsize, max_message_bytes);
  socket.set(zmq::sockopt::heartbeat_ivl, 1000);
  socket.set(zmq::sockopt::heartbeat_timeout, 5000);
  socket.set(zmq::sockopt::linger, 0);
  try {
    socket.bind(endpoint);
  } catch (const zmq::error_t& e) {
    throw std::runtime_error(component + ": cannot listen on " + endpoint + ": " + e.what());
  }
  return socket;
}

}  // namespace tessera::collab
