// Entropy coding of byte streams for point chunks (chunk_codec.cpp): a static-model rANS coder
// (Duda, "Asymmetric numeral systems: entropy coding combining speed of Huffman coding with
// compression rate of arithmetic coding", 2013; the byte-renormalised 32-bit variant of
// F. Giesen's public-domain rans_byte.h with 16-bit renormalisation, so a symbol reads at most
// one 16-bit word; two interleaved states), a packed bit stream for the
// bits an entropy model cannot predict, and log buckets that split an integer into a symbol
// (its bit length and the two bits below the leading one) and raw low bits.
//
// A packed stream is one mode byte and its body:
//   0: constant       one symbol byte; every symbol is it
//   1: rANS           max symbol m (1 byte), m + 1 LEB128 frequencies summing to 2^kScaleBits
//                     (0: absent, followed by the count of further absent symbols), two
//                     32-bit states, then the renormalisation words (16 bits each)
//   2: stored         the n bytes as they are
//   3: zstd           one zstd frame of exactly n bytes
// The encoder keeps whichever is smallest. Decoding checks every length, table and final state
// and never reads outside the span it is given: a damaged stream returns false.
#pragma once

#include <zstd.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

namespace tessera::lod::detail {

constexpr int kScaleBits = 12;
constexpr uint32_t kScale = 1u << kScaleBits;
constexpr uint32_t kRansLow = 1u << 16;  ///< lower bound of a normalised state (16-bit renorm)

enum StreamMode : uint8_t { kConstant = 0, kRans = 1, kStored = 2, kZstd = 3 };

inline void putLeb(std::vector<uint8_t>& out, uint64_t v) {
  while (v >= 0x80) {
    out.push_back(uint8_t(v | 0x80));
    v >>= 7;
  }
  out.push_back(uint8_t(v));
}

/// Reads a LEB128 value of at most 64 bits; false when it runs past `end` or is overlong.
inline bool getLeb(const uint8_t*& p, const uint8_t* end, uint64_t& v) {
  v = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (p >= end) return false;
    const uint8_t b = *p++;
    v |= uint64_t(b & 0x7F) << shift;
    if (!(b & 0x80)) return shift < 63 || b <= 1;
  }
  return false;
}

/// Frequencies scaled to sum to kScale, every symbol that occurs keeping at least 1.
inline std::array<uint32_t, 256> normalise(const std::array<uint32_t, 256>& counts, size_t n) {
  std::array<uint32_t, 256> f{};
  uint32_t sum = 0;
  int largest = 0;
  for (int s = 0; s < 256; ++s) {
    if (!counts[s]) continue;
    f[s] = std::max<uint32_t>(1, uint32_t(uint64_t(counts[s]) * kScale / n));
    sum += f[s];
    if (counts[s] > counts[largest]) largest = s;
  }
  // Rounding leaves the sum off by a little: take it from (or give it to) the largest symbols.
  while (sum != kScale) {
    if (sum < kScale) {
      f[largest] += kScale - sum;
      sum = kScale;
    } else {
      int best = -1;
      for (int s = 0; s < 256; ++s)
        if (f[s] > 1 && (best < 0 || f[s] > f[best])) best = s;
      const uint32_t take = std::min(sum - kScale, f[best] - 1);
      f[best] -= take;
      sum -= take;
    }
  }
  return f;
}

/// rANS-codes `s` with its own order-0 model; appends the table and the code to `out`.
inline void ransEncode(std::span<const uint8_t> s, std::vector<uint8_t>& out) {
  std::array<uint32_t, 256> counts{};
  for (uint8_t v : s) ++counts[v];
  const std::array<uint32_t, 256> freq = normalise(counts, s.size());
  std::array<uint32_t, 256> start{};
  int max_sym = 0;
  for (int v = 0, c = 0; v < 256; ++v) {
    start[v] = uint32_t(c);
    c += int(freq[v]);
    if (freq[v]) max_sym = v;
  }
  out.push_back(uint8_t(max_sym));
  // Frequencies as LEB128; a 0 is followed by how many more absent symbols follow it.
  for (int v = 0; v <= max_sym; ++v) {
    putLeb(out, freq[v]);
    if (freq[v] == 0) {
      int run = 0;
      while (v + 1 <= max_sym && freq[v + 1] == 0) ++v, ++run;
      putLeb(out, uint64_t(run));
    }
  }
  // Encoded backwards: the decoder reads forwards, 16-bit words little-endian.
  thread_local std::vector<uint16_t> rev;
  rev.clear();
  rev.reserve(s.size() / 2 + 16);
  uint32_t x[2] = {kRansLow, kRansLow};
  for (size_t i = s.size(); i-- > 0;) {
    uint32_t& st = x[i & 1];
    const uint32_t f = freq[s[i]];
    const uint32_t x_max = ((kRansLow >> kScaleBits) << 16) * f;
    if (st >= x_max) {
      rev.push_back(uint16_t(st));
      st >>= 16;
    }
    st = ((st / f) << kScaleBits) + (st % f) + start[s[i]];
  }
  for (int k = 0; k < 2; ++k)
    for (int b = 0; b < 4; ++b) out.push_back(uint8_t(x[k] >> (8 * b)));
  for (auto it = rev.rbegin(); it != rev.rend(); ++it) {
    out.push_back(uint8_t(*it));
    out.push_back(uint8_t(*it >> 8));
  }
}

