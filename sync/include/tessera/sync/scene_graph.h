// The versioned scene graph and its differential sync (Equalizer's distributed objects:
// instance data plus deltas, versions). The master mutates its SceneGraph, and once per frame
// takeFrame() turns what changed since the previous frame into one scene::Frame; each node's
// replica SceneGraph apply()s the frames, or first a snapshot() when it joins late. Applying a
// snapshot and then every later frame gives a replica equal to the master.
//
// A scene is a tree of nodes (scene::SceneNode, scene.proto) under an implicit root with id 0,
// plus the camera and the wall-level settings. One class plays both roles; a graph is used either
// as master (mutators, takeFrame) or as replica (apply), not both at once.
//
// Change tracking: the first mutation of a node in a frame keeps a copy of its state as of the
// previous frame (or notes that it did not exist). takeFrame() compares each touched node's
// saved and current state field by field and sends only the fields that differ, so a node
// deleted and re-created, or a field set and set back, costs nothing. The same saved copies let
// snapshot() give the state as of the last frame while new changes are pending.
//
// Not thread-safe: one thread owns a graph.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <tessera/config.pb.h>
#include <tessera/scene.pb.h>

namespace tessera::sync {

/// A frame, snapshot or byte string from outside that cannot be applied or parsed. The replica is
/// left as it was. what() starts with the function and names the frame, the field and the node.
class SyncError : public std::runtime_error {
 public:
  enum class Code {
    kParse,          ///< bytes are not a message of the expected type
    kVersionGap,     ///< a frame's version does not follow the replica's
    kUnknownNode,    ///< a change or delete names an id the replica does not have
    kDuplicateNode,  ///< a create names an id that exists, or an id appears twice
    kBadParent,      ///< a parent that does not exist, or a node left without its parent
    kParentCycle,    ///< the parents would form a cycle
    kBadField,       ///< a value out of range, a wrong payload for the kind, a bad camera ...
  };
  SyncError(Code code, const std::string& what) : std::runtime_error(what), mCode(code) {}
  Code code() const { return mCode; }

 private:
  Code mCode;
};

/// What a frame or a snapshot changed, for what updates incrementally from it (the renderer's
/// scene draw list): an empty frame changes nothing, so costs its consumers nothing.
struct SceneChanges {
  bool everything = false;      ///< a snapshot (or a first look): the whole scene is new
  std::vector<uint32_t> nodes;  ///< ids created, changed or deleted, ascending, each once
  bool camera = false, settings = false;

  bool empty() const { return !everything && nodes.empty() && !camera && !settings; }
  static SceneChanges all() {
    SceneChanges c;
    c.everything = true;
    return c;
  }
  /// What `frame` changes (the master knows it from the frame it took; replicas get it from
  /// apply()). Cost: the frame's size.
  static SceneChanges of(const scene::Frame& frame);
};

class SceneGraph {
 public:
  using NodeId = uint32_t;
  using Kind = scene::SceneNode::Kind;
  static constexpr NodeId kRoot = 0;
  /// A participant's name (a node's author, the leader) is at most this many bytes.
  static constexpr size_t kMaxParticipantName = 64;
  /// A database place's items in one ANNOTATION node, and the text each carries (scene.proto).
  static constexpr int kMaxAnnotationItems = 64;
  static constexpr size_t kMaxAnnotationText = 4096;
  /// An image item's picture in an open note: at most this many pixels a side, and all of a
  /// payload's pictures together at most kMaxAnnotationPictureBytes.
  static constexpr uint32_t kMaxAnnotationPicturePx = 256;
  static constexpr size_t kMaxAnnotationPictureBytes = size_t(1) << 20;
  /// A CLIP node's planes (ClipPayload::planes; a box is 6) and the MODEL nodes it names.
  static constexpr int kMaxClipNodePlanes = 6;
  static constexpr int kMaxClipModels = 64;

  /// An empty scene at version 0, frame 0: no nodes, camera at (0, 0, 1) looking at the origin
  /// with y up, settings defaultSettings().
  SceneGraph();

  /// A master's scene from a scene file (loadSceneFile(): ids assigned, stores absolute): its
  /// nodes, camera and settings (defaults where the file is silent), at version 0 with nothing
  /// pending. Throws SyncError as apply(Snapshot) does for anything the graph refuses.
  static SceneGraph fromFile(const scene::SceneFile& file);

  /// A node of `kind` as created: visible, opacity 1, identity transform, inherited shading and
  /// LOD threshold, empty name, parent root, the (empty) payload of its kind. Every field set.
  static scene::SceneNode defaultNode(NodeId id, Kind kind);
  /// Background black, shading colour, LOD threshold 1 pixel, 16 SPBR ensembles, no leader.
  static scene::Settings defaultSettings();

  // ---- Master: mutations. Preconditions are TESSERA_CHECKs (PreconditionError): they name
  // ---- API misuse, not bad input from outside.

