#include <tessera/lod/store_builder.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <system_error>
#include <thread>
#include <unordered_map>

#include <tessera/core/check.h>
#include <tessera/core/parallel.h>
#include <tessera/core/file_checks.h>
#include <tessera/core/progress.h>
#include <tessera/lod/store_format.h>

#include "chunk_codec.h"
#include "crc32c.h"
#include "file_io.h"
#include "node_sampler.h"
#include "point_distributor.h"

namespace tessera::lod {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

/// A finished node: where its payload is in the temporary payload file and its metadata.
struct NodeOut {
  CellKey key;
  uint8_t child_mask = 0;
  uint32_t points = 0;
  float spacing = 0.f;
  float error_bound = 0.f;
  uint64_t temp_offset = 0;
  uint32_t size = 0;
  uint32_t crc = 0;
  uint32_t position_color_bytes = 0;
  uint64_t final_offset = 0;
};

/// Removes temporary files and the partial output unless the build commits.
struct Cleanup {
  std::vector<std::filesystem::path> paths;
  ~Cleanup() {
    for (const auto& p : paths) {
      std::error_code ec;
      std::filesystem::remove_all(p, ec);
    }
  }
};

class Builder {
 public:
  Builder(const BuildOptions& o, const CubeFrame& frame, AttributeMask attributes, double precision,
          const std::filesystem::path& payload_file)
      : mOpt(o),
        mFrame(frame),
        mAttributes(attributes),
        mPrecision(precision),
        mPayload(payload_file, O_RDWR | O_CREAT | O_TRUNC, "temporary file") {}

  /// Encodes a node and appends its payload. Reorders `pts` (Morton order).
  void emit(const CellKey& key, std::span<BuildPoint> pts, uint8_t child_mask) {
    const double extent = mFrame.cellSize(key.level);
    const glm::dvec3 box_min = mFrame.cellMin(key);
    // Inner nodes hold one point per grid cell: their spacing is about a cell; measure it.
    double spacing = meanSpacing(pts, extent, extent / store::kGrid);
    // Quantisation error at most a quarter of the spacing (Euclidean: step * sqrt(3) / 2), but
    // no finer than the input's own resolution.
    double step = std::max(spacing / (2.0 * std::sqrt(3.0)), mPrecision);
    // Exact leaves: the input's declared resolution, cells on its lattice (the local frame's
    // origin lies on it); without one, a 1024th of the spacing, but at most 2^16 cells across
    // the node (float positions; two points a hair apart measure a spacing of almost 0).
    const bool exact = child_mask == 0 && mOpt.exact_leaves;
    if (exact)
      step = mPrecision > 0.0 ? mPrecision : std::max(spacing / 1024.0, extent / 65536.0);
    NodeOut out;
    out.key = key;
    out.child_mask = child_mask;
    out.points = uint32_t(pts.size());
    out.spacing = float(spacing);
    if (!pts.empty()) {
      EncodedChunk enc = encodeChunk(pts, box_min, extent, step, mAttributes, mOpt.zstd_level,
                                     exact && mPrecision > 0.0);
      out.size = uint32_t(enc.bytes.size());
      out.crc = crc32c(enc.bytes.data(), enc.bytes.size());
      out.position_color_bytes = enc.position_color_bytes;
      // The stated bound: what the step guarantees, never below what was measured. A leaf whose
      // cells are the input's integers states a thousandth of its step (double rounding only).
      const bool on_lattice = exact && mPrecision > 0.0 && enc.step == step &&
                              enc.max_error <= store::kLatticeTolerance * step;
      out.error_bound =
          on_lattice
              ? float(store::kLatticeTolerance * step)
              : float(std::max(enc.step * std::sqrt(3.0) / 2.0, enc.max_error) * (1.0 + 1e-6));
      std::lock_guard lock(mMutex);
      out.temp_offset = mPayloadEnd;
      mPayloadEnd += out.size;
      mMaxError = std::max(mMaxError, enc.max_error);
      if (child_mask == 0 && !on_lattice) mAllExact = false;
      pwriteAll(mPayload.get(), enc.bytes.data(), enc.bytes.size(), out.temp_offset,
                mPayload.name());
      mNodes.push_back(out);
      return;
    }
    std::lock_guard lock(mMutex);
    mNodes.push_back(out);
  }

