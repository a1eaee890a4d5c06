#include <tessera/render/chunk_streamer.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <glm/gtc/packing.hpp>

#include <tessera/render/point_pass.h>
#include <tessera/render/spbr.h>

namespace tessera::render {
namespace {

struct Key {
  const lod::PointStore* store;
  lod::NodeId node;
  bool operator==(const Key&) const = default;
};

struct KeyHash {
  size_t operator()(const Key& k) const {
    return std::hash<const void*>{}(k.store) ^ (size_t(k.node) * 0x9E3779B97F4A7C15ull);
  }
};

struct Item {
  lod::PointStore* store;
  lod::NodeId node;
  bool page;  ///< a hierarchy page (the node's children), not a chunk
  uint8_t level;
  double distance;
};

/// Loader order: hierarchy pages first (they unlock refinement), then coarse, then near.
bool before(const Item& a, const Item& b) {
  if (a.page != b.page) return a.page;
  if (a.level != b.level) return a.level < b.level;
  return a.distance < b.distance;
}

struct Loaded {
  Key key;
  uint32_t disk_bytes = 0;
  double spacing = 0.0, density = 0.0;
  std::vector<uint32_t> normals;
  std::vector<float> ratios;
  std::vector<glm::uvec2> cells;  ///< SurfaceCell as half floats: (dx, dy), (dz, weight)
  bool page = false;
  bool failed = false;
  glm::dvec3 offset{0.0};
  std::vector<GpuPoint> points;
};

/// GPU bytes a resident chunk holds.
uint64_t residentBytes(const GpuChunk& c) {
  return c.buffer.bytes() + c.normals.bytes() + c.density_ratios.bytes() + c.cells.bytes();
}

}  // namespace

struct ChunkStreamer::Impl {
  StreamerOptions options;
  uint32_t grey = 0;

  // Shared with the loader thread, under `mutex`.
  std::mutex mutex;
  std::condition_variable wake;  ///< loader: work or stop
  std::condition_variable idle;  ///< waiters: the loader finished an item
  std::vector<Item> queue;
  size_t next = 0;
  const lod::PointStore* busy = nullptr;  ///< store of the item in flight
  Key busy_key{nullptr, lod::kNoNode};    ///< the chunk in flight (not queued again)
  std::vector<Loaded> done;
  std::unordered_set<Key, KeyHash> done_keys;  ///< in `done`: not to be queued again
  bool paused = false, stop = false;

  // GL thread only.
  uint64_t frame = 0;
  std::unordered_map<Key, GpuChunk, KeyHash> resident;
  uint64_t resident_bytes = 0, resident_disk_bytes = 0;
  std::unordered_set<Key, KeyHash> failed;
  std::unordered_set<Key, KeyHash> failed_pages;
  std::vector<Item> wanted;  ///< this frame's requests
  std::unordered_set<Key, KeyHash> wanted_keys, wanted_pages;

  std::thread loader;

