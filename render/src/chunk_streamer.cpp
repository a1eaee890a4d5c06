#include <tessera/render/chunk_streamer.h>

#include <tessera/core/parallel.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <span>
#include <stop_token>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <glm/gtc/packing.hpp>

#include <tessera/render/mesh_pass.h>
#include <tessera/render/point_pass.h>
#include <tessera/render/spbr.h>
#include <tessera/render/splat_sizes.h>

namespace tessera::render {
namespace {

struct Key {
  const lod::LodHierarchy* store;
  lod::NodeId node;
  bool operator==(const Key&) const = default;
};

struct KeyHash {
  size_t operator()(const Key& k) const {
    return std::hash<const void*>{}(k.store) ^ (size_t(k.node) * 0x9E3779B97F4A7C15ull);
  }
};

struct Item {
  lod::LodHierarchy* store;  ///< pages: any hierarchy; chunks: `points`
  lod::PointStore* points;   ///< the point store whose chunk this is (null for pages, patches)
  lod::MeshStore* mesh;      ///< the mesh store whose patch this is (null otherwise)
  lod::NodeId node;
  bool page;  ///< a hierarchy page (the node's children), not a chunk
  /// What a chunk is decoded with beyond its points: kMeasure, kSplatSizes.
  uint8_t needs;
  uint8_t level;
  double distance;
};

/// Item::needs and GpuChunk's record of them: see-through measurements (density and what
/// StreamerOptions asks), the points' own splat sizes (leaves seen close).
constexpr uint8_t kMeasure = 1, kSplatSizes = 2;

/// What a resident chunk was decoded with (Item::needs).
uint8_t has(const GpuChunk& c) {
  return uint8_t((c.measured ? kMeasure : 0) | (c.splat_sized ? kSplatSizes : 0));
}

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
  std::vector<glm::uvec4> cells;  ///< SurfaceCell packed (packCell())
  bool page = false;
  bool failed = false;
  bool cancelled = false;  ///< given up: no frame wanted it any more (endFrame()), or forget()
  bool measured = false;
  bool splat_sized = false;  ///< splat sizes asked for (measured if a leaf)
  float max_splat_scale = 1.0f;
  glm::dvec3 offset{0.0};
  std::vector<GpuPoint> points;
  std::vector<GpuMeshVertex> mesh_vertices;  ///< a mesh patch
  std::vector<uint32_t> mesh_indices;
};

/// A surface cell as spbr_raster.comp reads it, 16 bytes: the rectangle's half-sides in node
/// spacings as half floats (u.x, u.y), (u.z, v.x), (v.y, v.z), then the weight as a half float
/// and the centroid in the rectangle's frame (offset = cu u + cv v) as two snorm8 of cu / 4, cv
/// / 4.
glm::uvec4 packCell(const SurfaceCell& c, double spacing) {
  const float unit = spacing > 0 ? float(1.0 / spacing) : 1.0f;
  const glm::vec3 u = c.axis_u * unit, v = c.axis_v * unit, o = c.offset * unit;
  auto along = [&](const glm::vec3& axis) {
    const float len2 = glm::dot(axis, axis);
    const float t = len2 > 0.0f ? glm::dot(o, axis) / len2 : 0.0f;
    return uint32_t(int32_t(std::lround(std::clamp(t * 0.25f, -1.0f, 1.0f) * 127.0f)) & 0xFF);
  };
  return {
      glm::packHalf2x16(glm::vec2(u.x, u.y)), glm::packHalf2x16(glm::vec2(u.z, v.x)),
      glm::packHalf2x16(glm::vec2(v.y, v.z)),
      (glm::packHalf2x16(glm::vec2(c.weight, 0.0f)) & 0xFFFFu) | along(u) << 16 | along(v) << 24};
}

/// GPU bytes a resident chunk holds.
uint64_t residentBytes(const GpuChunk& c) {
  return c.buffer.bytes() + c.indices.bytes() + c.normals.bytes() + c.density_ratios.bytes() +
         c.cells.bytes();
}

}  // namespace

struct ChunkStreamer::Impl {
  StreamerOptions options;
  uint32_t grey = 0;
  std::atomic<StoredAo> stored_ao{StoredAo::kModulate};  ///< read by the loader threads

