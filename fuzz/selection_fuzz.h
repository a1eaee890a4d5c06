// The check the selection fuzz target makes, shared with its regression replay
// (tests/master/lasso_selection_test.cpp): bytes read as a serialised selection
// (annotate/selection.h), as given and with the checksum fixed so the structure checks are
// reached. A SelectionError is the only failure allowed; bytes that pass must serialise back to
// themselves (the form is canonical).
#pragma once

#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include <tessera/annotate/selection.h>

namespace tessera::fuzz {

/// Writes the FNV-1a 64 of all but the last 8 bytes into the last 8 (selection.h's trailer).
inline void fixSelectionChecksum(uint8_t* data, size_t size) {
  if (size < 8) return;
  uint64_t h = 0xcbf29ce484222325ull;
  for (size_t i = 0; i + 8 < size; ++i) {
    h ^= data[i];
    h *= 0x100000001b3ull;
  }
  for (int i = 0; i < 8; ++i) data[size - 8 + i] = uint8_t(h >> (8 * i));
}

inline int readSelection(const uint8_t* data, size_t size) {
  std::vector<uint8_t> bytes(data, data + size);
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) fixSelectionChecksum(bytes.data(), bytes.size());
    try {
      const annotate::Selection s = annotate::Selection::deserialize(bytes);
      if (s.serialize() != bytes) std::abort();
      uint64_t count = 0;
      for (const auto& [id, node] : s.nodes()) {
        if (node.empty() || node.count() > node.size()) std::abort();
        count += node.count();
      }
      if (count != s.count()) std::abort();
    } catch (const annotate::SelectionError&) {
    }
  }
  return 0;
}

}  // namespace tessera::fuzz
