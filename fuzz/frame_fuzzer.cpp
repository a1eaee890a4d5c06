// libFuzzer target: bytes parsed as a scene::Frame and applied to a replica of a small scene, and
// parsed as a scene::Snapshot and applied to an empty one. SyncError is the only failure allowed;
// after a successful apply the replica must still be consistent: its snapshot, applied to a
// fresh graph, gives an equal graph, and every node's transform decodes to finite numbers.
#include <google/protobuf/stubs/logging.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include <tessera/sync/scene_graph.h>
#include <tessera/sync/transform.h>
#include <tessera/sync/wire.h>

namespace {

using tessera::scene::SceneNode;
using tessera::sync::SceneGraph;

void require(bool ok, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "frame fuzz: broken invariant: %s\n", what);
  std::abort();
}

/// Nodes 1 (group) > 2 (group) > 3 (model), 4 (annotation) and 5 (a clip plane on model 3) at
/// the root; version 1, frame 1.
const SceneGraph& baseScene() {
  static const SceneGraph base = [] {
    SceneGraph g;
    g.create(1, SceneNode::GROUP);
    g.create(2, SceneNode::GROUP, 1);
    g.create(3, SceneNode::MODEL, 2, "model");
    g.create(4, SceneNode::ANNOTATION);
    g.create(5, SceneNode::CLIP);
    tessera::scene::ClipPayload clip;
    for (double v : {1.0, 0.0, 0.0, -0.5}) clip.add_planes(v);
    clip.add_models(3);
    g.setPayload(5, clip);
    g.takeFrame(1, 0);
    return g;
  }();
  return base;
}

void requireConsistent(const SceneGraph& g) {
  SceneGraph copy;
  copy.apply(g.snapshot());  // a SyncError here escapes: the replica held an invalid state
  require(copy == g, "replica differs from a graph made from its own snapshot");
  // Every accepted transform, in either form (sync/transform.h), is a finite matrix.
  for (SceneGraph::NodeId id : g.ids()) {
    const glm::dmat4 m = tessera::sync::transformMatrix(g.node(id).transform());
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) require(std::isfinite(m[c][r]), "a transform decodes to NaN");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  google::protobuf::LogSilencer quiet;  // protobuf logs each invalid UTF-8 string it rejects
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  try {
    SceneGraph replica = baseScene();
    replica.apply(tessera::sync::parseFrame(bytes));
    requireConsistent(replica);
  } catch (const tessera::sync::SyncError&) {
  }
  try {
    SceneGraph replica;
    replica.apply(tessera::sync::parseSnapshot(bytes));
    requireConsistent(replica);
  } catch (const tessera::sync::SyncError&) {
  }
  return 0;
}