  // Shared with the loader threads, under `mutex`.
  mutable std::mutex mutex;
  std::condition_variable wake;  ///< loader threads: work or stop
  std::condition_variable idle;  ///< waiters: a loader thread finished an item
  std::vector<Item> queue;       ///< this frame's requests, highest priority first
  size_t next = 0;               ///< the next item a loader thread takes
  /// Per loader thread, the item it works on (store null: none). forget() waits on these.
  std::vector<Item> flight;
  /// Per loader thread, what gives its item up (a fresh source per item), and the frames in a
  /// row that did not want that item.
  std::vector<std::stop_source> flight_cancel;
  std::vector<uint32_t> flight_unwanted;
  uint64_t cancelled = 0;  ///< items given up since the last beginFrame()
  std::vector<Loaded> done;
  /// Chunks in `done` (not to be queued again), mapped to what they were decoded with.
  std::unordered_map<Key, uint8_t, KeyHash> done_keys;
  bool paused = false, stop = false;

  // GL thread only.
  uint64_t frame = 0;
  std::unordered_map<Key, GpuChunk, KeyHash> resident;
  uint64_t resident_bytes = 0, resident_disk_bytes = 0;
  std::unordered_set<Key, KeyHash> failed;
  std::unordered_set<Key, KeyHash> failed_pages;
  std::vector<Item> wanted;                                ///< this frame's requests
  std::unordered_map<Key, size_t, KeyHash> wanted_chunks;  ///< index into `wanted`
  std::unordered_set<Key, KeyHash> wanted_pages;

  std::vector<std::thread> loaders;

  /// Whether a loader thread works on what `item` asks for (the same page, or the same chunk
  /// with at least what it needs). Caller holds `mutex`.
  bool covered(const Item& item) const {
    return std::any_of(flight.begin(), flight.end(), [&](const Item& f) {
      return f.store == item.store && f.node == item.node && f.page == item.page &&
             (f.needs & item.needs) == item.needs;
    });
  }

  /// One loader thread: the highest-priority queued item, one at a time, until stopped.
  void run(size_t slot) {
    std::unique_lock lock(mutex);
    for (;;) {
      wake.wait(lock, [&] { return stop || (!paused && next < queue.size()); });
      if (stop) return;
      const Item item = queue[next++];
      flight[slot] = item;
      flight_cancel[slot] = std::stop_source();
      flight_unwanted[slot] = 0;
      const std::stop_token cancel = flight_cancel[slot].get_token();
      lock.unlock();
      Loaded out = load(item, cancel);
      lock.lock();
      flight[slot].store = nullptr;
      if (out.cancelled) {
        ++cancelled;  // not done: asked for again when a view wants it
      } else if (!item.page || out.failed) {
        if (!item.page) done_keys[out.key] |= item.needs;
        done.push_back(std::move(out));
      }
      idle.notify_all();
    }
  }

  /// Reads a hierarchy page, or decodes (and measures) a chunk. Any loader thread, no lock:
  /// PointStore reads are thread-safe and decode outside its locks. A stopped `cancel` gives a
  /// chunk up (Loaded::cancelled) during a slow read or before its measurements.
  Loaded load(const Item& item, std::stop_token cancel) const {
    Loaded out;
    out.key = {item.store, item.node};
    out.page = item.page;
    if (item.page) {
      try {
        item.store->children(item.node);
      } catch (const lod::StoreError&) {
        out.failed = true;
      }
      return out;
    }
    if (item.mesh) {
      loadPatch(item, out, cancel);
      return out;
    }
    try {
      auto chunk = item.points->decodeChunk(item.node, cancel);
      if (cancel.stop_requested() && (item.needs & (kMeasure | kSplatSizes))) {
        out.cancelled = true;  // the costly part skipped
        return out;
      }
      out.disk_bytes = item.store->chunkBytes(item.node);
      out.spacing = item.store->node(item.node).spacing;
      if (item.needs & kMeasure) measure(*item.points, item.node, chunk->positions, out);
      out.offset = chunk->offset;
      out.points.resize(chunk->size());
      const bool color = !chunk->colors.empty();
      // Leaves hold the scan's own sampling pattern (scan lines); inner nodes are even
      // subsamples whose discs already close them.
      std::vector<uint8_t> scales;
      out.splat_sized = (item.needs & kSplatSizes) != 0;
      if (out.splat_sized && item.store->node(item.node).leaf())
        scales = splatScales(chunk->positions, out.spacing);
      for (uint8_t b : scales)
        out.max_splat_scale = std::max(out.max_splat_scale, pointSplatScale(uint32_t(b) << 24));
      const StoredAo ao_mode = stored_ao.load();
      const bool ao = !chunk->ambient_occlusion.empty() && ao_mode != StoredAo::kOff;
      for (size_t i = 0; i < chunk->size(); ++i) {
        uint32_t rgb = grey;
        if (color) {
          const glm::u8vec4 c = chunk->colors[i];
          rgb = uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16;
        }
        if (ao) {  // each channel times the visibility v / 255, rounded
          const uint32_t v = chunk->ambient_occlusion[i];
          if (ao_mode == StoredAo::kAlone) rgb = 0xFFFFFFu;
          uint32_t shaded = 0;
          for (int shift = 0; shift < 24; shift += 8)
            shaded |= (((rgb >> shift & 0xFFu) * v + 127u) / 255u) << shift;
          rgb = shaded;
        }
        if (!scales.empty()) rgb |= uint32_t(scales[i]) << 24;
        out.points[i] = {chunk->positions[i], rgb};
      }
    } catch (const lod::ReadCancelled&) {
      out.cancelled = true;
    } catch (const lod::StoreError&) {
      out.failed = true;  // corrupt chunk: never drawn as garbage, never retried
    }
    return out;
  }

