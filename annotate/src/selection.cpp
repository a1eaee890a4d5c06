#include <tessera/annotate/selection.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <string>

#include <tessera/core/check.h>

namespace tessera::annotate {

namespace {

constexpr char kMagic[4] = {'T', 'S', 'E', 'L'};
constexpr uint8_t kVersion = 1;
constexpr size_t kHeaderBytes = 12;
constexpr size_t kChecksumBytes = 8;

size_t wordsFor(uint32_t size) {
  return (size_t(size) + 63) / 64;
}

/// FNV-1a, 64 bits: catches the torn and flipped bytes a file or a message may carry (not an
/// authenticator).
uint64_t fnv1a(std::span<const uint8_t> bytes) {
  uint64_t h = 0xcbf29ce484222325ull;
  for (uint8_t b : bytes) {
    h ^= b;
    h *= 0x100000001b3ull;
  }
  return h;
}

/// Runs of set bits as ranges.
std::vector<ElementRange> runsOf(const std::vector<uint64_t>& bits, uint32_t size) {
  std::vector<ElementRange> out;
  uint32_t i = 0;
  while (i < size) {
    const size_t w = i / 64;
    const uint64_t word = bits[w] >> (i % 64);
    if (word == 0) {  // skip to the next word
      i = uint32_t(std::min<uint64_t>(uint64_t(w + 1) * 64, size));
      continue;
    }
    i += uint32_t(std::countr_zero(word));
    const uint32_t begin = i;
    // Extend over set bits, a word at a time (bits past `size` are zero, so runs end there).
    while (i < size) {
      const uint32_t bit = i % 64;
      const uint64_t rest = ~(bits[i / 64] >> bit);  // the shifted-in top bits become ones
      const uint32_t ones = rest == 0 ? 64 : uint32_t(std::countr_zero(rest));
      i += ones;
      if (ones < 64 - bit) break;
    }
    i = std::min(i, size);
    out.push_back({begin, i});
  }
  return out;
}

class Writer {
 public:
  void u8(uint8_t v) { mBytes.push_back(v); }
  void u16(uint16_t v) { le(v, 2); }
  void u32(uint32_t v) { le(v, 4); }
  void u64(uint64_t v) { le(v, 8); }
  std::vector<uint8_t>& bytes() { return mBytes; }

 private:
  void le(uint64_t v, int n) {
    for (int i = 0; i < n; ++i) mBytes.push_back(uint8_t(v >> (8 * i)));
  }
  std::vector<uint8_t> mBytes;
};

class Reader {
 public:
  explicit Reader(std::span<const uint8_t> b) : mBytes(b) {}
  size_t left() const { return mBytes.size() - mAt; }
  uint8_t u8() { return uint8_t(le(1)); }
  uint16_t u16() { return uint16_t(le(2)); }
  uint32_t u32() { return uint32_t(le(4)); }
  uint64_t u64() { return le(8); }

