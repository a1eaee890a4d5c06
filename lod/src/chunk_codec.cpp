#include "chunk_codec.h"

#include "morton.h"

#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>

namespace tessera::lod {
namespace {

constexpr int kMaxBits = 21;  // per axis: 63-bit Morton codes

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

void putVarint(std::vector<uint8_t>& out, uint64_t v) {
  while (v >= 0x80) {
    out.push_back(uint8_t(v | 0x80));
    v >>= 7;
  }
  out.push_back(uint8_t(v));
}

ZSTD_CCtx* threadCCtx();

void compressInto(std::vector<uint8_t>& out, const std::vector<uint8_t>& raw, int level) {
  size_t start = out.size();
  out.resize(start + ZSTD_compressBound(raw.size()));
  size_t n = ZSTD_compressCCtx(threadCCtx(), out.data() + start, out.size() - start, raw.data(),
                               raw.size(), level);
  if (ZSTD_isError(n))
    throw StoreError(std::string("lod::encodeChunk(): zstd: ") + ZSTD_getErrorName(n));
  out.resize(start + n);
}

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

ZSTD_CCtx* threadCCtx() {
  struct Holder {
    ZSTD_CCtx* ctx = ZSTD_createCCtx();
    ~Holder() { ZSTD_freeCCtx(ctx); }
  };
  thread_local Holder holder;
  return holder.ctx;
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
         sources.size() * 2 + classifications.size() + ambient_occlusion.size() + sizeof(*this);
}

EncodedChunk encodeChunk(std::span<BuildPoint> pts, const glm::dvec3& box_min, double extent,
                         double step, AttributeMask attributes, int zstd_level) {
  const size_t n = pts.size();
  // Never more than 21 bits per axis: a coarser step if the box needs it.
  step = std::max(step, extent / double((1u << kMaxBits) - 1));
  int bits = 1;
  while (bits < kMaxBits && double((1u << bits) - 1) * step < extent) ++bits;
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
    putVarint(raw, codes[i] - prev);
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
                 const std::string& what) {
  ChunkHeader h;
  if (bytes.size() < sizeof h) corrupt(what, "shorter than its header");
  std::memcpy(&h, bytes.data(), sizeof h);
  if (uint64_t(sizeof h) + h.pc_size + h.extra_size != bytes.size())
    corrupt(what, "frame sizes do not add up");
  // Positions are float(step) * cell with cell < 2^bits: that must be finite and not zero
  // (a double step beyond float's range decoded to infinite or NaN positions; fuzz target).
  if (h.bits < 1 || h.bits > kMaxBits || !(h.step > 0.0) || !std::isfinite(h.step) ||
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
    size_t expect = (h.attributes & kIntensity ? 2 * n : 0) +
                    (h.attributes & kScanIndex ? 2 * n : 0) +
                    (h.attributes & kClassification ? n : 0) +
                    (h.attributes & kAmbientOcclusion ? n : 0);
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

}  // namespace tessera::lod
