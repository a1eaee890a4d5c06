// Frames and snapshots as bytes: protobuf's binary encoding of scene::Frame and
// scene::Snapshot (scene.proto), what MPI broadcasts and a late joiner receives.
#pragma once

#include <string>
#include <string_view>

#include <tessera/scene.pb.h>
#include <tessera/sync/scene_graph.h>

namespace tessera::sync {

/// The encoded message. Deterministic for one build (no maps in the schema). Frame sizes: see
/// bench/sync_bytes.cpp (about 12 bytes unchanged, under 64 with a camera move).
std::string serializeFrame(const scene::Frame& frame);
std::string serializeSnapshot(const scene::Snapshot& snapshot);

/// Parses bytes from outside. Throws SyncError(kParse) "sync::parseFrame(): N bytes are not a
/// valid Frame ..." on truncated or corrupt input (never crashes). Fields unknown to this build
/// are dropped. Parsing checks only the encoding: SceneGraph::apply() checks the content.
scene::Frame parseFrame(std::string_view bytes);
scene::Snapshot parseSnapshot(std::string_view bytes);

}  // namespace tessera::sync
