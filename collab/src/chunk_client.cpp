#include <tessera/collab/chunk_client.h>

#include <fcntl.h>
#include <sys/eventfd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <stop_token>
#include <thread>
#include <unordered_map>

#include <zmq.hpp>

#include <tessera/collab/chunk_cache.h>
#include <tessera/collab/chunk_server.h>
#include <tessera/collab/site_messages.h>
#include <tessera/sync/zmq_poll.h>

namespace tessera::collab {

namespace fs = std::filesystem;

std::string chunkEndpointFor(const std::string& announced, const std::string& master) {
  if (announced.empty()) return "";
  auto host_of = [](const std::string& e, size_t& begin, size_t& end) {
    begin = e.find("://");
    begin = begin == std::string::npos ? 0 : begin + 3;
    end = e.rfind(':');
    if (end == std::string::npos || end < begin) end = e.size();
  };
  size_t b = 0, e = 0;
  host_of(announced, b, e);
  const std::string host = announced.substr(b, e - b);
  if (host != "*" && host != "0.0.0.0" && host != "::" && host != "[::]") return announced;
  size_t mb = 0, me = 0;
  host_of(master, mb, me);
  return announced.substr(0, b) + master.substr(mb, me - mb) + announced.substr(e);
}

namespace {

std::string hex(uint64_t v) {
  char s[17];
  std::snprintf(s, sizeof s, "%016llx", (unsigned long long)v);
  return s;
}

std::string rangeText(uint64_t offset, uint64_t n) {
  return "bytes " + std::to_string(offset) + ".." + std::to_string(offset + n);
}

/// A request waiting for its reply.
struct Pending {
  bool done = false;
  site::ChunkReply reply;
};

/// The socket, its network thread and the requests in flight, shared by the client and the
/// sources it opened (which may outlive it: their reads then fail at once).
struct Link {
  ChunkClientOptions opt;
  zmq::context_t context{1};
  zmq::socket_t socket{context, zmq::socket_type::dealer};
  int wake = -1;  // eventfd: a loader queued a request
  std::thread thread;
  std::atomic<bool> stop{false};

  mutable std::mutex mutex;  // guards everything below
  std::condition_variable answered;
  std::deque<std::string> outbox;
  std::unordered_map<uint64_t, Pending*> pending;
  uint64_t next_id = 1;
  ChunkClientCounters counters;
  std::string cache_problem;
  std::unique_ptr<ChunkCacheBudget> cache_budget;  // with a cache folder

  ~Link() {
    stop = true;
    if (thread.joinable()) thread.join();
    if (wake >= 0) ::close(wake);
  }

  void noteCacheProblem(const std::string& why) {
    std::lock_guard lock(mutex);
    ++counters.cache_errors;
    if (cache_problem.empty()) cache_problem = why;
  }

  /// Sends `request` and waits for its reply; once more after a timeout. When `cancel` is
  /// stopped first, withdraws it from the server (a cancel message) and throws
  /// lod::ReadCancelled. Any thread.
  site::ChunkReply call(site::ChunkRequest request, const std::string& what,
                        std::stop_token cancel = {}) {
    const auto timeout = std::chrono::duration<double>(opt.timeout_s);
    for (int attempt = 0; attempt < 2; ++attempt) {
      if (cancel.stop_requested()) throw lod::ReadCancelled("cancelled before it was sent");
      Pending p;
      // Wakes the wait below; declared before `lock`, so that it is destroyed after the mutex is
      // released (its destructor waits for a callback running on the cancelling thread).
      std::stop_callback wake_on_cancel(cancel, [this] {
        std::lock_guard woken(mutex);
        answered.notify_all();
      });
      std::unique_lock lock(mutex);
      const uint64_t id = next_id++;
      request.set_id(id);
      pending[id] = &p;
      outbox.push_back(request.SerializeAsString());
      ++counters.requests;
      if (attempt > 0) ++counters.retries;
      const uint64_t one = 1;
      (void)!::write(wake, &one, sizeof one);  // fails only when the counter is full: awake anyway
      const bool got = answered.wait_for(
          lock, timeout, [&] { return p.done || stop.load() || cancel.stop_requested(); });
      pending.erase(id);
      if (got && p.done) return std::move(p.reply);
      if (stop) throw lod::RangeError("the chunk client was closed");
      if (cancel.stop_requested()) {
        site::ChunkRequest withdraw;
        withdraw.add_cancel(id);
        outbox.push_back(withdraw.SerializeAsString());
        ++counters.cancelled;
        (void)!::write(wake, &one, sizeof one);
        throw lod::ReadCancelled("cancelled: " + what + " is no longer needed");
      }
    }
    char secs[32];
    std::snprintf(secs, sizeof secs, "%g", opt.timeout_s);
    throw lod::RangeError("no reply from the chunk server at " + opt.endpoint + " for " + what +
                          " within " + secs + " s, twice (is the master running with --chunks?)");
  }