/// Appends `s` as a packed stream (mode byte + body), the smallest of the modes above; zstd is
/// tried only where `zstd_level` > 0.
inline void packStream(std::span<const uint8_t> s, std::vector<uint8_t>& out, int zstd_level) {
  if (s.empty()) {
    out.push_back(kStored);
    return;
  }
  if (std::all_of(s.begin(), s.end(), [&](uint8_t v) { return v == s[0]; })) {
    out.push_back(kConstant);
    out.push_back(s[0]);
    return;
  }
  const size_t base = out.size();
  out.push_back(kRans);
  ransEncode(s, out);
  size_t best = out.size() - base;
  if (zstd_level > 0) {
    thread_local std::vector<uint8_t> z;
    z.resize(ZSTD_compressBound(s.size()));
    const size_t n = ZSTD_compress(z.data(), z.size(), s.data(), s.size(), zstd_level);
    if (!ZSTD_isError(n) && n + 1 < best) {
      out.resize(base);
      out.push_back(kZstd);
      out.insert(out.end(), z.begin(), z.begin() + ptrdiff_t(n));
      best = n + 1;
    }
  }
  if (s.size() + 1 < best) {
    out.resize(base);
    out.push_back(kStored);
    out.insert(out.end(), s.begin(), s.end());
  }
}

/// Decodes a packed stream `in` (exactly its bytes) into `n` symbols at `out`. False when the
/// stream is damaged: a bad mode, table or length, a state that does not end where the
/// encoder started, bytes left over.
inline bool unpackStream(std::span<const uint8_t> in, size_t n, uint8_t* out) {
  if (in.empty()) return false;
  const uint8_t* p = in.data() + 1;
  const uint8_t* end = in.data() + in.size();
  switch (in[0]) {
    case kConstant:
      if (in.size() != 2) return false;
      std::memset(out, in[1], n);
      return true;
    case kStored:
      if (in.size() != n + 1) return false;
      if (n) std::memcpy(out, p, n);
      return true;
    case kZstd: {
      const unsigned long long size = ZSTD_getFrameContentSize(p, size_t(end - p));
      if (size != n) return false;
      struct Holder {
        ZSTD_DCtx* ctx = ZSTD_createDCtx();
        ~Holder() { ZSTD_freeDCtx(ctx); }
      };
      thread_local Holder holder;
      const size_t got = ZSTD_decompressDCtx(holder.ctx, out, n, p, size_t(end - p));
      return !ZSTD_isError(got) && got == n;
    }
    case kRans:
      break;
    default:
      return false;
  }
  if (p >= end) return false;
  const int max_sym = *p++;
  // One entry per slot: symbol | frequency << 8 | (slot - symbol start) << 20.
  thread_local uint32_t table[kScale];
  uint32_t sum = 0;
  for (int v = 0; v <= max_sym; ++v) {
    uint64_t f;
    if (!getLeb(p, end, f) || f >= kScale) return false;
    if (f == 0) {
      uint64_t run;
      if (!getLeb(p, end, run) || run > uint64_t(max_sym - v)) return false;
      v += int(run);
      continue;
    }
    if (sum + f > kScale) return false;
    for (uint32_t k = 0; k < f; ++k) table[sum + k] = uint32_t(v) | uint32_t(f) << 8 | k << 20;
    sum += uint32_t(f);
  }
  if (sum != kScale) return false;
  if (end - p < 8) return false;
  auto word32 = [](const uint8_t* q) {
    return uint32_t(q[0]) | uint32_t(q[1]) << 8 | uint32_t(q[2]) << 16 | uint32_t(q[3]) << 24;
  };
  uint32_t x0 = word32(p), x1 = word32(p + 4);
  p += 8;
  if (x0 < kRansLow || x1 < kRansLow) return false;
  constexpr uint32_t kMask = kScale - 1;
  const uint32_t* t = table;
  size_t i = 0;
  // Fast loop: a symbol reads at most one 16-bit word, so 4 spare bytes cover a pair.
  for (; i + 1 < n && end - p >= 4; i += 2) {
    const uint32_t e0 = t[x0 & kMask], e1 = t[x1 & kMask];
    out[i] = uint8_t(e0);
    out[i + 1] = uint8_t(e1);
    x0 = ((e0 >> 8) & 0xFFF) * (x0 >> kScaleBits) + (e0 >> 20);
    x1 = ((e1 >> 8) & 0xFFF) * (x1 >> kScaleBits) + (e1 >> 20);
    if (x0 < kRansLow) {
      x0 = (x0 << 16) | uint32_t(p[0]) | uint32_t(p[1]) << 8;
      p += 2;
    }
    if (x1 < kRansLow) {
      x1 = (x1 << 16) | uint32_t(p[0]) | uint32_t(p[1]) << 8;
      p += 2;
    }
  }
  for (; i < n; ++i) {
    uint32_t& st = i & 1 ? x1 : x0;
    const uint32_t e = t[st & kMask];
    out[i] = uint8_t(e);
    st = ((e >> 8) & 0xFFF) * (st >> kScaleBits) + (e >> 20);
    if (st < kRansLow) {
      if (end - p < 2) return false;
      st = (st << 16) | uint32_t(p[0]) | uint32_t(p[1]) << 8;
      p += 2;
    }
  }
  return p == end && x0 == kRansLow && x1 == kRansLow;
}

