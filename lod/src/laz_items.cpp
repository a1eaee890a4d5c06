// LAZ items, pointwise (versions 1 and 2) and layered (versions 3 and 4), and the chunks they
// make (see laz_items.h). Field offsets are those of the LAS 1.4 point records (ASPRS R15,
// section 2.6); the predictors and contexts are LASzip's, which every LAZ file is written with.
#include "laz_items.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

namespace tessera::lod::laz {
namespace {

template <typename T>
T get(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <typename T>
void put(uint8_t* p, T v) {
  std::memcpy(p, &v, sizeof v);
}

// Contexts of the POINT10 coders by return number r and number of returns n (3 bits each);
// pairs a correct file never has map to their own contexts.
constexpr uint8_t kReturnMap[8][8] = {
    {15, 14, 13, 12, 11, 10, 9, 8}, {14, 0, 1, 3, 6, 10, 10, 9},   {13, 1, 2, 4, 7, 11, 11, 10},
    {12, 3, 4, 5, 8, 12, 12, 11},   {11, 6, 7, 8, 9, 13, 13, 12},  {10, 10, 11, 12, 13, 14, 14, 13},
    {9, 10, 11, 12, 13, 14, 15, 14}, {8, 9, 10, 11, 12, 13, 14, 15}};
uint32_t returnLevel(uint32_t n, uint32_t r) {
  return n > r ? n - r : r - n;
}

// The same for POINT14 (4 bits each), folded to 6 contexts; its levels stop at 7.
constexpr uint8_t kReturnMap6[16][16] = {
    {0, 1, 2, 3, 4, 5, 3, 4, 4, 5, 5, 5, 5, 5, 5, 5}, {1, 0, 1, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3},
    {2, 1, 2, 4, 4, 4, 4, 4, 4, 4, 4, 3, 3, 3, 3, 3}, {3, 3, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
    {4, 3, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4}, {5, 3, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
    {3, 3, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4}, {4, 3, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4},
    {4, 3, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4}, {5, 3, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4},
    {5, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 4, 4, 4},
    {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4, 4}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4},
    {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5}};
uint32_t returnLevel8(uint32_t n, uint32_t r) {
  return std::min<uint32_t>(returnLevel(n, r), 7);
}

/// a * b wrapped to 32 bits, as LASzip's predictions of GPS time differences are.
int32_t times(int32_t a, int32_t b) {
  return int32_t(uint32_t(a) * uint32_t(b));
}

/// Zero-bit-cleared k, capped: the context LASzip derives from a previous correction's size.
uint32_t kContext(uint32_t k, uint32_t cap) {
  return k < cap ? (k & ~1u) : cap;
}

/// A model created on first use (LASzip creates per-value models lazily; a fresh model is the
/// same as one re-initialised at a chunk start, so each chunk starts with none).
SymbolModel& lazy(std::unique_ptr<SymbolModel>& m, uint32_t symbols) {
  if (!m) m = std::make_unique<SymbolModel>(symbols);
  return *m;
}

}  // namespace

/// One item of a pointwise record: initialised with the chunk's first (raw) record, then coded.
class ItemCoder {
 public:
  virtual ~ItemCoder() = default;
  virtual void init(const uint8_t* item) = 0;
  virtual void decode(Decoder& dec, uint8_t* item) = 0;
  virtual void encode(Encoder&, const uint8_t*) { throw std::logic_error("laz: no encoder"); }
};

namespace {

// ---- POINT10 (x y z intensity, return byte, classification, scan angle, user data, source)

class Point10V2 final : public ItemCoder {
 public:
  void init(const uint8_t* item) override {
    std::memcpy(mLast, item, 20);
    put<uint16_t>(mLast + 12, 0);  // the intensity predictor starts at zero
  }
  void decode(Decoder& dec, uint8_t* item) override {
    const uint32_t changed = dec.decodeSymbol(mChanged);
    uint32_t r, n, m, l;
    if (changed) {
      if (changed & 32) mLast[14] = uint8_t(dec.decodeSymbol(lazy(mBitByte[mLast[14]], 256)));
      returns(r, n, m, l);
      if (changed & 16) {
        mLastIntensity[m] = uint16_t(mIntensity.decode(dec, mLastIntensity[m], m < 3 ? m : 3));
      }
      put<uint16_t>(mLast + 12, mLastIntensity[m]);
      if (changed & 8) {
        mLast[15] = uint8_t(dec.decodeSymbol(lazy(mClassification[mLast[15]], 256)));
      }
      if (changed & 4) {
        const uint32_t v = dec.decodeSymbol(mScanAngle[(mLast[14] >> 6) & 1]);
        mLast[16] = foldByte(int32_t(v) + mLast[16]);
      }
      if (changed & 2) mLast[17] = uint8_t(dec.decodeSymbol(lazy(mUserData[mLast[17]], 256)));
      if (changed & 1) {
        put<uint16_t>(mLast + 18, uint16_t(mSource.decode(dec, get<uint16_t>(mLast + 18))));
      }
    } else {
      returns(r, n, m, l);
      put<uint16_t>(mLast + 12, mLastIntensity[m]);
    }
    int32_t diff = mDx.decode(dec, mMedianX[m].get(), n == 1);
    put<int32_t>(mLast, int32_t(uint32_t(get<int32_t>(mLast)) + uint32_t(diff)));
    mMedianX[m].add(diff);
    diff = mDy.decode(dec, mMedianY[m].get(), (n == 1) + kContext(mDx.k(), 20));
    put<int32_t>(mLast + 4, int32_t(uint32_t(get<int32_t>(mLast + 4)) + uint32_t(diff)));
    mMedianY[m].add(diff);
    const uint32_t kb = (mDx.k() + mDy.k()) / 2;
    const int32_t z = mZ.decode(dec, mLastHeight[l], (n == 1) + kContext(kb, 18));
    put<int32_t>(mLast + 8, z);
    mLastHeight[l] = z;
    std::memcpy(item, mLast, 20);
  }
  void encode(Encoder& enc, const uint8_t* item) override {
    const uint32_t r = item[14] & 7, n = (item[14] >> 3) & 7;
    const uint32_t m = kReturnMap[n][r], l = returnLevel(n, r);
    const uint16_t intensity = get<uint16_t>(item + 12);
    const uint32_t changed = (uint32_t(mLast[14] != item[14]) << 5) |
                             (uint32_t(mLastIntensity[m] != intensity) << 4) |
                             (uint32_t(mLast[15] != item[15]) << 3) |
                             (uint32_t(mLast[16] != item[16]) << 2) |
                             (uint32_t(mLast[17] != item[17]) << 1) |
                             uint32_t(get<uint16_t>(mLast + 18) != get<uint16_t>(item + 18));
    enc.encodeSymbol(mChanged, changed);
    if (changed & 32) enc.encodeSymbol(lazy(mBitByte[mLast[14]], 256), item[14]);
    if (changed & 16) {
      mIntensity.encode(enc, mLastIntensity[m], intensity, m < 3 ? m : 3);
      mLastIntensity[m] = intensity;
    }
    if (changed & 8) enc.encodeSymbol(lazy(mClassification[mLast[15]], 256), item[15]);
    if (changed & 4) {
      enc.encodeSymbol(mScanAngle[(item[14] >> 6) & 1],
                       foldByte(int32_t(item[16]) - int32_t(mLast[16])));
    }
    if (changed & 2) enc.encodeSymbol(lazy(mUserData[mLast[17]], 256), item[17]);
    if (changed & 1) mSource.encode(enc, get<uint16_t>(mLast + 18), get<uint16_t>(item + 18));
    int32_t diff = int32_t(uint32_t(get<int32_t>(item)) - uint32_t(get<int32_t>(mLast)));
    mDx.encode(enc, mMedianX[m].get(), diff, n == 1);
    mMedianX[m].add(diff);
    diff = int32_t(uint32_t(get<int32_t>(item + 4)) - uint32_t(get<int32_t>(mLast + 4)));
    mDy.encode(enc, mMedianY[m].get(), diff, (n == 1) + kContext(mDx.k(), 20));
    mMedianY[m].add(diff);
    const uint32_t kb = (mDx.k() + mDy.k()) / 2;
    const int32_t z = get<int32_t>(item + 8);
    mZ.encode(enc, mLastHeight[l], z, (n == 1) + kContext(kb, 18));
    mLastHeight[l] = z;
    std::memcpy(mLast, item, 20);
  }

 private:
  void returns(uint32_t& r, uint32_t& n, uint32_t& m, uint32_t& l) const {
    r = mLast[14] & 7;
    n = (mLast[14] >> 3) & 7;
    m = kReturnMap[n][r];
    l = returnLevel(n, r);
  }

  uint8_t mLast[20] = {};
  uint16_t mLastIntensity[16] = {};
  int32_t mLastHeight[8] = {};
  Median5 mMedianX[16], mMedianY[16];
  SymbolModel mChanged{64};
  SymbolModel mScanAngle[2] = {SymbolModel(256), SymbolModel(256)};
  std::unique_ptr<SymbolModel> mBitByte[256], mClassification[256], mUserData[256];
  IntegerCoder mIntensity{16, 4}, mSource{16}, mDx{32, 2}, mDy{32, 22}, mZ{32, 20};
};

class Point10V1 final : public ItemCoder {
 public:
  void init(const uint8_t* item) override { std::memcpy(mLast, item, 20); }
  void decode(Decoder& dec, uint8_t* item) override {
    const int32_t mx = median3(mLastX), my = median3(mLastY);
    const int32_t dx = mDx.decode(dec, mx);
    put<int32_t>(mLast, int32_t(uint32_t(get<int32_t>(mLast)) + uint32_t(dx)));
    uint32_t kb = mDx.k();
    const int32_t dy = mDy.decode(dec, my, kb < 19 ? kb : 19);
    put<int32_t>(mLast + 4, int32_t(uint32_t(get<int32_t>(mLast + 4)) + uint32_t(dy)));
    kb = (kb + mDy.k()) / 2;
    put<int32_t>(mLast + 8, mZ.decode(dec, get<int32_t>(mLast + 8), kb < 19 ? kb : 19));
    const uint32_t changed = dec.decodeSymbol(mChanged);
    if (changed & 32) {
      put<uint16_t>(mLast + 12, uint16_t(mIntensity.decode(dec, get<uint16_t>(mLast + 12))));
    }
    if (changed & 16) mLast[14] = uint8_t(dec.decodeSymbol(lazy(mBitByte[mLast[14]], 256)));
    if (changed & 8) {
      mLast[15] = uint8_t(dec.decodeSymbol(lazy(mClassification[mLast[15]], 256)));
    }
    if (changed & 4) mLast[16] = uint8_t(mScanAngle.decode(dec, mLast[16], kb < 3));
    if (changed & 2) mLast[17] = uint8_t(dec.decodeSymbol(lazy(mUserData[mLast[17]], 256)));
    if (changed & 1) {
      put<uint16_t>(mLast + 18, uint16_t(mSource.decode(dec, get<uint16_t>(mLast + 18))));
    }
    mLastX[mIncr] = dx;
    mLastY[mIncr] = dy;
    mIncr = (mIncr + 1) % 3;
    std::memcpy(item, mLast, 20);
  }

 private:
  static int32_t median3(const int32_t* v) {
    if (v[0] < v[1]) return v[1] < v[2] ? v[1] : v[0] < v[2] ? v[2] : v[0];
    return v[0] < v[2] ? v[0] : v[1] < v[2] ? v[2] : v[1];
  }

  uint8_t mLast[20] = {};
  int32_t mLastX[3] = {}, mLastY[3] = {};
  int mIncr = 0;
  SymbolModel mChanged{64};
  std::unique_ptr<SymbolModel> mBitByte[256], mClassification[256], mUserData[256];
  IntegerCoder mDx{32}, mDy{32, 20}, mZ{32, 20}, mIntensity{16}, mScanAngle{8, 2}, mSource{16};
};

// ---- GPS time: four interleaved sequences, each predicting its next difference as a multiple
// of its last one. Version 2 (pointwise) and version 3 (layered) differ only in their codes.

class GpsTimeCoder {
 public:
  explicit GpsTimeCoder(bool layered)
      : mLayered(layered), mMulti(layered ? 515 : 516), mZeroDiff(layered ? 5 : 6) {}
  void init(uint64_t first) {
    mTime[0] = first;
    mTime[1] = mTime[2] = mTime[3] = 0;
  }
  uint64_t current() const { return mTime[mLast]; }

  void decode(Decoder& dec) {
    const uint32_t zero_base = mLayered ? 0 : 1;  // v2 spends code 0 on "unchanged"
    const uint32_t full = mLayered ? 511 : 512;
    for (int hops = 0;; ++hops) {
      if (hops > 4) throw CorruptData("GPS time switches sequences endlessly");
      if (mDiff[mLast] == 0) {
        const uint32_t multi = dec.decodeSymbol(mZeroDiff);
        if (!mLayered && multi == 0) return;
        if (multi == zero_base) {
          mDiff[mLast] = mCoder.decode(dec, 0, 0);
          mTime[mLast] += uint64_t(int64_t(mDiff[mLast]));
          mExtreme[mLast] = 0;
        } else if (multi == zero_base + 1) {
          readFull(dec);
        } else {
          mLast = (mLast + multi - zero_base - 1) & 3;
          continue;
        }
        return;
      }
      const uint32_t multi = dec.decodeSymbol(mMulti);
      if (multi == 1) {
        mTime[mLast] += uint64_t(int64_t(mCoder.decode(dec, mDiff[mLast], 1)));
        mExtreme[mLast] = 0;
      } else if (multi < 511) {
        int32_t d;
        if (multi == 0) {
          d = mCoder.decode(dec, 0, 7);
          extreme(d);
        } else if (multi < 500) {
          d = mCoder.decode(dec, times(int32_t(multi), mDiff[mLast]), multi < 10 ? 2 : 3);
        } else if (multi == 500) {
          d = mCoder.decode(dec, times(500, mDiff[mLast]), 4);
          extreme(d);
        } else {
          const int32_t neg = 500 - int32_t(multi);
          if (neg > -10) {
            d = mCoder.decode(dec, times(neg, mDiff[mLast]), 5);
          } else {
            d = mCoder.decode(dec, times(-10, mDiff[mLast]), 6);
            extreme(d);
          }
        }
        mTime[mLast] += uint64_t(int64_t(d));
      } else if (multi == full) {
        readFull(dec);
      } else if (multi > full) {
        mLast = (mLast + multi - full) & 3;
        continue;
      }
      return;  // v2's code 511: unchanged
    }
  }

  void encode(Encoder& enc, uint64_t t) {
    const uint32_t zero_base = mLayered ? 0 : 1;
    const uint32_t full = mLayered ? 511 : 512;
    for (;;) {
      if (mDiff[mLast] == 0) {
        if (!mLayered && t == mTime[mLast]) {  // v2 only: layered points flag a same time
          enc.encodeSymbol(mZeroDiff, 0);
          return;
        }
        const int64_t d64 = int64_t(t - mTime[mLast]);
        if (d64 == int64_t(int32_t(d64))) {
          enc.encodeSymbol(mZeroDiff, zero_base);
          mCoder.encode(enc, 0, int32_t(d64), 0);
          mDiff[mLast] = int32_t(d64);
          mExtreme[mLast] = 0;
        } else {
          if (const int other = otherSequence(t)) {
            enc.encodeSymbol(mZeroDiff, zero_base + 1 + uint32_t(other));
            mLast = (mLast + uint32_t(other)) & 3;
            continue;
          }
          enc.encodeSymbol(mZeroDiff, zero_base + 1);
          writeFull(enc, t);
        }
        mTime[mLast] = t;
        return;
      }
      if (!mLayered && t == mTime[mLast]) {
        enc.encodeSymbol(mMulti, 511);  // v2 only, as above
        return;
      }
      const int64_t d64 = int64_t(t - mTime[mLast]);
      if (d64 != int64_t(int32_t(d64))) {
        if (const int other = otherSequence(t)) {
          enc.encodeSymbol(mMulti, full + uint32_t(other));
          mLast = (mLast + uint32_t(other)) & 3;
          continue;
        }
        enc.encodeSymbol(mMulti, full);
        writeFull(enc, t);
        mTime[mLast] = t;
        return;
      }
      const int32_t d = int32_t(d64);
      const float ratio = float(d) / float(mDiff[mLast]);
      const int32_t multi = std::abs(ratio) > 1e6f ? (ratio > 0 ? 1000000 : -1000000)
                            : ratio >= 0         ? int32_t(ratio + 0.5f)
                                                 : int32_t(ratio - 0.5f);
      if (multi == 1) {
        enc.encodeSymbol(mMulti, 1);
        mCoder.encode(enc, mDiff[mLast], d, 1);
        mExtreme[mLast] = 0;
      } else if (multi > 0 && multi < 500) {
        enc.encodeSymbol(mMulti, uint32_t(multi));
        mCoder.encode(enc, times(multi, mDiff[mLast]), d, multi < 10 ? 2 : 3);
      } else if (multi >= 500) {
        enc.encodeSymbol(mMulti, 500);
        mCoder.encode(enc, times(500, mDiff[mLast]), d, 4);
        extreme(d);
      } else if (multi < 0 && multi > -10) {
        enc.encodeSymbol(mMulti, uint32_t(500 - multi));
        mCoder.encode(enc, times(multi, mDiff[mLast]), d, 5);
      } else if (multi < 0) {
        enc.encodeSymbol(mMulti, 510);
        mCoder.encode(enc, times(-10, mDiff[mLast]), d, 6);
        extreme(d);
      } else {
        enc.encodeSymbol(mMulti, 0);
        mCoder.encode(enc, 0, d, 7);
        extreme(d);
      }
      mTime[mLast] = t;
      return;
    }
  }

 private:
  void extreme(int32_t d) {
    if (++mExtreme[mLast] > 3) {
      mDiff[mLast] = d;
      mExtreme[mLast] = 0;
    }
  }
  void readFull(Decoder& dec) {
    mNext = (mNext + 1) & 3;
    const uint32_t high = uint32_t(mCoder.decode(dec, int32_t(uint32_t(mTime[mLast] >> 32)), 8));
    mTime[mNext] = (uint64_t(high) << 32) | dec.readInt();
    mLast = mNext;
    mDiff[mLast] = 0;
    mExtreme[mLast] = 0;
  }
  void writeFull(Encoder& enc, uint64_t t) {
    mCoder.encode(enc, int32_t(uint32_t(mTime[mLast] >> 32)), int32_t(uint32_t(t >> 32)), 8);
    enc.writeInt(uint32_t(t));
    mNext = (mNext + 1) & 3;
    mLast = mNext;
    mDiff[mLast] = 0;
    mExtreme[mLast] = 0;
  }
  int otherSequence(uint64_t t) const {
    for (int i = 1; i < 4; ++i) {
      const int64_t d = int64_t(t - mTime[(mLast + uint32_t(i)) & 3]);
      if (d == int64_t(int32_t(d))) return i;
    }
    return 0;
  }

  bool mLayered;
  uint32_t mLast = 0, mNext = 0;
  uint64_t mTime[4] = {};
  int32_t mDiff[4] = {};
  int32_t mExtreme[4] = {};
  SymbolModel mMulti, mZeroDiff;
  IntegerCoder mCoder{32, 9};
};

class GpsTime11V2 final : public ItemCoder {
 public:
  void init(const uint8_t* item) override { mCoder.init(get<uint64_t>(item)); }
  void decode(Decoder& dec, uint8_t* item) override {
    mCoder.decode(dec);
    put<uint64_t>(item, mCoder.current());
  }
  void encode(Encoder& enc, const uint8_t* item) override { mCoder.encode(enc, get<uint64_t>(item)); }

 private:
  GpsTimeCoder mCoder{false};
};

class GpsTime11V1 final : public ItemCoder {
 public:
  void init(const uint8_t* item) override {
    mTime = get<uint64_t>(item);
    mDiff = 0;
    mExtreme = 0;
  }
  void decode(Decoder& dec, uint8_t* item) override {
    if (mDiff == 0) {
      const uint32_t multi = dec.decodeSymbol(mZeroDiff);
      if (multi == 1) {
        mDiff = mCoder.decode(dec, 0, 0);
        mTime += uint64_t(int64_t(mDiff));
      } else if (multi == 2) {
        mTime = dec.readInt64();
      }
    } else {
      const uint32_t multi = dec.decodeSymbol(mMulti);
      if (multi < 510) {
        int32_t d;
        if (multi == 1) {
          d = mCoder.decode(dec, mDiff, 1);
          mDiff = d;
          mExtreme = 0;
        } else if (multi == 0) {
          d = mCoder.decode(dec, mDiff / 4, 2);
          if (++mExtreme > 3) {
            mDiff = d;
            mExtreme = 0;
          }
        } else if (multi < 10) {
          d = mCoder.decode(dec, times(int32_t(multi), mDiff), 3);
        } else if (multi < 50) {
          d = mCoder.decode(dec, times(int32_t(multi), mDiff), 4);
        } else {
          d = mCoder.decode(dec, times(int32_t(multi), mDiff), 5);
          if (multi == 509 && ++mExtreme > 3) {
            mDiff = d;
            mExtreme = 0;
          }
        }
        mTime += uint64_t(int64_t(d));
      } else if (multi < 511) {
        mTime = dec.readInt64();
      }
    }
    put<uint64_t>(item, mTime);
  }

 private:
  uint64_t mTime = 0;
  int32_t mDiff = 0, mExtreme = 0;
  SymbolModel mMulti{512}, mZeroDiff{3};
  IntegerCoder mCoder{32, 6};
};

// ---- RGB: the low and high bytes of each channel, green and blue predicted from red's change.

struct RgbModels {
  SymbolModel used{128};
  SymbolModel diff[6] = {SymbolModel(256), SymbolModel(256), SymbolModel(256),
                         SymbolModel(256), SymbolModel(256), SymbolModel(256)};
};

void decodeRgb(Decoder& dec, RgbModels& m, const uint16_t* last, uint16_t* out) {
  const uint32_t sym = dec.decodeSymbol(m.used);
  auto byte = [&](int bit, int model, int32_t pred) -> int32_t {
    return (sym & (1u << bit)) ? foldByte(int32_t(dec.decodeSymbol(m.diff[model])) + pred) : pred;
  };
  const int32_t lo0 = byte(0, 0, last[0] & 0xFF);  // decoded in this order
  const int32_t hi0 = byte(1, 1, last[0] >> 8);
  out[0] = uint16_t(lo0 | (hi0 << 8));
  if (sym & (1u << 6)) {
    int32_t diff = (out[0] & 0xFF) - (last[0] & 0xFF);
    int32_t lo1 = (sym & 4) ? foldByte(int32_t(dec.decodeSymbol(m.diff[2])) +
                                       clampByte(diff + (last[1] & 0xFF)))
                            : (last[1] & 0xFF);
    diff = (diff + (lo1 - (last[1] & 0xFF))) / 2;
    int32_t lo2 = (sym & 16) ? foldByte(int32_t(dec.decodeSymbol(m.diff[4])) +
                                        clampByte(diff + (last[2] & 0xFF)))
                             : (last[2] & 0xFF);
    diff = (out[0] >> 8) - (last[0] >> 8);
    int32_t hi1 = (sym & 8) ? foldByte(int32_t(dec.decodeSymbol(m.diff[3])) +
                                       clampByte(diff + (last[1] >> 8)))
                            : (last[1] >> 8);
    diff = (diff + (hi1 - (last[1] >> 8))) / 2;
    int32_t hi2 = (sym & 32) ? foldByte(int32_t(dec.decodeSymbol(m.diff[5])) +
                                        clampByte(diff + (last[2] >> 8)))
                             : (last[2] >> 8);
    out[1] = uint16_t(lo1 | (hi1 << 8));
    out[2] = uint16_t(lo2 | (hi2 << 8));
  } else {
    out[1] = out[2] = out[0];
  }
}

void encodeRgb(Encoder& enc, RgbModels& m, const uint16_t* last, const uint16_t* c) {
  uint32_t sym = uint32_t((last[0] & 0xFF) != (c[0] & 0xFF)) |
                 (uint32_t((last[0] & 0xFF00) != (c[0] & 0xFF00)) << 1) |
                 (uint32_t((last[1] & 0xFF) != (c[1] & 0xFF)) << 2) |
                 (uint32_t((last[1] & 0xFF00) != (c[1] & 0xFF00)) << 3) |
                 (uint32_t((last[2] & 0xFF) != (c[2] & 0xFF)) << 4) |
                 (uint32_t((last[2] & 0xFF00) != (c[2] & 0xFF00)) << 5);
  if (c[0] != c[1] || c[0] != c[2]) sym |= 1u << 6;
  enc.encodeSymbol(m.used, sym);
  int32_t diff_l = 0, diff_h = 0;
  if (sym & 1) {
    diff_l = int32_t(c[0] & 0xFF) - (last[0] & 0xFF);
    enc.encodeSymbol(m.diff[0], foldByte(diff_l));
  }
  if (sym & 2) {
    diff_h = int32_t(c[0] >> 8) - (last[0] >> 8);
    enc.encodeSymbol(m.diff[1], foldByte(diff_h));
  }
  if (!(sym & (1u << 6))) return;
  if (sym & 4) {
    const int32_t corr = int32_t(c[1] & 0xFF) - clampByte(diff_l + (last[1] & 0xFF));
    enc.encodeSymbol(m.diff[2], foldByte(corr));
  }
  if (sym & 16) {
    diff_l = (diff_l + int32_t(c[1] & 0xFF) - (last[1] & 0xFF)) / 2;
    const int32_t corr = int32_t(c[2] & 0xFF) - clampByte(diff_l + (last[2] & 0xFF));
    enc.encodeSymbol(m.diff[4], foldByte(corr));
  }
  if (sym & 8) {
    const int32_t corr = int32_t(c[1] >> 8) - clampByte(diff_h + (last[1] >> 8));
    enc.encodeSymbol(m.diff[3], foldByte(corr));
  }
  if (sym & 32) {
    diff_h = (diff_h + int32_t(c[1] >> 8) - (last[1] >> 8)) / 2;
    const int32_t corr = int32_t(c[2] >> 8) - clampByte(diff_h + (last[2] >> 8));
    enc.encodeSymbol(m.diff[5], foldByte(corr));
  }
}

void loadRgb(const uint8_t* p, uint16_t* rgb, int n = 3) {
  for (int i = 0; i < n; ++i) rgb[i] = get<uint16_t>(p + 2 * i);
}
void storeRgb(uint8_t* p, const uint16_t* rgb, int n = 3) {
  for (int i = 0; i < n; ++i) put<uint16_t>(p + 2 * i, rgb[i]);
}

class Rgb12V2 final : public ItemCoder {
 public:
  void init(const uint8_t* item) override { loadRgb(item, mLast); }
  void decode(Decoder& dec, uint8_t* item) override {
    uint16_t c[3];
    decodeRgb(dec, mModels, mLast, c);
    std::copy(c, c + 3, mLast);
    storeRgb(item, c);
  }
  void encode(Encoder& enc, const uint8_t* item) override {
    uint16_t c[3];
    loadRgb(item, c);
    encodeRgb(enc, mModels, mLast, c);
    std::copy(c, c + 3, mLast);
  }

 private:
  uint16_t mLast[3] = {};
  RgbModels mModels;
};

class Rgb12V1 final : public ItemCoder {
 public:
  void init(const uint8_t* item) override { loadRgb(item, mLast); }
  void decode(Decoder& dec, uint8_t* item) override {
    const uint32_t sym = dec.decodeSymbol(mUsed);
    uint16_t c[3];
    for (int ch = 0; ch < 3; ++ch) {
      const uint32_t lo_bit = 1u << (2 * ch), hi_bit = 1u << (2 * ch + 1);
      uint32_t lo = mLast[ch] & 0xFF, hi = mLast[ch] >> 8;
      if (sym & lo_bit) lo = uint32_t(mCoder.decode(dec, int32_t(lo), uint32_t(2 * ch))) & 0xFF;
      if (sym & hi_bit) hi = uint32_t(mCoder.decode(dec, int32_t(hi), uint32_t(2 * ch + 1))) & 0xFF;
      c[ch] = uint16_t(lo | (hi << 8));
    }
    std::copy(c, c + 3, mLast);
    storeRgb(item, c);
  }

 private:
  uint16_t mLast[3] = {};
  SymbolModel mUsed{64};
  IntegerCoder mCoder{8, 6};
};

// ---- extra bytes

class ByteV2 final : public ItemCoder {
 public:
  explicit ByteV2(uint16_t n) : mLast(n) {
    for (uint16_t i = 0; i < n; ++i) mModels.emplace_back(256);
  }
  void init(const uint8_t* item) override { std::memcpy(mLast.data(), item, mLast.size()); }
  void decode(Decoder& dec, uint8_t* item) override {
    for (size_t i = 0; i < mLast.size(); ++i) {
      mLast[i] = foldByte(int32_t(mLast[i]) + int32_t(dec.decodeSymbol(mModels[i])));
    }
    std::memcpy(item, mLast.data(), mLast.size());
  }
  void encode(Encoder& enc, const uint8_t* item) override {
    for (size_t i = 0; i < mLast.size(); ++i) {
      enc.encodeSymbol(mModels[i], foldByte(int32_t(item[i]) - int32_t(mLast[i])));
      mLast[i] = item[i];
    }
  }

 private:
  std::vector<uint8_t> mLast;
  std::vector<SymbolModel> mModels;
};

class ByteV1 final : public ItemCoder {
 public:
  explicit ByteV1(uint16_t n) : mLast(n), mCoder(8, n) {}
  void init(const uint8_t* item) override { std::memcpy(mLast.data(), item, mLast.size()); }
  void decode(Decoder& dec, uint8_t* item) override {
    for (size_t i = 0; i < mLast.size(); ++i) {
      mLast[i] = uint8_t(mCoder.decode(dec, mLast[i], uint32_t(i)));
    }
    std::memcpy(item, mLast.data(), mLast.size());
  }

 private:
  std::vector<uint8_t> mLast;
  IntegerCoder mCoder;
};

std::unique_ptr<ItemCoder> makePointwise(const Item& item) {
  const bool v1 = item.version == 1;
  switch (item.type) {
    case kPoint10:
      if (v1) return std::make_unique<Point10V1>();
      return std::make_unique<Point10V2>();
    case kGpsTime11:
      if (v1) return std::make_unique<GpsTime11V1>();
      return std::make_unique<GpsTime11V2>();
    case kRgb12:
      if (v1) return std::make_unique<Rgb12V1>();
      return std::make_unique<Rgb12V2>();
    default:
      if (v1) return std::make_unique<ByteV1>(item.size);
      return std::make_unique<ByteV2>(item.size);
  }
}

/// One coder per pointwise item, each started from the chunk's first record, and each item's
/// offset in a record.
struct PointwiseCoders {
  std::vector<std::unique_ptr<ItemCoder>> coders;
  std::vector<uint32_t> offsets;
};

PointwiseCoders pointwiseCoders(const std::vector<Item>& items, const uint8_t* first) {
  PointwiseCoders pc;
  uint32_t at = 0;
  for (const Item& it : items) {
    pc.coders.push_back(makePointwise(it));
    pc.coders.back()->init(first + at);
    pc.offsets.push_back(at);
    at += it.size;
  }
  return pc;
}

// ---- layered LAS 1.4 items ------------------------------------------------------------------

/// The byte streams of one layered item in a chunk; an empty stream: the field never changes.
struct Layers {
  std::vector<std::span<const uint8_t>> bytes;
  std::vector<std::unique_ptr<Decoder>> decoders;
  void open() {
    decoders.clear();
    for (auto b : bytes) decoders.push_back(b.empty() ? nullptr : std::make_unique<Decoder>(b));
  }
  Decoder* operator[](size_t i) { return decoders[i].get(); }
  /// Every stream must end where its byte count says.
  void checkConsumed(const char* item) const {
    for (size_t i = 0; i < bytes.size(); ++i) {
      if (decoders[i] && decoders[i]->consumed() != bytes[i].size()) {
        throw CorruptData(std::string(item) + " layer " + std::to_string(i) + " holds " +
                          std::to_string(bytes[i].size()) + " bytes but decodes from " +
                          std::to_string(decoders[i]->consumed()));
      }
    }
  }
};

/// The fields of a LAS 1.4 point record (formats 6-10, bytes 0-29).
struct Point14 {
  int32_t x = 0, y = 0, z = 0;
  uint16_t intensity = 0;
  uint8_t return_number = 0, number_of_returns = 0;  // 4 bits each
  uint8_t class_flags = 0, channel = 0, scan_direction = 0, edge = 0;
  uint8_t classification = 0, user_data = 0;
  int16_t scan_angle = 0;
  uint16_t source = 0;
  uint64_t gps_time = 0;  // the double's bits
  bool gps_time_change = false;

  static Point14 load(const uint8_t* p) {
    Point14 q;
    q.x = get<int32_t>(p);
    q.y = get<int32_t>(p + 4);
    q.z = get<int32_t>(p + 8);
    q.intensity = get<uint16_t>(p + 12);
    q.return_number = p[14] & 15;
    q.number_of_returns = p[14] >> 4;
    q.class_flags = p[15] & 15;
    q.channel = (p[15] >> 4) & 3;
    q.scan_direction = (p[15] >> 6) & 1;
    q.edge = p[15] >> 7;
    q.classification = p[16];
    q.user_data = p[17];
    q.scan_angle = get<int16_t>(p + 18);
    q.source = get<uint16_t>(p + 20);
    q.gps_time = get<uint64_t>(p + 22);
    return q;
  }
  void store(uint8_t* p) const {
    put<int32_t>(p, x);
    put<int32_t>(p + 4, y);
    put<int32_t>(p + 8, z);
    put<uint16_t>(p + 12, intensity);
    p[14] = uint8_t(return_number | (number_of_returns << 4));
    p[15] = uint8_t(class_flags | (channel << 4) | (scan_direction << 6) | (edge << 7));
    p[16] = classification;
    p[17] = user_data;
    put<int16_t>(p + 18, scan_angle);
    put<uint16_t>(p + 20, source);
    put<uint64_t>(p + 22, gps_time);
  }
};

class LayeredItem {
 public:
  virtual ~LayeredItem() = default;
  virtual size_t layerCount() const = 0;
  /// The chunk's first record and the item's layers; `context` is the scanner channel.
  virtual void init(const uint8_t* item, Layers& layers, uint32_t& context) = 0;
  virtual void decode(uint8_t* item, uint32_t& context) = 0;
};

enum Point14Layer { kXY, kZ, kClass, kFlags, kIntensity, kAngle, kUser, kSource, kTime };

class Point14V3 final : public LayeredItem {
 public:
  explicit Point14V3(bool v4) : mV4(v4) {}
  size_t layerCount() const override { return 9; }
  void init(const uint8_t* item, Layers& layers, uint32_t& context) override {
    mLayers = &layers;
    for (auto& c : mContexts) c.reset();
    const Point14 first = Point14::load(item);
    mCurrent = first.channel;
    context = mCurrent;
    start(mCurrent, first);
  }
  void decode(uint8_t* item, uint32_t& context) override;

  struct Context {
    Point14 last;
    uint16_t last_intensity[8] = {};
    Median5 median_x[12], median_y[12];
    int32_t last_z[8] = {};
    SymbolModel changed[8] = {SymbolModel(128), SymbolModel(128), SymbolModel(128),
                              SymbolModel(128), SymbolModel(128), SymbolModel(128),
                              SymbolModel(128), SymbolModel(128)};
    SymbolModel channel{3}, return_gps_same{13};
    std::unique_ptr<SymbolModel> number_of_returns[16], return_number[16];
    IntegerCoder dx{32, 2}, dy{32, 22}, z{32, 20};
    std::unique_ptr<SymbolModel> classification[64], flags[64], user_data[64];
    IntegerCoder intensity{16, 4}, scan_angle{16, 2}, source{16};
    GpsTimeCoder time{true};
  };
  /// A channel's state, started from the point before it (or the chunk's first point).
  static std::unique_ptr<Context> startContext(const Point14& from) {
    auto ctx = std::make_unique<Context>();
    ctx->last = from;
    ctx->last.gps_time_change = false;
    std::fill(std::begin(ctx->last_z), std::end(ctx->last_z), from.z);
    std::fill(std::begin(ctx->last_intensity), std::end(ctx->last_intensity), from.intensity);
    ctx->time.init(from.gps_time);
    return ctx;
  }

 private:
  void start(uint32_t c, const Point14& from) { mContexts[c] = startContext(from); }

  bool mV4;
  Layers* mLayers = nullptr;
  uint32_t mCurrent = 0;
  std::unique_ptr<Context> mContexts[4];
};

void Point14V3::decode(uint8_t* item, uint32_t& context) {
  Layers& L = *mLayers;
  Decoder& xy = *L[kXY];
  Context* ctx = mContexts[mCurrent].get();
  Point14* last = &ctx->last;
  uint32_t lpr = (last->return_number == 1 ? 1 : 0) +
                 (last->return_number >= last->number_of_returns ? 2 : 0) +
                 (last->gps_time_change ? 4 : 0);
  const uint32_t changed = xy.decodeSymbol(ctx->changed[lpr]);
  if (changed & (1u << 6)) {  // another scanner channel
    const uint32_t diff = xy.decodeSymbol(ctx->channel);
    const uint32_t channel = (mCurrent + diff + 1) % 4;
    if (!mContexts[channel]) start(channel, *last);
    mCurrent = channel;
    ctx = mContexts[mCurrent].get();
    last = &ctx->last;
    last->channel = uint8_t(channel);
  }
  // LASzip 1.4 v3 passes the channel on to the other items only when it changes; v4 always.
  if (mV4 || (changed & (1u << 6))) context = mCurrent;
  const bool source_change = changed & (1u << 5);
  const bool gps_change = changed & (1u << 4);
  const bool angle_change = changed & (1u << 3);
  uint32_t n = last->number_of_returns, r = last->return_number;
  if (changed & (1u << 2)) {
    n = xy.decodeSymbol(lazy(ctx->number_of_returns[n], 16));
    last->number_of_returns = uint8_t(n);
  }
  switch (changed & 3) {
    case 0:
      break;
    case 1:
      r = (r + 1) % 16;
      break;
    case 2:
      r = (r + 15) % 16;
      break;
    default:
      if (gps_change) {
        r = xy.decodeSymbol(lazy(ctx->return_number[r], 16));
      } else {
        r = (r + xy.decodeSymbol(ctx->return_gps_same) + 2) % 16;
      }
  }
  last->return_number = uint8_t(r);
  const uint32_t m = kReturnMap6[n][r], l = returnLevel8(n, r);
  const uint32_t cpr = (r == 1 ? 2 : 0) + (r >= n ? 1 : 0);
  const uint32_t mi = (m << 1) | uint32_t(gps_change);
  int32_t diff = ctx->dx.decode(xy, ctx->median_x[mi].get(), n == 1);
  last->x = int32_t(uint32_t(last->x) + uint32_t(diff));
  ctx->median_x[mi].add(diff);
  diff = ctx->dy.decode(xy, ctx->median_y[mi].get(), (n == 1) + kContext(ctx->dx.k(), 20));
  last->y = int32_t(uint32_t(last->y) + uint32_t(diff));
  ctx->median_y[mi].add(diff);
  if (Decoder* d = L[kZ]) {
    const uint32_t kb = (ctx->dx.k() + ctx->dy.k()) / 2;
    last->z = ctx->z.decode(*d, ctx->last_z[l], (n == 1) + kContext(kb, 18));
    ctx->last_z[l] = last->z;
  }
  if (Decoder* d = L[kClass]) {
    const uint32_t ccc = ((last->classification & 0x1Fu) << 1) + (cpr == 3 ? 1 : 0);
    last->classification = uint8_t(d->decodeSymbol(lazy(ctx->classification[ccc], 256)));
  }
  if (Decoder* d = L[kFlags]) {
    const uint32_t last_flags = (uint32_t(last->edge) << 5) |
                                (uint32_t(last->scan_direction) << 4) | last->class_flags;
    const uint32_t flags = d->decodeSymbol(lazy(ctx->flags[last_flags], 64));
    last->edge = (flags >> 5) & 1;
    last->scan_direction = (flags >> 4) & 1;
    last->class_flags = flags & 15;
  }
  if (Decoder* d = L[kIntensity]) {
    uint16_t& pred = ctx->last_intensity[(cpr << 1) | uint32_t(gps_change)];
    pred = uint16_t(ctx->intensity.decode(*d, pred, cpr));
    last->intensity = pred;
  }
  if (Decoder* d = L[kAngle]; d && angle_change) {
    last->scan_angle = int16_t(ctx->scan_angle.decode(*d, last->scan_angle, gps_change));
  }
  if (Decoder* d = L[kUser]) {
    last->user_data = uint8_t(d->decodeSymbol(lazy(ctx->user_data[last->user_data / 4], 256)));
  }
  if (Decoder* d = L[kSource]; d && source_change) {
    last->source = uint16_t(ctx->source.decode(*d, last->source));
  }
  if (Decoder* d = L[kTime]; d && gps_change) {
    ctx->time.decode(*d);
    last->gps_time = ctx->time.current();
  }
  last->store(item);
  last->gps_time_change = gps_change;
}

/// RGB14 and RGBNIR14: RGB (and near infrared) per scanner channel.
class Rgb14V3 final : public LayeredItem {
 public:
  Rgb14V3(bool nir, bool v4) : mNir(nir), mV4(v4) {}
  size_t layerCount() const override { return mNir ? 2 : 1; }
  void init(const uint8_t* item, Layers& layers, uint32_t& context) override {
    mLayers = &layers;
    for (auto& c : mContexts) c.reset();
    mCurrent = context;
    uint16_t first[4] = {};
    loadRgb(item, first, mNir ? 4 : 3);
    start(mCurrent, first);
  }
  void decode(uint8_t* item, uint32_t& context) override {
    Context* ctx = mContexts[mCurrent].get();
    uint16_t* last = ctx->last;
    if (mCurrent != context) {
      mCurrent = context;
      if (!mContexts[mCurrent]) {
        start(mCurrent, last);
        last = mContexts[mCurrent]->last;
      } else if (mV4) {
        last = mContexts[mCurrent]->last;  // v3 keeps the previous channel's values here
      }
      ctx = mContexts[mCurrent].get();
    }
    uint16_t c[4];
    if (Decoder* d = (*mLayers)[0]) {
      decodeRgb(*d, ctx->rgb, last, c);
      std::copy(c, c + 3, last);
    } else {
      std::copy(last, last + 3, c);
    }
    if (mNir) {
      if (Decoder* d = (*mLayers)[1]) {
        const uint32_t sym = d->decodeSymbol(ctx->nir_used);
        uint32_t lo = last[3] & 0xFF, hi = last[3] >> 8;
        if (sym & 1) lo = foldByte(int32_t(d->decodeSymbol(ctx->nir[0]) + lo));
        if (sym & 2) hi = foldByte(int32_t(d->decodeSymbol(ctx->nir[1]) + hi));
        c[3] = uint16_t(lo | (hi << 8));
        // v3 stores the value in the pointer it read from; v4 in the current channel's.
        (mV4 ? ctx->last : last)[3] = c[3];
      } else {
        c[3] = (mV4 ? ctx->last : last)[3];
      }
    }
    storeRgb(item, c, mNir ? 4 : 3);
  }

  struct Context {
    uint16_t last[4] = {};
    RgbModels rgb;
    SymbolModel nir_used{4};
    SymbolModel nir[2] = {SymbolModel(256), SymbolModel(256)};
  };
  static std::unique_ptr<Context> startContext(const uint16_t* from) {
    auto ctx = std::make_unique<Context>();
    std::copy(from, from + 4, ctx->last);
    return ctx;
  }

 private:
  void start(uint32_t c, const uint16_t* from) { mContexts[c] = startContext(from); }

  bool mNir, mV4;
  Layers* mLayers = nullptr;
  uint32_t mCurrent = 0;
  std::unique_ptr<Context> mContexts[4];
};

class Byte14V3 final : public LayeredItem {
 public:
  Byte14V3(uint16_t n, bool v4) : mN(n), mV4(v4) {}
  size_t layerCount() const override { return mN; }
  void init(const uint8_t* item, Layers& layers, uint32_t& context) override {
    mLayers = &layers;
    for (auto& c : mContexts) c.reset();
    mCurrent = context;
    start(mCurrent, item);
  }
  void decode(uint8_t* item, uint32_t& context) override {
    Context* ctx = mContexts[mCurrent].get();
    uint8_t* last = ctx->last.data();
    if (mCurrent != context) {
      mCurrent = context;
      if (!mContexts[mCurrent]) {
        start(mCurrent, last);
        last = mContexts[mCurrent]->last.data();
      } else if (mV4) {
        last = mContexts[mCurrent]->last.data();
      }
      ctx = mContexts[mCurrent].get();
    }
    for (uint16_t i = 0; i < mN; ++i) {
      if (Decoder* d = (*mLayers)[i]) {
        last[i] = foldByte(int32_t(last[i]) + int32_t(d->decodeSymbol(ctx->models[i])));
      }
      item[i] = last[i];
    }
  }

  struct Context {
    std::vector<uint8_t> last;
    std::vector<SymbolModel> models;
  };
  static std::unique_ptr<Context> startContext(const uint8_t* from, uint16_t n) {
    auto ctx = std::make_unique<Context>();
    ctx->last.assign(from, from + n);
    for (uint16_t i = 0; i < n; ++i) ctx->models.emplace_back(256);
    return ctx;
  }

 private:
  void start(uint32_t c, const uint8_t* from) { mContexts[c] = startContext(from, mN); }

  uint16_t mN;
  bool mV4;
  Layers* mLayers = nullptr;
  uint32_t mCurrent = 0;
  std::unique_ptr<Context> mContexts[4];
};

std::unique_ptr<LayeredItem> makeLayered(const Item& item) {
  const bool v4 = item.version == 4;
  switch (item.type) {
    case kPoint14:
      return std::make_unique<Point14V3>(v4);
    case kRgb14:
      return std::make_unique<Rgb14V3>(false, v4);
    case kRgbNir14:
      return std::make_unique<Rgb14V3>(true, v4);
    default:
      return std::make_unique<Byte14V3>(item.size, v4);
  }
}

// ---- layered encoders: the mirror of the decoders above, state for state -------------------

/// One layer being written: its bytes, its encoder, and whether its value ever changed (a layer
/// whose field never changes in the chunk is left out, and its decoder never started).
struct OutLayer {
  std::vector<uint8_t> bytes;
  Encoder enc{bytes};
  bool changed = false;
};

class LayeredEncoderItem {
 public:
  virtual ~LayeredEncoderItem() = default;
  virtual size_t layerCount() const = 0;
  virtual void init(const uint8_t* item, uint32_t& context) = 0;
  virtual void encode(const uint8_t* item, uint32_t& context) = 0;
  /// The layers' bytes, finished; an empty vector for a layer left out.
  std::vector<std::vector<uint8_t>> finish(bool always_first_two) {
    std::vector<std::vector<uint8_t>> out;
    for (size_t i = 0; i < mOut.size(); ++i) {
      OutLayer& l = *mOut[i];
      if (l.changed || (always_first_two && i < 2)) {
        l.enc.finish();
        out.push_back(std::move(l.bytes));
      } else {
        out.emplace_back();
      }
    }
    return out;
  }

 protected:
  void openLayers(size_t n) {
    mOut.clear();
    for (size_t i = 0; i < n; ++i) mOut.push_back(std::make_unique<OutLayer>());
  }
  std::vector<std::unique_ptr<OutLayer>> mOut;
};

class Point14EncoderV3 final : public LayeredEncoderItem {
 public:
  size_t layerCount() const override { return 9; }
  void init(const uint8_t* item, uint32_t& context) override {
    openLayers(9);
    for (auto& c : mContexts) c.reset();
    const Point14 first = Point14::load(item);
    mCurrent = first.channel;
    context = mCurrent;
    start(mCurrent, first);
  }
  void encode(const uint8_t* item, uint32_t& context) override {
    const Point14 p = Point14::load(item);
    Encoder& xy = mOut[kXY]->enc;
    Context* ctx = mContexts[mCurrent].get();
    Point14* last = &ctx->last;
    const uint32_t lpr = (last->return_number == 1 ? 1 : 0) +
                         (last->return_number >= last->number_of_returns ? 2 : 0) +
                         (last->gps_time_change ? 4 : 0);
    const uint32_t channel = p.channel;
    if (channel != mCurrent && mContexts[channel]) last = &mContexts[channel]->last;
    const bool source_change = p.source != last->source;
    const bool gps_change = p.gps_time != last->gps_time;  // the bits: -0.0 is not 0.0 here
    const bool angle_change = p.scan_angle != last->scan_angle;
    const uint32_t last_n = last->number_of_returns, last_r = last->return_number;
    const uint32_t n = p.number_of_returns, r = p.return_number;
    uint32_t changed = (uint32_t(channel != mCurrent) << 6) | (uint32_t(source_change) << 5) |
                       (uint32_t(gps_change) << 4) | (uint32_t(angle_change) << 3) |
                       (uint32_t(n != last_n) << 2);
    if (r != last_r) changed |= r == (last_r + 1) % 16 ? 1 : r == (last_r + 15) % 16 ? 2 : 3;
    xy.encodeSymbol(ctx->changed[lpr], changed);
    if (changed & (1u << 6)) {
      const int32_t diff = int32_t(channel) - int32_t(mCurrent);
      xy.encodeSymbol(ctx->channel, uint32_t(diff > 0 ? diff - 1 : diff + 3));
      if (!mContexts[channel]) {
        start(channel, ctx->last);
        last = &mContexts[channel]->last;
      }
      mCurrent = channel;
      context = mCurrent;
      ctx = mContexts[mCurrent].get();
    }
    if (changed & (1u << 2)) xy.encodeSymbol(lazy(ctx->number_of_returns[last_n], 16), n);
    if ((changed & 3) == 3) {
      if (gps_change) {
        xy.encodeSymbol(lazy(ctx->return_number[last_r], 16), r);
      } else {
        const int32_t diff = int32_t(r) - int32_t(last_r);
        xy.encodeSymbol(ctx->return_gps_same, uint32_t(diff > 1 ? diff - 2 : diff + 14));
      }
    }
    const uint32_t m = kReturnMap6[n][r], l = returnLevel8(n, r);
    const uint32_t cpr = (r == 1 ? 2 : 0) + (r >= n ? 1 : 0);
    const uint32_t mi = (m << 1) | uint32_t(gps_change);
    int32_t diff = int32_t(uint32_t(p.x) - uint32_t(last->x));
    ctx->dx.encode(xy, ctx->median_x[mi].get(), diff, n == 1);
    ctx->median_x[mi].add(diff);
    diff = int32_t(uint32_t(p.y) - uint32_t(last->y));
    ctx->dy.encode(xy, ctx->median_y[mi].get(), diff, (n == 1) + kContext(ctx->dx.k(), 20));
    ctx->median_y[mi].add(diff);
    const uint32_t kb = (ctx->dx.k() + ctx->dy.k()) / 2;
    ctx->z.encode(mOut[kZ]->enc, ctx->last_z[l], p.z, (n == 1) + kContext(kb, 18));
    ctx->last_z[l] = p.z;
    mOut[kZ]->changed = true;
    OutLayer& cls = *mOut[kClass];
    cls.changed |= p.classification != last->classification;
    const uint32_t ccc = ((last->classification & 0x1Fu) << 1) + (cpr == 3 ? 1 : 0);
    cls.enc.encodeSymbol(lazy(ctx->classification[ccc], 256), p.classification);
    OutLayer& fl = *mOut[kFlags];
    const uint32_t last_flags = (uint32_t(last->edge) << 5) |
                                (uint32_t(last->scan_direction) << 4) | last->class_flags;
    const uint32_t flags =
        (uint32_t(p.edge) << 5) | (uint32_t(p.scan_direction) << 4) | p.class_flags;
    fl.changed |= flags != last_flags;
    fl.enc.encodeSymbol(lazy(ctx->flags[last_flags], 64), flags);
    OutLayer& in = *mOut[kIntensity];
    in.changed |= p.intensity != last->intensity;
    uint16_t& pred = ctx->last_intensity[(cpr << 1) | uint32_t(gps_change)];
    ctx->intensity.encode(in.enc, pred, p.intensity, cpr);
    pred = p.intensity;
    if (angle_change) {
      mOut[kAngle]->changed = true;
      ctx->scan_angle.encode(mOut[kAngle]->enc, last->scan_angle, p.scan_angle, gps_change);
    }
    OutLayer& ud = *mOut[kUser];
    ud.changed |= p.user_data != last->user_data;
    ud.enc.encodeSymbol(lazy(ctx->user_data[last->user_data / 4], 256), p.user_data);
    if (source_change) {
      mOut[kSource]->changed = true;
      ctx->source.encode(mOut[kSource]->enc, last->source, p.source);
    }
    if (gps_change) {
      mOut[kTime]->changed = true;
      ctx->time.encode(mOut[kTime]->enc, p.gps_time);
    }
    *last = p;
    last->gps_time_change = gps_change;
  }

 private:
  using Context = Point14V3::Context;
  void start(uint32_t c, const Point14& from) { mContexts[c] = Point14V3::startContext(from); }

  uint32_t mCurrent = 0;
  std::unique_ptr<Context> mContexts[4];
};

class Rgb14EncoderV3 final : public LayeredEncoderItem {
 public:
  explicit Rgb14EncoderV3(bool nir) : mNir(nir) {}
  size_t layerCount() const override { return mNir ? 2 : 1; }
  void init(const uint8_t* item, uint32_t& context) override {
    openLayers(layerCount());
    for (auto& c : mContexts) c.reset();
    mCurrent = context;
    uint16_t first[4] = {};
    loadRgb(item, first, mNir ? 4 : 3);
    mContexts[mCurrent] = Rgb14V3::startContext(first);
  }
  void encode(const uint8_t* item, uint32_t& context) override {
    Context* ctx = mContexts[mCurrent].get();
    uint16_t* last = ctx->last;
    if (mCurrent != context) {  // v3: a used channel keeps the previous channel's values
      mCurrent = context;
      if (!mContexts[mCurrent]) {
        mContexts[mCurrent] = Rgb14V3::startContext(last);
        last = mContexts[mCurrent]->last;
      }
      ctx = mContexts[mCurrent].get();
    }
    uint16_t c[4] = {};
    loadRgb(item, c, mNir ? 4 : 3);
    mOut[0]->changed |= c[0] != last[0] || c[1] != last[1] || c[2] != last[2];
    encodeRgb(mOut[0]->enc, ctx->rgb, last, c);
    if (mNir) {
      const uint32_t sym = uint32_t((last[3] & 0xFF) != (c[3] & 0xFF)) |
                           (uint32_t((last[3] & 0xFF00) != (c[3] & 0xFF00)) << 1);
      Encoder& e = mOut[1]->enc;
      e.encodeSymbol(ctx->nir_used, sym);
      if (sym & 1) e.encodeSymbol(ctx->nir[0], foldByte(int32_t(c[3] & 0xFF) - (last[3] & 0xFF)));
      if (sym & 2) e.encodeSymbol(ctx->nir[1], foldByte(int32_t(c[3] >> 8) - (last[3] >> 8)));
      mOut[1]->changed |= sym != 0;
    }
    std::copy(c, c + (mNir ? 4 : 3), last);
  }

 private:
  using Context = Rgb14V3::Context;
  bool mNir;
  uint32_t mCurrent = 0;
  std::unique_ptr<Context> mContexts[4];
};

class Byte14EncoderV3 final : public LayeredEncoderItem {
 public:
  explicit Byte14EncoderV3(uint16_t n) : mN(n) {}
  size_t layerCount() const override { return mN; }
  void init(const uint8_t* item, uint32_t& context) override {
    openLayers(mN);
    for (auto& c : mContexts) c.reset();
    mCurrent = context;
    mContexts[mCurrent] = Byte14V3::startContext(item, mN);
  }
  void encode(const uint8_t* item, uint32_t& context) override {
    Context* ctx = mContexts[mCurrent].get();
    uint8_t* last = ctx->last.data();
    if (mCurrent != context) {
      mCurrent = context;
      if (!mContexts[mCurrent]) {
        mContexts[mCurrent] = Byte14V3::startContext(last, mN);
        last = mContexts[mCurrent]->last.data();
      }
      ctx = mContexts[mCurrent].get();
    }
    for (uint16_t i = 0; i < mN; ++i) {
      const int32_t diff = int32_t(item[i]) - int32_t(last[i]);
      mOut[i]->enc.encodeSymbol(ctx->models[i], foldByte(diff));
      if (diff) {
        mOut[i]->changed = true;
        last[i] = item[i];
      }
    }
  }

 private:
  using Context = Byte14V3::Context;
  uint16_t mN;
  uint32_t mCurrent = 0;
  std::unique_ptr<Context> mContexts[4];
};

std::unique_ptr<LayeredEncoderItem> makeLayeredEncoder(const Item& item) {
  switch (item.type) {
    case kPoint14:
      return std::make_unique<Point14EncoderV3>();
    case kRgb14:
      return std::make_unique<Rgb14EncoderV3>(false);
    case kRgbNir14:
      return std::make_unique<Rgb14EncoderV3>(true);
    default:
      return std::make_unique<Byte14EncoderV3>(item.size);
  }
}

uint32_t expectedSize(uint16_t type) {
  switch (type) {
    case kPoint10:
      return 20;
    case kGpsTime11:
      return 8;
    case kRgb12:
    case kRgb14:
      return 6;
    case kPoint14:
      return 30;
    case kRgbNir14:
      return 8;
    default:
      return 0;  // bytes: any size
  }
}

}  // namespace

std::string itemName(const Item& item) {
  const char* name = "unknown item";
  switch (item.type) {
    case kByte:
      name = "BYTE";
      break;
    case kPoint10:
      name = "POINT10";
      break;
    case kGpsTime11:
      name = "GPSTIME11";
      break;
    case kRgb12:
      name = "RGB12";
      break;
    case kWavePacket13:
      name = "WAVEPACKET13";
      break;
    case kPoint14:
      name = "POINT14";
      break;
    case kRgb14:
      name = "RGB14";
      break;
    case kRgbNir14:
      name = "RGBNIR14";
      break;
    case kWavePacket14:
      name = "WAVEPACKET14";
      break;
    case kByte14:
      name = "BYTE14";
      break;
    default:
      return "item type " + std::to_string(item.type) + " v" + std::to_string(item.version);
  }
  return std::string(name) + " v" + std::to_string(item.version);
}

std::string unsupportedItems(const std::vector<Item>& items, bool layered) {
  if (items.empty()) return "no items";
  for (size_t i = 0; i < items.size(); ++i) {
    const Item& it = items[i];
    const std::string name = itemName(it);
    if (it.type == kWavePacket13 || it.type == kWavePacket14) {
      return name + ": waveform data packets are not supported";
    }
    const bool pointwise_type =
        it.type == kByte || it.type == kPoint10 || it.type == kGpsTime11 || it.type == kRgb12;
    const bool layered_type =
        it.type == kByte14 || it.type == kPoint14 || it.type == kRgb14 || it.type == kRgbNir14;
    if (!pointwise_type && !layered_type) return name + " is not a LAZ item";
    if (layered != layered_type) {
      return name + (layered ? " in a layered (LAS 1.4) file" : " in a pointwise file");
    }
    if (pointwise_type && it.version != 1 && it.version != 2) {
      return name + ": only versions 1 and 2 exist";
    }
    // Version 2 of the layered items comes from an early prototype writer and reads as 3.
    if (layered_type && (it.version < 2 || it.version > 4)) {
      return name + ": only versions 3 and 4 exist";
    }
    const uint32_t want = expectedSize(it.type);
    if (want ? it.size != want : it.size == 0) {
      return name + " has size " + std::to_string(it.size) +
             (want ? " (it is " + std::to_string(want) + " bytes)" : "");
    }
    if ((it.type == kPoint10 || it.type == kPoint14) && i != 0) {
      return name + " must be the first item";
    }
  }
  if (items[0].type != kPoint10 && items[0].type != kPoint14) {
    return "the first item is " + itemName(items[0]) + ", not POINT10 or POINT14";
  }
  return {};
}

uint32_t recordSize(const std::vector<Item>& items) {
  uint32_t n = 0;
  for (const Item& it : items) n += it.size;
  return n;
}

ChunkDecoder::ChunkDecoder(std::vector<Item> items, bool layered)
    : mItems(std::move(items)), mLayered(layered), mRecordSize(laz::recordSize(mItems)) {}
ChunkDecoder::~ChunkDecoder() = default;

size_t ChunkDecoder::decode(std::span<const uint8_t> bytes, uint64_t count, uint8_t* out) {
  if (count == 0) return 0;
  if (bytes.size() < mRecordSize) throw CorruptData("chunk ends inside its first point");
  std::memcpy(out, bytes.data(), mRecordSize);
  return mLayered ? decodeLayered(bytes, count, out) : decodePointwise(bytes, count, out);
}

size_t ChunkDecoder::decodePointwise(std::span<const uint8_t> bytes, uint64_t count,
                                     uint8_t* out) {
  const PointwiseCoders pc = pointwiseCoders(mItems, out);
  const auto& [coders, offsets] = pc;
  Decoder dec(bytes.subspan(mRecordSize));
  for (uint64_t p = 1; p < count; ++p) {
    uint8_t* rec = out + p * mRecordSize;
    for (size_t i = 0; i < coders.size(); ++i) coders[i]->decode(dec, rec + offsets[i]);
  }
  return mRecordSize + dec.consumed();
}

size_t ChunkDecoder::decodeLayered(std::span<const uint8_t> bytes, uint64_t count,
                                   uint8_t* out) {
  size_t at = mRecordSize;
  auto word = [&](const char* what) {
    if (at + 4 > bytes.size()) throw CorruptData(std::string("chunk ends inside its ") + what);
    const uint32_t v = get<uint32_t>(bytes.data() + at);
    at += 4;
    return v;
  };
  const uint32_t declared = word("point count");
  if (declared != count) {
    throw CorruptData("chunk says it holds " + std::to_string(declared) + " points, not " +
                      std::to_string(count));
  }
  std::vector<std::unique_ptr<LayeredItem>> items;
  std::vector<Layers> layers(mItems.size());
  for (size_t i = 0; i < mItems.size(); ++i) {
    items.push_back(makeLayered(mItems[i]));
    layers[i].bytes.resize(items.back()->layerCount());
  }
  std::vector<std::vector<uint32_t>> sizes(mItems.size());
  for (size_t i = 0; i < mItems.size(); ++i) {
    for (size_t k = 0; k < items[i]->layerCount(); ++k) sizes[i].push_back(word("layer sizes"));
  }
  for (size_t i = 0; i < mItems.size(); ++i) {
    for (size_t k = 0; k < sizes[i].size(); ++k) {
      if (sizes[i][k] > bytes.size() - at) {
        throw CorruptData(itemName(mItems[i]) + " layer " + std::to_string(k) + " of " +
                          std::to_string(sizes[i][k]) + " bytes runs past the chunk");
      }
      layers[i].bytes[k] = bytes.subspan(at, sizes[i][k]);
      at += sizes[i][k];
    }
    layers[i].open();
  }
  std::vector<uint32_t> offsets;
  uint32_t context = 0, rec_at = 0;
  for (size_t i = 0; i < mItems.size(); ++i) {
    items[i]->init(out + rec_at, layers[i], context);
    offsets.push_back(rec_at);
    rec_at += mItems[i].size;
  }
  for (uint64_t p = 1; p < count; ++p) {
    uint8_t* rec = out + p * mRecordSize;
    // Each point starts the items' context at channel 0; POINT14 v4 (and v3 on a change of
    // channel) sets it for the items after it.
    context = 0;
    for (size_t i = 0; i < items.size(); ++i) items[i]->decode(rec + offsets[i], context);
  }
  // Every layer's stream ends exactly where its byte count says.
  for (size_t i = 0; i < mItems.size(); ++i) layers[i].checkConsumed(itemName(mItems[i]).c_str());
  return at;
}

ChunkEncoder::ChunkEncoder(std::vector<Item> items, bool layered)
    : mItems(std::move(items)), mLayered(layered), mRecordSize(laz::recordSize(mItems)) {}

void ChunkEncoder::encode(const uint8_t* records, uint64_t count, std::vector<uint8_t>& out) {
  if (count == 0) return;
  out.insert(out.end(), records, records + mRecordSize);
  if (mLayered) {
    encodeLayered(records, count, out);
    return;
  }
  const PointwiseCoders pc = pointwiseCoders(mItems, records);
  const auto& [coders, offsets] = pc;
  Encoder enc(out);
  for (uint64_t p = 1; p < count; ++p) {
    const uint8_t* rec = records + p * mRecordSize;
    for (size_t i = 0; i < coders.size(); ++i) coders[i]->encode(enc, rec + offsets[i]);
  }
  enc.finish();
}

void ChunkEncoder::encodeLayered(const uint8_t* records, uint64_t count,
                                 std::vector<uint8_t>& out) {
  std::vector<std::unique_ptr<LayeredEncoderItem>> items;
  std::vector<uint32_t> offsets;
  uint32_t context = 0, at = 0;
  for (const Item& it : mItems) {
    items.push_back(makeLayeredEncoder(it));
    items.back()->init(records + at, context);
    offsets.push_back(at);
    at += it.size;
  }
  for (uint64_t p = 1; p < count; ++p) {
    const uint8_t* rec = records + p * mRecordSize;
    context = 0;  // as the decoder: POINT14 v3 sets it on a change of channel only
    for (size_t i = 0; i < items.size(); ++i) items[i]->encode(rec + offsets[i], context);
  }
  const uint32_t n = uint32_t(count);
  out.insert(out.end(), reinterpret_cast<const uint8_t*>(&n), reinterpret_cast<const uint8_t*>(&n) + 4);
  std::vector<std::vector<std::vector<uint8_t>>> layers;
  for (size_t i = 0; i < items.size(); ++i) {
    // POINT14's first two layers (XY and Z) are always written, as LASzip does.
    layers.push_back(items[i]->finish(mItems[i].type == kPoint14));
    for (const auto& l : layers.back()) {
      const uint32_t size = uint32_t(l.size());
      out.insert(out.end(), reinterpret_cast<const uint8_t*>(&size),
                 reinterpret_cast<const uint8_t*>(&size) + 4);
    }
  }
  for (const auto& item_layers : layers) {
    for (const auto& l : item_layers) out.insert(out.end(), l.begin(), l.end());
  }
}

std::vector<Item> itemsForFormat(int format, uint16_t extra) {
  std::vector<Item> items;
  if (format >= 0 && format <= 3) {
    items.push_back({kPoint10, 20, 2});
    if (format == 1 || format == 3) items.push_back({kGpsTime11, 8, 2});
    if (format == 2 || format == 3) items.push_back({kRgb12, 6, 2});
    if (extra) items.push_back({kByte, extra, 2});
  } else if (format >= 6 && format <= 8) {
    items.push_back({kPoint14, 30, 3});
    if (format == 7) items.push_back({kRgb14, 6, 3});
    if (format == 8) items.push_back({kRgbNir14, 8, 3});
    if (extra) items.push_back({kByte14, extra, 3});
  }
  return items;
}

void encodeChunkTable(const std::vector<uint32_t>& points, const std::vector<uint64_t>& bytes,
                      bool variable, std::vector<uint8_t>& out) {
  Encoder enc(out);
  IntegerCoder coder(32, 2);
  for (size_t i = 0; i < bytes.size(); ++i) {
    if (variable) coder.encode(enc, i ? int32_t(points[i - 1]) : 0, int32_t(points[i]), 0);
    coder.encode(enc, i ? int32_t(uint32_t(bytes[i - 1])) : 0, int32_t(uint32_t(bytes[i])), 1);
  }
  enc.finish();
}

void decodeChunkTable(std::span<const uint8_t> coded, uint32_t count, bool variable,
                      std::vector<uint32_t>& points, std::vector<uint64_t>& bytes) {
  points.assign(count, 0);
  bytes.assign(count, 0);
  if (count == 0) return;
  Decoder dec(coded);
  IntegerCoder coder(32, 2);
  for (uint32_t i = 0; i < count; ++i) {
    if (variable) points[i] = uint32_t(coder.decode(dec, i ? int32_t(points[i - 1]) : 0, 0));
    bytes[i] = uint32_t(coder.decode(dec, i ? int32_t(uint32_t(bytes[i - 1])) : 0, 1));
  }
}

}  // namespace tessera::lod::laz
