#include "max_flow.h"

#include <algorithm>
#include <cassert>
#include <limits>

#include <tessera/core/check.h>

namespace tessera::annotate {

namespace {
constexpr uint32_t kInfiniteDist = std::numeric_limits<uint32_t>::max();
}

MaxFlowGraph::MaxFlowGraph(uint32_t nodes, size_t edges_hint) {
  mNodes.resize(nodes);
  mArcs.reserve(2 * edges_hint);
}

uint32_t MaxFlowGraph::addNodes(uint32_t count) {
  const uint32_t first = uint32_t(mNodes.size());
  mNodes.resize(size_t(first) + count);
  return first;
}

void MaxFlowGraph::addTerminalWeights(uint32_t node, double to_source_side, double to_sink_side) {
  TESSERA_CHECK(node < mNodes.size(), "MaxFlowGraph::addTerminalWeights(): node out of range");
  TESSERA_CHECK(to_source_side >= 0 && to_sink_side >= 0,
                "MaxFlowGraph::addTerminalWeights(): capacities must be non-negative");
  // Both terminal links of a node carry min(cs, ct) on the path s -> node -> t whatever the
  // cut, so that much flow is pushed now and only the difference is kept (BK 2004, section 3).
  Node& n = mNodes[node];
  const double cs = to_source_side + std::max(n.tr_cap, 0.0);
  const double ct = to_sink_side + std::max(-n.tr_cap, 0.0);
  mFlow += std::min(cs, ct);
  n.tr_cap = cs - ct;
}

void MaxFlowGraph::addEdge(uint32_t i, uint32_t j, double cap, double rev_cap) {
  TESSERA_CHECK(i < mNodes.size() && j < mNodes.size() && i != j,
                "MaxFlowGraph::addEdge(): nodes out of range or equal");
  TESSERA_CHECK(cap >= 0 && rev_cap >= 0, "MaxFlowGraph::addEdge(): negative capacity");
  const int32_t a = int32_t(mArcs.size());
  mArcs.push_back({j, mNodes[i].first, cap});
  mArcs.push_back({i, mNodes[j].first, rev_cap});
  mNodes[i].first = a;
  mNodes[j].first = a + 1;
}

void MaxFlowGraph::setActive(uint32_t i) {
  if (mNodes[i].active) return;
  mNodes[i].active = true;
  mActive.push_back(i);
}

double MaxFlowGraph::maxflow() {
  TESSERA_CHECK(!mDone, "MaxFlowGraph::maxflow(): already run");
  mDone = true;
  // Initial trees: every node with residual terminal capacity is a root of its terminal's tree.
  for (uint32_t i = 0; i < mNodes.size(); ++i) {
    Node& n = mNodes[i];
    if (n.tr_cap != 0) {
      n.is_sink = n.tr_cap < 0;
      n.parent = kTerminal;
      n.ts = 0;
      n.dist = 1;
      setActive(i);
    }
  }
  int64_t current = -1;
  while (true) {
    uint32_t i;
    if (current >= 0) {
      i = uint32_t(current);
      current = -1;
      if (mNodes[i].parent == kNone) continue;
    } else {
      if (mActiveHead == mActive.size()) break;
      i = mActive[mActiveHead++];
      if (mActiveHead > 4096 && mActiveHead * 2 > mActive.size()) {
        mActive.erase(mActive.begin(), mActive.begin() + std::ptrdiff_t(mActiveHead));
        mActiveHead = 0;
      }
      mNodes[i].active = false;
      if (mNodes[i].parent == kNone) continue;
    }
    // Growth (BK 2004, section 3.2): explore i's residual arcs; a node of the other tree
    // closes an s-t path through the arc `middle` (oriented source tree -> sink tree).
    int32_t middle = kNone;
    Node& ni = mNodes[i];
    for (int32_t a = ni.first; a != kNone; a = mArcs[size_t(a)].next) {
      const double r = ni.is_sink ? mArcs[size_t(sister(a))].r_cap : mArcs[size_t(a)].r_cap;
      if (r <= 0) continue;
      const uint32_t j = mArcs[size_t(a)].head;
      Node& nj = mNodes[j];
      if (nj.parent == kNone) {
        nj.is_sink = ni.is_sink;
        nj.parent = sister(a);
        nj.ts = ni.ts;
        nj.dist = ni.dist + 1;
        setActive(j);
      } else if (nj.is_sink != ni.is_sink) {
        middle = ni.is_sink ? sister(a) : a;
        break;
      } else if (nj.ts <= ni.ts && nj.dist > ni.dist) {
        // A shorter path to the terminal through i (the distance heuristic of section 3.2).
        nj.parent = sister(a);
        nj.ts = ni.ts;
        nj.dist = ni.dist + 1;
      }
    }
    ++mTime;
    if (middle == kNone) continue;
    current = i;  // i may still have other paths
    augment(middle);
    // Adoption (section 3.3): orphans look for a new parent in their tree or become free.
    for (size_t k = 0; k < mOrphans.size(); ++k) {
      adoptOrphan(mOrphans[k]);
    }
    mOrphans.clear();
  }
  return mFlow;
}

void MaxFlowGraph::augment(int32_t middle) {
  // Bottleneck along source root -> ... -> tail(middle) -> head(middle) -> ... -> sink root.
  double b = mArcs[size_t(middle)].r_cap;
  uint32_t i = mArcs[size_t(sister(middle))].head;
  while (mNodes[i].parent != kTerminal) {
    const int32_t pa = mNodes[i].parent;
    b = std::min(b, mArcs[size_t(sister(pa))].r_cap);
    i = mArcs[size_t(pa)].head;
  }
  b = std::min(b, mNodes[i].tr_cap);
  i = mArcs[size_t(middle)].head;
  while (mNodes[i].parent != kTerminal) {
    const int32_t pa = mNodes[i].parent;
    b = std::min(b, mArcs[size_t(pa)].r_cap);
    i = mArcs[size_t(pa)].head;
  }
  b = std::min(b, -mNodes[i].tr_cap);
  assert(b > 0);

  mArcs[size_t(sister(middle))].r_cap += b;
  mArcs[size_t(middle)].r_cap -= b;
  // Saturated arcs orphan their child (the node below them in the tree).
  i = mArcs[size_t(sister(middle))].head;
  while (mNodes[i].parent != kTerminal) {
    const int32_t pa = mNodes[i].parent;
    mArcs[size_t(pa)].r_cap += b;
    mArcs[size_t(sister(pa))].r_cap -= b;
    if (mArcs[size_t(sister(pa))].r_cap <= 0) {
      mNodes[i].parent = kOrphan;
      mOrphans.push_back(i);
    }
    i = mArcs[size_t(pa)].head;
  }
  mNodes[i].tr_cap -= b;
  if (mNodes[i].tr_cap <= 0) {
    mNodes[i].parent = kOrphan;
    mOrphans.push_back(i);
  }
  i = mArcs[size_t(middle)].head;
  while (mNodes[i].parent != kTerminal) {
    const int32_t pa = mNodes[i].parent;
    mArcs[size_t(sister(pa))].r_cap += b;
    mArcs[size_t(pa)].r_cap -= b;
    if (mArcs[size_t(pa)].r_cap <= 0) {
      mNodes[i].parent = kOrphan;
      mOrphans.push_back(i);
    }
    i = mArcs[size_t(pa)].head;
  }
  mNodes[i].tr_cap += b;
  if (mNodes[i].tr_cap >= 0) {
    mNodes[i].parent = kOrphan;
    mOrphans.push_back(i);
  }
  mFlow += b;
}

void MaxFlowGraph::adoptOrphan(uint32_t i) {
  // A new parent is a node of the same tree with residual capacity towards i (source tree:
  // j -> i; sink tree: i -> j) whose path leads to the terminal, not to another orphan; the
  // one nearest to the terminal wins (BK 2004, section 3.3).
  const bool sink = mNodes[i].is_sink;
  auto residual = [&](int32_t a0) {
    return sink ? mArcs[size_t(a0)].r_cap : mArcs[size_t(sister(a0))].r_cap;
  };
  int32_t best = kNone;
  uint32_t best_d = kInfiniteDist;
  for (int32_t a0 = mNodes[i].first; a0 != kNone; a0 = mArcs[size_t(a0)].next) {
    if (residual(a0) <= 0) continue;
    uint32_t j = mArcs[size_t(a0)].head;
    if (mNodes[j].is_sink != sink || mNodes[j].parent == kNone) continue;
    uint32_t d = 0;
    while (true) {
      if (mNodes[j].ts == mTime) {
        d += mNodes[j].dist;
        break;
      }
      const int32_t a = mNodes[j].parent;
      ++d;
      if (a == kTerminal) {
        mNodes[j].ts = mTime;
        mNodes[j].dist = 1;
        break;
      }
      if (a == kOrphan) {
        d = kInfiniteDist;
        break;
      }
      j = mArcs[size_t(a)].head;
    }
    if (d == kInfiniteDist) continue;
    if (d < best_d) {
      best = a0;
      best_d = d;
    }
    // Stamp the path so later searches in this round stop early.
    for (j = mArcs[size_t(a0)].head; mNodes[j].ts != mTime;
         j = mArcs[size_t(mNodes[j].parent)].head) {
      mNodes[j].ts = mTime;
      mNodes[j].dist = d--;
    }
  }
  mNodes[i].parent = best;
  if (best != kNone) {
    mNodes[i].ts = mTime;
    mNodes[i].dist = best_d + 1;
    return;
  }
  // Free now: neighbours that could reach i become active, its children become orphans.
  for (int32_t a0 = mNodes[i].first; a0 != kNone; a0 = mArcs[size_t(a0)].next) {
    const uint32_t j = mArcs[size_t(a0)].head;
    const int32_t a = mNodes[j].parent;
    if (mNodes[j].is_sink != sink || a == kNone) continue;
    if (residual(a0) > 0) setActive(j);
    if (a != kTerminal && a != kOrphan && mArcs[size_t(a)].head == i) {
      mNodes[j].parent = kOrphan;
      mOrphans.push_back(j);
    }
  }
}

bool MaxFlowGraph::isSourceSide(uint32_t node) const {
  TESSERA_CHECK(mDone, "MaxFlowGraph::isSourceSide(): call maxflow() first");
  TESSERA_CHECK(node < mNodes.size(), "MaxFlowGraph::isSourceSide(): node out of range");
  const Node& n = mNodes[node];
  return n.parent != kNone && !n.is_sink;
}

}  // namespace tessera::annotate