  /// Decodes a mesh patch into the mesh pass's vertex layout.
  void loadPatch(const Item& item, Loaded& out, std::stop_token cancel) const {
    try {
      const lod::MeshPatch p = item.mesh->readPatch(item.node, cancel);
      out.disk_bytes = item.store->chunkBytes(item.node);
      out.spacing = item.store->node(item.node).spacing;
      out.offset = p.offset;
      const lod::MeshStore::MorphTargets morph = item.mesh->morphTargets(item.node, p, cancel);
      out.mesh_vertices.resize(p.positions.size());
      for (size_t i = 0; i < p.positions.size(); ++i) {
        uint32_t rgba = grey | 0xFF000000u;
        if (!p.colors.empty()) {
          const glm::u8vec4 c = p.colors[i];
          rgba = uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16 | 0xFF000000u;
        }
        out.mesh_vertices[i] = {p.positions[i], packNormal1010102(p.normals[i]), rgba,
                                morph.positions[i], packNormal1010102(morph.normals[i])};
      }
      out.mesh_indices = p.indices;
    } catch (const lod::ReadCancelled&) {
      out.cancelled = true;
    } catch (const lod::StoreError&) {
      out.failed = true;  // corrupt patch: its ancestor stands in, never retried
    }
  }

  /// What see-through rendering needs of a chunk (spbr.h), into `out`.
  void measure(const lod::PointStore& store, lod::NodeId node, std::span<const glm::vec3> positions,
               Loaded& out) const {
    out.measured = true;
    // Spheres four spacings wide hold about 50 points of a surface.
    out.density = sphereDensity(positions, 4.0 * out.spacing, 128, node, 16384);
    if (options.normals) out.normals = estimateNormals(positions, 2.5 * out.spacing);
    if (options.density_ratios) {
      const lod::NodeInfo info = store.node(node);
      out.ratios = densityRatios(positions, 4.0 * out.spacing, glm::vec3(0.0f),
                                 glm::vec3(info.box_max - info.box_min), out.density);
    }
    if (options.surface_cells) {
      // Six spacings hold ~28 neighbours: enough to close almost every cell.
      const lod::NodeInfo info = store.node(node);
      const std::vector<SurfaceCell> cells =
          surfaceCells(positions, 6.0 * out.spacing, out.density, glm::vec3(0.0f),
                       glm::vec3(info.box_max - info.box_min));
      out.cells.resize(cells.size());
      for (size_t i = 0; i < cells.size(); ++i) out.cells[i] = packCell(cells[i], out.spacing);
    }
  }

  /// Frees a resident chunk's buffers and takes it out of the byte counts.
  void erase(std::unordered_map<Key, GpuChunk, KeyHash>::iterator it) {
    resident_bytes -= residentBytes(it->second);
    resident_disk_bytes -= it->second.disk_bytes;
    resident.erase(it);
  }
};

ChunkStreamer::ChunkStreamer(const StreamerOptions& options) : mImpl(std::make_unique<Impl>()) {
  mImpl->options = options;
  mImpl->grey = uint32_t(options.default_color.r) | uint32_t(options.default_color.g) << 8 |
                uint32_t(options.default_color.b) << 16;
  mStats.budget_bytes = options.budget_bytes;
  uint32_t threads = options.loader_threads;
  if (threads == 0) threads = threadCount();
  mImpl->flight.assign(threads, Item{nullptr, nullptr, nullptr, lod::kNoNode, false, 0, 0, 0.0});
  mImpl->flight_cancel.resize(threads);
  mImpl->flight_unwanted.assign(threads, 0);
  for (size_t i = 0; i < threads; ++i)
    mImpl->loaders.emplace_back([impl = mImpl.get(), i] { impl->run(i); });
}