  void run() {
    for (;;) {
      std::unique_lock lock(mutex);
      wake.wait(lock, [&] { return stop || (!paused && next < queue.size()); });
      if (stop) return;
      const Item item = queue[next++];
      busy = item.store;
      busy_key = item.page ? Key{nullptr, lod::kNoNode} : Key{item.store, item.node};
      lock.unlock();
      Loaded out;
      out.key = {item.store, item.node};
      out.page = item.page;
      if (item.page) {
        try {
          item.store->children(item.node);
        } catch (const lod::StoreError&) {
          out.failed = true;
        }
      } else {
        try {
          auto chunk = item.store->decodeChunk(item.node);
          out.disk_bytes = item.store->chunkBytes(item.node);
          out.spacing = item.store->node(item.node).spacing;
          // Spheres four spacings wide hold about 50 points of a surface.
          out.density = sphereDensity(chunk->positions, 4.0 * out.spacing, 128, item.node, 16384);
          if (options.normals) out.normals = estimateNormals(chunk->positions, 2.5 * out.spacing);
          if (options.density_ratios) {
            const lod::NodeInfo info = item.store->node(item.node);
            out.ratios = densityRatios(chunk->positions, 4.0 * out.spacing, glm::vec3(0.0f),
                                       glm::vec3(info.box_max - info.box_min), out.density);
          }
          if (options.surface_cells) {
            // Six spacings hold ~28 neighbours: enough to close almost every cell.
            const std::vector<SurfaceCell> cells =
                surfaceCells(chunk->positions, 6.0 * out.spacing, out.density);
            out.cells.resize(cells.size());
            for (size_t i = 0; i < cells.size(); ++i) {
              const SurfaceCell& c = cells[i];
              out.cells[i] = {glm::packHalf2x16(glm::vec2(c.offset.x, c.offset.y)),
                              glm::packHalf2x16(glm::vec2(c.offset.z, c.weight))};
            }
          }
          out.offset = chunk->offset;
          out.points.resize(chunk->size());
          const bool color = !chunk->colors.empty();
          for (size_t i = 0; i < chunk->size(); ++i) {
            uint32_t rgb = grey;
            if (color) {
              const glm::u8vec4 c = chunk->colors[i];
              rgb = uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16;
            }
            out.points[i] = {chunk->positions[i], rgb};
          }
        } catch (const lod::StoreError&) {
          out.failed = true;  // corrupt chunk: never drawn as garbage, never retried
        }
      }
      lock.lock();
      busy = nullptr;
      busy_key = Key{nullptr, lod::kNoNode};
      if (!item.page || out.failed) {
        if (!item.page) done_keys.insert(out.key);
        done.push_back(std::move(out));
      }
      idle.notify_all();
    }
  }
};

ChunkStreamer::ChunkStreamer(const StreamerOptions& options) : mImpl(std::make_unique<Impl>()) {
  mImpl->options = options;
  mImpl->grey = uint32_t(options.default_color.r) | uint32_t(options.default_color.g) << 8 |
                uint32_t(options.default_color.b) << 16;
  mStats.budget_bytes = options.budget_bytes;
  mImpl->loader = std::thread([impl = mImpl.get()] { impl->run(); });
}

ChunkStreamer::~ChunkStreamer() {
  {
    std::lock_guard lock(mImpl->mutex);
    mImpl->stop = true;
  }
  mImpl->wake.notify_all();
  mImpl->loader.join();
}

void ChunkStreamer::beginFrame() {
  Impl& s = *mImpl;
  const uint64_t frame = ++s.frame;
  mStats = StreamStats{};
  mStats.budget_bytes = s.options.budget_bytes;
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<Loaded> done;
  {
    std::lock_guard lock(s.mutex);
    done.swap(s.done);
    s.done_keys.clear();
  }
  for (Loaded& l : done) {
    if (l.failed) {
      if (l.page) {
        s.failed_pages.insert(l.key);
      } else {
        s.failed.insert(l.key);
        ++mStats.failed;
      }
      continue;
    }
    if (s.resident.count(l.key)) continue;
    GpuChunk c;
    c.buffer = GlBuffer(l.points.size() * sizeof(GpuPoint), l.points.data());
    c.count = uint32_t(l.points.size());
    c.offset = l.offset;
    c.last_used = frame;
    c.disk_bytes = l.disk_bytes;
    c.spacing = l.spacing;
    c.density = l.density;
    if (!l.normals.empty()) c.normals = GlBuffer(l.normals.size() * 4, l.normals.data());
    if (!l.ratios.empty()) c.density_ratios = GlBuffer(l.ratios.size() * 4, l.ratios.data());
    if (!l.cells.empty()) c.cells = GlBuffer(l.cells.size() * 8, l.cells.data());
    s.resident_bytes += residentBytes(c);
    s.resident_disk_bytes += c.disk_bytes;
    s.resident.emplace(l.key, std::move(c));
    ++mStats.uploaded;
  }
  // LRU eviction beyond the budget, sparing what the previous frame drew.
  if (s.resident_bytes > s.options.budget_bytes) {
    std::vector<std::pair<uint64_t, Key>> old;
    for (const auto& [k, c] : s.resident) {
      if (c.last_used + 1 < frame) old.push_back({c.last_used, k});
    }
    std::sort(old.begin(), old.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first < b.first : a.second.node < b.second.node;
    });
    for (const auto& [used, k] : old) {
      if (s.resident_bytes <= s.options.budget_bytes) break;
      auto it = s.resident.find(k);
      s.resident_bytes -= residentBytes(it->second);
      s.resident_disk_bytes -= it->second.disk_bytes;
      s.resident.erase(it);
      ++mStats.evicted;
    }
  }
  s.wanted.clear();
  s.wanted_keys.clear();
  s.wanted_pages.clear();
  mStats.upload_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

const GpuChunk* ChunkStreamer::find(const lod::PointStore& store, lod::NodeId node) {
  auto it = mImpl->resident.find({&store, node});
  if (it == mImpl->resident.end()) return nullptr;
  it->second.last_used = mImpl->frame;
  return &it->second;
}

void ChunkStreamer::request(lod::PointStore& store, lod::NodeId node, uint8_t level,
                            double distance) {
  Impl& s = *mImpl;
  const Key k{&store, node};
  if (s.resident.count(k) || s.failed.count(k) || !s.wanted_keys.insert(k).second) return;
  s.wanted.push_back({&store, node, false, level, distance});
  ++mStats.requested;
}

void ChunkStreamer::requestChildren(lod::PointStore& store, lod::NodeId node) {
  Impl& s = *mImpl;
  const Key k{&store, node};
  if (s.failed_pages.count(k) || !s.wanted_pages.insert(k).second) return;
  s.wanted.push_back({&store, node, true, 0, 0.0});
  ++mStats.pages_requested;
}

bool ChunkStreamer::failed(const lod::PointStore& store, lod::NodeId node) const {
  return mImpl->failed.count({&store, node}) != 0;
}

void ChunkStreamer::endFrame() {
  Impl& s = *mImpl;
  std::stable_sort(s.wanted.begin(), s.wanted.end(), before);
  {
    std::lock_guard lock(s.mutex);
    s.queue.clear();
    s.next = 0;
    for (const Item& i : s.wanted) {
      const Key k{i.store, i.node};
      if (i.page || (!s.done_keys.count(k) && !(s.busy_key == k))) s.queue.push_back(i);
    }
    mStats.queued = s.queue.size();
  }
  s.wake.notify_all();
  mStats.resident_chunks = s.resident.size();
  mStats.resident_bytes = s.resident_bytes;
  mStats.resident_disk_bytes = s.resident_disk_bytes;
}

void ChunkStreamer::waitForLoader() {
  std::unique_lock lock(mImpl->mutex);
  mImpl->idle.wait(
      lock, [&] { return mImpl->paused || (mImpl->next >= mImpl->queue.size() && !mImpl->busy); });
}

void ChunkStreamer::pauseLoader(bool paused) {
  {
    std::lock_guard lock(mImpl->mutex);
    mImpl->paused = paused;
  }
  mImpl->wake.notify_all();
  mImpl->idle.notify_all();
}

void ChunkStreamer::forget(const lod::PointStore& store) {
  Impl& s = *mImpl;
  {
    std::unique_lock lock(s.mutex);
    s.queue.erase(std::remove_if(s.queue.begin() + std::ptrdiff_t(s.next), s.queue.end(),
                                 [&](const Item& i) { return i.store == &store; }),
                  s.queue.end());
    s.idle.wait(lock, [&] { return s.busy != &store; });
    std::erase_if(s.done, [&](const Loaded& l) { return l.key.store == &store; });
  }
  for (auto it = s.resident.begin(); it != s.resident.end();) {
    if (it->first.store == &store) {
      s.resident_bytes -= residentBytes(it->second);
      s.resident_disk_bytes -= it->second.disk_bytes;
      it = s.resident.erase(it);
    } else {
      ++it;
    }
  }
  std::erase_if(s.failed, [&](const Key& k) { return k.store == &store; });
  std::erase_if(s.failed_pages, [&](const Key& k) { return k.store == &store; });
}

}  // namespace tessera::render