  /// Creates node `id` (> 0, not in use) of a valid `kind` under `parent` (kRoot or an existing
  /// node), with defaultNode() fields and `name`.
  void create(NodeId id, Kind kind, NodeId parent = kRoot, std::string_view name = {});
  /// Same with the next id never used by this graph (one more than the largest seen). Returns it.
  NodeId add(Kind kind, NodeId parent = kRoot, std::string_view name = {});

  /// A node's payload, of its kind's type (none for a GROUP).
  using Payload =
      std::variant<std::monostate, scene::ModelPayload, scene::AnnotationPayload,
                   scene::SketchPayload, scene::AvatarPayload, scene::VideoInsetPayload,
                   scene::MeasurementPayload, scene::SelectionPayload, scene::ClipPayload>;
  /// A whole node in one checked step: `kind` under `parent` with `name`, `payload` (the kind's,
  /// moved in), `author` and `transform` (16 numbers, column-major, or none: identity), the next
  /// id. Every value is checked before anything changes: a refused one (a colour out of range, a
  /// NaN, a payload of another kind) throws PreconditionError naming the field and leaves the
  /// graph as it was.
  NodeId add(Kind kind, NodeId parent, std::string_view name, Payload payload,
             std::string_view author, std::span<const double> transform = {});
  /// Removes `id` and its whole subtree. Cost: the subtree's size.
  void remove(NodeId id);
  /// Moves `id` under `parent`, which must not be `id` or in its subtree.
  void setParent(NodeId id, NodeId parent);
  void setName(NodeId id, std::string_view name);
  /// Who made the node's last change ("" the master; a site's name, at most
  /// kMaxParticipantName bytes). The caller sets it with each change it applies for someone.
  void setAuthor(NodeId id, std::string_view author);
  void setVisible(NodeId id, bool visible);
  /// opacity in [0, 1].
  void setOpacity(NodeId id, float opacity);
  /// 16 finite numbers, column-major, node frame to parent frame, metres; or none: identity.
  /// Kept in the rigid form when that gives back exactly these numbers (sync/transform.h).
  void setTransform(NodeId id, std::span<const double> matrix);
  /// A Transform as it travels (sync/transform.h: rigidTransform() for a pose).
  void setTransform(NodeId id, const scene::Transform& transform);
  /// Any Shading; SHADING_INHERIT uses the wall-level setting.
  void setShading(NodeId id, scene::Shading shading);
  /// pixels >= 0; 0 uses the wall-level setting.
  void setLodPixels(NodeId id, float pixels);
  /// Replaces the payload; the node's kind must be the payload's (MODEL for ModelPayload ...).
  void setPayload(NodeId id, const scene::ModelPayload& payload);
  void setPayload(NodeId id, const scene::AnnotationPayload& payload);
  void setPayload(NodeId id, const scene::SketchPayload& payload);
  void setPayload(NodeId id, const scene::AvatarPayload& payload);
  void setPayload(NodeId id, const scene::VideoInsetPayload& payload);
  void setPayload(NodeId id, const scene::MeasurementPayload& payload);
  void setPayload(NodeId id, const scene::SelectionPayload& payload);
  void setPayload(NodeId id, const scene::ClipPayload& payload);

  /// Sets the camera (metres, scene frame), stored in its wire form (camera_state.h): camera()
  /// then returns it rounded as every node will see it. Preconditions as encodeCamera().
  void setCamera(const config::Camera& camera);
  /// r, g, b in [0, 1].
  void setBackground(float r, float g, float b);
  /// SHADING_COLOR or SHADING_EDL.
  void setShading(scene::Shading shading);
  /// pixels > 0.
  void setLodPixels(float pixels);
  /// 1..4096 (scene::Settings::spbr_ensembles).
  void setSpbrEnsembles(uint32_t ensembles);
  /// The pixel budget, points a covered pixel, finite and 0..10^6 (0: none;
  /// scene::Settings::points_per_pixel).
  void setPointsPerPixel(float points);
  /// The shading filters (scene::Analysis; checked as a frame's settings are).
  void setAnalysis(const scene::Analysis& analysis);
  /// What is wrong with `analysis` as settings.analysis ("settings.analysis.ao_strength: ..."),
  /// or nothing: for checks of outside messages before they are applied.
  static std::optional<std::string> analysisProblem(const scene::Analysis& analysis);
  /// Moves the foveal inset `name` (config::WallConfig::insets) to centre (x, y) on the wall
  /// plane, metres (scene::Settings::inset): every node draws it there from the next frame. The
  /// graph does not know the wall: whether the inset stays inside it is the caller's check
  /// (render::insetPlacementProblem()). Precondition (TESSERA_CHECK): name 1..64 bytes, x and y
  /// finite.
  void setInsetCentre(std::string_view name, double x, double y);
  /// Replaces the named inset's placement whole: its centre and whether it is switched off
  /// (scene::InsetCentre::hidden), as a camera path's setInset and the console's inset control
  /// do. The same wall check is the caller's. Precondition (TESSERA_CHECK): as setInsetCentre().
  void setInset(const scene::InsetCentre& centre);
  /// Moves the viewer's head (scene::Settings::head, wall frame, metres): every node sees its
  /// tiles and stereo eyes from it from the next frame (sync/viewer_head.h). The graph does not
  /// know the wall: that the head is in front of every tile is the caller's check
  /// (sync::headProblem()). Precondition (TESSERA_CHECK): headProblem(head) is nothing.
  void setHead(const scene::Head& head);
  /// What is wrong with `head` without a wall ("right: the head's right axis must not be
  /// zero ..."), or nothing: for checks of outside messages before the wall's.
  static std::optional<std::string> headProblem(const scene::Head& head);

