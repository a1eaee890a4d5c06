#include "chunk_codec.h"

#include "byte_streams.h"
#include "morton.h"

#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <numeric>

namespace tessera::lod {
namespace {

constexpr int kMaxBitsV1 = 21;  // format 1, per axis: 63-bit Morton codes

struct ChunkHeader {
  uint32_t points;
  uint32_t attributes;
  uint32_t pc_size;     // compressed position + colour frame
  uint32_t extra_size;  // compressed intensity / source / classification frame (0: none)
  double step;
  uint8_t bits;
  uint8_t reserved[7];
};
static_assert(sizeof(ChunkHeader) == 32);

constexpr AttributeMask kExtra = kIntensity | kScanIndex | kClassification | kAmbientOcclusion;

[[noreturn]] void corrupt(const std::string& what, const char* why) {
  throw StoreError("lod::decodeChunk(): " + what + ": corrupt chunk (" + why + ")");
}

/// One decompression context per thread: creating one per chunk costs more than small chunks'
/// decoding.
ZSTD_DCtx* threadDCtx() {
  struct Holder {
    ZSTD_DCtx* ctx = ZSTD_createDCtx();
    ~Holder() { ZSTD_freeDCtx(ctx); }
  };
  thread_local Holder holder;
  return holder.ctx;
}

/// One compression context per thread (format 1's encoder).
ZSTD_CCtx* threadCCtx() {
  struct Holder {
    ZSTD_CCtx* ctx = ZSTD_createCCtx();
    ~Holder() { ZSTD_freeCCtx(ctx); }
  };
  thread_local Holder holder;
  return holder.ctx;
}

void compressInto(std::vector<uint8_t>& out, const std::vector<uint8_t>& raw, int level) {
  size_t start = out.size();
  out.resize(start + ZSTD_compressBound(raw.size()));
  size_t n = ZSTD_compressCCtx(threadCCtx(), out.data() + start, out.size() - start, raw.data(),
                               raw.size(), level);
  if (ZSTD_isError(n))
    throw StoreError(std::string("lod::encodeChunk(): zstd: ") + ZSTD_getErrorName(n));
  out.resize(start + n);
}

/// Decompresses exactly `expect` bytes or reports corruption.
void decompress(std::span<const uint8_t> in, std::vector<uint8_t>& out, size_t expect,
                const std::string& what) {
  unsigned long long size = ZSTD_getFrameContentSize(in.data(), in.size());
  if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN || size != expect) {
    corrupt(what, "frame size does not match the point count");
  }
  out.resize(expect);
  size_t n = ZSTD_decompressDCtx(threadDCtx(), out.data(), out.size(), in.data(), in.size());
  if (ZSTD_isError(n) || n != expect) corrupt(what, "zstd frame does not decode");
}

#if defined(__x86_64__)
bool haveBmi2() {
  static const bool have = __builtin_cpu_supports("bmi2");
  return have;
}
__attribute__((target("bmi2"))) inline uint32_t compactBmi2(uint64_t v, int axis) {
  return uint32_t(__builtin_ia32_pext_di(v, 0x1249249249249249ull << axis));
}
#else
bool haveBmi2() {
  return false;
}
inline uint32_t compactBmi2(uint64_t, int) {
  return 0;
}
#endif

/// Decodes `n` LEB128 Morton deltas into positions (cell * step). Returns false on a malformed
/// stream (ends early, overlong varint, code outside the node, trailing bytes are checked by the
/// caller through `p`). kBmi2: one PEXT per axis instead of the magic-bits compaction.
template <bool kBmi2>
#if defined(__x86_64__)
__attribute__((target("bmi2")))
#endif
bool decodePositions(const uint8_t*& p, const uint8_t* end, size_t n, uint64_t limit, float step, glm::vec3* out) {
  uint64_t code = 0;
  for (size_t i = 0; i < n; ++i) {
    uint64_t d;
    if (end - p >= 10) {
      // Fast path: no bounds checks inside a varint (at most 10 bytes).
      uint8_t b = *p++;
      d = b & 0x7F;
      for (int shift = 7; b & 0x80; shift += 7) {
        if (shift > 63) return false;
        b = *p++;
        d |= uint64_t(b & 0x7F) << shift;
      }
    } else {
      d = 0;
      for (int shift = 0;; shift += 7) {
        if (p >= end || shift > 63) return false;
        uint8_t b = *p++;
        d |= uint64_t(b & 0x7F) << shift;
        if (!(b & 0x80)) break;
      }
    }
    code += d;
    if (code > limit) return false;
    if constexpr (kBmi2) {
      out[i] = glm::vec3(float(compactBmi2(code, 0)), float(compactBmi2(code, 1)),
                         float(compactBmi2(code, 2))) *
               step;
    } else {
      out[i] = glm::vec3(float(mortonCompact(code)), float(mortonCompact(code >> 1)),
                         float(mortonCompact(code >> 2))) *
               step;
    }
  }
  return true;
}

}  // namespace