  /// Builds the subtree of a chunk in memory and emits every node of it. Leaves hold all their
  /// points; an inner node holds a grid-sampled copy of the points below it (Bettio et al. 2009,
  /// section 3.2: self-contained nodes, a cut is drawn from its own nodes only). The points of
  /// the subtree root are copied to `root_points`: the levels above sample from them. Reorders
  /// `pts`.
  uint8_t buildSubtree(const CellKey& key, std::span<BuildPoint> pts,
                       std::vector<BuildPoint>* root_points) {
    // The partition's other half: each level copies its points by child into the other buffer
    // and the children work there, so a point moves once a level.
    thread_local std::unique_ptr<BuildPoint[]> scratch;
    thread_local size_t scratch_size = 0;
    if (scratch_size < pts.size()) {
      scratch.reset();
      scratch = std::make_unique_for_overwrite<BuildPoint[]>(pts.size());
      scratch_size = pts.size();
    }
    std::vector<BuildPoint> stored;
    const uint8_t mask =
        buildNode(key, pts, std::span<BuildPoint>(scratch.get(), pts.size()), stored, 0, nullptr);
    if (root_points) root_points->swap(stored);
    return mask;
  }

  std::vector<NodeOut>& nodes() { return mNodes; }
  ScopedFd& payload() { return mPayload; }
  uint64_t payloadEnd() const { return mPayloadEnd; }
  double maxError() const { return mMaxError; }

  /// Whether every leaf keeps the input's integers (store::kExactLeaves).
  bool allExact() const { return mAllExact; }

 private:
  /// buildSubtree() of a node `depth` levels below the chunk root; `scratch` as many points.
  /// The node's stored points (a leaf's all, an inner node's sample) are appended to `stored`.
  /// `presorted`: the node's points are already grouped by child, these 9 boundaries (its
  /// parent partitioned two levels at once), else null.
  uint8_t buildNode(const CellKey& key, std::span<BuildPoint> pts, std::span<BuildPoint> scratch,
                    std::vector<BuildPoint>& stored, int depth, const size_t* presorted) {
    if (pts.size() <= mOpt.leaf_max || key.level >= store::kMaxLevel) {
      emit(key, pts, 0);
      stored.insert(stored.end(), pts.begin(), pts.end());
      return 0;
    }
    // Children first. An inner node samples its children's stored points, not every point
    // below it, as the levels above the chunks do: every occupied cell of its grid holds an
    // occupied cell of a child's finer grid, so it gets the same one point per occupied cell,
    // each within a child cell of the one nearest the centre, and a point is sampled once
    // instead of once a level (Potree's indexing moves points up the same way).
    thread_local std::vector<std::vector<BuildPoint>> candidates_at(store::kMaxLevel + 2);
    std::vector<BuildPoint>& candidates = candidates_at[size_t(depth)];
    candidates.clear();
    // Children's points: grouped in place when the parent did it, else copied by child (and by
    // grandchild, when there is room below) into `scratch`, which they then work in.
    std::array<size_t, 65> bounds;
    std::span<BuildPoint> kids = scratch, kids_scratch = pts;
    const int levels = presorted ? 0 : key.level + 2 <= store::kMaxLevel ? 2 : 1;
    if (presorted) {
      std::copy(presorted, presorted + 9, bounds.begin());
      std::swap(kids, kids_scratch);
    } else {
      partitionCells(pts, scratch, mFrame, key, levels, bounds);
    }
    const int per_child = levels == 2 ? 8 : 1;
    uint8_t mask = 0;
    for (int i = 0; i < 8; ++i) {
      const size_t a = bounds[size_t(i * per_child)], b = bounds[size_t((i + 1) * per_child)];
      if (a == b) continue;
      std::array<size_t, 9> sub;
      if (levels == 2) {
        for (int j = 0; j < 9; ++j) sub[size_t(j)] = bounds[size_t(i * 8 + j)] - a;
      }
      buildNode(key.child(i), kids.subspan(a, b - a), kids_scratch.subspan(a, b - a), candidates,
                depth + 1, levels == 2 ? sub.data() : nullptr);
      mask |= uint8_t(1u << i);
    }
    thread_local std::vector<uint8_t> chosen;
    const glm::dvec3 box_min = mFrame.cellMin(key);
    const double extent = mFrame.cellSize(key.level);
    size_t selected = gridSelect(candidates, box_min, extent, store::kGrid, chosen);
    // Overhead bound: an inner node keeps at most kMaxInnerFraction of the points below it (a
    // coarser grid where the data is thick, e.g. noisy overlapping scans), so each inner level
    // costs at most f of the input. `pts` are input points, so the levels' fractions add up
    // (not f + f^2 + ...): 1.40x measured on a random cube, where two levels reach the cap.
    const double cap = store::kMaxInnerFraction * double(pts.size());
    for (int grid = store::kGrid, tries = 0; double(selected) > cap && grid > 2 && tries < 6;
         ++tries) {
      grid = std::max(2, int(double(grid) * std::sqrt(cap / double(selected))));
      selected = gridSelect(candidates, box_min, extent, grid, chosen);
    }
    thread_local std::vector<BuildPoint> sample;
    sample.clear();
    sample.reserve(selected);
    for (size_t i = 0; i < candidates.size(); ++i) {
      if (chosen[i]) sample.push_back(candidates[i]);
    }
    emit(key, sample, mask);
    stored.insert(stored.end(), sample.begin(), sample.end());
    return mask;
  }