  /// Who leads the view ("" nobody; at most kMaxParticipantName bytes): scene::Settings::leader.
  void setLeader(std::string_view leader);

  /// Queues a command (screenshot, quit) for the next frame. It does not change the scene.
  void addCommand(const scene::Command& command);

  /// The frame holding everything changed since the previous takeFrame() (or since
  /// construction), and the queued commands. Bumps the version by one when the scene changed;
  /// a frame without changes holds number, version and time only. `number` is stored as the
  /// last frame number (snapshot().frame()). Cost: the nodes touched since the last frame.
  scene::Frame takeFrame(uint64_t number, uint64_t time_us);

  /// True when a mutation happened since the last takeFrame() (commands do not count).
  bool hasPendingChanges() const;

  /// The scene as of the last takeFrame() (pending changes are not in it), at version(), nodes
  /// in ascending id. Cost: the whole scene.
  scene::Snapshot snapshot() const;

  // ---- Replica: applying what the master sent. Both throw SyncError on bad input and then
  // ---- leave the graph unchanged. Precondition: no pending local mutations.

  /// Applies one frame (see scene::Frame for the order and the version rule). Commands are not
  /// executed here; the caller reads them from the frame. Cost: the size of the frame, plus the
  /// depth of the tree for each node whose parent changed.
  /// Returns what it changed (SceneChanges::of(frame)).
  SceneChanges apply(const scene::Frame& frame);
  /// Replaces the whole state with a snapshot's. Cost: the snapshot's size. Returns all().
  SceneChanges apply(const scene::Snapshot& snapshot);

  // ---- Queries (the current state, pending changes included).

  uint64_t version() const { return mVersion; }
  uint64_t frameNumber() const { return mFrameNumber; }
  size_t size() const { return mNodes.size(); }
  bool contains(NodeId id) const { return mNodes.count(id) != 0; }
  /// The node's full state. Precondition: contains(id).
  const scene::SceneNode& node(NodeId id) const;
  /// Direct children of `id` (or of the root), ascending.
  std::vector<NodeId> children(NodeId id) const;
  /// Every node id, ascending.
  std::vector<NodeId> ids() const;
  /// The first node (lowest id) with this name, if any.
  std::optional<NodeId> findByName(std::string_view name) const;
  /// The camera as every process decodes it (unit up, orthogonal to the view).
  config::Camera camera() const;
  const scene::CameraState& cameraState() const { return mCamera; }
  const scene::Settings& settings() const { return mSettings; }

  /// Same version, frame number, camera, settings and nodes.
  bool operator==(const SceneGraph& other) const;

 private:
  scene::SceneNode& mutableNode(NodeId id);  // checks, saves the committed copy
  void replacePayload(NodeId id, Kind kind, const std::function<void(scene::SceneNode&)>& set);
  void checkNode(const scene::SceneNode& node) const;  // a mutator's result is valid
  void insertNode(scene::SceneNode node);              // no checks, keeps mChildren
  void eraseNode(NodeId id);                           // the node only, keeps mChildren
  void touchCamera();
  void touchSettings();
  void validateFrame(const scene::Frame& frame) const;

  std::map<NodeId, scene::SceneNode> mNodes;
  std::map<NodeId, std::set<NodeId>> mChildren;  // parent (kRoot too) -> children
  scene::CameraState mCamera;
  scene::Settings mSettings;
  uint64_t mVersion = 0;
  uint64_t mFrameNumber = 0;
  NodeId mNextId = 1;

  // Change tracking since the last takeFrame(): a touched node's committed state (nullopt: it
  // did not exist), and the committed camera and settings when touched.
  std::map<NodeId, std::optional<scene::SceneNode>> mCommitted;
  std::optional<scene::CameraState> mCommittedCamera;
  std::optional<scene::Settings> mCommittedSettings;
  std::vector<scene::Command> mCommands;
};

}  // namespace tessera::sync