size_t ChunkPoints::byteSize() const {
  return positions.size() * sizeof(glm::vec3) + colors.size() * 4 + intensities.size() * 2 +
         sources.size() * 2 + classifications.size() + ambient_occlusion.size() +
         cells.size() * sizeof(glm::uvec3) + sizeof(*this);
}

namespace {

/// Format 1 (stores of version 1-3): Morton deltas as varints, zstd frames.
void decodeChunkV1(std::span<const uint8_t> bytes, const glm::dvec3& box_min, ChunkPoints& out,
                   const std::string& what) {
  ChunkHeader h;
  if (bytes.size() < sizeof h) corrupt(what, "shorter than its header");
  std::memcpy(&h, bytes.data(), sizeof h);
  if (uint64_t(sizeof h) + h.pc_size + h.extra_size != bytes.size())
    corrupt(what, "frame sizes do not add up");
  // Positions are float(step) * cell with cell < 2^bits: that must be finite and not zero
  // (a double step beyond float's range decoded to infinite or NaN positions; fuzz target).
  if (h.bits < 1 || h.bits > kMaxBitsV1 || !(h.step > 0.0) || !std::isfinite(h.step) ||
      !(float(h.step) > 0.0f) || !std::isfinite(float(h.step) * float(1u << h.bits)))
    corrupt(what, "bad quantisation");
  if ((h.attributes & ~(kColor | kExtra)) != 0) corrupt(what, "unknown attributes");
  if (h.points > (1u << 26)) corrupt(what, "implausible point count");
  const size_t n = h.points;
  const bool color = h.attributes & kColor;

  thread_local std::vector<uint8_t> raw;
  // The varint stream's length is not stored: decompress whatever the frame holds (bounded).
  unsigned long long size = ZSTD_getFrameContentSize(bytes.data() + sizeof h, h.pc_size);
  if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN ||
      size < n * (color ? 4 : 1) || size > n * (10 + (color ? 3 : 0))) {
    corrupt(what, "position frame size does not match the point count");
  }
  decompress(bytes.subspan(sizeof h, h.pc_size), raw, size_t(size), what);

  out.attributes = h.attributes;
  out.offset = box_min;
  out.step = h.step;
  out.positions.resize(n);
  const size_t varint_end = raw.size() - (color ? 3 * n : 0);
  const uint8_t* p = raw.data();
  const uint8_t* end = raw.data() + varint_end;
  const float step = float(h.step);
  const uint64_t limit = h.bits == 21 ? ~uint64_t(0) >> 1 : (uint64_t(1) << (3 * h.bits)) - 1;
  bool ok = haveBmi2() ? decodePositions<true>(p, end, n, limit, step, out.positions.data())
                       : decodePositions<false>(p, end, n, limit, step, out.positions.data());
  if (!ok) corrupt(what, "position stream is malformed or leaves the node");
  if (p != end) corrupt(what, "position stream has trailing bytes");
  if (color) {
    out.colors.resize(n);
    const uint8_t* g = end;
    const uint8_t* r = end + n;
    const uint8_t* b = end + 2 * n;
    uint8_t cg = 0, cr = 0, cb = 0;
    for (size_t i = 0; i < n; ++i) {
      cg = uint8_t(cg + g[i]);
      cr = uint8_t(cr + r[i]);
      cb = uint8_t(cb + b[i]);
      out.colors[i] = glm::u8vec4(uint8_t(cr + cg), cg, uint8_t(cb + cg), 255);
    }
  } else {
    out.colors.clear();
  }
  out.intensities.clear();
  out.sources.clear();
  out.classifications.clear();
  out.ambient_occlusion.clear();
  if (h.attributes & kExtra) {
    size_t expect =
        (h.attributes & kIntensity ? 2 * n : 0) + (h.attributes & kScanIndex ? 2 * n : 0) +
        (h.attributes & kClassification ? n : 0) + (h.attributes & kAmbientOcclusion ? n : 0);
    if (h.extra_size == 0) corrupt(what, "attribute frame missing");
    decompress(bytes.subspan(sizeof h + h.pc_size, h.extra_size), raw, expect, what);
    const uint8_t* q = raw.data();
    if (h.attributes & kIntensity) {
      out.intensities.resize(n);
      uint16_t v = 0;
      for (size_t i = 0; i < n; ++i) {
        uint16_t z = uint16_t(q[i] | q[n + i] << 8);
        v = uint16_t(v + uint16_t((z >> 1) ^ uint16_t(-(z & 1))));
        out.intensities[i] = v;
      }
      q += 2 * n;
    }
    if (h.attributes & kScanIndex) {
      out.sources.resize(n);
      for (size_t i = 0; i < n; ++i) out.sources[i] = uint16_t(q[i] | q[n + i] << 8);
      q += 2 * n;
    }
    if (h.attributes & kClassification) {
      out.classifications.assign(q, q + n);
      q += n;
    }
    if (h.attributes & kAmbientOcclusion) {
      out.ambient_occlusion.resize(n);
      uint8_t v = 0;
      for (size_t i = 0; i < n; ++i) out.ambient_occlusion[i] = v = uint8_t(v + q[i]);
    }
  } else if (h.extra_size != 0) {
    corrupt(what, "unexpected attribute frame");
  }
}