 private:
  uint64_t le(size_t n) {
    if (left() < n)
      throw SelectionError("Selection::deserialize(): truncated at byte " + std::to_string(mAt));
    uint64_t v = 0;
    for (size_t i = 0; i < n; ++i) v |= uint64_t(mBytes[mAt + i]) << (8 * i);
    mAt += n;
    return v;
  }
  std::span<const uint8_t> mBytes;
  size_t mAt = 0;
};

[[noreturn]] void bad(const std::string& what) {
  throw SelectionError("Selection::deserialize(): " + what);
}

}  // namespace

// --- NodeSelection ---------------------------------------------------------------------------

NodeSelection NodeSelection::all(uint32_t size) {
  TESSERA_CHECK(size > 0, "NodeSelection::all(): a node has at least one element");
  NodeSelection s;
  s.mSize = size;
  s.mCount = size;
  s.mForm = Form::kAll;
  return s;
}

NodeSelection NodeSelection::fromBits(uint32_t size, std::vector<uint64_t> bits) {
  TESSERA_CHECK(bits.size() == wordsFor(size),
                "NodeSelection::fromBits(): expected ceil(size / 64) words");
  if (size % 64 != 0)
    TESSERA_CHECK((bits.back() >> (size % 64)) == 0,
                  "NodeSelection::fromBits(): a bit is set past the node's size");
  NodeSelection s;
  s.mSize = size;
  uint64_t count = 0;
  for (uint64_t w : bits) count += uint64_t(std::popcount(w));
  s.mCount = uint32_t(count);
  if (count == 0 || count == size) {  // empty, or all: no payload
    s.mForm = Form::kAll;
    return s;
  }
  std::vector<ElementRange> runs = runsOf(bits, size);
  // Ranges when they are no larger than the bitset (ties keep ranges: cheaper to test).
  if (runs.size() <= bits.size()) {
    s.mForm = Form::kRanges;
    s.mRanges = std::move(runs);
  } else {
    s.mForm = Form::kBits;
    s.mBits = std::move(bits);
  }
  return s;
}

bool NodeSelection::contains(uint32_t index) const {
  if (index >= mSize || mCount == 0) return false;
  switch (mForm) {
    case Form::kAll:
      return true;
    case Form::kBits:
      return (mBits[index / 64] >> (index % 64)) & 1u;
    case Form::kRanges: {
      auto it = std::upper_bound(mRanges.begin(), mRanges.end(), index,
                                 [](uint32_t i, const ElementRange& r) { return i < r.begin; });
      return it != mRanges.begin() && index < std::prev(it)->end;
    }
  }
  return false;
}

std::vector<ElementRange> NodeSelection::ranges() const {
  switch (mForm) {
    case Form::kAll:
      return mCount == 0 ? std::vector<ElementRange>{} : std::vector<ElementRange>{{0, mSize}};
    case Form::kRanges:
      return mRanges;
    case Form::kBits:
      return runsOf(mBits, mSize);
  }
  return {};
}

std::vector<uint64_t> NodeSelection::bits() const {
  if (mForm == Form::kBits) return mBits;
  std::vector<uint64_t> out(wordsFor(mSize), 0);
  for (const ElementRange& r : ranges()) {
    for (uint32_t i = r.begin; i < r.end;) {
      const uint32_t bit = i % 64, n = std::min(64 - bit, r.end - i);
      const uint64_t mask = n == 64 ? ~0ull : ((1ull << n) - 1) << bit;
      out[i / 64] |= mask;
      i += n;
    }
  }
  return out;
}

size_t NodeSelection::payloadBytes() const {
  switch (mForm) {
    case Form::kAll:
      return 0;
    case Form::kRanges:
      return 4 + 8 * mRanges.size();
    case Form::kBits:
      return 8 * mBits.size();
  }
  return 0;
}

bool NodeSelection::operator==(const NodeSelection& o) const {
  // Forms are canonical (fromBits() picks one per set), so equal sets have equal forms.
  return mSize == o.mSize && mCount == o.mCount && mForm == o.mForm && mRanges == o.mRanges &&
         mBits == o.mBits;
}

// --- Selection -------------------------------------------------------------------------------

uint64_t Selection::count() const {
  uint64_t n = 0;
  for (const auto& [id, s] : mNodes) n += s.count();
  return n;
}

const NodeSelection* Selection::node(lod::NodeId id) const {
  auto it = mNodes.find(id);
  return it == mNodes.end() ? nullptr : &it->second;
}

bool Selection::contains(lod::NodeId id, uint32_t index) const {
  const NodeSelection* s = node(id);
  return s && s->contains(index);
}

void Selection::set(lod::NodeId id, NodeSelection s) {
  if (s.empty())
    mNodes.erase(id);
  else
    mNodes.insert_or_assign(id, std::move(s));
}

namespace {

enum class Op { kUnite, kIntersect, kSubtract };

/// One node's result; `a` or `b` may be null (the node is not in that operand).
NodeSelection combine(const NodeSelection* a, const NodeSelection* b, Op op) {
  if (!b) return op == Op::kIntersect ? NodeSelection{} : *a;
  if (!a) return op == Op::kUnite ? *b : NodeSelection{};
  TESSERA_CHECK(a->size() == b->size(),
                "Selection: a node has different sizes in the two operands (selections of "
                "different stores?)");
  const bool a_all = a->count() == a->size(), b_all = b->count() == b->size();
  switch (op) {  // the common cases of whole nodes need no bitset
    case Op::kUnite:
      if (a_all) return *a;
      if (b_all) return *b;
      break;
    case Op::kIntersect:
      if (a_all) return *b;
      if (b_all) return *a;
      break;
    case Op::kSubtract:
      if (b_all) return NodeSelection{};
      break;
  }
  std::vector<uint64_t> x = a->bits();
  const std::vector<uint64_t> y = b->bits();
  for (size_t i = 0; i < x.size(); ++i) {
    switch (op) {
      case Op::kUnite:
        x[i] |= y[i];
        break;
      case Op::kIntersect:
        x[i] &= y[i];
        break;
      case Op::kSubtract:
        x[i] &= ~y[i];
        break;
    }
  }
  return NodeSelection::fromBits(a->size(), std::move(x));
}

Selection apply(const Selection& a, const Selection& b, Op op) {
  TESSERA_CHECK(a.elements() == b.elements(),
                "Selection: combining a point selection with a triangle selection");
  Selection out(a.elements());
  auto ia = a.nodes().begin(), ib = b.nodes().begin();
  while (ia != a.nodes().end() || ib != b.nodes().end()) {
    if (ib == b.nodes().end() || (ia != a.nodes().end() && ia->first < ib->first)) {
      out.set(ia->first, combine(&ia->second, nullptr, op));
      ++ia;
    } else if (ia == a.nodes().end() || ib->first < ia->first) {
      out.set(ib->first, combine(nullptr, &ib->second, op));
      ++ib;
    } else {
      out.set(ia->first, combine(&ia->second, &ib->second, op));
      ++ia;
      ++ib;
    }
  }
  return out;
}

}  // namespace

Selection Selection::unite(const Selection& o) const {
  return apply(*this, o, Op::kUnite);
}
Selection Selection::intersect(const Selection& o) const {
  return apply(*this, o, Op::kIntersect);
}
Selection Selection::subtract(const Selection& o) const {
  return apply(*this, o, Op::kSubtract);
}

std::vector<uint8_t> Selection::serialize() const {
  Writer w;
  for (char c : kMagic) w.u8(uint8_t(c));
  w.u8(kVersion);
  w.u8(uint8_t(mElements));
  w.u16(0);
  w.u32(uint32_t(mNodes.size()));
  for (const auto& [id, s] : mNodes) {
    w.u32(id);
    w.u32(s.size());
    w.u8(uint8_t(s.form()));
    if (s.form() == NodeSelection::Form::kRanges) {
      w.u32(uint32_t(s.mRanges.size()));
      for (const ElementRange& r : s.mRanges) {
        w.u32(r.begin);
        w.u32(r.end);
      }
    } else if (s.form() == NodeSelection::Form::kBits) {
      for (uint64_t word : s.mBits) w.u64(word);
    }
  }
  const uint64_t sum = fnv1a(w.bytes());
  w.u64(sum);
  return std::move(w.bytes());
}

Selection Selection::deserialize(std::span<const uint8_t> bytes) {
  if (bytes.size() < kHeaderBytes + kChecksumBytes)
    bad("expected at least " + std::to_string(kHeaderBytes + kChecksumBytes) + " bytes, got " +
        std::to_string(bytes.size()));
  if (std::memcmp(bytes.data(), kMagic, 4) != 0) bad("not a selection (magic is not TSEL)");
  if (bytes[4] != kVersion)
    bad("version " + std::to_string(bytes[4]) + ", expected " + std::to_string(kVersion));
  const std::span<const uint8_t> body = bytes.first(bytes.size() - kChecksumBytes);
  uint64_t stored = 0;
  for (size_t i = 0; i < kChecksumBytes; ++i) stored |= uint64_t(bytes[body.size() + i]) << (8 * i);
  if (fnv1a(body) != stored) bad("checksum mismatch (corrupt or truncated)");

  Reader r(body);
  r.u32();  // magic
  r.u8();   // version
  const uint8_t elements = r.u8();
  if (elements > uint8_t(SelectionElements::kTriangles))
    bad("unknown element kind " + std::to_string(elements));
  if (r.u16() != 0) bad("reserved header bytes are not zero");
  const uint32_t nodes = r.u32();
  if (nodes > r.left() / 9) bad("node count " + std::to_string(nodes) + " exceeds the bytes");
  Selection out{SelectionElements(elements)};
  int64_t previous = -1;
  for (uint32_t n = 0; n < nodes; ++n) {
    const uint32_t id = r.u32(), size = r.u32();
    const uint8_t form = r.u8();
    const std::string where = "node " + std::to_string(id) + ": ";
    if (int64_t(id) <= previous) bad(where + "node ids are not strictly increasing");
    previous = id;
    if (size == 0) bad(where + "size 0");
    NodeSelection s;
    s.mSize = size;
    if (form == uint8_t(NodeSelection::Form::kAll)) {
      s = NodeSelection::all(size);
    } else if (form == uint8_t(NodeSelection::Form::kRanges)) {
      const uint32_t count = r.u32();
      if (count == 0 || count > r.left() / 8)
        bad(where + "range count " + std::to_string(count) + " is zero or exceeds the bytes");
      s.mForm = NodeSelection::Form::kRanges;
      s.mRanges.reserve(count);
      uint64_t total = 0;
      for (uint32_t i = 0; i < count; ++i) {
        const ElementRange e{r.u32(), r.u32()};
        if (e.begin >= e.end || e.end > size)
          bad(where + "range [" + std::to_string(e.begin) + ", " + std::to_string(e.end) +
              ") is empty or past the node's size " + std::to_string(size));
        if (!s.mRanges.empty() && e.begin <= s.mRanges.back().end)
          bad(where + "ranges are not sorted, disjoint and apart");
        total += e.end - e.begin;
        s.mRanges.push_back(e);
      }
      s.mCount = uint32_t(total);
      // Canonical form only: what fromBits() would pick for this set.
      if (total == size || count > wordsFor(size))
        bad(where + "ranges where a smaller form exists");
    } else if (form == uint8_t(NodeSelection::Form::kBits)) {
      const size_t words = wordsFor(size);
      if (words > r.left() / 8) bad(where + "bitset exceeds the bytes");
      std::vector<uint64_t> bits(words);
      for (uint64_t& word : bits) word = r.u64();
      if (size % 64 != 0 && (bits.back() >> (size % 64)) != 0)
        bad(where + "a bit is set past the node's size");
      s = NodeSelection::fromBits(size, std::move(bits));
      if (s.form() != NodeSelection::Form::kBits)
        bad(where + "bitset where a smaller form exists (or none set)");
    } else {
      bad(where + "unknown form " + std::to_string(form));
    }
    out.mNodes.emplace(id, std::move(s));
  }
  if (r.left() != 0) bad(std::to_string(r.left()) + " stray bytes after the last node");
  return out;
}

}  // namespace tessera::annotate
