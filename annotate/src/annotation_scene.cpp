#include <tessera/annotate/annotation_scene.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <tessera/sync/scene_edits.h>

namespace tessera::annotate {

namespace {

using NodeId = sync::SceneGraph::NodeId;

/// Authors in the database are never empty; the master's own edits (script, console) are the
/// wall's.
std::string dbAuthor(const std::string& author) { return author.empty() ? "wall" : author; }

/// `text` cut to at most `max` bytes at a UTF-8 boundary, ending "..." when cut.
std::string cut(const std::string& text, size_t max) {
  if (text.size() <= max) return text;
  size_t n = max - 3;
  while (n > 0 && (static_cast<unsigned char>(text[n]) & 0xc0) == 0x80) --n;
  return text.substr(0, n) + "...";
}

scene::AnnotationItem shown(const Item& it) {
  scene::AnnotationItem out;
  out.set_id(uint64_t(it.id));
  out.set_kind(toString(it.kind));
  out.set_title(it.title);
  out.set_text(cut(it.text, sync::SceneGraph::kMaxAnnotationText));
  out.set_number(it.number);
  out.set_unit(it.unit);
  out.set_uri(it.kind == ItemKind::kLink ? it.link_uri : it.path);
  out.set_link_item(uint64_t(std::max<int64_t>(it.link_item, 0)));
  out.set_author(it.author.substr(0, 256));
  out.set_revision(uint64_t(it.revision));
  return out;
}

/// The label a closed note shows: its first item's title, and how many more there are.
std::string labelOf(const std::vector<Item>& items) {
  if (items.empty()) return {};
  std::string label = items.front().title;
  if (items.front().kind == ItemKind::kNumber) {
    char number[64];
    std::snprintf(number, sizeof number, ": %.6g", items.front().number);
    label += number;
    if (!items.front().unit.empty()) label += " " + items.front().unit;
  }
  if (items.size() > 1) label += " (+" + std::to_string(items.size() - 1) + ")";
  return cut(label, 200);
}

/// The layer path of a node: the names of its GROUP ancestors, root first ("measurements").
std::string layerOf(const sync::SceneGraph& graph, NodeId node) {
  std::vector<std::string> parts;
  for (NodeId p = graph.node(node).parent(); p != sync::SceneGraph::kRoot;
       p = graph.node(p).parent()) {
    const scene::SceneNode& n = graph.node(p);
    if (n.kind() == scene::SceneNode::GROUP && !n.name().empty()) parts.push_back(n.name());
  }
  std::string path;
  for (auto it = parts.rbegin(); it != parts.rend(); ++it) path += (path.empty() ? "" : "/") + *it;
  return path;
}

/// Where a measurement's label stands (scene frame): the middle of a distance, the vertex of an
/// angle, the centroid of an area, the end of a path.
glm::dvec3 measurementAnchor(const scene::MeasurementPayload& m) {
  const int n = m.points_size() / 3;
  auto at = [&](int i) {
    return glm::dvec3(m.points(3 * i), m.points(3 * i + 1), m.points(3 * i + 2));
  };
  if (n == 0) return glm::dvec3(0.0);
  switch (m.type()) {
    case scene::MeasurementPayload::DISTANCE:
      return 0.5 * (at(0) + at(n - 1));
    case scene::MeasurementPayload::ANGLE:
      return at(std::min(1, n - 1));
    case scene::MeasurementPayload::AREA: {
      glm::dvec3 c(0.0);
      for (int i = 0; i < n; ++i) c += at(i) / double(n);
      return c;
    }
    default:
      return at(n - 1);
  }
}

/// A measurement's number item: the value in metres, square metres or degrees, and its bound.
Item measurementItem(const scene::MeasurementPayload& m, const std::string& title,
                     const std::string& layer) {
  Item it;
  it.kind = ItemKind::kNumber;
  it.layer = layer;
  it.title = title.empty() ? "measurement" : title;
  const bool angle = m.type() == scene::MeasurementPayload::ANGLE;
  const double scale = angle ? 180.0 / std::numbers::pi : 1.0;
  it.number = m.value() * scale;
  it.unit = angle ? "deg" : m.type() == scene::MeasurementPayload::AREA ? "m^2" : "m";
  char text[128];
  std::snprintf(text, sizeof text, "%s %.6g %s +- %.3g %s",
                scene::MeasurementPayload::Type_Name(m.type()).c_str(), it.number,
                it.unit.c_str(), m.uncertainty() * scale, it.unit.c_str());
  it.text = text;
  return it;
}

}  // namespace

AnnotationScene::AnnotationScene(const std::filesystem::path& file, AnnotationDbOptions options)
    : mDb(file, options) {}

NodeId AnnotationScene::layerNode(sync::SceneGraph& graph, const std::string& layer,
                                  const std::string& author) {
  if (auto it = mLayers.find(layer); it != mLayers.end() && graph.contains(it->second))
    return it->second;
  std::map<std::string, bool> flags;
  for (const Layer& l : mDb.layers()) flags[l.path] = l.visible;
  NodeId node = 0;
  // Every level: its group, visible as that layer's own flag.
  for (size_t end = 0; end != std::string::npos;) {
    end = layer.find('/', end + 1);
    const std::string prefix = layer.substr(0, end);
    node = sync::layerPath(graph, prefix, author);
    const auto flag = flags.find(prefix);
    const bool visible = flag == flags.end() || flag->second;
    if (graph.node(node).visible() != visible) graph.setVisible(node, visible);
    mLayers[prefix] = node;
    mLayerShown[prefix] = visible;
  }
  return node;
}

void AnnotationScene::addPicture(const Item& item, scene::AnnotationItem& out, size_t& budget) {
  auto [at, fresh] = mPictures.try_emplace({item.id, item.revision});
  Picture& p = at->second;
  if (fresh) {
    // Kept: the newest revision of each item, at most kMaxPictures (some 30 MiB) in all.
    std::erase_if(mPictures, [&](const auto& e) {
      return e.first.first == item.id && e.first.second != item.revision;
    });
    while (mPictures.size() > kMaxPictures) {
      auto victim = mPictures.begin();
      if (victim->first == at->first) ++victim;
      mPictures.erase(victim);
    }
    try {
      p.picture = item.data.empty()
                      ? readNotePicture(item.path, mDb.file().parent_path(), kNotePicturePx)
                      : decodeNotePicture(item.data, kNotePicturePx);
    } catch (const std::exception& e) {
      p.problem = cut(e.what(), 256);
      std::fprintf(stderr, "tessera-master: annotations: item %lld's picture: %s\n",
                   static_cast<long long>(item.id), p.problem.c_str());
    }
  }
  if (!p.problem.empty()) {
    out.set_picture_problem(p.problem);
    return;
  }
  if (p.picture.rgba.size() > budget) {
    out.set_picture_problem("not shown: the note's pictures would exceed " +
                            std::to_string(sync::SceneGraph::kMaxAnnotationPictureBytes >> 20) +
                            " MiB");
    return;
  }
  budget -= p.picture.rgba.size();
  out.set_picture_width(p.picture.width);
  out.set_picture_height(p.picture.height);
  out.set_picture(p.picture.rgba.data(), p.picture.rgba.size());
}

void AnnotationScene::refreshPlace(sync::SceneGraph& graph, int64_t place_id,
                                   const std::string& author, std::optional<bool> open_now) {
  const std::optional<Place> place = mDb.place(place_id);
  std::map<std::string, std::vector<Item>> by_layer;
  if (place && place->kind != PlaceKind::kSelection) {
    for (int64_t id : mDb.itemsAt(place_id))
      if (std::optional<Item> it = mDb.item(id)) by_layer[it->layer].push_back(std::move(*it));
  }
  // Nodes of layers the place no longer has items in go.
  for (auto it = mNotes.lower_bound({place_id, std::string()});
       it != mNotes.end() && it->first.first == place_id;) {
    if (!by_layer.count(it->first.second)) {
      if (graph.contains(it->second)) graph.remove(it->second);
      it = mNotes.erase(it);
    } else {
      ++it;
    }
  }
  for (auto& [layer, items] : by_layer) {
    NodeId& node = mNotes[{place_id, layer}];
    const bool exists = node && graph.contains(node);
    bool open = exists && graph.node(node).annotation().open();
    if (open_now) open = *open_now;
    scene::AnnotationPayload a;
    a.set_text(labelOf(items));
    a.set_layer(layer);
    a.set_place(uint64_t(place_id));
    a.set_radius(place->kind == PlaceKind::kHotSpot ? place->radius : 0.0);
    if (place->view) {
      const StoredView& v = *place->view;
      for (const glm::dvec3& p : {v.eye, v.target, v.up})
        for (int k = 0; k < 3; ++k) a.add_view(p[k]);
      a.add_view(v.fovy_deg);
    }
    // An open note carries its pictures; a closed one sends none to the tiles.
    size_t budget = sync::SceneGraph::kMaxAnnotationPictureBytes;
    for (size_t i = 0; i < items.size() && i < size_t(sync::SceneGraph::kMaxAnnotationItems); ++i) {
      scene::AnnotationItem& shown_item = *a.add_items();
      shown_item = shown(items[i]);
      if (open && items[i].kind == ItemKind::kImage) addPicture(items[i], shown_item, budget);
    }
    a.set_open(open);
    if (!exists) {
      const glm::dmat4 t = glm::translate(glm::dmat4(1.0), place->position);
      node = graph.add(scene::SceneNode::ANNOTATION, layerNode(graph, layer, author),
                       "note " + std::to_string(place_id), std::move(a), author,
                       std::span<const double>(glm::value_ptr(t), 16));
      continue;
    }
    const scene::SceneNode& n = graph.node(node);
    if (n.has_annotation() && n.annotation().SerializeAsString() == a.SerializeAsString())
      continue;  // unchanged: the tiles get nothing
    graph.setPayload(node, a);
    graph.setAuthor(node, author);
  }
}

void AnnotationScene::loadStored(sync::SceneGraph& graph, const Place& p) {
  // The measurement's number item, if any: its title names the node, its layer places it.
  std::optional<Item> item;
  for (int64_t id : mDb.itemsAt(p.id))
    if ((item = mDb.item(id))) break;
  if (p.selection_id == kMeasurementBlob) {
    scene::MeasurementPayload m;
    if (!m.ParseFromString(std::string(p.selection.begin(), p.selection.end())))
      throw std::runtime_error("its measurement does not parse");
    const std::string layer = item ? item->layer : "measurements";
    const NodeId node =
        graph.add(scene::SceneNode::MEASUREMENT, layerNode(graph, layer, ""),
                  item ? item->title : "measurement", std::move(m),
                  item && item->author != "wall" ? std::string_view(item->author) : "");
    mStoredNodes[node] = {p.id, item ? item->id : 0};
  } else if (p.selection_id == kSelectionBlob) {
    scene::SelectionPayload s;
    if (!s.ParseFromString(std::string(p.selection.begin(), p.selection.end())))
      throw std::runtime_error("its selection does not parse");
    const std::optional<NodeId> model = graph.findByName(p.model);
    if (!model || graph.node(*model).kind() != scene::SceneNode::MODEL)
      throw std::runtime_error("the scene has no model named \"" + p.model + "\"");
    s.set_model(*model);
    const NodeId node =
        graph.add(scene::SceneNode::SELECTION, layerNode(graph, "selections", ""),
                  item ? item->title : "selection " + std::to_string(p.id), std::move(s), "");
    mStoredNodes[node] = {p.id, item ? item->id : 0};
  }
  // Other selection formats (imports from other tools) are kept, not shown.
}

namespace {

std::string storedProblem(const Place& p, const std::string& why) {
  return "place " + std::to_string(p.id) + " (" + p.selection_id + " on \"" + p.model +
         "\"): " + why + "; it stays in the database";
}

}  // namespace

std::vector<std::string> AnnotationScene::load(sync::SceneGraph& graph) {
  std::vector<std::string> problems;
  mDataVersion = mDb.dataVersion();
  for (const Layer& l : mDb.layers()) layerNode(graph, l.path, "");
  for (const Place& p : mDb.places()) {
    if (p.kind != PlaceKind::kSelection) {
      refreshPlace(graph, p.id, "");
      continue;
    }
    try {
      loadStored(graph, p);
    } catch (const std::exception& e) {
      problems.push_back(storedProblem(p, e.what()));
    }
  }
  return problems;
}

std::vector<std::string> AnnotationScene::refresh(sync::SceneGraph& graph) {
  std::vector<std::string> problems;
  const int64_t version = mDb.dataVersion();
  if (version == mDataVersion) return problems;
  mDataVersion = version;
  // Layers: new ones get their groups; a flag changed elsewhere shows or hides the group.
  for (const Layer& l : mDb.layers()) {
    const NodeId node = layerNode(graph, l.path, "");
    bool& stored = mLayerShown[l.path];
    if (stored != l.visible) {
      stored = l.visible;
      if (graph.node(node).visible() != l.visible) graph.setVisible(node, l.visible);
    }
  }
  std::set<int64_t> places, stored_places;
  for (const auto& [node, s] : mStoredNodes) stored_places.insert(s.place);
  for (const Place& p : mDb.places()) {
    places.insert(p.id);
    if (p.kind != PlaceKind::kSelection) {
      refreshPlace(graph, p.id, "");
    } else if (!stored_places.count(p.id)) {
      try {
        loadStored(graph, p);
      } catch (const std::exception& e) {
        problems.push_back(storedProblem(p, e.what()));
      }
    }
  }
  // Notes and stored nodes whose places were deleted elsewhere go from the scene.
  std::set<int64_t> gone;
  for (const auto& [key, node] : mNotes)
    if (!places.count(key.first)) gone.insert(key.first);
  for (int64_t place : gone) refreshPlace(graph, place, "");
  for (auto it = mStoredNodes.begin(); it != mStoredNodes.end();) {
    if (places.count(it->second.place)) {
      ++it;
      continue;
    }
    if (graph.contains(it->first)) graph.remove(it->first);
    it = mStoredNodes.erase(it);
  }
  return problems;
}

void AnnotationScene::storeNode(sync::SceneGraph& graph, NodeId node) {
  const scene::SceneNode& n = graph.node(node);
  Place place;
  place.kind = PlaceKind::kSelection;
  std::optional<Item> item;
  if (n.kind() == scene::SceneNode::MEASUREMENT) {
    place.model = "scene";
    place.position = measurementAnchor(n.measurement());
    place.selection_id = kMeasurementBlob;
    const std::string bytes = n.measurement().SerializeAsString();
    place.selection.assign(bytes.begin(), bytes.end());
    std::string layer = layerOf(graph, node);
    if (layer.empty()) layer = "measurements";
    item = measurementItem(n.measurement(), n.name(), layer);
    // The layer's group is the node's parent: its visibility is the layer's from now on.
    if (!mLayers.count(layer) && n.parent() != sync::SceneGraph::kRoot) {
      mLayers[layer] = n.parent();
      mLayerShown[layer] = true;  // as the database makes a new layer
    }
  } else {
    const uint32_t model = n.selection().model();
    place.model = graph.contains(model) && !graph.node(model).name().empty()
                      ? graph.node(model).name()
                      : "model " + std::to_string(model);
    place.selection_id = kSelectionBlob;
    const std::string bytes = n.selection().SerializeAsString();
    place.selection.assign(bytes.begin(), bytes.end());
  }
  Stored stored;
  mDb.transaction([&] {
    stored.place = mDb.addPlace(place);
    if (item) {
      stored.item = mDb.addItem(*item, dbAuthor(n.author()));
      mDb.attach(stored.item, stored.place);
    }
  });
  mStoredNodes[node] = stored;
}

void AnnotationScene::sync(sync::SceneGraph& graph) {
  const auto now = std::chrono::steady_clock::now();
  if (now - mPolled >= mPollEvery) {
    mPolled = now;
    try {
      const int64_t before = mDataVersion;
      for (const std::string& p : refresh(graph))
        std::fprintf(stderr, "tessera-master: annotations: %s\n", p.c_str());
      if (mDataVersion != before)
        std::fprintf(stderr, "tessera-master: annotations: took in other programs' edits of %s\n",
                     mDb.file().string().c_str());
    } catch (const AnnotationError& e) {
      std::fprintf(stderr, "tessera-master: annotations: reading other programs' edits: %s\n",
                   e.what());
    }
  }
  if (!graph.hasPendingChanges() && mSyncedVersion == graph.version()) return;
  mSyncedVersion = graph.version();
  for (NodeId id : graph.ids()) {
    const auto kind = graph.node(id).kind();
    if (kind != scene::SceneNode::MEASUREMENT && kind != scene::SceneNode::SELECTION) continue;
    if (mStoredNodes.count(id) || mRefused.count(id)) continue;
    try {
      storeNode(graph, id);
    } catch (const AnnotationError& e) {
      mRefused.insert(id);
      std::fprintf(stderr, "tessera-master: annotations: %s \"%s\" not stored: %s\n",
                   kind == scene::SceneNode::MEASUREMENT ? "measurement" : "selection",
                   graph.node(id).name().c_str(), e.what());
    }
  }
  for (auto it = mStoredNodes.begin(); it != mStoredNodes.end();) {
    if (graph.contains(it->first)) {
      ++it;
      continue;
    }
    const Stored s = it->second;
    it = mStoredNodes.erase(it);
    try {
      mDb.transaction([&] {
        if (s.item) {
          if (const std::optional<Item> item = mDb.item(s.item))
            mDb.removeItem(s.item, item->revision);
        }
        if (mDb.place(s.place)) mDb.removePlace(s.place);
      });
    } catch (const AnnotationError& e) {
      std::fprintf(stderr, "tessera-master: annotations: a removed node's place %lld stays: %s\n",
                   static_cast<long long>(s.place), e.what());
    }
  }
  std::erase_if(mRefused, [&](NodeId id) { return !graph.contains(id); });
  for (auto it = mLayers.begin(); it != mLayers.end();) {
    if (!graph.contains(it->second)) {
      it = mLayers.erase(it);  // the group went: the layer stays as it was
      continue;
    }
    const bool visible = graph.node(it->second).visible();
    bool& stored = mLayerShown[it->first];
    if (visible != stored) {
      try {
        mDb.setLayerVisible(it->first, visible);
        stored = visible;
      } catch (const AnnotationError& e) {
        stored = visible;  // said once
        std::fprintf(stderr, "tessera-master: annotations: layer \"%s\" shown=%d not stored: %s\n",
                     it->first.c_str(), int(visible), e.what());
      }
    }
    ++it;
  }
}

std::pair<int64_t, int64_t> AnnotationScene::addNote(sync::SceneGraph& graph, const Place& place,
                                                     const Item& item, const std::string& author,
                                                     int64_t at) {
  int64_t place_id = at, item_id = 0;
  mDb.transaction([&] {
    if (place_id > 0) {
      const std::optional<Place> p = mDb.place(place_id);
      if (!p)
        throw AnnotationError(AnnotationError::Kind::kNotFound,
                              "AnnotationDb: no place " + std::to_string(place_id));
      if (p->kind == PlaceKind::kSelection)
        throw AnnotationError(AnnotationError::Kind::kBadInput,
                              "AnnotationDb: place " + std::to_string(place_id) +
                                  " is a selection; notes hang at points and hot spots");
    } else {
      place_id = mDb.addPlace(place);
    }
    item_id = mDb.addItem(item, dbAuthor(author));
    mDb.attach(item_id, place_id);
  });
  refreshPlace(graph, place_id, author);
  return {item_id, place_id};
}

int64_t AnnotationScene::updateItem(sync::SceneGraph& graph, const Item& item,
                                    int64_t base_revision, const std::string& author) {
  const int64_t revision = mDb.updateItem(item, base_revision, dbAuthor(author));
  for (int64_t place : mDb.placesOf(item.id)) refreshPlace(graph, place, author);
  return revision;
}

void AnnotationScene::removeItem(sync::SceneGraph& graph, int64_t item, int64_t base_revision) {
  const std::vector<int64_t> places = mDb.placesOf(item);
  mDb.removeItem(item, base_revision);
  for (int64_t place : places) refreshPlace(graph, place, "");
}

void AnnotationScene::setLayerVisible(sync::SceneGraph& graph, const std::string& layer,
                                      bool visible, const std::string& author) {
  mDb.setLayerVisible(layer, visible);
  const NodeId node = layerNode(graph, layer, author);
  if (graph.node(node).visible() != visible) {
    graph.setVisible(node, visible);
    graph.setAuthor(node, author);
  }
  mLayerShown[layer] = visible;
}

void AnnotationScene::setOpen(sync::SceneGraph& graph, int64_t place, bool open,
                              const std::string& author) {
  if (nodesOf(place).empty())
    throw AnnotationError(AnnotationError::Kind::kNotFound,
                          "AnnotationDb: no note at place " + std::to_string(place));
  refreshPlace(graph, place, author, open);
}

std::vector<NodeId> AnnotationScene::nodesOf(int64_t place) const {
  std::vector<NodeId> out;
  for (auto it = mNotes.lower_bound({place, std::string()});
       it != mNotes.end() && it->first.first == place; ++it)
    out.push_back(it->second);
  return out;
}

std::optional<int64_t> AnnotationScene::placeOfNode(NodeId node) const {
  const auto it = mStoredNodes.find(node);
  if (it == mStoredNodes.end()) return std::nullopt;
  return it->second.place;
}

}  // namespace tessera::annotate
