// The region mask of a SELECTION node without a lasso (scene.proto SelectionPayload.mask; issue
// 16, 3D lazy snapping): cells over the selection view's NDC square, run-length coded. Encoded
// by the master (interact/snap_tool.h), checked by the scene graph, decoded by every view that
// tints the selection (render/scene_overlay.h sceneHighlights()).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::sync {

/// Largest side of a mask, cells.
constexpr uint32_t kMaxSelectionMaskSide = 4096;
/// Largest coded mask, bytes.
constexpr size_t kMaxSelectionMaskBytes = size_t(4) << 20;

/// Codes `cells` (0: unset, else set; row-major, row 0 at the bottom) as scene.proto says:
/// unsigned LEB128 lengths of alternating unset and set runs, starting with unset. At most 5
/// bytes a run; a mask of few edges costs a few bytes per row.
std::string encodeSelectionMask(std::span<const uint8_t> cells);

/// Checks `bytes` as a width x height mask (sides 1..kMaxSelectionMaskSide, at most
/// kMaxSelectionMaskBytes, varints of at most 5 bytes, runs adding up to exactly width x height)
/// and, when `cells` is not null, decodes it there (width x height bytes, 0 or 1). Returns what
/// is wrong, starting with "selection.mask" (or the side's field), or nothing. Allocates nothing
/// beyond `cells`; any bytes are safe.
std::optional<std::string> decodeSelectionMask(std::string_view bytes, uint32_t width,
                                               uint32_t height, std::vector<uint8_t>* cells);

}  // namespace tessera::sync
