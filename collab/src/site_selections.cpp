#include <tessera/collab/site_selections.h>

#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <thread>

#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_store.h>
#include <tessera/master/select_tool.h>
#include <tessera/master/snap_tool.h>
#include <tessera/render/scene_draw_list.h>

namespace tessera::collab {

namespace {

/// A store as the jobs share it.
struct SharedStore {
  std::shared_ptr<lod::PointStore> points;
  std::shared_ptr<lod::MeshStore> mesh;
};

}  // namespace

struct SiteSelections::Impl {
  Say say;
  std::map<std::string, SharedStore> stores;  // by path, as the scene names them
  struct Job {
    enum class Kind { kLasso, kSnap, kRobustLasso } kind = Kind::kLasso;
    uint32_t site = 0;
    std::string name, store;
    uint32_t model = 0;
    SharedStore shared;
    render::ModelInstance instance;
    render::ViewSetup view;
    std::vector<glm::dvec2> lasso;       ///< the lasso, or the foreground or heavy stroke
    std::vector<glm::dvec2> background;  ///< kSnap
    double heavy_width = 0.0;            ///< kRobustLasso
    master::LassoSelection result;
    const char* what() const {
      return kind == Kind::kLasso ? "lasso" : kind == Kind::kSnap ? "snap" : "robust lasso";
    }
    std::string error;
  };
  mutable std::mutex mutex;
  std::condition_variable wake;
  std::deque<Job> queued, finished;
  std::map<uint32_t, int> per_site;  // queued or at work
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
        if (job.kind == Job::Kind::kLasso)
          job.result = master::lassoSelection(job.instance, job.model, job.view, job.lasso, 1);
        else if (job.kind == Job::Kind::kSnap)
          job.result =
              master::snapSelection(job.instance, job.model, job.view, job.lasso, job.background);
        else
          job.result = master::robustLassoSelection(job.instance, job.model, job.view, job.lasso,
                                                    job.heavy_width);
      } catch (const std::exception& e) {
        job.error = e.what();
      }
      lock.lock();
      finished.push_back(std::move(job));
    }
  }
};

SiteSelections::SiteSelections(Say say) : m(std::make_unique<Impl>()) {
  m->say = std::move(say);
  m->worker = std::thread([impl = m.get()] { impl->run(); });
}

SiteSelections::~SiteSelections() {
  {
    std::lock_guard lock(m->mutex);
    m->stop = true;
  }
  m->wake.notify_all();
  m->worker.join();
}

int SiteSelections::pending() const {
  std::lock_guard lock(m->mutex);
  int n = 0;
  for (const auto& [site, count] : m->per_site) n += count;
  return n;
}

namespace {

/// The job's view from a SiteSelect or SiteSnap (checked: 16 + 16 numbers).
template <class M>
render::ViewSetup sentView(const M& s) {
  render::ViewSetup v;
  for (int k = 0; k < 16; ++k) {
    v.view[k / 4][k % 4] = s.view(k);
    v.projection[k / 4][k % 4] = s.projection(k);
  }
  v.width = s.width();
  v.height = s.height();
  return v;
}

std::vector<glm::dvec2> pixelsOf(const google::protobuf::RepeatedField<double>& px) {
  std::vector<glm::dvec2> out;
  for (int i = 0; i + 1 < px.size(); i += 2) out.emplace_back(px[i], px[i + 1]);
  return out;
}

}  // namespace

void SiteSelections::request(const sync::SceneGraph& graph, uint32_t site, const std::string& name,
                             const site::SiteSelect& s) {
  Impl::Job job;
  job.view = sentView(s);
  job.lasso = pixelsOf(s.lasso());
  enqueue(graph, site, name, s.model(), std::move(job));
}

void SiteSelections::request(const sync::SceneGraph& graph, uint32_t site, const std::string& name,
                             const site::SiteSnap& s) {
  Impl::Job job;
  job.kind = s.heavy_width() > 0.0f ? Impl::Job::Kind::kRobustLasso : Impl::Job::Kind::kSnap;
  job.view = sentView(s);
  job.lasso = pixelsOf(s.foreground());
  job.background = pixelsOf(s.background());
  job.heavy_width = s.heavy_width();
  enqueue(graph, site, name, s.model(), std::move(job));
}

template <class Job>
void SiteSelections::enqueue(const sync::SceneGraph& graph, uint32_t site, const std::string& name,
                             uint32_t model, Job job) {
  auto refuse = [&](const std::string& why) {
    m->say(name + ": " + job.what() + " refused: " + why);
  };
  if (!graph.contains(model) || graph.node(model).kind() != scene::SceneNode::MODEL)
    return refuse("node " + std::to_string(model) + " is not a model");
  {
    std::lock_guard lock(m->mutex);
    if (m->per_site[site] >= kMaxPending)
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
  job.site = site;
  job.name = name;
  job.store = path;
  job.model = model;
  job.shared = store;
  const render::NodePlacement placed = render::placeNode(graph, model);
  job.instance.store = store.points.get();
  job.instance.mesh = store.mesh.get();
  job.instance.model = placed.world * (store.mesh ? render::storeModel(*store.mesh)
                                                  : render::storeModel(*store.points));
  {
    std::lock_guard lock(m->mutex);
    m->per_site[site]++;
    m->queued.push_back(std::move(job));
  }
  m->wake.notify_one();
}

int SiteSelections::collect(sync::SceneGraph& graph) {
  std::deque<Impl::Job> done;
  {
    std::lock_guard lock(m->mutex);
    done.swap(m->finished);
    for (const Impl::Job& j : done)
      if (--m->per_site[j.site] <= 0) m->per_site.erase(j.site);
  }
  int added = 0;
  for (const Impl::Job& j : done) {
    if (!j.error.empty()) {
      m->say(j.name + ": " + j.what() + " failed: " + j.error);
      continue;
    }
    if (!graph.contains(j.model) || graph.node(j.model).kind() != scene::SceneNode::MODEL ||
        graph.node(j.model).model().store() != j.store) {
      m->say(j.name + ": " + j.what() + " dropped: its model changed while it was selected");
      continue;
    }
    if (j.result.count == 0) {
      m->say(j.name + ": " + j.what() + " on model " + std::to_string(j.model) +
             ": nothing selected");
      continue;
    }
    try {
      master::addSelection(graph, j.result.payload, j.name);
      ++added;
      m->say(j.name + ": " + j.what() + " on model " + std::to_string(j.model) + ": " +
             std::to_string(j.result.count) + " elements selected" +
             (j.result.corrupt
                  ? " (" + std::to_string(j.result.corrupt) + " corrupt leaves skipped)"
                  : std::string()));
    } catch (const std::exception& e) {  // over 16 MiB of elements
      m->say(j.name + ": " + j.what() + " refused: " + e.what());
    }
  }
  return added;
}

}  // namespace tessera::collab
