#include "metis_pool.h"

#include <malloc.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace tessera::lod {
namespace {

/// One METIS call. The caller makes sure no other runs in this process meanwhile (the generator).
int callMetis(idx_t n, const idx_t* xadj, const idx_t* adjncy, const idx_t* vwgt,
              const idx_t* adjwgt, idx_t parts, idx_t seed, idx_t* part) {
  idx_t ncon = 1, objval = 0;
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_SEED] = seed;
  options[METIS_OPTION_NUMBERING] = 0;
  // METIS takes the graph by non-const pointers but, with 0-based numbering, only reads it.
  return METIS_PartGraphKway(&n, &ncon, const_cast<idx_t*>(xadj), const_cast<idx_t*>(adjncy),
                             const_cast<idx_t*>(vwgt), nullptr, const_cast<idx_t*>(adjwgt), &parts,
                             nullptr, nullptr, options, &objval, part);
}

/// A request's fixed part; xadj (n + 1), adjncy (edges), then vwgt (n) and adjwgt (edges) when
/// their bits are set in `weights` follow. The answer: METIS's return code (int64_t), then n part
/// ids. Both ends are the same binary, so idx_t and the byte order agree.
struct Request {
  int64_t n = 0, edges = 0, parts = 0, seed = 0, weights = 0;
};
constexpr int64_t kVertexWeights = 1, kEdgeWeights = 2;
constexpr int kClosed = -1;  ///< recvAll: the stream ended

/// Sends exactly `bytes` (through EINTR and short writes; MSG_NOSIGNAL: a closed peer is EPIPE,
/// not SIGPIPE). Returns 0 or the errno that stopped it.
int sendAll(int fd, const void* data, size_t bytes) {
  const auto* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const ssize_t sent = ::send(fd, p, std::min<size_t>(bytes, size_t(1) << 30), MSG_NOSIGNAL);
    if (sent < 0 && errno == EINTR) continue;
    if (sent <= 0) return sent < 0 ? errno : EPIPE;
    p += sent;
    bytes -= size_t(sent);
  }
  return 0;
}

/// Receives exactly `bytes` (through EINTR and short reads). Returns 0, kClosed when the stream
/// ended first, or the errno that stopped it.
int recvAll(int fd, void* data, size_t bytes) {
  auto* p = static_cast<char*>(data);
  while (bytes > 0) {
    const ssize_t got = ::recv(fd, p, std::min<size_t>(bytes, size_t(1) << 30), 0);
    if (got < 0 && errno == EINTR) continue;
    if (got == 0) return kClosed;
    if (got < 0) return errno;
    p += got;
    bytes -= size_t(got);
  }
  return 0;
}

template <class T>
size_t bytesOf(const std::vector<T>& v) {
  return v.size() * sizeof(T);
}

/// The worker's loop: a request, METIS, the answer, until the pool closes the socket. Never
/// returns: _exit, so the parent's atexit handlers and stdio buffers stay the parent's.
[[noreturn]] void serve(int fd) {
  int code = 0;
  try {
    std::vector<idx_t> xadj, adjncy, vwgt, adjwgt, part;
    for (;;) {
      Request q;
      const int got = recvAll(fd, &q, sizeof q);
      if (got == kClosed) break;
      if (got != 0 || q.n < 0 || q.edges < 0) {
        code = 1;
        break;
      }
      xadj.resize(size_t(q.n) + 1);
      adjncy.resize(size_t(q.edges));
      vwgt.resize(q.weights & kVertexWeights ? size_t(q.n) : 0);
      adjwgt.resize(q.weights & kEdgeWeights ? size_t(q.edges) : 0);
      if (recvAll(fd, xadj.data(), bytesOf(xadj)) || recvAll(fd, adjncy.data(), bytesOf(adjncy)) ||
          recvAll(fd, vwgt.data(), bytesOf(vwgt)) || recvAll(fd, adjwgt.data(), bytesOf(adjwgt))) {
        code = 1;
        break;
      }
      part.assign(size_t(q.n), 0);
      const int64_t rc = callMetis(
          idx_t(q.n), xadj.data(), adjncy.data(), vwgt.empty() ? nullptr : vwgt.data(),
          adjwgt.empty() ? nullptr : adjwgt.data(), idx_t(q.parts), idx_t(q.seed), part.data());
      if (sendAll(fd, &rc, sizeof rc) || sendAll(fd, part.data(), bytesOf(part))) {
        code = 1;
        break;
      }
    }
  } catch (...) {
    code = 2;  // out of memory: the pool sees the socket close
  }
  ::_exit(code);
}