/// Format 2 (stores of version 4). The header, then two sections of packed streams
/// (byte_streams.h), each stream preceded by its byte length (LEB128):
///   position + colour: the 2D Morton deltas of the cells across the height axis (log-bucket
///     symbols, then their raw bits), the height residuals against the previous point
///     (zig-zag, log-bucket symbols, raw bits); with colour, green deltas, then red - green and
///     blue - green deltas (zig-zag bytes), each split in three streams by the size of the green
///     delta;
///   attributes: intensity low and high bytes, source low and high bytes, classification,
///     ambient-occlusion deltas (those the chunk carries).
struct ChunkHeader2 {
  uint32_t points;
  uint32_t attributes;
  uint32_t pc_size;     // bytes of the position + colour section
  uint32_t extra_size;  // bytes of the attribute section
  double step;
  uint8_t bits;    // cells per axis < 2^bits
  uint8_t format;  // 2 (byte 25: always 0 in format 1)
  uint8_t axis;    // height axis: points sorted by the 2D Morton code of the two others
  uint8_t reserved[5];
  double grid[3];  // position of cell 0 relative to the node box minimum, in [-step, 0]
};
static_assert(sizeof(ChunkHeader2) == 56);
static_assert(offsetof(ChunkHeader2, format) == 25);

constexpr int kMaxBits = 31;  // per axis: 62-bit 2D Morton codes, heights below 2^31

/// A byte delta d (mod 256) as a small symbol: 0, -1, 1, -2, 2, ... -> 0, 1, 2, 3, 4, ...
inline uint8_t zigzag8(uint8_t d) {
  return uint8_t((d << 1) ^ uint8_t(int8_t(d) >> 7));
}
inline uint8_t unzigzag8(uint8_t z) {
  return uint8_t((z >> 1) ^ uint8_t(-(z & 1)));
}

/// Context of the red and blue deltas: how far green moved (zig-zag symbol: 0, 1-6, more).
inline int colorContext(uint8_t green_symbol) {
  return green_symbol == 0 ? 0 : green_symbol < 7 ? 1 : 2;
}

inline uint64_t zigzag(int64_t v) {
  return (uint64_t(v) << 1) ^ uint64_t(v >> 63);
}
inline int64_t unzigzag(uint64_t z) {
  return int64_t(z >> 1) ^ -int64_t(z & 1);
}

/// Appends a stream with its length.
void putStream(std::vector<uint8_t>& out, std::span<const uint8_t> s, int zstd_level) {
  thread_local std::vector<uint8_t> packed;
  packed.clear();
  detail::packStream(s, packed, zstd_level);
  detail::putLeb(out, packed.size());
  out.insert(out.end(), packed.begin(), packed.end());
}
void putRaw(std::vector<uint8_t>& out, const std::vector<uint8_t>& bits) {
  detail::putLeb(out, bits.size());
  out.insert(out.end(), bits.begin(), bits.end());
}

