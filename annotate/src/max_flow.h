// Max-flow / min-cut on sparse graphs with terminal links: the Boykov-Kolmogorov algorithm
// (Y. Boykov, V. Kolmogorov, "An experimental comparison of min-cut/max-flow algorithms for
// energy minimization in vision", PAMI 2004), the solver lazy snapping uses (thesis 4.2.1, [5]).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace tessera::annotate {

/// A directed graph with a source and a sink, built once and cut once.
///
/// Capacities are non-negative doubles (finite; use a large finite value for "infinite" seeds).
/// Memory: 2 arcs of 16 bytes per addEdge() plus 32 bytes per node. maxflow() costs
/// O(n^2 m |C|) in the worst case, close to linear on the grid-like graphs of segmentation.
/// Not thread-safe; one graph per cut.
class MaxFlowGraph {
 public:
  explicit MaxFlowGraph(uint32_t nodes = 0, size_t edges_hint = 0);

  /// Appends `count` nodes; returns the index of the first.
  uint32_t addNodes(uint32_t count);
  uint32_t nodeCount() const { return uint32_t(mNodes.size()); }

  /// Adds capacity source -> `node` and `node` -> sink (accumulates over calls).
  void addTerminalWeights(uint32_t node, double to_source_side, double to_sink_side);
  /// An edge i -> j of capacity `cap` and j -> i of capacity `rev_cap` (i != j).
  void addEdge(uint32_t i, uint32_t j, double cap, double rev_cap);

  /// Runs the algorithm; returns the max-flow value (= the min-cut capacity). Call once.
  double maxflow();
  /// After maxflow(): true when `node` is on the source side of the minimum cut (the set of
  /// nodes reachable from the source in the residual graph).
  bool isSourceSide(uint32_t node) const;

 private:
  static constexpr int32_t kNone = -1, kTerminal = -2, kOrphan = -3;
  struct Arc {
    uint32_t head;
    int32_t next;  ///< next arc out of the same tail, kNone at the end
    double r_cap;  ///< residual capacity
  };
  struct Node {
    int32_t first = kNone;   ///< first outgoing arc
    int32_t parent = kNone;  ///< arc to the parent in its tree, kTerminal, kOrphan or kNone (free)
    uint32_t ts = 0;         ///< time stamp of dist
    uint32_t dist = 0;       ///< distance to the terminal (heuristic)
    bool is_sink = false;
    bool active = false;
    double tr_cap = 0;  ///< residual terminal capacity: > 0 from the source, < 0 to the sink
  };
  static int32_t sister(int32_t a) { return a ^ 1; }
  void setActive(uint32_t i);
  void augment(int32_t middle);
  void adoptOrphan(uint32_t i);

  std::vector<Node> mNodes;
  std::vector<Arc> mArcs;
  std::vector<uint32_t> mActive;  ///< FIFO of active nodes, from mActiveHead
  size_t mActiveHead = 0;
  std::vector<uint32_t> mOrphans;
  uint32_t mTime = 0;
  double mFlow = 0;
  bool mDone = false;
};

}  // namespace tessera::annotate