  /// The network thread: sends what the loaders queued, hands replies to whoever waits.
  void run() {
    while (!stop.load()) {
      bool backlog = false;
      {
        std::deque<std::string> out;
        {
          std::lock_guard lock(mutex);
          out.swap(outbox);
        }
        while (!out.empty()) {
          // Never blocks: a DEALER without a connection would hold the thread (and stop()).
          if (!socket.send(zmq::buffer(out.front()), zmq::send_flags::dontwait)) break;
          out.pop_front();
        }
        if (!out.empty()) {
          std::lock_guard lock(mutex);
          outbox.insert(outbox.begin(), out.begin(), out.end());
          backlog = true;
        }
      }
      zmq::pollitem_t items[2] = {{socket.handle(), 0, ZMQ_POLLIN, 0},
                                  {nullptr, wake, ZMQ_POLLIN, 0}};
      sync::pollItems(items, 2, std::chrono::milliseconds(backlog ? 10 : 200));
      if (items[1].revents & ZMQ_POLLIN) {
        uint64_t v = 0;
        (void)!::read(wake, &v, sizeof v);
      }
      for (int budget = 1000; budget > 0; --budget) {
        zmq::message_t msg;
        if (!socket.recv(msg, zmq::recv_flags::dontwait)) break;
        site::ChunkReply r;
        if (msg.more() || !r.ParseFromArray(msg.data(), int(msg.size()))) continue;
        std::lock_guard lock(mutex);
        auto it = pending.find(r.id());
        if (it == pending.end()) continue;  // timed out meanwhile, or not ours
        if (r.kind_case() == site::ChunkReply::kData) counters.fetched_bytes += r.data().size();
        it->second->reply = std::move(r);
        it->second->done = true;
        answered.notify_all();
      }
    }
    std::lock_guard lock(mutex);
    answered.notify_all();
  }
};

/// The cached copy this thread's last read came from (empty: it came from the server), so that
/// refetch() drops the copy that read and not a good one another thread has written since: the
/// copy's generation, how many times this source had written that file when it was opened (a
/// file's inode number is no identity: a new file may take the one just freed).
struct CachedCopy {
  fs::path path;
  uint64_t generation = 0;
};
thread_local CachedCopy tLastCached;

/// One store's bytes: the disk cache, else the chunk server.
class RemoteRangeSource final : public lod::RangeSource {
 public:
  RemoteRangeSource(std::shared_ptr<Link> client, std::string path, uint64_t size, fs::path folder)
      : mClient(std::move(client)),
        mPath(std::move(path)),
        mSize(size),
        mFolder(std::move(folder)) {}

  uint64_t size() const override { return mSize; }
  std::string name() const override { return mPath; }

  bool refetch(uint64_t offset, size_t n) const override {
    const fs::path p = file(offset, n);
    if (mFolder.empty() || tLastCached.path != p) return false;  // it came from the server
    dropCopy(p, tLastCached.generation);
    tLastCached.path.clear();
    return true;
  }

