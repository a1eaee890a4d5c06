#include <tessera/master/selection_worker.h>

#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <thread>

#include <set>

#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_store.h>
#include <tessera/interact/select_tool.h>
#include <tessera/interact/snap_tool.h>
#include <tessera/render/scene_draw_list.h>

namespace tessera::master {

namespace {

/// A store as the jobs share it.
struct SharedStore {
  std::shared_ptr<lod::PointStore> points;
  std::shared_ptr<lod::MeshStore> mesh;
};

}  // namespace

struct SelectionWorker::Impl {
  Say say;
  std::map<std::string, SharedStore> stores;  // by path, as the scene names them
  struct Job {
    SelectionRequest request;
    uint32_t who = 0;
    std::string name, store;
    SharedStore shared;
    render::ModelInstance instance;
    interact::LassoSelection result;
    std::string error;
  };
  mutable std::mutex mutex;
  std::condition_variable wake;
  std::deque<Job> queued, finished;
  std::map<uint32_t, int> per_who;  // queued or at work
  bool stop = false;
  std::thread worker;

  void run() {
    std::unique_lock lock(mutex);
    while (true) {
      wake.wait(lock, [&] { return stop || !queued.empty(); });
      if (stop) return;
      Job job = std::move(queued.front());
      queued.pop_front();
      lock.unlock();
      try {
        // One thread: the master's loop and the nodes of this host keep the other core.
        const SelectionRequest& r = job.request;
        if (r.kind == SelectionRequest::Kind::kLasso)
          job.result = interact::lassoSelection(job.instance, r.model, r.view, r.pixels, 1);
        else if (r.kind == SelectionRequest::Kind::kSnap)
          job.result = interact::snapSelection(job.instance, r.model, r.view, r.pixels, r.background);
        else
          job.result =
              interact::robustLassoSelection(job.instance, r.model, r.view, r.pixels, r.heavy_width);
      } catch (const std::exception& e) {
        job.error = e.what();
      }
      lock.lock();
      finished.push_back(std::move(job));
    }
  }
};

SelectionWorker::SelectionWorker(Say say) : m(std::make_unique<Impl>()) {
  m->say = std::move(say);
  m->worker = std::thread([impl = m.get()] { impl->run(); });
}

SelectionWorker::~SelectionWorker() {
  {
    std::lock_guard lock(m->mutex);
    m->stop = true;
  }
  m->wake.notify_all();
  m->worker.join();
}

int SelectionWorker::pending() const {
  std::lock_guard lock(m->mutex);
  int n = 0;
  for (const auto& [who, count] : m->per_who) n += count;
  return n;
}

bool SelectionWorker::request(const sync::SceneGraph& graph, uint32_t who,
                              const std::string& name, SelectionRequest request) {
  const uint32_t model = request.model;
  auto refuse = [&](const std::string& why) {
    m->say(name + ": " + request.what() + " refused: " + why);
    return false;
  };
  if (!graph.contains(model) || graph.node(model).kind() != scene::SceneNode::MODEL)
    return refuse("node " + std::to_string(model) + " is not a model");
  {
    std::lock_guard lock(m->mutex);
    if (m->per_who[who] >= kMaxPending)
      return refuse(std::to_string(kMaxPending) + " of its selections are still being made");
    if (int(m->queued.size()) >= kMaxQueued) return refuse("the master is busy selecting");
  }
  const std::string& path = graph.node(model).model().store();
  SharedStore& store = m->stores[path];
  try {
    if (!store.points && !store.mesh) {
      if (render::SceneDrawList::isMeshPath(path))
        store.mesh = lod::MeshStore::open(path);
      else
        store.points = lod::PointStore::open(path);
    }
  } catch (const std::exception& e) {
    m->stores.erase(path);
    return refuse(e.what());
  }
  Impl::Job job;
  job.request = std::move(request);
  job.who = who;
  job.name = name;
  job.store = path;
  job.shared = store;
  const render::NodePlacement placed = render::placeNode(graph, model);
  job.instance.store = store.points.get();
  job.instance.mesh = store.mesh.get();
  job.instance.model = placed.world * (store.mesh ? render::storeModel(*store.mesh)
                                                  : render::storeModel(*store.points));
  {
    std::lock_guard lock(m->mutex);
    m->per_who[who]++;
    m->queued.push_back(std::move(job));
  }
  m->wake.notify_one();
  return true;
}

int SelectionWorker::collect(sync::SceneGraph& graph) {
  std::deque<Impl::Job> done;
  {
    std::lock_guard lock(m->mutex);
    done.swap(m->finished);
    for (const Impl::Job& j : done)
      if (--m->per_who[j.who] <= 0) m->per_who.erase(j.who);
  }
  int added = 0;
  for (const Impl::Job& j : done) {
    if (!j.error.empty()) {
      m->say(j.name + ": " + j.request.what() + " failed: " + j.error);
      continue;
    }
    const uint32_t model = j.request.model;
    if (!graph.contains(model) || graph.node(model).kind() != scene::SceneNode::MODEL ||
        graph.node(model).model().store() != j.store) {
      m->say(j.name + ": " + j.request.what() + " dropped: its model changed while it was selected");
      continue;
    }
    if (j.result.count == 0) {
      m->say(j.name + ": " + j.request.what() + " on model " + std::to_string(model) +
             ": nothing selected");
      continue;
    }
    try {
      interact::addSelection(graph, j.result.payload, j.name);
      ++added;
      m->say(j.name + ": " + j.request.what() + " on model " + std::to_string(model) + ": " +
             std::to_string(j.result.count) + " elements selected" +
             (j.result.corrupt
                  ? " (" + std::to_string(j.result.corrupt) + " corrupt leaves skipped)"
                  : std::string()));
    } catch (const std::exception& e) {  // over 16 MiB of elements
      m->say(j.name + ": " + j.request.what() + " refused: " + e.what());
    }
  }
  done.clear();
  // Stores stay open while a model of the scene names them (the next lasso on it opens
  // nothing); one no model names and no job holds closes. Only this thread copies the map's
  // pointers, so a count of one means no job has it.
  std::set<std::string> named;
  for (const auto id : graph.ids())
    if (graph.node(id).kind() == scene::SceneNode::MODEL) named.insert(graph.node(id).model().store());
  std::erase_if(m->stores, [&](const auto& entry) {
    const SharedStore& s = entry.second;
    return !named.count(entry.first) && (!s.points || s.points.use_count() == 1) &&
           (!s.mesh || s.mesh.use_count() == 1);
  });
  return added;
}

size_t SelectionWorker::openStores() const {
  return m->stores.size();
}

}  // namespace tessera::master
