#include <tessera/collab/site_selections.h>

namespace tessera::collab {

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
  master::SelectionRequest r;
  r.model = s.model();
  r.view = sentView(s);
  r.pixels = pixelsOf(s.lasso());
  mWorker.request(graph, site, name, std::move(r));
}

void SiteSelections::request(const sync::SceneGraph& graph, uint32_t site, const std::string& name,
                             const site::SiteSnap& s) {
  master::SelectionRequest r;
  r.kind = s.heavy_width() > 0.0f ? master::SelectionRequest::Kind::kRobustLasso
                                  : master::SelectionRequest::Kind::kSnap;
  r.model = s.model();
  r.view = sentView(s);
  r.pixels = pixelsOf(s.foreground());
  r.background = pixelsOf(s.background());
  r.heavy_width = s.heavy_width();
  mWorker.request(graph, site, name, std::move(r));
}

}  // namespace tessera::collab
