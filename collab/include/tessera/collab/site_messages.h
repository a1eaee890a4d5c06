// What a site may send (site.proto's ToMaster), checked before the master looks at it: the
// master is never disturbed by a misbehaving site. Sizes, counts, ids and numbers
// are bounded; names are UTF-8; everything a check refuses names the message and the field.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <glm/glm.hpp>

#include <tessera/config.pb.h>
#include <tessera/site.pb.h>

namespace tessera::collab {

/// The largest message a site may send, bytes (a stroke of kMaxStrokePoints is about 72 kB).
constexpr size_t kMaxSiteMessageBytes = 128 * 1024;
/// Samples in one stroke (a long, slow stroke at 60 Hz for 50 s).
constexpr int kMaxStrokePoints = 3000;
/// Sketches one site may keep in the scene; more is refused (undo or clear first).
constexpr size_t kMaxSketchesPerSite = 1000;
/// Points in one measurement (annotate/measurement.h kMaxAreaLoop), and the measurements one
/// site may keep in the scene.
constexpr int kMaxMeasurePoints = 1024;
constexpr size_t kMaxMeasurementsPerSite = 1000;
/// Vertices of a lasso (the scene's SelectionPayload limit).
constexpr int kMaxLassoPoints = 4096;
/// Points of each stroke of a snap (SiteSnap: two strokes of doubles fit a message).
constexpr int kMaxSnapStrokePoints = 2048;
/// Widest heavy stroke of the robust lasso, pixels.
constexpr float kMaxHeavyStrokeWidth = 512.0f;
/// A note's text from a site, bytes (longer texts go in with tessera-annotate).
constexpr size_t kMaxNoteTextBytes = 16 * 1024;
/// Coordinates beyond this are refused (metres; georeferenced scenes stay far below it).
constexpr double kMaxCoordinate = 1e8;

/// Chunks on demand (site.proto ChunkRequest): the largest request message, the largest range
/// one request may ask for, the longest store path, and the most ids one cancel may name.
constexpr size_t kMaxChunkRequestBytes = 8 * 1024;
constexpr uint32_t kMaxChunkRangeBytes = 8u << 20;
constexpr size_t kMaxStorePathBytes = 4096;
constexpr size_t kMaxChunkCancelIds = 256;

/// Parses and checks one message from a site. Returns the reason it is refused ("pose.eye:
/// numbers must be finite"), or std::nullopt with `out` filled.
std::optional<std::string> parseToMaster(std::string_view bytes, site::ToMaster& out);

/// Parses and checks a chunk request: its size, the store path (1..kMaxStorePathBytes, no NUL),
/// the length (0..kMaxChunkRangeBytes) and that offset + length does not overflow; or, for a
/// cancel (`cancel` ids), 1..kMaxChunkCancelIds ids and no store, offset or length. Whether the
/// store is served and the range lies within it is the server's to check. Returns the reason
/// it is refused, or std::nullopt with `out` filled.
std::optional<std::string> parseChunkRequest(std::string_view bytes, site::ChunkRequest& out);

/// Whether a checked range request lies within a store of `store_size` bytes (a length-0
/// request, for the store's identity, always does). Returns the reason it does not.
std::optional<std::string> checkChunkRange(const site::ChunkRequest& request, uint64_t store_size);

/// The check alone (what parseToMaster() does after parsing).
std::optional<std::string> checkToMaster(const site::ToMaster& message);

/// A participant's name: 1..64 bytes of valid UTF-8 without control characters.
std::optional<std::string> checkName(std::string_view name, const std::string& field);

/// A checked pose as a camera (eye, target, up as sent).
config::Camera poseCamera(const site::SitePose& pose);

/// The camera `s` of the way from `a` to `b` (eye, target and up interpolated linearly; `b`
/// where the mix would not be a view). For smooth hand-overs of the view (follow-me).
config::Camera blendCameras(const config::Camera& a, const config::Camera& b, double s);

/// The pose's camera frame as a node transform (column-major 4x4: right, up, back, eye), the
/// form of an AVATAR node's transform (scene.proto). Precondition: a checked pose.
glm::dmat4 poseFrame(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up);

}  // namespace tessera::collab