/// The forked child: only its socket kept (a descriptor left open here would hold the parent's
/// files, pipes and the other workers' sockets open), the parent's signal handlers dropped.
[[noreturn]] void becomeWorker(int fd) {
  constexpr unsigned kFirst = 3;  // stdin, stdout, stderr stay
  if (unsigned(fd) > kFirst) ::close_range(kFirst, unsigned(fd) - 1, 0);
  ::close_range(std::max(unsigned(fd) + 1, kFirst), ~0u, 0);
  for (int s = 1; s < NSIG; ++s) {
    struct sigaction sa {};
    if (::sigaction(s, nullptr, &sa) == 0 && sa.sa_handler != SIG_DFL && sa.sa_handler != SIG_IGN)
      ::signal(s, SIG_DFL);
  }
  // The parent's free heap memory, given back: what the parent allocates from it next would
  // otherwise be copied on its first write and the old copy kept here (about 200 MB a worker in
  // the 17.8 M-triangle bench, whose heap held the subdivision's freed tables).
  ::malloc_trim(0);
  serve(fd);
}

std::string describe(int status) {
  if (WIFEXITED(status)) return "exited with status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status))
    return "killed by signal " + std::to_string(WTERMSIG(status)) + " (" +
           ::strsignal(WTERMSIG(status)) + ")";
  return "stopped (status " + std::to_string(status) + ")";
}

/// Reaps a worker and says how it ended. One whose socket closed is leaving: it gets 2 s, then
/// SIGKILL (at once with `now`), so this never hangs.
std::string reap(pid_t pid, bool now) {
  int status = 0;
  for (int waited_ms = 0; !now && waited_ms < 2000; ++waited_ms) {
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) return describe(status);
    if (r < 0 && errno != EINTR) return std::string("exit status unknown: ") + std::strerror(errno);
    ::usleep(1000);
  }
  ::kill(pid, SIGKILL);
  pid_t r;
  while ((r = ::waitpid(pid, &status, 0)) < 0 && errno == EINTR) {
  }
  if (r != pid) return std::string("exit status unknown: ") + std::strerror(errno);
  return describe(status);
}

}  // namespace

MetisPool::MetisPool(uint32_t workers) {
  mWorkers.reserve(workers);
  for (uint32_t i = 0; i < workers; ++i) {
    int sv[2];
    if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0) {
      std::fprintf(stderr, "lod::MetisPool: socketpair failed (%s): %zu partition workers\n",
                   std::strerror(errno), mWorkers.size());
      break;
    }
    const pid_t pid = ::fork();
    if (pid == 0) becomeWorker(sv[1]);
    const int fork_errno = errno;
    ::close(sv[1]);
    if (pid < 0) {
      ::close(sv[0]);
      std::fprintf(stderr, "lod::MetisPool: fork failed (%s): %zu partition workers\n",
                   std::strerror(fork_errno), mWorkers.size());
      break;
    }
    Worker& w = mWorkers.emplace_back();
    w.pid = pid;
    w.fd = sv[0];
  }
}

MetisPool::~MetisPool() {
  for (Worker& w : mWorkers)
    if (!w.dead) ::close(w.fd);  // the worker reads the end of its stream and leaves
  for (Worker& w : mWorkers)
    if (!w.dead) reap(w.pid, false);
}

std::vector<pid_t> MetisPool::pids() const {
  std::vector<pid_t> pids;
  for (const Worker& w : mWorkers) pids.push_back(w.pid);
  return pids;
}

