// `tessera-lod verify`: every input point must be in the store, one to one, within the error
// bound its node states. The inputs are distributed out of core in the store's own frame; each
// region is then matched against the store nodes that overlap it.
//
// Every input point is stored once, in the leaf whose cell contains it (inner nodes hold
// sampled copies). A stored point is the input point quantised on its leaf's grid, so the
// candidate for p is key(L, p) = round((p - L.min) / L.step), or one of its neighbours when p
// lies half a step from that grid; a multiset per leaf makes the match one to one, and the
// distance from p to the decoded position is checked against the bound the hierarchy states
// for L.
#include <tessera/lod/store_builder.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <thread>
#include <unordered_map>
#include <unordered_set>

#include <tessera/core/parallel.h>
#include <tessera/core/progress.h>
#include <tessera/lod/store_format.h>

#include "file_io.h"
#include "point_distributor.h"

namespace tessera::lod {
namespace {

struct ActiveNode {
  std::unordered_map<CellKey, uint32_t, CellKeyHash> keys;  // cell -> multiplicity
  glm::dvec3 box_min{0.0};
  glm::dvec3 grid{0.0};  // cell 0 relative to box_min
  double step = 0.0;
  double bound = 0.0;
  uint64_t remaining = 0;  // stored points not matched yet: at 0 the node is released
};

CellKey packKey(const glm::dvec3& q) {
  return CellKey{0, uint32_t(q.x), uint32_t(q.y), uint32_t(q.z)};
}

bool overlaps(const NodeInfo& n, const glm::dvec3& lo, const glm::dvec3& hi) {
  return glm::all(glm::lessThanEqual(n.box_min, hi)) &&
         glm::all(glm::greaterThanEqual(n.box_max, lo));
}

bool inside(const NodeInfo& n, const glm::dvec3& lo, const glm::dvec3& hi) {
  return glm::all(glm::greaterThanEqual(n.box_min, lo)) &&
         glm::all(glm::lessThanEqual(n.box_max, hi));
}

}  // namespace

VerifyReport verifyStore(const std::filesystem::path& store_path,
                         const std::vector<std::filesystem::path>& inputs,
                         const BuildOptions& options) {
  auto store = PointStore::open(store_path, 64ull << 20);
  const StoreSummary& sum = store->summary();
  VerifyReport report;
  report.store_points = sum.points;
  report.exact_store = sum.exact_leaves;

  CubeFrame frame;
  frame.origin = sum.origin;
  frame.cube_size = sum.cube_size;
  frame.cube_min = store->node(store->root()).box_min;  // the root node's box is the cube

  // The whole hierarchy (metadata only) and a key -> node map. Inner nodes are decoded here
  // (checksums, and their sampled copies must lie in their box); leaves during matching.
  std::unordered_map<CellKey, NodeId, CellKeyHash> by_key;
  std::vector<NodeId> stack{store->root()};
  while (!stack.empty()) {
    NodeId id = stack.back();
    stack.pop_back();
    NodeInfo n = store->node(id);
    by_key[CellKey{n.level, n.cell.x, n.cell.y, n.cell.z}] = id;
    for (NodeId c : store->children(id)) stack.push_back(c);
    if (n.leaf() || n.points == 0) continue;
    try {
      auto pts = store->decodeChunk(id);
      const glm::vec3 extent(n.box_max - n.box_min);
      for (const glm::vec3& p : pts->positions) {
        if (glm::any(glm::greaterThan(p, extent + n.error_bound)) ||
            glm::any(glm::lessThan(p, glm::vec3(0.f)))) {
          ++report.stray_points;
        }
      }
    } catch (const StoreError&) {
      ++report.corrupt_chunks;
    }
  }

  const std::filesystem::path temp_dir =
      (options.temp_dir.empty() ? store_path.parent_path() : options.temp_dir) /
      (store_path.filename().string() + ".verify-tmp");
  std::error_code ec;
  std::filesystem::remove_all(temp_dir, ec);
  std::filesystem::create_directories(temp_dir, ec);
  struct Remove {
    std::filesystem::path p;
    ~Remove() {
      std::error_code e;
      std::filesystem::remove_all(p, e);
    }
  } remove{temp_dir};

  PointDistributor dist(inputs, options.quiet);
  dist.setThreads(threadCount(options.threads));
  dist.measureInFrame(frame, temp_dir / "raw.bin");
  report.input_points = dist.points();
  const uint64_t region_max = std::max<uint64_t>(200'000, (options.memory_mb << 20) / 400);
  std::vector<Chunk> regions =
      dist.distribute(region_max, temp_dir / "points.bin",
                      int(threadCount(options.threads)));
  ScopedFd points_file(temp_dir / "points.bin", O_RDWR | O_CREAT, "temporary file");
  const int fd = points_file.get();
  // The bucketed route reads the regions a group at a time (a group too large for half the
  // memory is spilled to the file first); the other route reads them from the file in key order.
  std::vector<ChunkGroup> groups;
  std::vector<bool> spilled;
  if (dist.bucketed()) {
    const uint64_t group_max =
        std::max(region_max, (options.memory_mb << 20) / 2 / (2 * sizeof(BuildPoint) + 8));
    uint64_t temp_end = 0;
    groups = dist.groups(regions);
    for (const ChunkGroup& g : groups) {
      spilled.push_back(g.points > group_max);
      if (spilled.back()) dist.spillGroup(g, regions, fd, points_file.name(), temp_end);
    }
  } else {
    std::sort(regions.begin(), regions.end(),
              [](const Chunk& a, const Chunk& b) { return a.key < b.key; });
  }

  std::unordered_map<NodeId, ActiveNode> active;
  std::unordered_map<NodeId, bool> corrupt;
  // Leaves whose every stored point is matched: released, so memory holds the leaves the
  // regions are working through (a leaf across a region's border waits for its other part),
  // never every leaf met so far. A later input point cannot bring one back.
  std::unordered_set<NodeId> finished;
  auto activate = [&](NodeId id) {
    if (active.count(id) || corrupt.count(id) || finished.count(id)) return;
    std::shared_ptr<ChunkPoints> pts;
    try {
      pts = store->decodeChunk(id, {}, true);
    } catch (const StoreError&) {
      corrupt[id] = true;
      ++report.corrupt_chunks;
      return;
    }
    ActiveNode a;
    a.box_min = pts->offset;
    a.grid = pts->grid;
    a.step = pts->step;
    a.bound = store->node(id).error_bound;
    for (const glm::uvec3& c : pts->cells) ++a.keys[CellKey{0, c.x, c.y, c.z}];
    a.remaining = pts->cells.size();
    active.emplace(id, std::move(a));
  };

  Progress progress(dist.bucketed() ? "verify 2/2 matching" : "verify 4/4 matching",
                    dist.points(), " points", options.quiet);
  std::vector<NodeId> path;
  auto matchRegion = [&](const Chunk& region, const std::vector<BuildPoint>& pts) {
    const glm::dvec3 lo = frame.cellMin(region.key), hi = lo + frame.cellSize(region.key.level);
    // Every node overlapping the region (ancestors and descendants).
    std::vector<NodeId> todo{store->root()};
    while (!todo.empty()) {
      NodeId id = todo.back();
      todo.pop_back();
      NodeInfo n = store->node(id);
      if (!overlaps(n, lo, hi)) continue;
      if (n.points > 0 && n.leaf()) activate(id);
      for (NodeId c : store->children(id)) todo.push_back(c);
    }
    for (const BuildPoint& bp : pts) {
      const glm::dvec3 p = bp.position;
      path.clear();
      for (int level = 0; level < int(sum.depth); ++level) {
        auto it = by_key.find(frame.cellOf(p, level));
        if (it == by_key.end()) break;
        path.push_back(it->second);
      }
      bool matched = false;
      // The deepest node on p's path is the leaf that must hold it.
      auto a = path.empty() ? active.end() : active.find(path.back());
      if (a != active.end()) {
        ActiveNode& node = a->second;
        const glm::dvec3 q0 = glm::max(
            glm::round((p - node.box_min - node.grid) / node.step), glm::dvec3(0.0));
        // The key p rounds to first; then its 26 neighbours: a point half a step from the grid
        // (every point of a leaf whose grid is offset by half a step from the input's own, as
        // inputs without a declared lattice give) may have been rounded the other way.
        for (int n = -1; n < 27 && !matched; ++n) {  // -1: q0; 0-26: the cube around it
          const glm::dvec3 q =
              n < 0 ? q0 : q0 + glm::dvec3(n % 3 - 1, n / 3 % 3 - 1, n / 9 - 1);
          if (n == 13 || glm::any(glm::lessThan(q, glm::dvec3(0.0)))) continue;  // 13: q0 again
          auto k = node.keys.find(packKey(q));
          if (k == node.keys.end() || k->second == 0) continue;
          // The decoded position: exact leaves in double (the integers they keep), others as a
          // renderer gets them (float relative to the node).
          const bool exact =
              sum.exact_leaves && node.bound <= store::kLatticeTolerance * node.step * 1.001;
          const glm::dvec3 stored =
              exact ? node.box_min + node.grid + q * node.step
                    : node.box_min +
                          glm::dvec3(glm::vec3(q) * float(node.step) + glm::vec3(node.grid));
          const double d = glm::length(stored - p);
          if (d > node.bound) continue;
          --k->second;
          --node.remaining;
          matched = true;
          if (exact) ++report.exact;
          report.max_error = std::max(report.max_error, d);
          if (node.bound > 0)
            report.max_error_ratio = std::max(report.max_error_ratio, d / node.bound);
        }
      }
      if (matched) {
        ++report.matched;
        if (a->second.remaining == 0) {
          finished.insert(a->first);
          active.erase(a);
        }
      } else {
        ++report.unmatched;
      }
    }
    progress.add(region.count);
    // Nodes entirely inside this region are done.
    for (auto it = active.begin(); it != active.end();) {
      if (inside(store->node(it->first), lo, hi)) {
        it = active.erase(it);
      } else {
        ++it;
      }
    }
  };
  std::vector<BuildPoint> pts;
  auto fromFile = [&](const Chunk& region) {
    pts.resize(region.count);
    readTempPoints(dist.tempLayout(), fd, region.first, region.count, pts.data(),
                   "verify temporary file");
    matchRegion(region, pts);
  };
  if (!dist.bucketed()) {
    for (const Chunk& region : regions) fromFile(region);
    return report;
  }
  std::vector<std::vector<BuildPoint>> by_region;
  for (size_t g = 0; g < groups.size(); ++g) {
    if (spilled[g]) {
      for (uint32_t ci : groups[g].chunks) fromFile(regions[ci]);
      continue;
    }
    dist.readGroup(groups[g], regions, by_region);
    for (size_t j = 0; j < groups[g].chunks.size(); ++j) {
      matchRegion(regions[groups[g].chunks[j]], by_region[j]);
      std::vector<BuildPoint>().swap(by_region[j]);
    }
  }
  return report;
}

}  // namespace tessera::lod
