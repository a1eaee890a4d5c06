// A render node's loop (render_node/): joins the master through a cluster link
// (sync/cluster_link.h), receives the wall, its tile and a snapshot, then per frame applies the
// master's changes to its replica, renders its tile's off-axis view, reports (statistics, and the
// pixels when the frame asks for read-back), and presents at the swap. A node that cannot start
// or goes wrong says why to the master (a cluster::NodeFailure code and text) instead of dying
// silently; a node dropped by the master (it missed a deadline) joins again with its caches warm.
//
// Owns the GL context (a window, or headless EGL): construct, run and destroy it on one thread.
#pragma once

#include <memory>
#include <string>

#include <tessera/sync/cluster_link.h>

namespace tessera::render_node {

struct NodeOptions {
  bool headless = false;       ///< render off-screen (EGL) instead of in a window
  std::string tile;            ///< the tile to drive (empty: the first free one)
  double join_timeout_s = 10;  ///< waiting for the master's welcome
  /// After losing the master: wait this long for a new one at the same endpoint (0: exit).
  double wait_master_s = 0;
  /// No message from the master for this long ends the node (ZeroMQ heartbeats notice a dead
  /// master much sooner; this bounds a master alive but stuck).
  double master_timeout_s = 600;
};

class RenderNode {
 public:
  RenderNode(sync::NodeLink& link, NodeOptions options);
  ~RenderNode();

  /// The whole session. Returns the exit code: 0 when the master ended the session, else a
  /// cluster::NodeFailure (NODE_REFUSED, NODE_MASTER_LOST, or why this node failed). Prints
  /// what happened to stderr, starting "tessera-node".
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace tessera::render_node