 private:
  void readRange(uint64_t offset, void* dst, size_t n, std::stop_token cancel) const override {
    tLastCached.path.clear();
    if (readCached(offset, dst, n)) return;
    site::ChunkRequest q;
    q.set_store(mPath);
    q.set_offset(offset);
    q.set_length(uint32_t(n));
    if (n > kMaxChunkRangeBytes)
      throw lod::RangeError(rangeText(offset, n) + " of " + mPath + ": more than the " +
                            std::to_string(kMaxChunkRangeBytes) + " one request may ask for");
    site::ChunkReply r = mClient->call(q, rangeText(offset, n) + " of " + mPath, cancel);
    if (r.kind_case() == site::ChunkReply::kRefused)
      throw lod::RangeError("the chunk server refused " + rangeText(offset, n) + ": " +
                            r.refused());
    if (r.kind_case() != site::ChunkReply::kData || r.data().size() != n)
      throw lod::RangeError("the chunk server sent " + std::to_string(r.data().size()) +
                            " bytes for " + rangeText(offset, n));
    std::memcpy(dst, r.data().data(), n);
    writeCached(offset, r.data());
  }

  fs::path file(uint64_t offset, size_t n) const {
    return mFolder / (std::to_string(offset) + "+" + std::to_string(n));
  }

  bool readCached(uint64_t offset, void* dst, size_t n) const {
    if (mFolder.empty()) return false;
    const fs::path p = file(offset, n);
    int fd = -1;
    uint64_t generation = 0;
    {
      std::lock_guard files(mFiles);  // the file opened and its generation go together
      fd = ::open(p.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK);
      generation = generationOf(p);
    }
    if (fd < 0) return false;
    struct stat st {};
    bool ok = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && uint64_t(st.st_size) == n;
    for (size_t done = 0; ok && done < n;) {
      const ssize_t got = ::pread(fd, static_cast<uint8_t*>(dst) + done, n - done, off_t(done));
      if (got < 0 && errno == EINTR) continue;
      ok = got > 0;
      if (ok) done += size_t(got);
    }
    ::close(fd);
    if (!ok) {  // the wrong size or unreadable: fetched again and rewritten
      dropCopy(p, generation);
      return false;
    }
    mClient->cache_budget->used(p);
    tLastCached = {p, generation};
    std::lock_guard lock(mClient->mutex);
    ++mClient->counters.cache_hits;
    mClient->counters.cache_bytes += n;
    return true;
  }

  /// How many times this source has written the cached file `p` (0: a previous session's, or
  /// none). Caller holds mFiles.
  uint64_t generationOf(const fs::path& p) const {
    const auto it = mWritten.find(p.string());
    return it == mWritten.end() ? 0 : it->second;
  }

  /// Removes the cached copy `p` if it is still the copy of `generation` a read found broken,
  /// and counts it. Loader threads may read one broken copy at once (a patch, and its child's
  /// morph targets): the first drops it, and a good copy another thread has put in its place
  /// since is kept, so each broken copy counts once.
  void dropCopy(const fs::path& p, uint64_t generation) const {
    std::lock_guard files(mFiles);
    std::error_code ec;
    if (generationOf(p) != generation || !fs::remove(p, ec)) return;
    mClient->cache_budget->removed(p);
    std::lock_guard lock(mClient->mutex);
    ++mClient->counters.refetched;
  }

  void writeCached(uint64_t offset, const std::string& bytes) const {
    if (mFolder.empty()) return;
    static std::atomic<uint64_t> serial{0};
    const fs::path final_path = file(offset, bytes.size());
    const fs::path tmp = mFolder / (".tmp-" + std::to_string(::getpid()) + "-" +
                                    std::to_string(serial.fetch_add(1)));
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    bool ok = fd >= 0;
    for (size_t done = 0; ok && done < bytes.size();) {
      const ssize_t put = ::write(fd, bytes.data() + done, bytes.size() - done);
      if (put < 0 && errno == EINTR) continue;
      ok = put > 0;
      if (ok) done += size_t(put);
    }
    const int err = errno;
    if (fd >= 0 && ::close(fd) != 0) ok = false;
    std::error_code ec;
    if (ok) {
      std::lock_guard files(mFiles);    // never between dropCopy()'s look and its removal
      fs::rename(tmp, final_path, ec);  // atomic: a reader sees all of it or nothing
      if (!ec) ++mWritten[final_path.string()];
    }
    if (ok && !ec) mClient->cache_budget->added(final_path, bytes.size());
    if (!ok || ec) {
      fs::remove(tmp, ec);
      mClient->noteCacheProblem("cannot write " + final_path.string() + ": " +
                                (ok ? ec.message() : std::string(std::strerror(err))));
    }
  }

