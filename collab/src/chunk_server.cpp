#include <tessera/collab/chunk_server.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include <zmq.hpp>

#include <tessera/collab/curve.h>
#include <tessera/collab/site_messages.h>
#include <tessera/lod/range_source.h>
#include <tessera/lod/store_cache.h>
#include <tessera/render/scene_draw_list.h>
#include <tessera/sync/zmq_poll.h>

#include "server_socket.h"
#include "token_bucket.h"

namespace tessera::collab {

uint64_t storeIdentity(uint64_t size, const void* head, size_t head_bytes) {
  uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a, 64 bit
  auto mix = [&](uint8_t b) {
    h ^= b;
    h *= 0x100000001b3ull;
  };
  for (int i = 0; i < 8; ++i) mix(uint8_t(size >> (8 * i)));
  for (size_t i = 0; i < head_bytes; ++i) mix(static_cast<const uint8_t*>(head)[i]);
  return h;
}

namespace {

using Clock = std::chrono::steady_clock;

double seconds() {
  return std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
}

/// A request waiting for its site's bandwidth.
struct Waiting {
  std::string rid;  // the connection it came on
  site::ChunkRequest request;
};

/// A site, by its CURVE key: reconnecting does not give it a fresh bucket.
struct Site {
  TokenBucket bytes, requests;
  std::deque<Waiting> waiting;
  double last_seen = 0;
  double blocked_until = 0;  // its connection's queue was full: try again then
};

/// An open store of the scene.
struct Store {
  std::unique_ptr<lod::FileRangeSource> source;
  uint64_t identity = 0;
};

}  // namespace

struct ChunkServer::Impl {
  ChunkServerOptions opt;
  zmq::socket_t socket;
  std::string endpoint;  // as bound (the socket is the server thread's once it runs)
  std::thread thread;
  std::atomic<bool> stop{false};

  mutable std::mutex mutex;  // guards `named`, `generation` and `counters`
  std::set<std::string> named;
  uint64_t generation = 0;
  ChunkServerCounters counters;

  // The server thread's own.
  std::set<std::string> served;
  uint64_t served_generation = ~0ull;
  std::map<std::string, Store> stores;
  std::map<std::string, Site> sites;
  TokenBucket total;        // all sites together (opt.total_bytes_per_s > 0)
  std::string last_served;  // the site served last: the next round starts after it
  double last_said = 0;
  uint64_t unsaid = 0;

  void say(const std::string& text) {
    // At most a line a second: a site sending garbage must not fill the master's log.
    const double now = seconds();
    if (now - last_said < 1.0) {
      ++unsaid;
      return;
    }
    last_said = now;
    std::printf("tessera-master: chunks: %s%s\n", text.c_str(),
                unsaid ? (" (and " + std::to_string(unsaid) + " more)").c_str() : "");
    std::fflush(stdout);
    unsaid = 0;
  }

  void count(uint64_t ChunkServerCounters::*field, uint64_t n = 1) {
    std::lock_guard lock(mutex);
    counters.*field += n;
  }

  /// Sends a reply on connection `rid`: 1 sent, 0 its queue is full, -1 it is gone.
  int send(const std::string& rid, const site::ChunkReply& reply) {
    const std::string bytes = reply.SerializeAsString();
    try {
      if (!socket.send(zmq::buffer(rid), zmq::send_flags::sndmore | zmq::send_flags::dontwait))
        return 0;
      socket.send(zmq::buffer(bytes), zmq::send_flags::dontwait);
      return 1;
    } catch (const zmq::error_t& e) {
      if (e.num() == EHOSTUNREACH) return -1;
      throw;
    }
  }

  void refuse(const std::string& rid, const std::string& key, uint64_t id, const std::string& why) {
    site::ChunkReply r;
    r.set_id(id);
    r.set_refused(why);
    send(rid, r);
    count(&ChunkServerCounters::refused);
    say("refused a request of key " + key.substr(0, 8) + ": " + why);
  }

  void syncStores() {
    std::lock_guard lock(mutex);
    if (served_generation == generation) return;
    served_generation = generation;
    served = named;
    std::erase_if(stores, [&](const auto& s) { return !served.count(s.first); });
  }