/// Cuts the next length-prefixed stream out of [p, end); false when it does not fit.
bool takeStream(const uint8_t*& p, const uint8_t* end, std::span<const uint8_t>& s) {
  uint64_t len;
  if (!detail::getLeb(p, end, len) || len > uint64_t(end - p)) return false;
  s = {p, size_t(len)};
  p += len;
  return true;
}

#if defined(__x86_64__)
__attribute__((target("bmi2"))) inline uint32_t compact2Bmi2(uint64_t v) {
  return uint32_t(__builtin_ia32_pext_di(v, 0x5555555555555555ull));
}
#else
inline uint32_t compact2Bmi2(uint64_t v) {
  return mortonCompact2(v);
}
#endif

template <bool kBmi2>
#if defined(__x86_64__)
__attribute__((target("bmi2")))
#endif
inline uint32_t
compact2Bmi2Or(uint64_t v) {
  if constexpr (kBmi2) {
    return compact2Bmi2(v);
  } else {
    return mortonCompact2(v);
  }
}

/// Decodes the cells of `n` points into positions (and `cells` where not null). False on a
/// malformed stream.
template <bool kBmi2>
#if defined(__x86_64__)
__attribute__((target("bmi2")))
#endif
bool decodeCells(const uint8_t* xy_sym, detail::BitReader& xy_raw, const uint8_t* h_sym,
                 detail::BitReader& h_raw, size_t n, const ChunkHeader2& h, glm::vec3* out,
                 glm::uvec3* cells) {
  const uint64_t limit = (uint64_t(1) << (2 * h.bits)) - 1;
  const int64_t hmax = (int64_t(1) << h.bits) - 1;
  const float step = float(h.step);
  const glm::vec3 grid(h.grid[0], h.grid[1], h.grid[2]);
  const int u = (h.axis + 1) % 3, w = (h.axis + 2) % 3;
  uint64_t code = 0;
  int64_t height = 0;
  for (size_t i = 0; i < n; ++i) {
    const uint64_t d = detail::bucketGet(xy_sym[i], xy_raw);
    if (d > limit - code) return false;
    code += d;
    height += unzigzag(detail::bucketGet(h_sym[i], h_raw));
    if (height < 0 || height > hmax) return false;
    glm::vec3 c;
    if constexpr (kBmi2) {
      c[u] = float(compact2Bmi2(code));
      c[w] = float(compact2Bmi2(code >> 1));
    } else {
      c[u] = float(mortonCompact2(code));
      c[w] = float(mortonCompact2(code >> 1));
    }
    c[h.axis] = float(height);
    out[i] = c * step + grid;
    if (cells) {
      glm::uvec3& k = cells[i];
      k[u] = compact2Bmi2Or<kBmi2>(code);
      k[w] = compact2Bmi2Or<kBmi2>(code >> 1);
      k[h.axis] = uint32_t(height);
    }
  }
  return !xy_raw.overrun() && !h_raw.overrun();
}

