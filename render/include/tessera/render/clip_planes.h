// Clip planes and clip boxes (the scene's CLIP nodes, sync/proto/tessera/scene.proto
// ClipPayload): what cuts one model, as the scene draw list collects it (world frame, double)
// and as the geometry passes test it per point and per fragment (the batch's local frame,
// float: shaders/shared_layout.h tesseraClipped(), the same rule as keeps() here).
//
// The rule: planes come in groups (one group per CLIP node). Group g keeps a position where
// every plane of g has a*x + b*y + c*z + d >= 0 (its inside), or, with bit g of `invert`, where
// at least one is negative (its outside). A position is drawn when every group keeps it.
//
// Precision: georeferenced data sits at 10^6 m, where a float steps by 6 cm. Planes are built
// and moved between frames in double (transformed()), and reach float only in a batch's own
// frame (a chunk's or patch's box, metres), normalised to a unit normal there, so the test on
// the GPU is as exact as the positions it reads.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include <glm/glm.hpp>

namespace tessera::render {

/// Most planes that cut one model (TESSERA_MAX_CLIP_PLANES in shaders/shared_layout.h): two
/// boxes, or a box and six planes. Also the most groups.
constexpr uint32_t kMaxClipPlanes = 12;

struct ClipPlanes {
  std::array<glm::dvec4, kMaxClipPlanes> planes{};  ///< (a, b, c, d), the first `count` used
  std::array<uint32_t, kMaxClipPlanes> groups{};    ///< each plane's group, < group_count
  uint32_t count = 0;
  uint32_t group_count = 0;
  uint32_t invert = 0;  ///< bit g: group g keeps its outside

  bool empty() const { return count == 0; }
  /// Appends a group of `planes` (at least one). Returns false, adding nothing, when the planes
  /// or the groups would exceed kMaxClipPlanes.
  bool addGroup(std::span<const glm::dvec4> group, bool keep_outside);
  /// The same cut for positions in another frame: `this_from_other` takes that frame's
  /// positions to this one's (e.g. world_from_local), so each plane becomes plane *
  /// this_from_other, scaled to a unit normal. In double.
  ClipPlanes transformed(const glm::dmat4& this_from_other) const;
  /// Whether the cut keeps position `p` (this frame).
  bool keeps(const glm::dvec3& p) const;
};

/// The six planes of a box (centre +- half extents along the frame's axes) that keep its
/// inside: +x, -x, +y, -y, +z, -z faces.
std::array<glm::dvec4, 6> boxPlanes(const glm::dvec3& centre, const glm::dvec3& half_extents);

/// The planes as the shaders take them: floats, in the frame of the positions they test.
struct GpuClipPlanes {
  std::array<glm::vec4, kMaxClipPlanes> planes{};
  std::array<uint32_t, kMaxClipPlanes> groups{};
  uint32_t count = 0;
  uint32_t invert = 0;
};

/// `world` (the model's cut, world frame) for a batch whose positions are in the frame
/// `world_from_local` places: transformed in double, then to float.
GpuClipPlanes gpuClipPlanes(const ClipPlanes& world, const glm::dmat4& world_from_local);

}  // namespace tessera::render