  /// The scene's store `path`, opened on first use; null with `why` when it cannot be.
  Store* store(const std::string& path, std::string& why) {
    if (!served.count(path)) {
      why = "store " + path + " is not in the scene (only the stores its models name are served)";
      return nullptr;
    }
    auto it = stores.find(path);
    if (it != stores.end()) return &it->second;
    try {
      // A see-through mesh's points (SceneDrawList::storeKey(): MESH#points) are the store its
      // host sampled from the mesh into the store cache: served once the master has made it.
      std::string file = path;
      if (const auto mesh = render::SceneDrawList::meshOfPointsKey(path)) {
        file = lod::cachedStorePath(*mesh, "chunk server").string();
        std::error_code ec;
        if (!std::filesystem::is_regular_file(file, ec)) {
          why = "store " + path + ": the mesh's see-through points are not made on the master yet";
          return nullptr;
        }
      }
      Store s;
      s.source = std::make_unique<lod::FileRangeSource>(file);
      std::string head(std::min<uint64_t>(s.source->size(), kIdentityHeadBytes), '\0');
      s.source->read(0, head.data(), head.size());
      s.identity = storeIdentity(s.source->size(), head.data(), head.size());
      return &stores.emplace(path, std::move(s)).first->second;
    } catch (const std::runtime_error& e) {  // lod::RangeError; the cache's folder
      why = "store " + path + " on the master: " + e.what();
      return nullptr;
    }
  }

  /// One message from the socket (routing id, then the request).
  void receive(double now) {
    zmq::message_t id, payload;
    if (!socket.recv(id, zmq::recv_flags::dontwait)) return;
    if (!id.more()) return;
    (void)socket.recv(payload, zmq::recv_flags::dontwait);
    bool multipart = false;
    for (bool more = payload.more(); more;) {
      zmq::message_t rest;
      if (!socket.recv(rest, zmq::recv_flags::dontwait)) break;
      more = rest.more();
      multipart = true;
    }
    const std::string rid = id.to_string();
    const char* user = payload.gets("User-Id");
    const std::string key = user ? user : "";
    count(&ChunkServerCounters::requests);
    auto [it, fresh] = sites.try_emplace(key);
    Site& s = it->second;
    if (fresh) {
      s.bytes.start(opt.bytes_per_s, opt.burst_s, now);
      s.requests.start(opt.requests_per_s, opt.requests_burst_s, now);
    }
    s.last_seen = now;
    if (!s.requests.take(1.0, now)) {
      count(&ChunkServerCounters::discarded);
      say("key " + key.substr(0, 8) + " sends more than " +
          std::to_string(int(opt.requests_per_s)) + " requests a second: the excess is discarded");
      return;
    }
    site::ChunkRequest r;
    if (multipart) return refuse(rid, key, 0, "chunk request: more than one part");
    if (auto why = parseChunkRequest(
            std::string_view(static_cast<const char*>(payload.data()), payload.size()), r))
      return refuse(rid, key, r.id(), *why);
    if (r.cancel_size() > 0) {  // withdrawn by the site: dropped unanswered if still waiting
      const std::set<uint64_t> ids(r.cancel().begin(), r.cancel().end());
      const size_t dropped = std::erase_if(s.waiting, [&](const Waiting& w) {
        return w.rid == rid && ids.count(w.request.id()) != 0;
      });
      count(&ChunkServerCounters::cancelled, dropped);
      return;
    }
    std::string why;
    Store* st = store(r.store(), why);
    if (!st) return refuse(rid, key, r.id(), why);
    if (r.length() == 0) {
      site::ChunkReply reply;
      reply.set_id(r.id());
      reply.mutable_info()->set_size(st->source->size());
      reply.mutable_info()->set_identity(st->identity);
      send(rid, reply);
      count(&ChunkServerCounters::replies);
      return;
    }
    if (auto outside = checkChunkRange(r, st->source->size()))
      return refuse(rid, key, r.id(), *outside);
    if (s.waiting.size() >= opt.queue_per_site)
      return refuse(rid, key, r.id(),
                    "too many requests waiting (" + std::to_string(opt.queue_per_site) +
                        "): wait for replies");
    s.waiting.push_back({rid, std::move(r)});
  }