  const BuildOptions& mOpt;
  CubeFrame mFrame;
  AttributeMask mAttributes;
  double mPrecision;
  ScopedFd mPayload;
  std::mutex mMutex;
  uint64_t mPayloadEnd = 0;
  std::vector<NodeOut> mNodes;
  double mMaxError = 0.0;
  bool mAllExact = true;
};

/// The points of a chunk root or upper node, kept for its parent to sample from.
struct Pending {
  std::vector<BuildPoint> pts;
  uint8_t child_mask = 0;
};

/// Splits chunks too large for memory into their octants (streamed through the temp file).
void splitOversized(std::vector<Chunk>& chunks, uint64_t chunk_max, const CubeFrame& frame,
                    const TempLayout& layout, int fd, const std::string& name,
                    uint64_t& temp_end) {
  std::vector<Chunk> out;
  std::vector<Chunk> work(chunks.begin(), chunks.end());
  const uint64_t kStream = 1 << 20;
  std::vector<BuildPoint> buf;
  while (!work.empty()) {
    Chunk c = work.back();
    work.pop_back();
    if (c.count <= chunk_max || c.key.level >= store::kMaxLevel - 1) {
      out.push_back(c);
      continue;
    }
    std::array<uint64_t, 8> counts{};
    auto octant = [&](const BuildPoint& p) {
      CellKey k = frame.cellOf(p.position, c.key.level + 1);
      return k.childIndex();
    };
    for (uint64_t i = 0; i < c.count; i += kStream) {
      uint64_t n = std::min(kStream, c.count - i);
      buf.resize(n);
      readTempPoints(layout, fd, c.first + i, n, buf.data(), name);
      for (const auto& p : buf) ++counts[size_t(octant(p))];
    }
    std::array<Chunk, 8> kids;
    std::array<uint64_t, 8> fill{};
    for (int i = 0; i < 8; ++i) {
      kids[size_t(i)] = {c.key.child(i), temp_end, counts[size_t(i)]};
      temp_end += counts[size_t(i)];
    }
    std::array<std::vector<BuildPoint>, 8> bufs;
    for (uint64_t i = 0; i < c.count; i += kStream) {
      uint64_t n = std::min(kStream, c.count - i);
      buf.resize(n);
      readTempPoints(layout, fd, c.first + i, n, buf.data(), name);
      for (const auto& p : buf) bufs[size_t(octant(p))].push_back(p);
      for (int k = 0; k < 8; ++k) {
        auto& b = bufs[size_t(k)];
        writeTempPoints(layout, fd, kids[size_t(k)].first + fill[size_t(k)], b.data(), b.size(),
                        name);
        fill[size_t(k)] += b.size();
        b.clear();
      }
    }
    for (const Chunk& k : kids) {
      if (k.count > 0) work.push_back(k);
    }
  }
  chunks.swap(out);
}

}  // namespace

