#include <tessera/sync/selection_mask.h>

#include <algorithm>
#include <cstddef>

namespace tessera::sync {

namespace {

void putVarint(std::string& out, uint64_t v) {
  while (v >= 0x80) {
    out.push_back(char(uint8_t(v) | 0x80));
    v >>= 7;
  }
  out.push_back(char(uint8_t(v)));
}

}  // namespace

std::string encodeSelectionMask(std::span<const uint8_t> cells) {
  std::string out;
  bool set = false;
  uint64_t run = 0;
  for (const uint8_t c : cells) {
    if ((c != 0) != set) {
      putVarint(out, run);
      set = !set;
      run = 0;
    }
    ++run;
  }
  putVarint(out, run);
  return out;
}

std::optional<std::string> decodeSelectionMask(std::string_view bytes, uint32_t width,
                                               uint32_t height, std::vector<uint8_t>* cells) {
  for (const auto& [v, field] :
       {std::pair{width, "selection.mask_width"}, {height, "selection.mask_height"}})
    if (v < 1 || v > kMaxSelectionMaskSide)
      return std::string(field) + ": 1.." + std::to_string(kMaxSelectionMaskSide) +
             " cells with a mask, got " + std::to_string(v);
  if (bytes.size() > kMaxSelectionMaskBytes)
    return "selection.mask: " + std::to_string(bytes.size()) + " bytes; at most " +
           std::to_string(kMaxSelectionMaskBytes);
  const uint64_t total = uint64_t(width) * height;
  if (cells) cells->assign(size_t(total), 0);
  uint64_t at = 0;
  bool set = false;
  size_t i = 0;
  while (i < bytes.size()) {
    uint64_t run = 0;
    int shift = 0;
    while (true) {
      if (i >= bytes.size()) return std::string("selection.mask: ends inside a run length");
      if (shift >= 35) return std::string("selection.mask: a run length longer than 5 bytes");
      const uint8_t b = uint8_t(bytes[i++]);
      run |= uint64_t(b & 0x7f) << shift;
      shift += 7;
      if (!(b & 0x80)) break;
    }
    if (run > total - at)
      return "selection.mask: runs pass the " + std::to_string(width) + " x " +
             std::to_string(height) + " cells";
    if (set && cells)
      std::fill(cells->begin() + ptrdiff_t(at), cells->begin() + ptrdiff_t(at + run), 1);
    at += run;
    set = !set;
  }
  if (at != total)
    return "selection.mask: runs cover " + std::to_string(at) + " of the " + std::to_string(total) +
           " cells";
  return std::nullopt;
}

}  // namespace tessera::sync
