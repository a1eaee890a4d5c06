#include <tessera/sync/scene_graph.h>

#include "scene_checks.h"
#include <tessera/sync/view.h>

#include <google/protobuf/util/message_differencer.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <functional>
#include <type_traits>
#include <unordered_set>

#include <glm/glm.hpp>

#include <tessera/core/check.h>
#include <tessera/sync/camera_state.h>
#include <tessera/sync/selection_mask.h>
#include <tessera/sync/transform.h>

namespace tessera::sync {
namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::util::MessageDifferencer;
using scene::SceneNode;
using NodeId = SceneGraph::NodeId;
using Code = SyncError::Code;
using namespace checks;

// ---- Field-wise diff and overwrite, through reflection, so new fields need no code here.
// State messages have every field present; in deltas presence means "changed to this". A
// repeated field counts as present when non-empty (a state never holds an empty one that a
// delta would need to send: an empty transform is the default, and the camera's are complete).

bool present(const Message& m, const FieldDescriptor* f) {
  const auto* r = m.GetReflection();
  return f->is_repeated() ? r->FieldSize(m, f) > 0 : r->HasField(m, f);
}

bool sameField(const Message& a, const Message& b, const FieldDescriptor* f) {
  MessageDifferencer differencer;  // exact float comparison, repeated fields as lists
  const std::vector<const FieldDescriptor*> fields{f};
  return differencer.CompareWithFields(a, b, fields, fields);
}

/// Makes `delta` hold the fields of `now` that `before` lacks or holds with another value
/// (`skip` excepted). Returns whether there is any.
bool diffFields(const Message& before, const Message& now, Message& delta,
                const FieldDescriptor* skip = nullptr) {
  delta.CopyFrom(now);
  const auto* r = delta.GetReflection();
  const auto* d = delta.GetDescriptor();
  for (int i = 0; i < d->field_count(); ++i) {
    const FieldDescriptor* f = d->field(i);
    if (f == skip || (present(now, f) && present(before, f) && sameField(before, now, f)))
      r->ClearField(&delta, f);
  }
  std::vector<const FieldDescriptor*> left;
  r->ListFields(delta, &left);
  return !left.empty();
}

/// Overwrites in `state` every field present in `delta`: scalars and strings take the new value,
/// messages and repeated fields are replaced whole (MergeFrom alone would merge and append).
void overwriteFields(Message& state, const Message& delta) {
  const auto* r = state.GetReflection();
  std::vector<const FieldDescriptor*> fields;
  delta.GetReflection()->ListFields(delta, &fields);
  for (const FieldDescriptor* f : fields) {
    if (f->is_repeated() || f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE)
      r->ClearField(&state, f);
  }
  state.MergeFrom(delta);
}

bool equal(const Message& a, const Message& b) {
  return MessageDifferencer::Equals(a, b);
}

/// Checks that every node in `start` reaches the root through existing parents without a cycle.
/// `parentOf(id)` gives an existing node's parent; `exists(id)` whether a node exists. Each node
/// is walked once (`verified`), so the cost is the number of nodes on the paths.
void checkAncestry(const std::vector<NodeId>& start, const std::function<NodeId(NodeId)>& parentOf,
                   const std::function<bool(NodeId)>& exists, const std::string& context) {
  std::unordered_set<NodeId> verified;
  std::vector<NodeId> path;
  std::unordered_set<NodeId> on_path;
  for (NodeId first : start) {
    path.clear();
    on_path.clear();
    NodeId id = first;
    while (id != SceneGraph::kRoot && !verified.count(id)) {
      if (!on_path.insert(id).second) {
        std::string cycle;
        auto from = std::find(path.begin(), path.end(), id);
        for (auto it = from; it != path.end(); ++it) cycle += std::to_string(*it) + " -> ";
        throw SyncError(Code::kParentCycle, context + ": node " + std::to_string(first) +
                                                ": parents form a cycle " + cycle +
                                                std::to_string(id));
      }
      path.push_back(id);
      const NodeId parent = parentOf(id);
      if (parent != SceneGraph::kRoot && !exists(parent)) {
        throw SyncError(Code::kBadParent, context + ": node " + std::to_string(id) + ": parent " +
                                              std::to_string(parent) + " does not exist");
      }
      id = parent;
    }
    verified.insert(path.begin(), path.end());
  }
}

[[noreturn]] void fail(Code code, const std::string& context, const std::string& where,
                       const std::string& what) {
  throw SyncError(code, context + ": " + where + ": " + what);
}

std::string nodeWhere(const char* list, int index, NodeId id) {
  return std::string(list) + "[" + std::to_string(index) + "] (node " + std::to_string(id) + ")";
}

const FieldDescriptor* idField() {
  static const FieldDescriptor* f =
      SceneNode::descriptor()->FindFieldByNumber(SceneNode::kIdFieldNumber);
  return f;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Construction

SceneGraph::SceneGraph() : mSettings(defaultSettings()) {
  config::Camera camera;
  camera.mutable_eye()->set_z(1.0);
  camera.mutable_up()->set_y(1.0);
  mCamera = encodeCamera(camera);
}

SceneGraph SceneGraph::fromFile(const scene::SceneFile& file) {
  scene::Snapshot snapshot;
  scene::Scene& sc = *snapshot.mutable_scene();
  *sc.mutable_camera() = encodeCamera(file.camera());
  *sc.mutable_settings() = file.settings();
  for (const SceneNode& n : file.nodes()) *sc.add_nodes() = n;
  SceneGraph graph;
  graph.apply(snapshot);
  return graph;
}

SceneNode SceneGraph::defaultNode(NodeId id, Kind kind) {
  SceneNode n;
  n.set_id(id);
  n.set_opacity(1.0f);
  n.set_visible(true);
  n.mutable_transform();
  n.set_parent(kRoot);
  n.set_name("");
  n.set_kind(kind);
  n.set_shading(scene::SHADING_INHERIT);
  n.set_lod_pixels(0.0f);
  n.set_author("");
  switch (payloadCaseOf(kind)) {
    case SceneNode::kModel:
      n.mutable_model();
      break;
    case SceneNode::kAnnotation:
      n.mutable_annotation();
      break;
    case SceneNode::kSketch:
      n.mutable_sketch();
      break;
    case SceneNode::kAvatar:
      n.mutable_avatar();
      break;
    case SceneNode::kVideoInset:
      n.mutable_video_inset();
      break;
    case SceneNode::kMeasurement:
      n.mutable_measurement();
      break;
    case SceneNode::kSelection:
      n.mutable_selection();
      break;
    case SceneNode::kClip:
      n.mutable_clip();
      break;
    default:
      break;
  }
  return n;
}

scene::Settings SceneGraph::defaultSettings() {
  scene::Settings s;
  s.mutable_background();
  s.set_shading(scene::SHADING_COLOR);
  s.set_lod_pixels(1.0f);
  s.set_spbr_ensembles(16);
  s.set_leader("");
  return s;
}

// ---------------------------------------------------------------------------------------------
// Master: mutations

void SceneGraph::insertNode(SceneNode node) {
  const NodeId id = node.id(), parent = node.parent();
  mNodes.insert_or_assign(id, std::move(node));
  mChildren[parent].insert(id);
  mNextId = std::max(mNextId, id + 1);
}

void SceneGraph::eraseNode(NodeId id) {
  auto it = mNodes.find(id);
  assert(it != mNodes.end());
  auto siblings = mChildren.find(it->second.parent());
  if (siblings != mChildren.end()) {
    siblings->second.erase(id);
    if (siblings->second.empty()) mChildren.erase(siblings);
  }
  mNodes.erase(it);
}

SceneNode& SceneGraph::mutableNode(NodeId id) {
  auto it = mNodes.find(id);
  TESSERA_CHECK(it != mNodes.end(),
                "sync::SceneGraph: node " + std::to_string(id) + " does not exist");
  mCommitted.try_emplace(id, it->second);
  return it->second;
}

void SceneGraph::checkNode(const SceneNode& n) const {
  const Problem p = checkNodeFields(n, n.kind());
  TESSERA_CHECK(!p, "sync::SceneGraph: node " + std::to_string(n.id()) + ": " + p.value_or(""));
}

void SceneGraph::create(NodeId id, Kind kind, NodeId parent, std::string_view name) {
  TESSERA_CHECK(id != kRoot && !contains(id),
                "sync::SceneGraph::create(): id " + std::to_string(id) + " is 0 or in use");
  TESSERA_CHECK(validKind(kind), "sync::SceneGraph::create(): invalid kind");
  TESSERA_CHECK(parent == kRoot || contains(parent),
                "sync::SceneGraph::create(): parent " + std::to_string(parent) + " does not exist");
  mCommitted.try_emplace(id, std::nullopt);
  SceneNode n = defaultNode(id, kind);
  n.set_parent(parent);
  n.set_name(std::string(name));
  insertNode(std::move(n));
}

SceneGraph::NodeId SceneGraph::add(Kind kind, NodeId parent, std::string_view name) {
  TESSERA_CHECK(mNextId != 0, "sync::SceneGraph::add(): ids exhausted");
  const NodeId id = mNextId;
  create(id, kind, parent, name);
  return id;
}

SceneGraph::NodeId SceneGraph::add(Kind kind, NodeId parent, std::string_view name,
                                   Payload payload, std::string_view author,
                                   std::span<const double> transform) {
  TESSERA_CHECK(mNextId != 0, "sync::SceneGraph::add(): ids exhausted");
  TESSERA_CHECK(validKind(kind), "sync::SceneGraph::add(): invalid kind");
  TESSERA_CHECK(parent == kRoot || contains(parent),
                "sync::SceneGraph::add(): parent " + std::to_string(parent) + " does not exist");
  TESSERA_CHECK(transform.empty() || transform.size() == 16,
                "sync::SceneGraph::add(): a transform needs 16 numbers or none");
  const Problem bad_transform = checkTransform(transform);
  TESSERA_CHECK(!bad_transform, "sync::SceneGraph::add(): " + bad_transform.value_or(""));
  const NodeId id = mNextId;
  SceneNode n = defaultNode(id, kind);
  n.set_parent(parent);
  n.set_name(std::string(name));
  n.set_author(std::string(author));
  if (!transform.empty()) *n.mutable_transform() = encodeTransform(transform);
  std::visit(
      [&n](auto&& p) {
        using P = std::decay_t<decltype(p)>;
        if constexpr (std::is_same_v<P, scene::ModelPayload>) *n.mutable_model() = std::move(p);
        if constexpr (std::is_same_v<P, scene::AnnotationPayload>)
          *n.mutable_annotation() = std::move(p);
        if constexpr (std::is_same_v<P, scene::SketchPayload>) *n.mutable_sketch() = std::move(p);
        if constexpr (std::is_same_v<P, scene::AvatarPayload>) *n.mutable_avatar() = std::move(p);
        if constexpr (std::is_same_v<P, scene::VideoInsetPayload>)
          *n.mutable_video_inset() = std::move(p);
        if constexpr (std::is_same_v<P, scene::MeasurementPayload>)
          *n.mutable_measurement() = std::move(p);
        if constexpr (std::is_same_v<P, scene::SelectionPayload>)
          *n.mutable_selection() = std::move(p);
        if constexpr (std::is_same_v<P, scene::ClipPayload>) *n.mutable_clip() = std::move(p);
      },
      std::move(payload));
  checkNode(n);  // the payload belongs to the kind, every value in range
  mCommitted.try_emplace(id, std::nullopt);
  insertNode(std::move(n));
  return id;
}

void SceneGraph::remove(NodeId id) {
  TESSERA_CHECK(contains(id),
                "sync::SceneGraph::remove(): node " + std::to_string(id) + " does not exist");
  // Depth-first, children before their parent.
  std::vector<NodeId> order, stack{id};
  while (!stack.empty()) {
    const NodeId n = stack.back();
    stack.pop_back();
    order.push_back(n);
    if (auto c = mChildren.find(n); c != mChildren.end())
      stack.insert(stack.end(), c->second.begin(), c->second.end());
  }
  for (auto it = order.rbegin(); it != order.rend(); ++it) {
    mutableNode(*it);  // saves the committed copy
    eraseNode(*it);
  }
}

void SceneGraph::setParent(NodeId id, NodeId parent) {
  TESSERA_CHECK(contains(id),
                "sync::SceneGraph::setParent(): node " + std::to_string(id) + " does not exist");
  TESSERA_CHECK(
      parent == kRoot || contains(parent),
      "sync::SceneGraph::setParent(): parent " + std::to_string(parent) + " does not exist");
  for (NodeId a = parent; a != kRoot; a = node(a).parent()) {
    TESSERA_CHECK(a != id, "sync::SceneGraph::setParent(): node " + std::to_string(parent) +
                               " is node " + std::to_string(id) + " or in its subtree");
  }
  SceneNode& n = mutableNode(id);
  if (n.parent() == parent) return;
  auto siblings = mChildren.find(n.parent());
  siblings->second.erase(id);
  if (siblings->second.empty()) mChildren.erase(siblings);
  mChildren[parent].insert(id);
  n.set_parent(parent);
}

void SceneGraph::setName(NodeId id, std::string_view name) {
  mutableNode(id).set_name(std::string(name));
}

void SceneGraph::setAuthor(NodeId id, std::string_view author) {
  TESSERA_CHECK(author.size() <= kMaxParticipantName,
                "sync::SceneGraph::setAuthor(): a participant's name is at most 64 bytes");
  mutableNode(id).set_author(std::string(author));
}

void SceneGraph::setVisible(NodeId id, bool visible) {
  mutableNode(id).set_visible(visible);
}

void SceneGraph::setOpacity(NodeId id, float opacity) {
  TESSERA_CHECK(opacity >= 0.0f && opacity <= 1.0f,
                "sync::SceneGraph::setOpacity(): " + num(opacity) + " is not in [0, 1]");
  mutableNode(id).set_opacity(opacity);
}

void SceneGraph::setTransform(NodeId id, std::span<const double> matrix) {
  TESSERA_CHECK(matrix.empty() || matrix.size() == 16,
                "sync::SceneGraph::setTransform(): needs 16 numbers or none");
  const Problem problem = checkTransform(matrix);
  TESSERA_CHECK(!problem, "sync::SceneGraph::setTransform(): " + problem.value_or(""));
  *mutableNode(id).mutable_transform() = encodeTransform(matrix);
}

void SceneGraph::setTransform(NodeId id, const scene::Transform& transform) {
  const Problem problem = checkTransform(transform);
  TESSERA_CHECK(!problem, "sync::SceneGraph::setTransform(): " + problem.value_or(""));
  *mutableNode(id).mutable_transform() = transform;
}

void SceneGraph::setShading(NodeId id, scene::Shading shading) {
  TESSERA_CHECK(scene::Shading_IsValid(shading), "sync::SceneGraph::setShading(): invalid value");
  mutableNode(id).set_shading(shading);
}

void SceneGraph::setLodPixels(NodeId id, float pixels) {
  TESSERA_CHECK(pixels >= 0.0f && std::isfinite(pixels),
                "sync::SceneGraph::setLodPixels(): must be finite and >= 0");
  mutableNode(id).set_lod_pixels(pixels);
}

void SceneGraph::replacePayload(NodeId id, Kind kind, const std::function<void(SceneNode&)>& set) {
  TESSERA_CHECK(contains(id) && node(id).kind() == kind,
                "sync::SceneGraph::setPayload(): node " + std::to_string(id) +
                    " does not exist or is not a " + SceneNode::Kind_Name(kind));
  SceneNode changed = node(id);
  set(changed);
  checkNode(changed);
  mutableNode(id).Swap(&changed);
}

void SceneGraph::setPayload(NodeId id, const scene::ModelPayload& payload) {
  replacePayload(id, SceneNode::MODEL, [&](SceneNode& n) { *n.mutable_model() = payload; });
}

void SceneGraph::setPayload(NodeId id, const scene::AnnotationPayload& payload) {
  replacePayload(id, SceneNode::ANNOTATION,
                 [&](SceneNode& n) { *n.mutable_annotation() = payload; });
}

void SceneGraph::setPayload(NodeId id, const scene::SketchPayload& payload) {
  replacePayload(id, SceneNode::SKETCH, [&](SceneNode& n) { *n.mutable_sketch() = payload; });
}

void SceneGraph::setPayload(NodeId id, const scene::AvatarPayload& payload) {
  replacePayload(id, SceneNode::AVATAR, [&](SceneNode& n) { *n.mutable_avatar() = payload; });
}

void SceneGraph::setPayload(NodeId id, const scene::SelectionPayload& payload) {
  replacePayload(id, SceneNode::SELECTION, [&](SceneNode& n) { *n.mutable_selection() = payload; });
}

void SceneGraph::setPayload(NodeId id, const scene::ClipPayload& payload) {
  replacePayload(id, SceneNode::CLIP, [&](SceneNode& n) { *n.mutable_clip() = payload; });
}

void SceneGraph::setPayload(NodeId id, const scene::MeasurementPayload& payload) {
  replacePayload(id, SceneNode::MEASUREMENT,
                 [&](SceneNode& n) { *n.mutable_measurement() = payload; });
}

void SceneGraph::setPayload(NodeId id, const scene::VideoInsetPayload& payload) {
  replacePayload(id, SceneNode::VIDEO_INSET,
                 [&](SceneNode& n) { *n.mutable_video_inset() = payload; });
}

void SceneGraph::touchCamera() {
  if (!mCommittedCamera) mCommittedCamera = mCamera;
}

void SceneGraph::touchSettings() {
  if (!mCommittedSettings) mCommittedSettings = mSettings;
}

void SceneGraph::setCamera(const config::Camera& camera) {
  scene::CameraState state = encodeCamera(camera);  // checks before anything is touched
  touchCamera();
  mCamera = std::move(state);
}

void SceneGraph::setBackground(float r, float g, float b) {
  scene::Color c;
  c.set_r(r);
  c.set_g(g);
  c.set_b(b);
  const Problem p = checkColor(c, "background");
  TESSERA_CHECK(!p, "sync::SceneGraph::setBackground(): " + p.value_or(""));
  touchSettings();
  *mSettings.mutable_background() = c;
}

void SceneGraph::setShading(scene::Shading shading) {
  TESSERA_CHECK(shading == scene::SHADING_COLOR || shading == scene::SHADING_EDL,
                "sync::SceneGraph::setShading(): the wall needs SHADING_COLOR or SHADING_EDL");
  touchSettings();
  mSettings.set_shading(shading);
}

void SceneGraph::setLodPixels(float pixels) {
  TESSERA_CHECK(pixels > 0.0f && std::isfinite(pixels),
                "sync::SceneGraph::setLodPixels(): must be finite and > 0");
  touchSettings();
  mSettings.set_lod_pixels(pixels);
}

void SceneGraph::setPointsPerPixel(float points) {
  TESSERA_CHECK(std::isfinite(points) && points >= 0.0f && points <= 1e6f,
                "sync::SceneGraph::setPointsPerPixel(): must be finite and 0..1e6");
  touchSettings();
  mSettings.set_points_per_pixel(points);
}

void SceneGraph::setSpbrEnsembles(uint32_t ensembles) {
  TESSERA_CHECK(ensembles >= 1 && ensembles <= 4096,
                "sync::SceneGraph::setSpbrEnsembles(): must be 1..4096");
  touchSettings();
  mSettings.set_spbr_ensembles(ensembles);
}

std::optional<std::string> SceneGraph::analysisProblem(const scene::Analysis& analysis) {
  return checkAnalysis(analysis);
}

void SceneGraph::setAnalysis(const scene::Analysis& analysis) {
  const Problem p = checkAnalysis(analysis);
  TESSERA_CHECK(!p, "sync::SceneGraph::setAnalysis(): " + p.value_or(""));
  touchSettings();
  *mSettings.mutable_analysis() = analysis;
}

void SceneGraph::setInsetCentre(std::string_view name, double x, double y) {
  TESSERA_CHECK(!name.empty() && name.size() <= 64 && std::isfinite(x) && std::isfinite(y),
                "sync::SceneGraph::setInsetCentre(): a name of 1..64 bytes and a finite centre");
  touchSettings();
  scene::InsetPlacement& p = *mSettings.mutable_inset();
  for (scene::InsetCentre& c : *p.mutable_centres()) {
    if (c.name() != name) continue;
    c.set_x(x);
    c.set_y(y);
    return;
  }
  scene::InsetCentre& c = *p.add_centres();
  c.set_name(std::string(name));
  c.set_x(x);
  c.set_y(y);
}

void SceneGraph::setInset(const scene::InsetCentre& centre) {
  setInsetCentre(centre.name(), centre.x(), centre.y());
  for (scene::InsetCentre& c : *mSettings.mutable_inset()->mutable_centres())
    if (c.name() == centre.name()) c.set_hidden(centre.hidden());
}

std::optional<std::string> SceneGraph::headProblem(const scene::Head& head) {
  return checkHead(head);
}

void SceneGraph::setHead(const scene::Head& head) {
  const Problem p = checkHead(head);
  TESSERA_CHECK(!p, "sync::SceneGraph::setHead(): " + p.value_or(""));
  touchSettings();
  *mSettings.mutable_head() = head;
}

void SceneGraph::setLeader(std::string_view leader) {
  TESSERA_CHECK(leader.size() <= kMaxParticipantName,
                "sync::SceneGraph::setLeader(): a participant's name is at most 64 bytes");
  touchSettings();
  mSettings.set_leader(std::string(leader));
}

void SceneGraph::addCommand(const scene::Command& command) {
  const Problem p = checkCommand(command);
  TESSERA_CHECK(!p, "sync::SceneGraph::addCommand(): " + p.value_or(""));
  mCommands.push_back(command);
}

bool SceneGraph::hasPendingChanges() const {
  return !mCommitted.empty() || mCommittedCamera || mCommittedSettings;
}

// ---------------------------------------------------------------------------------------------
// Master: frames and snapshots

scene::Frame SceneGraph::takeFrame(uint64_t number, uint64_t time_us) {
  scene::Frame frame;
  frame.set_number(number);
  frame.set_time_us(time_us);
  // A created node sends what differs from the defaults of its kind, plus id and kind.
  auto addCreated = [&](const SceneNode& now) {
    SceneNode* c = frame.add_created();
    diffFields(defaultNode(now.id(), now.kind()), now, *c, idField());
    c->set_id(now.id());
    c->set_kind(now.kind());
  };
  for (const auto& [id, before] : mCommitted) {  // ascending ids: a deterministic frame
    auto now = mNodes.find(id);
    if (!before) {
      if (now != mNodes.end()) addCreated(now->second);
    } else if (now == mNodes.end()) {
      frame.add_deleted(id);
    } else if (before->kind() != now->second.kind()) {
      frame.add_deleted(id);
      addCreated(now->second);
    } else {
      SceneNode delta;
      if (diffFields(*before, now->second, delta, idField())) {
        delta.set_id(id);
        frame.add_changed()->Swap(&delta);
      }
    }
  }
  if (mCommittedCamera) {
    scene::CameraState delta;
    if (diffFields(*mCommittedCamera, mCamera, delta)) frame.mutable_camera()->Swap(&delta);
  }
  if (mCommittedSettings) {
    scene::Settings delta;
    if (diffFields(*mCommittedSettings, mSettings, delta)) frame.mutable_settings()->Swap(&delta);
  }
  for (scene::Command& c : mCommands) frame.add_commands()->Swap(&c);

  const bool changed = frame.has_camera() || frame.has_settings() || frame.created_size() > 0 ||
                       frame.deleted_size() > 0 || frame.changed_size() > 0;
  if (changed) ++mVersion;
  frame.set_version(mVersion);
  mFrameNumber = number;
  mCommitted.clear();
  mCommittedCamera.reset();
  mCommittedSettings.reset();
  mCommands.clear();
  return frame;
}

scene::Snapshot SceneGraph::snapshot() const {
  scene::Snapshot s;
  s.set_version(mVersion);
  s.set_frame(mFrameNumber);
  scene::Scene& sc = *s.mutable_scene();
  *sc.mutable_camera() = mCommittedCamera.value_or(mCamera);
  *sc.mutable_settings() = mCommittedSettings.value_or(mSettings);
  // Merge of two ascending sequences: the current nodes, and the saved states of touched ones.
  auto n = mNodes.begin();
  auto c = mCommitted.begin();
  while (n != mNodes.end() || c != mCommitted.end()) {
    if (c == mCommitted.end() || (n != mNodes.end() && n->first < c->first)) {
      *sc.add_nodes() = n->second;
      ++n;
    } else {
      if (c->second) *sc.add_nodes() = *c->second;
      if (n != mNodes.end() && n->first == c->first) ++n;
      ++c;
    }
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// Replica

void SceneGraph::validateFrame(const scene::Frame& frame) const {
  const std::string context = "sync::SceneGraph::apply(): frame " + std::to_string(frame.number());
  const bool changes = frame.has_camera() || frame.has_settings() || frame.created_size() > 0 ||
                       frame.deleted_size() > 0 || frame.changed_size() > 0;
  const uint64_t expected = mVersion + (changes ? 1 : 0);
  if (frame.version() != expected) {
    fail(Code::kVersionGap, context, "version",
         "brings version " + std::to_string(frame.version()) + " but the replica is at version " +
             std::to_string(mVersion) + " and expects " + std::to_string(expected) +
             " (a frame was lost, repeated or reordered)");
  }

  std::unordered_set<NodeId> deleted;
  for (int i = 0; i < frame.deleted_size(); ++i) {
    const NodeId id = frame.deleted(i);
    const std::string where = nodeWhere("deleted", i, id);
    if (!contains(id)) fail(Code::kUnknownNode, context, where, "no such node");
    if (!deleted.insert(id).second) fail(Code::kDuplicateNode, context, where, "listed twice");
  }
  std::map<NodeId, const SceneNode*> created, changed;
  for (int i = 0; i < frame.created_size(); ++i) {
    const SceneNode& c = frame.created(i);
    const std::string where = nodeWhere("created", i, c.id());
    if (c.id() == kRoot) fail(Code::kBadField, context, where, "id 0 is the root");
    if (contains(c.id()) && !deleted.count(c.id()))
      fail(Code::kDuplicateNode, context, where, "already exists");
    if (!created.emplace(c.id(), &c).second)
      fail(Code::kDuplicateNode, context, where, "created twice");
    if (!c.has_kind() || !validKind(c.kind()))
      fail(Code::kBadField, context, where, "kind: missing or unknown");
    if (const Problem p = checkNodeFields(c, c.kind())) fail(Code::kBadField, context, where, *p);
  }
  auto existsAfter = [&](NodeId id) {
    return created.count(id) != 0 || (contains(id) && !deleted.count(id));
  };
  for (int i = 0; i < frame.changed_size(); ++i) {
    const SceneNode& c = frame.changed(i);
    const std::string where = nodeWhere("changed", i, c.id());
    if (c.id() == kRoot || !existsAfter(c.id()))
      fail(Code::kUnknownNode, context, where, "no such node");
    if (!changed.emplace(c.id(), &c).second)
      fail(Code::kDuplicateNode, context, where, "changed twice");
    auto cr = created.find(c.id());
    const Kind kind = cr != created.end() ? cr->second->kind() : node(c.id()).kind();
    if (const Problem p = checkNodeFields(c, kind)) fail(Code::kBadField, context, where, *p);
  }
  if (frame.has_camera()) {
    if (const Problem p = checkCameraDelta(frame.camera()))
      fail(Code::kBadField, context, "camera", *p);
  }
  if (frame.has_settings()) {
    if (const Problem p = checkSettings(frame.settings()))
      fail(Code::kBadField, context, "settings", *p);
  }
  for (int i = 0; i < frame.commands_size(); ++i) {
    if (const Problem p = checkCommand(frame.commands(i)))
      fail(Code::kBadField, context, "commands[" + std::to_string(i) + "]", *p);
  }

  // The tree after the frame: nodes whose parent is new, and the surviving children of deleted
  // nodes, must reach the root. Other nodes keep a path that was valid and is untouched.
  auto parentAfter = [&](NodeId id) -> NodeId {
    if (auto ch = changed.find(id); ch != changed.end() && ch->second->has_parent())
      return ch->second->parent();
    if (auto cr = created.find(id); cr != created.end()) return cr->second->parent();
    return node(id).parent();
  };
  std::vector<NodeId> start;
  for (const auto& [id, c] : created) start.push_back(id);
  for (const auto& [id, c] : changed) {
    if (c->has_parent()) start.push_back(id);
  }
  for (NodeId d : deleted) {
    if (auto kids = mChildren.find(d); kids != mChildren.end()) {
      for (NodeId k : kids->second) {
        if (existsAfter(k)) start.push_back(k);
      }
    }
  }
  checkAncestry(start, parentAfter, existsAfter, context);
}

SceneChanges SceneChanges::of(const scene::Frame& frame) {
  SceneChanges c;
  for (const SceneNode& n : frame.changed()) c.nodes.push_back(n.id());
  for (const SceneNode& n : frame.created()) c.nodes.push_back(n.id());
  c.nodes.insert(c.nodes.end(), frame.deleted().begin(), frame.deleted().end());
  std::sort(c.nodes.begin(), c.nodes.end());
  c.nodes.erase(std::unique(c.nodes.begin(), c.nodes.end()), c.nodes.end());
  c.camera = frame.has_camera();
  c.settings = frame.has_settings();
  return c;
}

SceneChanges SceneGraph::apply(const scene::Frame& frame) {
  TESSERA_CHECK(!hasPendingChanges(),
                "sync::SceneGraph::apply(): the graph has local changes not taken as a frame");
  validateFrame(frame);  // throws before anything changes
  for (NodeId id : frame.deleted()) eraseNode(id);
  for (const SceneNode& c : frame.created()) {
    SceneNode n = defaultNode(c.id(), c.kind());
    overwriteFields(n, c);
    n.DiscardUnknownFields();
    insertNode(std::move(n));
  }
  for (const SceneNode& c : frame.changed()) {
    SceneNode& n = mNodes.at(c.id());
    const NodeId old_parent = n.parent();
    overwriteFields(n, c);
    n.DiscardUnknownFields();
    if (n.parent() != old_parent) {
      auto siblings = mChildren.find(old_parent);
      if (siblings != mChildren.end()) {
        siblings->second.erase(c.id());
        if (siblings->second.empty()) mChildren.erase(siblings);
      }
      mChildren[n.parent()].insert(c.id());
    }
  }
  if (frame.has_camera()) overwriteFields(mCamera, frame.camera());
  if (frame.has_settings()) overwriteFields(mSettings, frame.settings());
  mCamera.DiscardUnknownFields();
  mSettings.DiscardUnknownFields();
  mVersion = frame.version();
  mFrameNumber = frame.number();
  return SceneChanges::of(frame);
}

SceneChanges SceneGraph::apply(const scene::Snapshot& snapshot) {
  TESSERA_CHECK(!hasPendingChanges(),
                "sync::SceneGraph::apply(): the graph has local changes not taken as a frame");
  const std::string context =
      "sync::SceneGraph::apply(): snapshot at version " + std::to_string(snapshot.version());
  const scene::Scene& sc = snapshot.scene();
  if (!isCompleteCamera(sc.camera()))
    fail(Code::kBadField, context, "scene.camera", "incomplete or invalid (needs eye, view, roll)");
  if (const Problem p = checkSettings(sc.settings())) fail(Code::kBadField, context, "scene", *p);
  std::map<NodeId, SceneNode> nodes;
  for (int i = 0; i < sc.nodes_size(); ++i) {
    const SceneNode& s = sc.nodes(i);
    const std::string where = nodeWhere("scene.nodes", i, s.id());
    if (s.id() == kRoot) fail(Code::kBadField, context, where, "id 0 is the root");
    if (!s.has_kind() || !validKind(s.kind()))
      fail(Code::kBadField, context, where, "kind: missing or unknown");
    if (const Problem p = checkNodeFields(s, s.kind())) fail(Code::kBadField, context, where, *p);
    SceneNode n = defaultNode(s.id(), s.kind());
    overwriteFields(n, s);
    n.DiscardUnknownFields();
    if (!nodes.emplace(s.id(), std::move(n)).second)
      fail(Code::kDuplicateNode, context, where, "listed twice");
  }
  std::vector<NodeId> start;
  for (const auto& [id, n] : nodes) start.push_back(id);
  checkAncestry(
      start, [&](NodeId id) { return nodes.at(id).parent(); },
      [&](NodeId id) { return nodes.count(id) != 0; }, context);

  mNodes.clear();
  mChildren.clear();
  mNextId = 1;
  for (auto& [id, n] : nodes) insertNode(std::move(n));
  mCamera = sc.camera();
  mCamera.DiscardUnknownFields();
  mSettings = defaultSettings();
  overwriteFields(mSettings, sc.settings());
  mSettings.DiscardUnknownFields();
  mVersion = snapshot.version();
  mFrameNumber = snapshot.frame();
  mCommands.clear();
  return SceneChanges::all();
}

// ---------------------------------------------------------------------------------------------
// Queries

const SceneNode& SceneGraph::node(NodeId id) const {
  auto it = mNodes.find(id);
  TESSERA_CHECK(it != mNodes.end(),
                "sync::SceneGraph::node(): node " + std::to_string(id) + " does not exist");
  return it->second;
}

std::vector<SceneGraph::NodeId> SceneGraph::children(NodeId id) const {
  auto it = mChildren.find(id);
  if (it == mChildren.end()) return {};
  return {it->second.begin(), it->second.end()};
}

std::vector<SceneGraph::NodeId> SceneGraph::ids() const {
  std::vector<NodeId> out;
  out.reserve(mNodes.size());
  for (const auto& [id, n] : mNodes) out.push_back(id);
  return out;
}

std::optional<SceneGraph::NodeId> SceneGraph::findByName(std::string_view name) const {
  for (const auto& [id, n] : mNodes) {
    if (n.name() == name) return id;
  }
  return std::nullopt;
}

config::Camera SceneGraph::camera() const {
  return decodeCamera(mCamera);
}

bool SceneGraph::operator==(const SceneGraph& other) const {
  if (mVersion != other.mVersion || mFrameNumber != other.mFrameNumber ||
      mNodes.size() != other.mNodes.size() || !equal(mCamera, other.mCamera) ||
      !equal(mSettings, other.mSettings)) {
    return false;
  }
  for (auto a = mNodes.begin(), b = other.mNodes.begin(); a != mNodes.end(); ++a, ++b) {
    if (a->first != b->first || !equal(a->second, b->second)) return false;
  }
  return true;
}

}  // namespace tessera::sync
