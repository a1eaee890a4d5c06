// zmq::poll that a stop signal cannot end. A process stopped (SIGSTOP, a debugger, a laptop lid)
// and continued gets EINTR from poll() even without a signal handler, which cppzmq throws as
// zmq::error_t: a continued node, master or site would die of it. Here nothing is ready then,
// and the callers' loops recompute their deadlines and poll again.
#pragma once

#include <zmq.hpp>

#include <cerrno>
#include <chrono>

namespace tessera::sync {

inline int pollItems(zmq::pollitem_t* items, size_t n, std::chrono::milliseconds timeout) {
  try {
    return zmq::poll(items, n, timeout);
  } catch (const zmq::error_t& e) {
    if (e.num() == EINTR) return 0;
    throw;
  }
}

}  // namespace tessera::sync