BuildReport buildStore(const std::vector<std::filesystem::path>& inputs,
                       const std::filesystem::path& output, const BuildOptions& options) {
  const auto t0 = Clock::now();
  BuildReport report;
  TESSERA_CHECK(options.threads >= 0 && options.threads <= kMaxThreads,
                "lod::buildStore(): threads must be in [0, " + std::to_string(kMaxThreads) + "]");
  TESSERA_CHECK(options.direct_io >= -1 && options.direct_io <= 1,
                "lod::buildStore(): direct_io must be -1, 0 or 1");
  for (const auto& in : inputs) {
    const auto read = filesRead(in);  // throws ReadError naming a missing or bad input
    if (const auto same = sameFileAs(output, read)) {
      throw StoreError("lod::buildStore(): output " + output.string() + " is the input " +
                       same->string() + " (the same file); refusing to write over an input");
    }
  }
  const int threads = int(threadCount(options.threads));
  const std::filesystem::path partial = output.string() + ".partial";
  const std::filesystem::path temp_dir =
      (options.temp_dir.empty() ? output.parent_path() : options.temp_dir) /
      (output.filename().string() + ".build-tmp");
  Cleanup cleanup{{partial, temp_dir}};
  {
    std::error_code ec;
    std::filesystem::remove_all(temp_dir, ec);
    std::filesystem::remove(partial, ec);
    std::filesystem::create_directories(temp_dir, ec);
    if (ec)
      throw StoreError("lod::buildStore(): cannot create " + temp_dir.string() + ": " +
                       ec.message());
  }

  PointDistributor dist(inputs, options.quiet);
  dist.setAmbientOcclusion(options.ambient_occlusion);
  dist.setThreads(unsigned(threads));
  dist.setMemory(options.memory_mb << 20);
  dist.setDirectIo(options.direct_io);
  dist.measure(temp_dir / "raw.bin");
  const CubeFrame frame = dist.frame();
  // Reading blocks around the page cache blocks a worker until the disk answers: one worker
  // more than the cores keeps them busy meanwhile (and the memory is shared by one more).
  const int workers = threads + (dist.directIo() ? 1 : 0);
  // Memory: the chunk being worked on dominates (point + partition buffer + codec temporaries,
  // under 100 bytes a point) on every thread; a fixed ~128 MB for grids and buffers.
  const uint64_t budget = options.memory_mb << 20;
  const uint64_t fixed = 128ull << 20;
  // Chunks of at most 2 M points even with memory to spare: a chunk's top levels sort and
  // partition all of its points, which stays in cache better (measured: 512 MB budget, 171
  // chunks, 14.7 s of chunk work for 10^8 points against 17.0 s with 39 chunks at 2048 MB).
  const uint64_t kChunkCap = 2'000'000;
  const uint64_t chunk_max =
      options.chunk_points > 0
          ? options.chunk_points
          : std::clamp<uint64_t>(
                (budget > fixed ? budget - fixed : budget / 2) / (uint64_t(threads) * 100), 100'000,
                kChunkCap);
  const std::filesystem::path temp_points = temp_dir / "points.bin";
  std::vector<Chunk> chunks = dist.distribute(chunk_max, temp_points, threads);
  report.seconds_read = since(t0);
  report.points = dist.points();
  report.skipped = dist.skipped();
  report.temp_record_bytes = dist.tempLayout().recordSize();
  report.bucketed = dist.bucketed();

  const auto t1 = Clock::now();
  ScopedFd points_fd(temp_points, O_RDWR | O_CREAT, "temporary file");
  // The chunks read from points.bin (every chunk on the raw route; on the bucketed route those
  // of groups too large for memory, spilled there) and the groups read whole.
  std::vector<ChunkGroup> groups;
  std::vector<Chunk> from_file;
  uint64_t temp_end = dist.points();
  if (dist.bucketed()) {
    // A group in memory: its points twice (read, then by chunk) beside the chunk being built.
    const uint64_t per_thread = (budget > fixed ? budget - fixed : budget / 2) / uint64_t(workers);
    const uint64_t group_max =
        std::max(chunk_max, (per_thread > chunk_max * 100 ? per_thread - chunk_max * 100 : 0) /
                                (2 * sizeof(BuildPoint) + 8));
    temp_end = 0;
    for (ChunkGroup& g : dist.groups(chunks)) {
      if (g.points <= group_max) {
        groups.push_back(std::move(g));
        continue;
      }
      dist.spillGroup(g, chunks, points_fd.get(), points_fd.name(), temp_end);
      for (uint32_t ci : g.chunks) from_file.push_back(chunks[ci]);
    }
    std::sort(groups.begin(), groups.end(),
              [](const ChunkGroup& a, const ChunkGroup& b) { return a.points > b.points; });
  } else {
    from_file = chunks;
  }
  splitOversized(from_file, chunk_max, frame, dist.tempLayout(), points_fd.get(),
                 points_fd.name(), temp_end);
  std::sort(from_file.begin(), from_file.end(),
            [](const Chunk& a, const Chunk& b) { return a.count > b.count; });

  Builder builder(options, frame, dist.attributes(), dist.inputPrecision(),
                  temp_dir / "payload.bin");
  std::unordered_map<CellKey, Pending, CellKeyHash> pending;
  std::mutex pending_mutex;
  std::atomic<uint64_t> subtrees{0};
  {
    Progress progress(dist.bucketed() ? "build 2/3 chunks" : "build 4/5 chunks", dist.points(),
                      " points", options.quiet);
    std::mutex progress_mutex;
    auto build = [&](const CellKey& key, std::span<BuildPoint> pts) {
      Pending root;
      root.child_mask = builder.buildSubtree(key, pts, &root.pts);
      {
        std::lock_guard lock(pending_mutex);
        pending.emplace(key, std::move(root));
      }
      ++subtrees;
      std::lock_guard lock(progress_mutex);
      progress.add(pts.size());
    };
    // A chunk in memory larger than the chunk size (one counting cell holds more) splits into
    // octants in memory as splitOversized() does through the file.
    std::function<void(const CellKey&, std::vector<BuildPoint>&)> buildInMemory =
        [&](const CellKey& key, std::vector<BuildPoint>& pts) {
          if (pts.size() <= chunk_max || key.level >= store::kMaxLevel - 1) {
            build(key, pts);
            return;
          }
          std::array<std::vector<BuildPoint>, 8> kids;
          for (const BuildPoint& p : pts)
            kids[size_t(frame.cellOf(p.position, key.level + 1).childIndex())].push_back(p);
          std::vector<BuildPoint>().swap(pts);
          for (int i = 0; i < 8; ++i) {
            if (!kids[size_t(i)].empty()) buildInMemory(key.child(i), kids[size_t(i)]);
          }
        };
    std::atomic<size_t> next_group{0}, next{0};
    std::atomic<bool> failed{false};
    // Groups largest first, then the chunks from the file largest first; each worker with its
    // own point buffers.
    runWorkers(unsigned(workers), [&](unsigned) {
      std::vector<BuildPoint> pts;
      std::vector<std::vector<BuildPoint>> by_chunk;
      try {
        for (size_t gi; !failed && (gi = next_group++) < groups.size();) {
          const ChunkGroup& g = groups[gi];
          dist.readGroup(g, chunks, by_chunk);
          for (size_t j = 0; j < g.chunks.size(); ++j) {
            buildInMemory(chunks[g.chunks[j]].key, by_chunk[j]);
            std::vector<BuildPoint>().swap(by_chunk[j]);
          }
        }
        for (size_t ci; !failed && (ci = next++) < from_file.size();) {
          const Chunk& c = from_file[ci];
          pts.resize(c.count);
          readTempPoints(dist.tempLayout(), points_fd.get(), c.first, c.count, pts.data(),
                         points_fd.name());
          build(c.key, pts);
        }
      } catch (...) {
        failed = true;
        throw;
      }
    });
  }
  report.chunks = subtrees;

  // Levels above the chunks: each upper node is a grid sample of its children's points.
  {
    std::map<int, std::vector<CellKey>, std::greater<int>> upper;  // deepest level first
    std::unordered_map<CellKey, bool, CellKeyHash> seen;
    for (const auto& [key, p] : pending) {
      for (CellKey k = key; k.level > 0;) {
        k = k.parent();
        if (pending.count(k) || seen.count(k)) break;
        seen[k] = true;
        upper[k.level].push_back(k);
      }
    }
    // The nodes of a level are independent: they share the threads (a level above the chunks
    // samples up to 8 x 48^3 points a node, which on one thread was a tail after the chunks).
    for (auto& [level, keys] : upper) {
      parallelFor(keys.size(), unsigned(threads), [&](size_t k) {
        const CellKey key = keys[k];
        Pending parent;
        std::array<std::vector<BuildPoint>, 8> children;
        {
          std::lock_guard lock(pending_mutex);
          for (int i = 0; i < 8; ++i) {
            auto it = pending.find(key.child(i));
            if (it == pending.end()) continue;
            children[size_t(i)] = std::move(it->second.pts);
            parent.child_mask |= uint8_t(1u << i);
            pending.erase(it);
          }
        }
        for (const auto& c : children) parent.pts.insert(parent.pts.end(), c.begin(), c.end());
        size_t selected =
            gridSample(parent.pts, frame.cellMin(key), frame.cellSize(key.level), store::kGrid);
        parent.pts.resize(selected);
        builder.emit(key, parent.pts, parent.child_mask);
        std::lock_guard lock(pending_mutex);
        pending.emplace(key, std::move(parent));
      });
    }
    if (pending.size() != 1 || !pending.count(CellKey{})) {
      throw StoreError(
          "lod::buildStore(): internal error: upper levels did not converge to one root");
    }
    pending.clear();
  }
  report.seconds_process = since(t1);

  // Final file: header, payload in (level, Morton) order, hierarchy pages, source table.
  const auto t2 = Clock::now();
  std::vector<NodeOut>& nodes = builder.nodes();
  std::sort(nodes.begin(), nodes.end(),
            [](const NodeOut& a, const NodeOut& b) { return a.key < b.key; });
  std::unordered_map<CellKey, size_t, CellKeyHash> index;
  for (size_t i = 0; i < nodes.size(); ++i) index[nodes[i].key] = i;

  // The output in order: the header's place, payload, pages, source table; the header last.
  SequentialWriter out(partial, dist.directIo(), "output");
  {
    const std::vector<uint8_t> zeros(store::kHeaderSize, 0);
    out.append(zeros.data(), zeros.size());
  }
  uint64_t pos = store::kHeaderSize;
  uint64_t pc_bytes = 0;
  {
    Progress progress(dist.bucketed() ? "build 3/3 writing" : "build 5/5 writing", nodes.size(),
                      " nodes", options.quiet);
    std::vector<uint8_t> buf;
    for (NodeOut& n : nodes) {
      buf.resize(n.size);
      if (n.size)
        preadAll(builder.payload().get(), buf.data(), n.size, n.temp_offset,
                 builder.payload().name());
      n.final_offset = pos;
      if (n.size) out.append(buf.data(), n.size);
      pos += n.size;
      pc_bytes += n.position_color_bytes;
      progress.add(1);
    }
  }
  const uint64_t payload_size = pos - store::kHeaderSize;

  auto record = [&](const NodeOut& n) {
    store::NodeRecord r{};
    r.payload_offset = n.final_offset;
    r.x = n.key.x;
    r.y = n.key.y;
    r.z = n.key.z;
    r.points = n.points;
    r.spacing = n.spacing;
    r.error_bound = n.error_bound;
    r.payload_size = n.size;
    r.payload_crc = n.crc;
    r.level = n.key.level;
    r.child_mask = n.child_mask;
    return r;
  };
  // Pages: the subtree of a page root down to kPageLevels levels below it; nodes on the bottom
  // level that have children point to the page rooted at themselves. Child pages first.
  std::function<std::pair<uint64_t, uint32_t>(size_t)> writePage = [&](size_t root) {
    std::vector<size_t> bfs{root};
    for (size_t i = 0; i < bfs.size(); ++i) {
      const NodeOut& n = nodes[bfs[i]];
      if (n.key.level - nodes[root].key.level >= store::kPageLevels) continue;
      for (int c = 0; c < 8; ++c) {
        if (n.child_mask & (1u << c)) bfs.push_back(index.at(n.key.child(c)));
      }
    }
    std::vector<store::NodeRecord> recs;
    for (size_t i : bfs) {
      store::NodeRecord r = record(nodes[i]);
      if (nodes[i].child_mask && nodes[i].key.level - nodes[root].key.level == store::kPageLevels) {
        auto [off, size] = writePage(i);
        r.flags |= store::kHasPage;
        r.page_offset = off;
        r.page_size = size;
      }
      recs.push_back(r);
    }
    store::PageHeader ph{};
    std::memcpy(ph.magic, "TPAG", 4);
    ph.nodes = uint32_t(recs.size());
    ph.crc = crc32c(recs.data(), recs.size() * sizeof(store::NodeRecord));
    uint64_t at = pos;
    out.append(&ph, sizeof ph);
    pos += sizeof ph;
    out.append(recs.data(), recs.size() * sizeof(store::NodeRecord));
    pos += recs.size() * sizeof(store::NodeRecord);
    return std::make_pair(at, uint32_t(pos - at));
  };
  auto [root_off, root_size] = writePage(index.at(CellKey{}));

  std::string table;
  for (const std::string& s : dist.sourceNames()) table += s + '\n';
  const uint64_t table_off = pos;
  out.append(table.data(), table.size());
  pos += table.size();
  if (out.size() != pos)
    throw StoreError("lod::buildStore(): internal error: the output is not written in order");
  out.finish();

  store::FileHeader h{};
  std::memcpy(h.magic, store::kMagic, 4);
  h.version = store::kVersion;
  h.header_size = store::kHeaderSize;
  h.attributes = dist.attributes();
  for (int i = 0; i < 3; ++i) {
    h.origin[i] = frame.origin[i];
    h.cube_min[i] = frame.cube_min[i];
    h.bbox_min[i] = dist.boundsMin()[i];
    h.bbox_max[i] = dist.boundsMax()[i];
  }
  h.cube_size = frame.cube_size;
  h.points = dist.points();
  h.nodes = nodes.size();
  uint32_t depth = 0;
  double finest = std::numeric_limits<double>::max();
  for (const NodeOut& n : nodes) {
    h.stored_points += n.points;
    depth = std::max<uint32_t>(depth, n.key.level + 1u);
    if (n.points > 0) finest = std::min(finest, double(n.spacing));
  }
  h.depth = depth;
  h.sources = uint32_t(dist.sourceNames().size());
  h.payload_offset = store::kHeaderSize;
  h.payload_size = payload_size;
  h.root_page_offset = root_off;
  h.root_page_size = root_size;
  h.source_table_offset = table_off;
  h.source_table_size = uint32_t(table.size());
  h.source_table_crc = crc32c(table.data(), table.size());
  h.input_precision = dist.inputPrecision();
  h.flags = builder.allExact() && h.input_precision > 0.0 ? store::kExactLeaves : 0;
  h.spacing_root = nodes[index.at(CellKey{})].spacing;
  h.spacing_finest = finest;
  h.payload_position_color_bytes = pc_bytes;
  h.header_crc = 0;
  h.header_crc = crc32c(&h, sizeof h);
  std::vector<uint8_t> header(store::kHeaderSize, 0);
  std::memcpy(header.data(), &h, sizeof h);
  out.writeFirstBlock(header.data());
  if (::fsync(out.file().get()) != 0)
    throw StoreError("lod::buildStore(): flushing " + out.file().name() +
                     " failed: " + std::strerror(errno));
  std::error_code ec;
  std::filesystem::rename(partial, output, ec);
  if (ec)
    throw StoreError("lod::buildStore(): cannot move " + partial.string() + " to " +
                     output.string() + ": " + ec.message());

  report.nodes = nodes.size();
  report.stored_points = h.stored_points;
  report.depth = depth;
  report.file_bytes = pos;
  report.position_color_bytes = pc_bytes;
  report.max_error = builder.maxError();
  report.seconds_write = since(t2);
  report.seconds = since(t0);
  return report;
}

}  // namespace tessera::lod