  std::shared_ptr<Link> mClient;
  std::string mPath;
  uint64_t mSize;
  fs::path mFolder;           // empty: no disk cache
  mutable std::mutex mFiles;  // dropCopy() against writeCached()'s rename
  mutable std::unordered_map<std::string, uint64_t> mWritten;  // generations, under mFiles
};

}  // namespace

struct ChunkClient::Impl : Link {};

ChunkClient::ChunkClient(ChunkClientOptions options) : m(std::make_shared<Impl>()) {
  m->opt = std::move(options);
  curveClient(m->socket, m->opt.keys, m->opt.master_key);
  m->socket.set(zmq::sockopt::linger, 0);
  m->socket.set(zmq::sockopt::sndhwm, 10000);
  m->socket.set(zmq::sockopt::rcvhwm, 10000);
  m->socket.set(zmq::sockopt::heartbeat_ivl, 1000);
  m->socket.set(zmq::sockopt::heartbeat_timeout, 5000);
  m->socket.set(zmq::sockopt::maxmsgsize, int64_t(kMaxChunkRangeBytes) + 4096);
  try {
    m->socket.connect(m->opt.endpoint);
  } catch (const zmq::error_t& e) {
    throw lod::RangeError("chunk server " + m->opt.endpoint +
                          ": not a ZeroMQ endpoint: " + e.what());
  }
  if (!m->opt.cache_dir.empty())
    m->cache_budget =
        std::make_unique<ChunkCacheBudget>(m->opt.cache_dir, m->opt.cache_limit_bytes);
  m->wake = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (m->wake < 0) throw lod::RangeError(std::string("eventfd: ") + std::strerror(errno));
  m->thread = std::thread([impl = m.get()] { impl->run(); });
}

ChunkClient::~ChunkClient() {
  m->stop = true;
  if (m->thread.joinable()) m->thread.join();
}

std::unique_ptr<lod::RangeSource> ChunkClient::open(const std::string& path) {
  site::ChunkRequest q;
  q.set_store(path);
  q.set_length(0);
  site::ChunkReply r = m->call(q, "the size of " + path);
  if (r.kind_case() == site::ChunkReply::kRefused)
    throw lod::RangeError("the chunk server refused it: " + r.refused());
  if (r.kind_case() != site::ChunkReply::kInfo || r.info().size() == 0)
    throw lod::RangeError("the chunk server's answer for it is not a store's size");
  fs::path folder;
  if (!m->opt.cache_dir.empty()) {
    // The folder names the store's path and identity: a rebuilt store gets a fresh one.
    const uint64_t name_hash = storeIdentity(0, path.data(), path.size());
    folder = fs::path(m->opt.cache_dir) / (hex(name_hash) + "-" + hex(r.info().identity()) + "-" +
                                           std::to_string(r.info().size()));
    std::error_code ec;
    fs::create_directories(folder, ec);
    if (ec || !fs::is_directory(folder)) {
      m->noteCacheProblem("--cache " + m->opt.cache_dir + ": cannot make " + folder.string() +
                          ": " + (ec ? ec.message() : "not a folder"));
      folder.clear();
    } else if (!fs::exists(folder / "store.txt")) {
      std::ofstream(folder / "store.txt") << path << "\n" << r.info().size() << " bytes\n";
    }
  }
  return std::make_unique<RemoteRangeSource>(m, path, r.info().size(), folder);
}

ChunkClientCounters ChunkClient::counters() const {
  std::lock_guard lock(m->mutex);
  ChunkClientCounters c = m->counters;
  if (m->cache_budget) {
    c.cache_evicted_files = m->cache_budget->evictedFiles();
    c.cache_evicted_bytes = m->cache_budget->evictedBytes();
  }
  return c;
}

std::string ChunkClient::cacheProblem() const {
  std::lock_guard lock(m->mutex);
  return m->cache_problem;
}

}  // namespace tessera::collab
