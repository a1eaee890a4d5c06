// A selection of elements (points or triangles) of one store, kept compactly per leaf node: the
// selection stored compactly (per chunk ranges or bitsets). Elements are named by
// (leaf node id, index in the node's decoded payload): PointStore leaf chunks (every input point
// is in exactly one leaf; the LOD copies in inner nodes are never selected) or MeshStore leaf
// patches (their triangles in index-buffer order).
//
// Per node the smallest of three forms is kept: "all" (no payload), sorted disjoint ranges
// (8 bytes a range) or a bitset (8 bytes per 64 elements). Set algebra serves the lasso's
// modifier keys (add, remove, intersect: the thesis' 2D selection procedure lets strokes add and
// remove regions, ../shared/papers/patch-lod-annotation-thesis.txt section 4.1.1).
//
// Serialised form (little-endian), version 1:
//   "TSEL" | version u8 | elements u8 | reserved u16 = 0 | node count u32 |
//   per node, ids strictly increasing: id u32 | size u32 (elements in the node, > 0) | form u8 |
//     form 0 (all): nothing | form 1 (ranges): count u32, count x (begin u32, end u32), sorted,
//     non-empty, not touching, end <= size | form 2 (bits): ceil(size / 64) u64 words, no bit at
//     or past `size`, not all zero |
//   FNV-1a 64 of every byte before it, u64.
// deserialize() takes any bytes: anything else is a SelectionError, never a crash or an
// allocation larger than the input.
#pragma once

#include <cstdint>
#include <map>
#include <span>
#include <stdexcept>
#include <vector>

#include <tessera/lod/lod_hierarchy.h>

namespace tessera::annotate {

/// Bytes that are not a selection (bad magic, version, checksum, structure). The message starts
/// with the function and names what was expected.
class SelectionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What a selection's elements are.
enum class SelectionElements : uint8_t { kPoints = 0, kTriangles = 1 };

/// A half-open range of element indices [begin, end).
struct ElementRange {
  uint32_t begin = 0, end = 0;
  bool operator==(const ElementRange&) const = default;
};

/// The selected elements of one node, in its most compact form.
class NodeSelection {
 public:
  enum class Form : uint8_t { kAll = 0, kRanges = 1, kBits = 2 };

  /// Every element of a node of `size` elements.
  static NodeSelection all(uint32_t size);
  /// From a bitset of ceil(size / 64) words (bit i of word i / 64 is element i; bits past `size`
  /// must be zero); picks the compact form. Empty when no bit is set.
  static NodeSelection fromBits(uint32_t size, std::vector<uint64_t> bits);

  uint32_t size() const { return mSize; }
  Form form() const { return mForm; }
  uint32_t count() const { return mCount; }
  bool empty() const { return mCount == 0; }
  bool contains(uint32_t index) const;
  /// The selected elements as sorted, disjoint, non-touching ranges.
  std::vector<ElementRange> ranges() const;
  /// The selected elements as a bitset of ceil(size / 64) words.
  std::vector<uint64_t> bits() const;
  /// Payload bytes of the chosen form (what serialize() spends on it besides 9 bytes of header).
  size_t payloadBytes() const;

  bool operator==(const NodeSelection& o) const;

 private:
  friend class Selection;
  uint32_t mSize = 0;
  uint32_t mCount = 0;
  Form mForm = Form::kAll;
  std::vector<ElementRange> mRanges;  ///< kRanges
  std::vector<uint64_t> mBits;        ///< kBits
};

/// A set of elements of one store: per leaf node id a non-empty NodeSelection.
class Selection {
 public:
  explicit Selection(SelectionElements elements = SelectionElements::kPoints)
      : mElements(elements) {}

  SelectionElements elements() const { return mElements; }
  /// Selected elements over all nodes.
  uint64_t count() const;
  bool empty() const { return mNodes.empty(); }
  bool contains(lod::NodeId node, uint32_t index) const;
  /// Nodes with at least one selected element, by id.
  const std::map<lod::NodeId, NodeSelection>& nodes() const { return mNodes; }
  /// The node's selection, or nullptr when none of its elements is selected.
  const NodeSelection* node(lod::NodeId id) const;

  /// Sets a node's selection (replacing what it had; an empty one removes the node).
  void set(lod::NodeId id, NodeSelection s);

  /// Set algebra: `this` and `o` must have the same elements and give each node they share the
  /// same size (PreconditionError otherwise: they would not be selections of one store).
  Selection unite(const Selection& o) const;
  Selection intersect(const Selection& o) const;
  Selection subtract(const Selection& o) const;

  /// Bytes of the serialised form (header comment). Cost: linear in the payload.
  std::vector<uint8_t> serialize() const;
  /// Parses and checks bytes from outside. Throws SelectionError.
  static Selection deserialize(std::span<const uint8_t> bytes);

  bool operator==(const Selection&) const = default;

 private:
  SelectionElements mElements;
  std::map<lod::NodeId, NodeSelection> mNodes;
};

}  // namespace tessera::annotate