/// Bits appended least significant first.
class BitWriter {
 public:
  explicit BitWriter(std::vector<uint8_t>& out) : mOut(out) {}
  /// Precondition: bits <= 64, value < 2^bits.
  void put(uint64_t value, int bits) {
    if (bits > 32) {
      put(value & 0xFFFFFFFFu, 32);
      put(value >> 32, bits - 32);
      return;
    }
    mAcc |= value << mCount;
    mCount += bits;
    while (mCount >= 8) {
      mOut.push_back(uint8_t(mAcc));
      mAcc >>= 8;
      mCount -= 8;
    }
  }
  void flush() {
    if (mCount > 0) mOut.push_back(uint8_t(mAcc));
    mAcc = 0;
    mCount = 0;
  }

 private:
  std::vector<uint8_t>& mOut;
  uint64_t mAcc = 0;
  int mCount = 0;
};

/// Reads what BitWriter wrote; reading past the end sets a flag (and yields zeros) instead of
/// touching memory beyond the span.
class BitReader {
 public:
  explicit BitReader(std::span<const uint8_t> in) : mData(in.data()), mSize(in.size()) {}
  /// Precondition: bits <= 64.
  uint64_t get(int bits) {
    if (bits > 56) {
      const uint64_t lo = get(32);
      return lo | get(bits - 32) << 32;
    }
    // One unaligned 64-bit load covers the bits wanted (shift <= 7, bits <= 56).
    const size_t byte = mPos >> 3;
    uint64_t w = 0;
    if (byte + 8 <= mSize) {
      std::memcpy(&w, mData + byte, 8);
    } else {
      for (size_t k = byte; k < mSize && k < byte + 8; ++k)
        w |= uint64_t(mData[k]) << (8 * (k - byte));
    }
    const uint64_t v = (w >> (mPos & 7)) & ((uint64_t(1) << bits) - 1);
    mPos += uint64_t(bits);
    return v;
  }
  bool overrun() const { return mPos > 8 * uint64_t(mSize); }
  /// Whether every byte was consumed and the unread bits of the last one are zero.
  bool exhausted() const {
    if (overrun() || (mPos + 7) / 8 != mSize) return false;
    return (mPos & 7) == 0 || (mData[mSize - 1] >> (mPos & 7)) == 0;
  }

 private:
  const uint8_t* mData;
  size_t mSize;
  uint64_t mPos = 0;  ///< bits read
};

/// Log bucket of v: values below 8 are their own symbol; above, 8 + 4 (bit length - 4) + the
/// two bits below the leading one, and the remaining (bit length - 3) low bits go raw.
inline void bucketPut(uint64_t v, std::vector<uint8_t>& symbols, BitWriter& raw) {
  if (v < 8) {
    symbols.push_back(uint8_t(v));
    return;
  }
  const int k = 64 - __builtin_clzll(v);
  const int sh = k - 3;
  symbols.push_back(uint8_t(8 + 4 * (k - 4) + ((v >> sh) & 3)));
  raw.put(v & ((uint64_t(1) << sh) - 1), sh);
}

/// Largest symbol bucketPut() writes for values below 2^64.
constexpr uint8_t kMaxBucket = 8 + 4 * (64 - 4) + 3;

/// Inverse of bucketPut(). Precondition: sym <= kMaxBucket.
inline uint64_t bucketGet(uint8_t sym, BitReader& raw) {
  if (sym < 8) return sym;
  const int k = (sym - 8) / 4 + 4;
  const int sh = k - 3;
  return (uint64_t(4 | ((sym - 8) & 3)) << sh) | raw.get(sh);
}

}  // namespace tessera::lod::detail