ChunkStreamer::~ChunkStreamer() {
  {
    std::lock_guard lock(mImpl->mutex);
    mImpl->stop = true;
  }
  mImpl->wake.notify_all();
  for (std::thread& t : mImpl->loaders) t.join();
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
    mStats.cancelled = s.cancelled;
    s.cancelled = 0;
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
    const uint8_t loaded = uint8_t((l.measured ? kMeasure : 0) | (l.splat_sized ? kSplatSizes : 0));
    if (auto it = s.resident.find(l.key); it != s.resident.end()) {
      // A decode with more (measured for see-through, splat sizes) replaces the copy without.
      const uint8_t old = has(it->second);
      if ((old | loaded) == old || (old & loaded) != old) continue;
      s.erase(it);
    }
    GpuChunk c;
    if (!l.mesh_indices.empty()) {
      c.buffer = GlBuffer(l.mesh_vertices.size() * sizeof(GpuMeshVertex), l.mesh_vertices.data());
      c.count = uint32_t(l.mesh_vertices.size());
      c.indices = GlBuffer(l.mesh_indices.size() * 4, l.mesh_indices.data());
      c.index_count = uint32_t(l.mesh_indices.size());
    } else {
      c.buffer = GlBuffer(l.points.size() * sizeof(GpuPoint), l.points.data());
      c.count = uint32_t(l.points.size());
    }
    c.offset = l.offset;
    c.last_used = frame;
    c.disk_bytes = l.disk_bytes;
    c.spacing = l.spacing;
    c.measured = l.measured;
    c.splat_sized = l.splat_sized;
    c.max_splat_scale = l.max_splat_scale;
    c.density = l.density;
    if (!l.normals.empty()) c.normals = GlBuffer(l.normals.size() * 4, l.normals.data());
    if (!l.ratios.empty()) c.density_ratios = GlBuffer(l.ratios.size() * 4, l.ratios.data());
    if (!l.cells.empty()) c.cells = GlBuffer(l.cells.size() * 16, l.cells.data());
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
      s.erase(s.resident.find(k));
      ++mStats.evicted;
    }
  }
  s.wanted.clear();
  s.wanted_chunks.clear();
  s.wanted_pages.clear();
  mStats.upload_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

const GpuChunk* ChunkStreamer::find(const lod::LodHierarchy& store, lod::NodeId node,
                                    ChunkUse use) {
  auto it = mImpl->resident.find({&store, node});
  if (it == mImpl->resident.end()) return nullptr;
  if (use == ChunkUse::kSeeThrough && !it->second.measured) return nullptr;
  it->second.last_used = mImpl->frame;
  return &it->second;
}

void ChunkStreamer::request(lod::PointStore& store, lod::NodeId node, uint8_t level,
                            double distance, ChunkUse use, bool splat_sizes) {
  Impl& s = *mImpl;
  const Key k{&store, node};
  uint8_t needs =
      uint8_t((use == ChunkUse::kSeeThrough || s.options.measure_every_chunk ? kMeasure : 0) |
              (splat_sizes && s.options.point_splat_sizes ? kSplatSizes : 0));
  if (auto it = s.resident.find(k); it != s.resident.end()) {
    const uint8_t old = has(it->second);
    if ((old & needs) == needs) return;
    needs |= old;  // a new decode keeps what the resident copy had
  }
  if (s.failed.count(k)) return;
  const auto [it, added] = s.wanted_chunks.try_emplace(k, s.wanted.size());
  if (!added) {
    s.wanted[it->second].needs |= needs;  // one view opaque, another see-through
    return;
  }
  s.wanted.push_back({&store, &store, nullptr, node, false, needs, level, distance});
  ++mStats.requested;
}

void ChunkStreamer::request(lod::MeshStore& store, lod::NodeId node, uint8_t level,
                            double distance) {
  Impl& s = *mImpl;
  const Key k{&store, node};
  if (s.resident.count(k) || s.failed.count(k)) return;
  if (!s.wanted_chunks.try_emplace(k, s.wanted.size()).second) return;
  s.wanted.push_back({&store, nullptr, &store, node, false, 0, level, distance});
  ++mStats.requested;
}

void ChunkStreamer::requestChildren(lod::LodHierarchy& store, lod::NodeId node) {
  Impl& s = *mImpl;
  const Key k{&store, node};
  if (s.failed_pages.count(k) || !s.wanted_pages.insert(k).second) return;
  s.wanted.push_back({&store, nullptr, nullptr, node, true, 0, 0, 0.0});
  ++mStats.pages_requested;
}