void decodeChunkV2(std::span<const uint8_t> bytes, const glm::dvec3& box_min, ChunkPoints& out,
                   const std::string& what, bool with_cells) {
  ChunkHeader2 h;
  if (bytes.size() < sizeof h) corrupt(what, "shorter than its header");
  std::memcpy(&h, bytes.data(), sizeof h);
  if (uint64_t(sizeof h) + h.pc_size + h.extra_size != bytes.size())
    corrupt(what, "section sizes do not add up");
  if (h.bits < 1 || h.bits > kMaxBits || !(h.step > 0.0) || !std::isfinite(h.step) ||
      !(float(h.step) > 0.0f) || !std::isfinite(float(h.step) * 2147483648.0f) || h.axis > 2)
    corrupt(what, "bad quantisation");
  for (double g : h.grid)
    if (!(g <= 0.0 && g >= -h.step)) corrupt(what, "grid origin outside its step");
  if ((h.attributes & ~(kColor | kExtra)) != 0) corrupt(what, "unknown attributes");
  if (h.points > (1u << 26)) corrupt(what, "implausible point count");
  const size_t n = h.points;
  const bool color = h.attributes & kColor;

  out.attributes = h.attributes;
  out.offset = box_min;
  out.step = h.step;
  out.grid = glm::dvec3(h.grid[0], h.grid[1], h.grid[2]);
  out.positions.resize(n);
  thread_local std::vector<uint8_t> sym;
  sym.resize(2 * n);
  const uint8_t* p = bytes.data() + sizeof h;
  const uint8_t* end = p + h.pc_size;
  std::span<const uint8_t> s, xy_raw, h_raw;
  if (!takeStream(p, end, s) || !detail::unpackStream(s, n, sym.data()) ||
      !takeStream(p, end, xy_raw) || !takeStream(p, end, s) ||
      !detail::unpackStream(s, n, sym.data() + n) || !takeStream(p, end, h_raw))
    corrupt(what, "position streams are malformed");
  for (size_t i = 0; i < 2 * n; ++i)
    if (sym[i] > detail::kMaxBucket) corrupt(what, "position symbol out of range");
  {
    detail::BitReader xr(xy_raw), hr(h_raw);
    if (with_cells) out.cells.resize(n);
    glm::uvec3* cells = with_cells ? out.cells.data() : nullptr;
    const bool ok = haveBmi2() ? decodeCells<true>(sym.data(), xr, sym.data() + n, hr, n, h,
                                                   out.positions.data(), cells)
                               : decodeCells<false>(sym.data(), xr, sym.data() + n, hr, n, h,
                                                    out.positions.data(), cells);
    if (!ok || !xr.exhausted() || !hr.exhausted())
      corrupt(what, "position stream is malformed or leaves the node");
  }
  out.colors.clear();
  if (color) {
    // Green deltas, then red and blue deltas per context of the green delta.
    thread_local std::vector<uint8_t> g, rb[3];
    g.resize(n);
    if (!takeStream(p, end, s) || !detail::unpackStream(s, n, g.data()))
      corrupt(what, "colour streams are malformed");
    size_t count[3] = {0, 0, 0};
    for (size_t i = 0; i < n; ++i) ++count[colorContext(g[i])];
    for (int c = 0; c < 3; ++c) rb[c].resize(2 * count[c]);
    for (int plane = 0; plane < 2; ++plane)
      for (int c = 0; c < 3; ++c)
        if (!takeStream(p, end, s) ||
            !detail::unpackStream(s, count[c], rb[c].data() + size_t(plane) * count[c]))
          corrupt(what, "colour streams are malformed");
    out.colors.resize(n);
    size_t at[3] = {0, 0, 0};
    uint8_t cg = 0, cr = 0, cb = 0;
    for (size_t i = 0; i < n; ++i) {
      const int c = colorContext(g[i]);
      cg = uint8_t(cg + unzigzag8(g[i]));
      cr = uint8_t(cr + unzigzag8(rb[c][at[c]]));
      cb = uint8_t(cb + unzigzag8(rb[c][count[c] + at[c]]));
      ++at[c];
      out.colors[i] = glm::u8vec4(uint8_t(cr + cg), cg, uint8_t(cb + cg), 255);
    }
  }
  if (p != end) corrupt(what, "position and colour section has trailing bytes");

  out.intensities.clear();
  out.sources.clear();
  out.classifications.clear();
  out.ambient_occlusion.clear();
  if (!(h.attributes & kExtra)) {
    if (h.extra_size != 0) corrupt(what, "unexpected attribute section");
    return;
  }
  end = p + h.extra_size;
  auto plane = [&](uint8_t* dst, const char* name) {
    if (!takeStream(p, end, s) || !detail::unpackStream(s, n, dst))
      corrupt(what, (std::string(name) + " stream is malformed").c_str());
  };
  auto two = [&](std::vector<uint16_t>& v, const char* name) {
    sym.resize(2 * n);
    plane(sym.data(), name);
    plane(sym.data() + n, name);
    v.resize(n);
    for (size_t i = 0; i < n; ++i) v[i] = uint16_t(sym[i] | sym[n + i] << 8);
  };
  if (h.attributes & kIntensity) two(out.intensities, "intensity");
  if (h.attributes & kScanIndex) two(out.sources, "source");
  if (h.attributes & kClassification) {
    out.classifications.resize(n);
    plane(out.classifications.data(), "classification");
  }
  if (h.attributes & kAmbientOcclusion) {
    out.ambient_occlusion.resize(n);
    plane(out.ambient_occlusion.data(), "ambient occlusion");
    uint8_t v = 0;
    for (auto& a : out.ambient_occlusion) a = v = uint8_t(v + a);
  }
  if (p != end) corrupt(what, "attribute section has trailing bytes");
}

}  // namespace

