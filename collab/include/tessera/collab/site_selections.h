// Sites' lassos and snaps (site.proto SiteSelect, SiteSnap; issue 16): the master selects at full
// resolution what of a model lies inside a site's lasso, on a worker thread of its own, so the wall
// never waits for a selection of 10^8 points (about half a second here, bench/lasso). Each finished
// selection becomes a SELECTION node recorded as the site's before the next frame.
//
// The master opens the stores it selects in itself (shared with the jobs that use them, so a
// model removed meanwhile cannot close a store under a job); a job whose model was removed or
// re-pointed meanwhile is dropped when it finishes. At most kMaxPending lassos per site and
// kMaxQueued in all wait; more are refused with a message.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include <tessera/site.pb.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::collab {

class SiteSelections {
 public:
  static constexpr int kMaxPending = 2;
  static constexpr int kMaxQueued = 16;
  using Say = std::function<void(const std::string&)>;

  explicit SiteSelections(Say say);
  ~SiteSelections();  ///< waits for the job at work, drops the queued ones

  /// Queues a checked SiteSelect from participant `site` (its name `name`). Refused (said) when
  /// the model is not a MODEL node, its store cannot be opened, or too many are waiting.
  void request(const sync::SceneGraph& graph, uint32_t site, const std::string& name,
               const site::SiteSelect& select);
  /// Queues a checked SiteSnap (lazy snapping, or the robust lasso with heavy_width > 0; see
  /// master/snap_tool.h), refused as a lasso is; its strokes count among the site's pending.
  void request(const sync::SceneGraph& graph, uint32_t site, const std::string& name,
               const site::SiteSnap& snap);
  /// Before a frame: the finished selections as SELECTION nodes. Returns how many were added.
  int collect(sync::SceneGraph& graph);
  /// Jobs queued or at work.
  int pending() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
  template <class Job>
  void enqueue(const sync::SceneGraph& graph, uint32_t site, const std::string& name,
               uint32_t model, Job job);
};

}  // namespace tessera::collab