bool ChunkStreamer::failed(const lod::LodHierarchy& store, lod::NodeId node) const {
  return mImpl->failed.count({&store, node}) != 0;
}

void ChunkStreamer::endFrame() {
  Impl& s = *mImpl;
  std::stable_sort(s.wanted.begin(), s.wanted.end(), before);
  std::vector<std::stop_source> give_up;
  {
    std::lock_guard lock(s.mutex);
    s.queue.clear();
    s.next = 0;
    for (const Item& i : s.wanted) {
      if (s.covered(i)) continue;  // in flight
      if (!i.page) {
        const auto d = s.done_keys.find({i.store, i.node});
        if (d != s.done_keys.end() && (d->second & i.needs) == i.needs)
          continue;  // waits for upload
      }
      s.queue.push_back(i);
    }
    mStats.queued = s.queue.size();
    // Chunks in flight that no frame wants any more (the view moved on) are given up after
    // `cancel_after_frames` such frames in a row; a chunk flickering at the cut's edge is not.
    for (size_t slot = 0; slot < s.flight.size(); ++slot) {
      const Item& f = s.flight[slot];
      if (!f.store || f.page) continue;
      if (s.wanted_chunks.count({f.store, f.node})) {
        s.flight_unwanted[slot] = 0;
      } else if (s.options.cancel_after_frames > 0 &&
                 ++s.flight_unwanted[slot] == s.options.cancel_after_frames) {
        give_up.push_back(s.flight_cancel[slot]);
      }
    }
  }
  // Outside the lock: a source's cancel callback runs on this thread (chunk_client.cpp).
  for (std::stop_source& c : give_up) c.request_stop();
  s.wake.notify_all();
  mStats.resident_chunks = s.resident.size();
  mStats.resident_bytes = s.resident_bytes;
  mStats.resident_disk_bytes = s.resident_disk_bytes;
}

void ChunkStreamer::waitForLoader() {
  Impl& s = *mImpl;
  std::unique_lock lock(s.mutex);
  s.idle.wait(lock, [&] {
    return s.paused || (s.next >= s.queue.size() &&
                        std::all_of(s.flight.begin(), s.flight.end(),
                                    [](const Item& f) { return f.store == nullptr; }));
  });
}

void ChunkStreamer::pauseLoader(bool paused) {
  {
    std::lock_guard lock(mImpl->mutex);
    mImpl->paused = paused;
  }
  mImpl->wake.notify_all();
  mImpl->idle.notify_all();
}

void ChunkStreamer::forget(const lod::LodHierarchy& store) {
  Impl& s = *mImpl;
  {
    std::unique_lock lock(s.mutex);
    s.queue.erase(std::remove_if(s.queue.begin() + std::ptrdiff_t(s.next), s.queue.end(),
                                 [&](const Item& i) { return i.store == &store; }),
                  s.queue.end());
    // Every loader thread on an item of it gives it up, or finishes it when it cannot (a
    // file's read; a page). The cancel callbacks run here, with `mutex` held: they take only
    // their source's own lock (chunk_client.cpp), which no holder of `mutex` waits for.
    for (size_t slot = 0; slot < s.flight.size(); ++slot) {
      if (s.flight[slot].store == &store) s.flight_cancel[slot].request_stop();
    }
    s.idle.wait(lock, [&] {
      return std::none_of(s.flight.begin(), s.flight.end(),
                          [&](const Item& f) { return f.store == &store; });
    });
    std::erase_if(s.done, [&](const Loaded& l) { return l.key.store == &store; });
    std::erase_if(s.done_keys, [&](const auto& d) { return d.first.store == &store; });
  }
  for (auto it = s.resident.begin(); it != s.resident.end();) {
    auto here = it++;
    if (here->first.store == &store) s.erase(here);
  }
  std::erase_if(s.failed, [&](const Key& k) { return k.store == &store; });
  std::erase_if(s.failed_pages, [&](const Key& k) { return k.store == &store; });
}

void ChunkStreamer::setStoredAo(StoredAo mode) {
  mImpl->stored_ao.store(mode);
}

StoredAo ChunkStreamer::storedAo() const {
  return mImpl->stored_ao.load();
}

uint32_t ChunkStreamer::loaderThreads() const {
  return uint32_t(mImpl->flight.size());
}

uint32_t ChunkStreamer::inFlight() const {
  std::lock_guard lock(mImpl->mutex);
  return uint32_t(std::count_if(mImpl->flight.begin(), mImpl->flight.end(),
                                [](const Item& f) { return f.store != nullptr; }));
}

}  // namespace tessera::render