EncodedChunk encodeChunk(std::span<BuildPoint> pts, const glm::dvec3& box_min, double extent,
                         double step, AttributeMask attributes, int zstd_level, bool lattice) {
  const size_t n = pts.size();
  // Never more than kMaxBits per axis: a coarser step if the box needs it (the lattice's grid
  // origin lies up to a step below the box, so it needs one cell more).
  step = std::max(step, (extent + step) / double((1u << kMaxBits) - 2));
  int bits = 1;
  while (bits < kMaxBits && double((1u << bits) - 1) * step < extent + step) ++bits;
  const double qmax = double((1u << bits) - 1);
  // Cell 0: the box minimum, or with `lattice` the multiple of step at or below it, so cells
  // are the input's own integers when the local frame's origin lies on them.
  glm::dvec3 grid(0.0);
  if (lattice) {
    for (int a = 0; a < 3; ++a) {
      grid[a] = std::floor(box_min[a] / step) * step - box_min[a];
      if (!(grid[a] <= 0.0 && grid[a] >= -step)) grid[a] = 0.0;  // rounding at huge offsets
    }
  }

  EncodedChunk out;
  out.step = step;
  thread_local std::vector<glm::u64vec3> cells;
  cells.resize(n);
  const double inv_step = 1.0 / step;
  double max_error2 = 0.0;
  glm::u64vec3 lo(~uint64_t(0)), hi(0);
  for (size_t i = 0; i < n; ++i) {
    const glm::dvec3 rel = pts[i].position - box_min - grid;
    const glm::dvec3 q = glm::clamp(glm::round(rel * inv_step), glm::dvec3(0.0), glm::dvec3(qmax));
    const glm::dvec3 e = q * step - rel;
    max_error2 = std::max(max_error2, glm::dot(e, e));
    cells[i] = glm::u64vec3(q);
    lo = glm::min(lo, cells[i]);
    hi = glm::max(hi, cells[i]);
  }
  out.max_error = std::sqrt(max_error2);
  // The height axis: the one the points spread least along (z for terrain, a patch's normal
  // direction for a scanned surface).
  int axis = 2;
  for (int a : {0, 1})
    if (n && hi[a] - lo[a] < hi[axis] - lo[axis]) axis = a;
  const int u = (axis + 1) % 3, w = (axis + 2) % 3;
  // Sort (2D Morton code, height << 32 | index): contiguous keys sort fast.
  thread_local std::vector<std::pair<uint64_t, uint64_t>> keyed;
  keyed.resize(n);
  for (size_t i = 0; i < n; ++i)
    keyed[i] = {mortonSpread2(cells[i][u]) | mortonSpread2(cells[i][w]) << 1,
                cells[i][axis] << 32 | i};
  std::sort(keyed.begin(), keyed.end());
  {
    thread_local std::vector<BuildPoint> sorted;
    sorted.resize(n);
    for (size_t i = 0; i < n; ++i) sorted[i] = pts[keyed[i].second & 0xFFFFFFFFu];
    std::copy(sorted.begin(), sorted.begin() + ptrdiff_t(n), pts.begin());
  }

  ChunkHeader2 h{};
  h.points = uint32_t(n);
  h.attributes = attributes;
  h.step = step;
  h.bits = uint8_t(bits);
  h.format = 2;
  h.axis = uint8_t(axis);
  for (int a = 0; a < 3; ++a) h.grid[a] = grid[a];
  out.bytes.resize(sizeof h);

  thread_local std::vector<uint8_t> sym, raw;
  {
    sym.clear();
    raw.clear();
    detail::BitWriter bits_out(raw);
    uint64_t prev = 0;
    for (const auto& k : keyed) {
      detail::bucketPut(k.first - prev, sym, bits_out);
      prev = k.first;
    }
    bits_out.flush();
    putStream(out.bytes, sym, 0);
    putRaw(out.bytes, raw);
    sym.clear();
    raw.clear();
    int64_t prev_h = 0;
    for (const auto& k : keyed) {
      const int64_t height = int64_t(k.second >> 32);
      detail::bucketPut(zigzag(height - prev_h), sym, bits_out);
      prev_h = height;
    }
    bits_out.flush();
    putStream(out.bytes, sym, 0);
    putRaw(out.bytes, raw);
  }
  if (attributes & kColor) {
    // Reversible subtract-green, deltas along the point order; red and blue by green's move.
    thread_local std::vector<uint8_t> g, rb[3][2];
    g.resize(n);
    for (auto& c : rb)
      for (auto& plane : c) plane.clear();
    uint8_t pg = 0, pr = 0, pb = 0;
    for (size_t i = 0; i < n; ++i) {
      const glm::u8vec3 c = pts[i].rgb;
      const uint8_t gv = c.g, rv = uint8_t(c.r - c.g), bv = uint8_t(c.b - c.g);
      g[i] = zigzag8(uint8_t(gv - pg));
      const int ctx = colorContext(g[i]);
      rb[ctx][0].push_back(zigzag8(uint8_t(rv - pr)));
      rb[ctx][1].push_back(zigzag8(uint8_t(bv - pb)));
      pg = gv;
      pr = rv;
      pb = bv;
    }
    putStream(out.bytes, g, 0);
    for (int plane = 0; plane < 2; ++plane)
      for (int c = 0; c < 3; ++c) putStream(out.bytes, rb[c][plane], 0);
  }
  h.pc_size = uint32_t(out.bytes.size() - sizeof h);
  out.position_color_bytes = uint32_t(out.bytes.size());
  if (attributes & kExtra) {
    const size_t before = out.bytes.size();
    auto planes = [&](auto value) {
      sym.resize(2 * n);
      for (size_t i = 0; i < n; ++i) {
        const uint16_t v = value(pts[i]);
        sym[i] = uint8_t(v);
        sym[n + i] = uint8_t(v >> 8);
      }
      putStream(out.bytes, std::span(sym).first(n), zstd_level);
      putStream(out.bytes, std::span(sym).subspan(n), zstd_level);
    };
    if (attributes & kIntensity) planes([](const BuildPoint& b) { return b.intensity; });
    if (attributes & kScanIndex) planes([](const BuildPoint& b) { return b.source; });
    if (attributes & kClassification) {
      sym.resize(n);
      for (size_t i = 0; i < n; ++i) sym[i] = pts[i].classification;
      putStream(out.bytes, sym, zstd_level);
    }
    if (attributes & kAmbientOcclusion) {
      // Deltas mod 256 along the point order: neighbours' AO is close.
      sym.resize(n);
      uint8_t prev_ao = 0;
      for (size_t i = 0; i < n; ++i) {
        sym[i] = uint8_t(pts[i].ao - prev_ao);
        prev_ao = pts[i].ao;
      }
      putStream(out.bytes, sym, zstd_level);
    }
    h.extra_size = uint32_t(out.bytes.size() - before);
  }
  std::memcpy(out.bytes.data(), &h, sizeof h);
  return out;
}

