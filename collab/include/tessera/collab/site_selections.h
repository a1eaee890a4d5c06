// Sites' lassos and snaps (site.proto SiteSelect, SiteSnap) as requests to the master's
// selection worker (master/selection_worker.h): selected at full resolution on a thread of its
// own, so the wall never waits for a selection of 10^8 points; each finished one becomes a
// SELECTION node recorded as the site's before the next frame. At most
// SelectionWorker::kMaxPending per site and kMaxQueued in all wait; more are refused (said).
#pragma once

#include <cstdint>
#include <string>

#include <tessera/master/selection_worker.h>
#include <tessera/site.pb.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::collab {

class SiteSelections {
 public:
  using Say = master::SelectionWorker::Say;

  explicit SiteSelections(Say say) : mWorker(std::move(say)) {}

  /// Queues a checked SiteSelect from participant `site` (its name `name`).
  void request(const sync::SceneGraph& graph, uint32_t site, const std::string& name,
               const site::SiteSelect& select);
  /// Queues a checked SiteSnap (lazy snapping, or the robust lasso with heavy_width > 0; see
  /// interact/snap_tool.h).
  void request(const sync::SceneGraph& graph, uint32_t site, const std::string& name,
               const site::SiteSnap& snap);
  /// Before a frame: the finished selections as SELECTION nodes. Returns how many were added.
  int collect(sync::SceneGraph& graph) { return mWorker.collect(graph); }
  /// Jobs queued or at work.
  int pending() const { return mWorker.pending(); }

 private:
  master::SelectionWorker mWorker;
};

}  // namespace tessera::collab