int MetisPool::partGraphKway(const std::vector<idx_t>& xadj, const std::vector<idx_t>& adjncy,
                             const std::vector<idx_t>* vwgt, const std::vector<idx_t>* adjwgt,
                             idx_t parts, idx_t seed, std::vector<idx_t>& part) {
  assert(!xadj.empty() && size_t(xadj.back()) == adjncy.size());
  const idx_t n = idx_t(xadj.size()) - 1;
  assert(!vwgt || vwgt->size() == size_t(n));
  assert(!adjwgt || adjwgt->size() == adjncy.size());
  part.assign(size_t(n), 0);
  if (mWorkers.empty() || n < kInProcessBelow) {
    static std::mutex generator;  // this process's: one call at a time, across pools
    std::lock_guard lock(generator);
    return callMetis(n, xadj.data(), adjncy.data(), vwgt ? vwgt->data() : nullptr,
                     adjwgt ? adjwgt->data() : nullptr, parts, seed, part.data());
  }
  // The first free worker that lives; an exception once every worker died.
  size_t index = 0;
  {
    std::unique_lock lock(mMutex);
    const auto freeWorker = [&] {
      for (index = 0; index < mWorkers.size(); ++index)
        if (!mWorkers[index].busy && !mWorkers[index].dead) return true;
      return false;
    };
    const auto allDead = [&] {
      return std::all_of(mWorkers.begin(), mWorkers.end(), [](const Worker& w) { return w.dead; });
    };
    mFree.wait(lock, [&] { return freeWorker() || allDead(); });
    if (index == mWorkers.size())
      throw std::runtime_error("lod::MetisPool: every partition worker died; worker 0 (pid " +
                               std::to_string(mWorkers[0].pid) + ") " + mWorkers[0].fate);
    mWorkers[index].busy = true;
  }
  struct Release {  // the worker goes back, dead or alive, so that waiting callers look again
    MetisPool& pool;
    Worker& w;
    ~Release() {
      {
        std::lock_guard lock(pool.mMutex);
        w.busy = false;
      }
      pool.mFree.notify_all();  // all: once every worker died, every waiter must throw
    }
  } release{*this, mWorkers[index]};
  return remote(mWorkers[index], index, xadj, adjncy, vwgt, adjwgt, parts, seed, part);
}

int MetisPool::remote(Worker& w, size_t index, const std::vector<idx_t>& xadj,
                      const std::vector<idx_t>& adjncy, const std::vector<idx_t>* vwgt,
                      const std::vector<idx_t>* adjwgt, idx_t parts, idx_t seed,
                      std::vector<idx_t>& part) {
  const std::string who = "lod::MetisPool: partition worker " + std::to_string(index) + " (pid " +
                          std::to_string(w.pid) + ") ";
  Request q;
  q.n = int64_t(part.size());
  q.edges = int64_t(adjncy.size());
  q.parts = parts;
  q.seed = seed;
  q.weights = (vwgt ? kVertexWeights : 0) | (adjwgt ? kEdgeWeights : 0);
  int64_t rc = METIS_ERROR;
  int err = sendAll(w.fd, &q, sizeof q);
  if (!err) err = sendAll(w.fd, xadj.data(), bytesOf(xadj));
  if (!err) err = sendAll(w.fd, adjncy.data(), bytesOf(adjncy));
  if (!err && vwgt) err = sendAll(w.fd, vwgt->data(), bytesOf(*vwgt));
  if (!err && adjwgt) err = sendAll(w.fd, adjwgt->data(), bytesOf(*adjwgt));
  if (!err) err = recvAll(w.fd, &rc, sizeof rc);
  if (!err) err = recvAll(w.fd, part.data(), bytesOf(part));
  if (err) {
    // A worker whose socket closed is leaving by itself; one that failed otherwise is stopped.
    const bool closed = err == kClosed || err == EPIPE || err == ECONNRESET;
    ::close(w.fd);
    w.fd = -1;
    const std::string fate = (closed ? std::string("died during a call")
                                     : "failed: " + std::string(std::strerror(err))) +
                             " (" + reap(w.pid, !closed) + ")";
    {
      std::lock_guard lock(mMutex);  // waiting callers read it
      w.dead = true;
      w.fate = fate;
    }
    throw std::runtime_error(who + fate);
  }
  return int(rc);
}

}  // namespace tessera::lod