EncodedChunk encodeChunkFormat1(std::span<BuildPoint> pts, const glm::dvec3& box_min, double extent,
                                double step, AttributeMask attributes, int zstd_level) {
  const size_t n = pts.size();
  // Never more than 21 bits per axis: a coarser step if the box needs it.
  step = std::max(step, extent / double((1u << kMaxBitsV1) - 1));
  int bits = 1;
  while (bits < kMaxBitsV1 && double((1u << bits) - 1) * step < extent) ++bits;
  const double qmax = double((1u << bits) - 1);

  EncodedChunk out;
  out.step = step;
  thread_local std::vector<uint64_t> codes;
  codes.resize(n);
  const double inv_step = 1.0 / step;
  double max_error2 = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const glm::dvec3 rel = pts[i].position - box_min;
    glm::dvec3 q = glm::clamp(glm::round(rel * inv_step), glm::dvec3(0.0), glm::dvec3(qmax));
    const glm::dvec3 e = q * step - rel;
    max_error2 = std::max(max_error2, glm::dot(e, e));
    codes[i] = mortonEncode(uint64_t(q.x), uint64_t(q.y), uint64_t(q.z));
  }
  out.max_error = std::sqrt(max_error2);
  // Sort (code, index) pairs: contiguous keys sort much faster than an indirect comparison.
  thread_local std::vector<std::pair<uint64_t, uint32_t>> keyed;
  keyed.resize(n);
  for (size_t i = 0; i < n; ++i) keyed[i] = {codes[i], uint32_t(i)};
  std::sort(keyed.begin(), keyed.end());
  {
    thread_local std::vector<BuildPoint> sorted;
    sorted.resize(n);
    for (size_t i = 0; i < n; ++i) {
      sorted[i] = pts[keyed[i].second];
      codes[i] = keyed[i].first;
    }
    std::copy(sorted.begin(), sorted.begin() + ptrdiff_t(n), pts.begin());
  }

  std::vector<uint8_t> raw;
  raw.reserve(n * 8);
  uint64_t prev = 0;
  for (size_t i = 0; i < n; ++i) {
    detail::putLeb(raw, codes[i] - prev);
    prev = codes[i];
  }
  if (attributes & kColor) {
    // Reversible subtract-green, then deltas along the Morton order, as three byte planes.
    size_t base = raw.size();
    raw.resize(base + 3 * n);
    uint8_t pg = 0, pr = 0, pb = 0;
    for (size_t i = 0; i < n; ++i) {
      const glm::u8vec3 c = pts[i].rgb;
      uint8_t g = c.g, r = uint8_t(c.r - c.g), b = uint8_t(c.b - c.g);
      raw[base + i] = uint8_t(g - pg);
      raw[base + n + i] = uint8_t(r - pr);
      raw[base + 2 * n + i] = uint8_t(b - pb);
      pg = g;
      pr = r;
      pb = b;
    }
  }
  ChunkHeader h{};
  h.points = uint32_t(n);
  h.attributes = attributes;
  h.step = step;
  h.bits = uint8_t(bits);
  out.bytes.resize(sizeof h);
  compressInto(out.bytes, raw, zstd_level);
  h.pc_size = uint32_t(out.bytes.size() - sizeof h);
  if (attributes & kExtra) {
    raw.clear();
    if (attributes & kIntensity) {
      // Zig-zag deltas, low and high byte planes.
      size_t base = raw.size();
      raw.resize(base + 2 * n);
      uint16_t prev_i = 0;
      for (size_t i = 0; i < n; ++i) {
        auto d = int16_t(uint16_t(pts[i].intensity - prev_i));
        uint16_t z = uint16_t((uint16_t(d) << 1) ^ uint16_t(d >> 15));
        raw[base + i] = uint8_t(z);
        raw[base + n + i] = uint8_t(z >> 8);
        prev_i = pts[i].intensity;
      }
    }
    if (attributes & kScanIndex) {
      size_t base = raw.size();
      raw.resize(base + 2 * n);
      for (size_t i = 0; i < n; ++i) {
        raw[base + i] = uint8_t(pts[i].source);
        raw[base + n + i] = uint8_t(pts[i].source >> 8);
      }
    }
    if (attributes & kClassification) {
      for (size_t i = 0; i < n; ++i) raw.push_back(pts[i].classification);
    }
    if (attributes & kAmbientOcclusion) {
      // Deltas mod 256 along the Morton order: neighbours' AO is close, so zstd sees small bytes.
      uint8_t prev_ao = 0;
      for (size_t i = 0; i < n; ++i) {
        raw.push_back(uint8_t(pts[i].ao - prev_ao));
        prev_ao = pts[i].ao;
      }
    }
    size_t before = out.bytes.size();
    compressInto(out.bytes, raw, zstd_level);
    h.extra_size = uint32_t(out.bytes.size() - before);
  }
  std::memcpy(out.bytes.data(), &h, sizeof h);
  out.position_color_bytes = uint32_t(sizeof h) + h.pc_size;
  return out;
}

void decodeChunk(std::span<const uint8_t> bytes, const glm::dvec3& box_min, ChunkPoints& out,
                 const std::string& what, bool with_cells) {
  out.cells.clear();
  // Byte 25 tells the formats apart: reserved (0) in format 1, the format number in 2.
  if (bytes.size() > 25 && bytes[25] == 2) {
    decodeChunkV2(bytes, box_min, out, what, with_cells);
  } else if (bytes.size() > 25 && bytes[25] != 0) {
    corrupt(what, "unknown chunk format");
  } else {
    decodeChunkV1(bytes, box_min, out, what);
    out.grid = glm::dvec3(0.0);
    if (with_cells) {
      // Format 1 cells are below 2^21: the float positions divide back exactly.
      out.cells.resize(out.size());
      for (size_t i = 0; i < out.size(); ++i)
        out.cells[i] = glm::uvec3(glm::round(glm::dvec3(out.positions[i]) / out.step));
    }
  }
}

}  // namespace tessera::lod
