// Selections made off the master's loop: a lasso on 10^8 points takes about half a
// second here (bench/lasso), lazy snapping on a point store seconds (bench/lazy_snapping), and
// the wall must not wait for either. Requests from sites (collab/site_selections.h) and the
// console's snap tool go to one worker thread; each finished selection becomes a SELECTION node
// recorded as its requester's before the next frame.
//
// The worker opens the stores it selects in itself (shared with the jobs that use them, so a
// model removed meanwhile cannot close a store under a job); a job whose model was removed or
// re-pointed meanwhile is dropped when it finishes. At most kMaxPending requests per requester
// and kMaxQueued in all wait; more are refused with a message.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/render/tile_frustum.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::master {

struct SelectionRequest {
  enum class Kind { kLasso, kSnap, kRobustLasso } kind = Kind::kLasso;
  uint32_t model = 0;     ///< the MODEL node
  render::ViewSetup view;  ///< the view the pixels are in
  /// The lasso (kLasso), the foreground stroke (kSnap, one polyline) or the
  /// heavy stroke (kRobustLasso), in the view's pixels (x right, y down from the top-left).
  std::vector<glm::dvec2> pixels;
  std::vector<glm::dvec2> background;  ///< kSnap: the background strokes
  double heavy_width = 0.0;            ///< kRobustLasso: the stroke's width, pixels

  const char* what() const {
    return kind == Kind::kLasso ? "lasso" : kind == Kind::kSnap ? "snap" : "robust lasso";
  }
};

class SelectionWorker {
 public:
  static constexpr int kMaxPending = 2;
  static constexpr int kMaxQueued = 16;
  using Say = std::function<void(const std::string&)>;

  explicit SelectionWorker(Say say);
  ~SelectionWorker();  ///< waits for the job at work, drops the queued ones
  SelectionWorker(const SelectionWorker&) = delete;
  SelectionWorker& operator=(const SelectionWorker&) = delete;

  /// Queues a request from requester `who` (named `name`: the author of its node). Refused
  /// (said) when the model is not a MODEL node, its store cannot be opened, or too many wait.
  /// Returns whether it was queued.
  bool request(const sync::SceneGraph& graph, uint32_t who, const std::string& name,
               SelectionRequest request);
  /// Before a frame: the finished selections as SELECTION nodes. Returns how many were added.
  int collect(sync::SceneGraph& graph);
  /// Jobs queued or at work.
  int pending() const;
  /// Stores held open for selections: those the scene's models name, and those a job still
  /// uses (collect() closes the rest).
  size_t openStores() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace tessera::master
