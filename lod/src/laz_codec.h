// The entropy coder of LAZ (LASzip): a 32-bit range coder with adaptive symbol and bit models
// (Said's FastAC as Isenburg adapted it, "LASzip: lossless compression of LiDAR data", 2013) and
// the integer corrector coder built on it. The decoder reads one chunk or layer held in memory;
// the encoder appends to a byte vector. Both must agree bit for bit with every LAZ writer, so the
// constants and the order of model updates follow the published format exactly.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace tessera::lod::laz {

/// Compressed bytes that do not decode: a stream that ends early or a value out of range.
class CorruptData : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// An adaptive model over `symbols` symbols (2..2048); counts start equal.
class SymbolModel {
 public:
  explicit SymbolModel(uint32_t symbols);
  uint32_t symbols() const { return mSymbols; }

 private:
  friend class Decoder;
  friend class Encoder;
  void update();

  uint32_t mSymbols, mLast;
  uint32_t mTableShift = 0, mTableSize = 0;
  uint32_t mTotal = 0, mUpdateCycle = 0, mUntilUpdate = 0;
  std::vector<uint32_t> mDistribution, mCount, mTable;
};

/// An adaptive model of one binary decision.
class BitModel {
 private:
  friend class Decoder;
  friend class Encoder;
  void update();

  uint32_t mZeroCount = 1, mCount = 2, mZeroProb = 1u << 12;
  uint32_t mUpdateCycle = 4, mUntilUpdate = 4;
};

class Decoder {
 public:
  /// Starts on `bytes` (reads the first four). Throws CorruptData when fewer than four.
  explicit Decoder(std::span<const uint8_t> bytes);
  uint32_t decodeBit(BitModel& m);
  uint32_t decodeSymbol(SymbolModel& m);
  /// `bits` raw bits (1..32).
  uint32_t readBits(uint32_t bits);
  uint32_t readShort();
  uint32_t readInt();
  uint64_t readInt64();
  /// Bytes consumed so far (equals the stream's length once its last symbol is decoded).
  size_t consumed() const { return size_t(mAt - mBegin); }

 private:
  uint8_t nextByte() {
    if (mAt == mEnd) throw CorruptData("compressed data ends early");
    return *mAt++;
  }
  void renormalise();

  const uint8_t *mBegin, *mAt, *mEnd;
  uint32_t mValue = 0, mLength = 0xFFFFFFFFu;
};

class Encoder {
 public:
  /// Appends to `out`.
  explicit Encoder(std::vector<uint8_t>& out) : mOut(out), mStart(out.size()) {}
  void encodeBit(BitModel& m, uint32_t bit);
  void encodeSymbol(SymbolModel& m, uint32_t symbol);
  void writeBits(uint32_t bits, uint32_t value);
  void writeShort(uint32_t value);
  void writeInt(uint32_t value);
  void writeInt64(uint64_t value);
  /// Flushes the interval: the decoder then reads exactly the bytes written.
  void finish();

 private:
  void carry();
  void renormalise();

  std::vector<uint8_t>& mOut;
  size_t mStart;
  uint32_t mBase = 0, mLength = 0xFFFFFFFFu;
};

/// Integers coded as a correction to a prediction: the correction's bit length k by a model per
/// context, then its value (k <= bits_high in one symbol, else the high part by a model and the
/// low bits raw). `bits` is the integers' width (32: any int32).
class IntegerCoder {
 public:
  explicit IntegerCoder(uint32_t bits = 16, uint32_t contexts = 1, uint32_t bits_high = 8,
                        uint32_t range = 0);
  int32_t decode(Decoder& dec, int32_t pred, uint32_t context = 0);
  void encode(Encoder& enc, int32_t pred, int32_t real, uint32_t context = 0);
  /// The bit length k of the last correction (other coders take their context from it).
  uint32_t k() const { return mK; }

 private:
  int32_t readCorrector(Decoder& dec, SymbolModel& bits);
  void writeCorrector(Encoder& enc, int32_t c, SymbolModel& bits);

  uint32_t mBitsHigh, mCorrBits = 0, mCorrRange = 0;
  int32_t mCorrMin = 0, mCorrMax = 0;
  uint32_t mK = 0;
  std::vector<SymbolModel> mBits;
  BitModel mCorrector0;
  std::vector<SymbolModel> mCorrector;  // [k - 1] for k = 1..corr_bits
};

/// A running median of the last five values (LASzip's predictor of coordinate differences).
class Median5 {
 public:
  int32_t get() const { return mValues[2]; }
  void add(int32_t v);

 private:
  int32_t mValues[5] = {0, 0, 0, 0, 0};
  bool mHigh = true;
};

/// Wraps `v` into 0..255 the way LASzip folds byte differences.
inline uint8_t foldByte(int32_t v) {
  return uint8_t(v < 0 ? v + 256 : v > 255 ? v - 256 : v);
}
inline int32_t clampByte(int32_t v) {
  return v <= 0 ? 0 : v >= 255 ? 255 : v;
}

}  // namespace tessera::lod::laz