  /// Sends the replies the sites' buckets allow, one per site in turn. Returns the seconds
  /// until the next one may go (at most `idle`).
  double serve(double idle) {
    double next = idle;
    const bool capped = opt.total_bytes_per_s > 0;
    for (bool sent = true; sent;) {
      sent = false;
      const double now = seconds();
      // In turn from the site after the one served last, so that under the cap on all sites
      // together the first sites in key order do not take every reply the cap allows.
      std::vector<std::map<std::string, Site>::iterator> order;
      for (auto it = sites.upper_bound(last_served); it != sites.end(); ++it) order.push_back(it);
      for (auto it = sites.begin(); it != sites.end() && it->first <= last_served; ++it)
        order.push_back(it);
      for (auto site : order) {
        const std::string& key = site->first;
        Site& s = site->second;
        if (s.waiting.empty()) continue;
        if (capped) {
          const double all = total.wait(now);
          if (all > 0) {
            next = std::min(next, all);
            break;
          }
        }
        if (now < s.blocked_until) {
          next = std::min(next, s.blocked_until - now);
          continue;
        }
        const double wait = s.bytes.wait(now);
        if (wait > 0) {
          next = std::min(next, wait);
          continue;
        }
        Waiting w = std::move(s.waiting.front());
        s.waiting.pop_front();
        site::ChunkReply reply;
        reply.set_id(w.request.id());
        std::string why;
        Store* st = store(w.request.store(), why);  // the scene may have dropped it meanwhile
        if (!st) {
          refuse(w.rid, key, w.request.id(), why);
          continue;
        }
        std::string* data = reply.mutable_data();
        data->resize(w.request.length());
        try {
          st->source->read(w.request.offset(), data->data(), data->size());
        } catch (const lod::RangeError& e) {
          refuse(w.rid, key, w.request.id(),
                 "reading " + w.request.store() + " on the master failed: " + e.what());
          continue;
        }
        const int r = send(w.rid, reply);
        if (r == 0) {  // its connection's queue is full: the site reads slower than its rate
          s.waiting.push_front(std::move(w));
          s.blocked_until = now + 0.005;
          next = std::min(next, 0.005);
          continue;
        }
        if (r < 0) {  // gone: nobody reads the rest of its requests on that connection
          std::erase_if(s.waiting, [&](const Waiting& x) { return x.rid == w.rid; });
          continue;
        }
        s.bytes.take(double(w.request.length()), now);
        if (capped) total.take(double(w.request.length()), now);
        last_served = key;
        count(&ChunkServerCounters::replies);
        count(&ChunkServerCounters::bytes_out, w.request.length());
        sent = true;
      }
    }
    // Sites idle for ten minutes are forgotten (their buckets full again by then anyway).
    const double now = seconds();
    std::erase_if(sites, [&](const auto& s) {
      return s.second.waiting.empty() && now - s.second.last_seen > 600.0;
    });
    return next;
  }

  void run() {
    while (!stop.load()) {
      syncStores();
      const double wait = serve(0.1);
      zmq::pollitem_t item{socket.handle(), 0, ZMQ_POLLIN, 0};
      if (sync::pollItems(&item, 1, std::chrono::milliseconds(int64_t(std::ceil(wait * 1000)))) >
          0) {
        syncStores();  // the scene's stores as of now: a site welcomed meanwhile may ask at once
        const double now = seconds();
        for (int budget = 1000; budget > 0 && (socket.get(zmq::sockopt::events) & ZMQ_POLLIN);
             --budget)
          receive(now);
      }
    }
  }
};

ChunkServer::ChunkServer(zmq::context_t& context, const KeyPair& keys, ChunkServerOptions options)
    : m(std::make_unique<Impl>()) {
  m->opt = std::move(options);
  if (m->opt.total_bytes_per_s > 0)
    m->total.start(m->opt.total_bytes_per_s, m->opt.burst_s, seconds());
  m->socket = bindSiteServer(context, keys, m->opt.endpoint, 64, int64_t(kMaxChunkRequestBytes),
                             "collab::ChunkServer");
  m->endpoint = m->socket.get(zmq::sockopt::last_endpoint);
  m->thread = std::thread([this] { m->run(); });
}

ChunkServer::~ChunkServer() {
  m->stop = true;
  if (m->thread.joinable()) m->thread.join();
  m->socket.close();
}

std::string ChunkServer::endpoint() const {
  return m->endpoint;
}

void ChunkServer::setStores(std::vector<std::string> paths) {
  std::set<std::string> named(paths.begin(), paths.end());
  std::lock_guard lock(m->mutex);
  if (named == m->named) return;
  m->named = std::move(named);
  ++m->generation;
}

ChunkServerCounters ChunkServer::counters() const {
  std::lock_guard lock(m->mutex);
  return m->counters;
}

}  // namespace tessera::collab
