// The LAZ range coder, its models and the integer corrector coder (see laz_codec.h).
#include "laz_codec.h"

#include <stdexcept>

namespace tessera::lod::laz {
namespace {

constexpr uint32_t kMinLength = 0x01000000u;  // renormalise below this interval length
constexpr uint32_t kBitShift = 13;            // bit models: length bits dropped before a product
constexpr uint32_t kBitMaxCount = 1u << kBitShift;
constexpr uint32_t kSymbolShift = 15;  // symbol models: the same, and their count limit
constexpr uint32_t kSymbolMaxCount = 1u << kSymbolShift;

}  // namespace

SymbolModel::SymbolModel(uint32_t symbols) : mSymbols(symbols), mLast(symbols - 1) {
  if (symbols < 2 || symbols > 2048) throw std::invalid_argument("laz::SymbolModel: symbols");
  if (symbols > 16) {  // a lookup table narrows the decoder's search
    uint32_t table_bits = 3;
    while (symbols > (1u << (table_bits + 2))) ++table_bits;
    mTableSize = 1u << table_bits;
    mTableShift = kSymbolShift - table_bits;
    mTable.assign(mTableSize + 2, 0);
  }
  mDistribution.assign(symbols, 0);
  mCount.assign(symbols, 1);
  mUpdateCycle = symbols;
  update();
  mUntilUpdate = mUpdateCycle = (symbols + 6) >> 1;
}

void SymbolModel::update() {
  if ((mTotal += mUpdateCycle) > kSymbolMaxCount) {  // halve the counts
    mTotal = 0;
    for (uint32_t& c : mCount) mTotal += (c = (c + 1) >> 1);
  }
  const uint32_t scale = 0x80000000u / mTotal;
  uint32_t sum = 0, s = 0;
  for (uint32_t k = 0; k < mSymbols; ++k) {
    mDistribution[k] = (scale * sum) >> (31 - kSymbolShift);
    sum += mCount[k];
    if (mTableSize) {
      const uint32_t w = mDistribution[k] >> mTableShift;
      while (s < w) mTable[++s] = k - 1;
    }
  }
  if (mTableSize) {
    mTable[0] = 0;
    while (s <= mTableSize) mTable[++s] = mSymbols - 1;
  }
  mUpdateCycle = (5 * mUpdateCycle) >> 2;
  const uint32_t max_cycle = (mSymbols + 6) << 3;
  if (mUpdateCycle > max_cycle) mUpdateCycle = max_cycle;
  mUntilUpdate = mUpdateCycle;
}

void BitModel::update() {
  if ((mCount += mUpdateCycle) > kBitMaxCount) {
    mCount = (mCount + 1) >> 1;
    mZeroCount = (mZeroCount + 1) >> 1;
    if (mZeroCount == mCount) ++mCount;
  }
  const uint32_t scale = 0x80000000u / mCount;
  mZeroProb = (mZeroCount * scale) >> (31 - kBitShift);
  mUpdateCycle = (5 * mUpdateCycle) >> 2;
  if (mUpdateCycle > 64) mUpdateCycle = 64;
  mUntilUpdate = mUpdateCycle;
}

// ---- decoder --------------------------------------------------------------------------------

Decoder::Decoder(std::span<const uint8_t> bytes)
    : mBegin(bytes.data()), mAt(bytes.data()), mEnd(bytes.data() + bytes.size()) {
  for (int i = 0; i < 4; ++i) mValue = (mValue << 8) | nextByte();
}

void Decoder::renormalise() {
  do {
    mValue = (mValue << 8) | nextByte();
  } while ((mLength <<= 8) < kMinLength);
}

uint32_t Decoder::decodeBit(BitModel& m) {
  const uint32_t x = m.mZeroProb * (mLength >> kBitShift);
  const uint32_t bit = mValue >= x;
  if (bit == 0) {
    mLength = x;
    ++m.mZeroCount;
  } else {
    mValue -= x;
    mLength -= x;
  }
  if (mLength < kMinLength) renormalise();
  if (--m.mUntilUpdate == 0) m.update();
  return bit;
}

uint32_t Decoder::decodeSymbol(SymbolModel& m) {
  uint32_t sym, x, y = mLength;
  if (m.mTableSize) {
    const uint32_t dv = mValue / (mLength >>= kSymbolShift);
    const uint32_t t = dv >> m.mTableShift;
    if (t > m.mTableSize) throw CorruptData("compressed value outside its interval");
    sym = m.mTable[t];
    uint32_t n = m.mTable[t + 1] + 1;
    while (n > sym + 1) {  // bisection between the table's bounds
      const uint32_t k = (sym + n) >> 1;
      if (m.mDistribution[k] > dv) {
        n = k;
      } else {
        sym = k;
      }
    }
    x = m.mDistribution[sym] * mLength;
    if (sym != m.mLast) y = m.mDistribution[sym + 1] * mLength;
  } else {
    x = sym = 0;
    mLength >>= kSymbolShift;
    uint32_t n = m.mSymbols, k = n >> 1;
    do {
      const uint32_t z = mLength * m.mDistribution[k];
      if (z > mValue) {
        n = k;
        y = z;
      } else {
        sym = k;
        x = z;
      }
    } while ((k = (sym + n) >> 1) != sym);
  }
  mValue -= x;
  mLength = y - x;
  if (mLength < kMinLength) renormalise();
  ++m.mCount[sym];
  if (--m.mUntilUpdate == 0) m.update();
  return sym;
}

uint32_t Decoder::readBits(uint32_t bits) {
  if (bits > 19) {
    const uint32_t low = readShort();
    return (readBits(bits - 16) << 16) | low;
  }
  const uint32_t sym = mValue / (mLength >>= bits);
  mValue -= mLength * sym;
  if (mLength < kMinLength) renormalise();
  if (sym >= (1u << bits)) throw CorruptData("raw bits out of range");
  return sym;
}

uint32_t Decoder::readShort() {
  return readBits(16);
}

uint32_t Decoder::readInt() {
  const uint32_t low = readShort();
  return (readShort() << 16) | low;
}

uint64_t Decoder::readInt64() {
  const uint64_t low = readInt();
  return (uint64_t(readInt()) << 32) | low;
}

// ---- encoder --------------------------------------------------------------------------------

void Encoder::carry() {
  size_t i = mOut.size();
  while (i > mStart && mOut[i - 1] == 0xFF) mOut[--i] = 0;
  if (i > mStart) ++mOut[i - 1];
}

void Encoder::renormalise() {
  do {
    mOut.push_back(uint8_t(mBase >> 24));
    mBase <<= 8;
  } while ((mLength <<= 8) < kMinLength);
}

void Encoder::encodeBit(BitModel& m, uint32_t bit) {
  const uint32_t x = m.mZeroProb * (mLength >> kBitShift);
  if (bit == 0) {
    mLength = x;
    ++m.mZeroCount;
  } else {
    const uint32_t before = mBase;
    mBase += x;
    mLength -= x;
    if (before > mBase) carry();
  }
  if (mLength < kMinLength) renormalise();
  if (--m.mUntilUpdate == 0) m.update();
}

void Encoder::encodeSymbol(SymbolModel& m, uint32_t sym) {
  const uint32_t before = mBase;
  if (sym == m.mLast) {
    const uint32_t x = m.mDistribution[sym] * (mLength >> kSymbolShift);
    mBase += x;
    mLength -= x;
  } else {
    const uint32_t x = m.mDistribution[sym] * (mLength >>= kSymbolShift);
    mBase += x;
    mLength = m.mDistribution[sym + 1] * mLength - x;
  }
  if (before > mBase) carry();
  if (mLength < kMinLength) renormalise();
  ++m.mCount[sym];
  if (--m.mUntilUpdate == 0) m.update();
}

void Encoder::writeBits(uint32_t bits, uint32_t value) {
  if (bits > 19) {
    writeShort(value & 0xFFFF);
    value >>= 16;
    bits -= 16;
  }
  const uint32_t before = mBase;
  mBase += value * (mLength >>= bits);
  if (before > mBase) carry();
  if (mLength < kMinLength) renormalise();
}

void Encoder::writeShort(uint32_t value) {
  writeBits(16, value & 0xFFFF);
}

void Encoder::writeInt(uint32_t value) {
  writeShort(value & 0xFFFF);
  writeShort(value >> 16);
}

void Encoder::writeInt64(uint64_t value) {
  writeInt(uint32_t(value));
  writeInt(uint32_t(value >> 32));
}

void Encoder::finish() {
  const uint32_t before = mBase;
  bool another_byte = true;
  if (mLength > 2 * kMinLength) {
    mBase += kMinLength;
    mLength = kMinLength >> 1;
  } else {
    mBase += kMinLength >> 1;
    mLength = kMinLength >> 9;
    another_byte = false;
  }
  if (before > mBase) carry();
  renormalise();
  // Zeros the decoder's four-byte look-ahead reads at the end.
  mOut.push_back(0);
  mOut.push_back(0);
  if (another_byte) mOut.push_back(0);
}

// ---- integer corrector coder ----------------------------------------------------------------

IntegerCoder::IntegerCoder(uint32_t bits, uint32_t contexts, uint32_t bits_high, uint32_t range)
    : mBitsHigh(bits_high) {
  if (range) {
    mCorrRange = range;
    for (uint32_t r = range; r; r >>= 1) ++mCorrBits;
    if (mCorrRange == (1u << (mCorrBits - 1))) --mCorrBits;
    mCorrMin = -int32_t(mCorrRange / 2);
    mCorrMax = int32_t(int64_t(mCorrMin) + mCorrRange - 1);
  } else if (bits && bits < 32) {
    mCorrBits = bits;
    mCorrRange = 1u << bits;
    mCorrMin = -int32_t(mCorrRange / 2);
    mCorrMax = int32_t(int64_t(mCorrMin) + mCorrRange - 1);
  } else {
    mCorrBits = 32;
    mCorrRange = 0;
    mCorrMin = INT32_MIN;
    mCorrMax = INT32_MAX;
  }
  mBits.reserve(contexts);
  for (uint32_t i = 0; i < contexts; ++i) mBits.emplace_back(mCorrBits + 1);
  mCorrector.reserve(mCorrBits);
  for (uint32_t i = 1; i <= mCorrBits; ++i) {
    mCorrector.emplace_back(1u << (i <= mBitsHigh ? i : mBitsHigh));
  }
}

int32_t IntegerCoder::readCorrector(Decoder& dec, SymbolModel& bits) {
  mK = dec.decodeSymbol(bits);
  if (mK == 0) return int32_t(dec.decodeBit(mCorrector0));
  if (mK >= 32) return mCorrMin;
  uint32_t c;
  if (mK <= mBitsHigh) {
    c = dec.decodeSymbol(mCorrector[mK - 1]);
  } else {
    const uint32_t k1 = mK - mBitsHigh;
    c = dec.decodeSymbol(mCorrector[mK - 1]);
    c = (c << k1) | dec.readBits(k1);
  }
  // c in [0, 2^(k-1)) codes -(2^k - 1) .. -2^(k-1); c in [2^(k-1), 2^k) codes 2^(k-1) + 1 .. 2^k.
  if (c >= (1u << (mK - 1))) return int32_t(c + 1);
  return int32_t(c - ((1u << mK) - 1));
}

int32_t IntegerCoder::decode(Decoder& dec, int32_t pred, uint32_t context) {
  uint32_t real = uint32_t(pred) + uint32_t(readCorrector(dec, mBits[context]));
  if (mCorrRange) {
    if (int32_t(real) < 0) {
      real += mCorrRange;
    } else if (real >= mCorrRange) {
      real -= mCorrRange;
    }
  }
  return int32_t(real);
}

void IntegerCoder::writeCorrector(Encoder& enc, int32_t c, SymbolModel& bits) {
  uint32_t c1 = c <= 0 ? 0u - uint32_t(c) : uint32_t(c) - 1;
  mK = 0;
  while (c1) {
    c1 >>= 1;
    ++mK;
  }
  enc.encodeSymbol(bits, mK);
  if (mK == 0) {
    enc.encodeBit(mCorrector0, uint32_t(c));
    return;
  }
  if (mK >= 32) return;
  uint32_t v = c < 0 ? uint32_t(c) + ((1u << mK) - 1) : uint32_t(c) - 1;
  if (mK <= mBitsHigh) {
    enc.encodeSymbol(mCorrector[mK - 1], v);
  } else {
    const uint32_t k1 = mK - mBitsHigh;
    const uint32_t low = v & ((1u << k1) - 1);
    enc.encodeSymbol(mCorrector[mK - 1], v >> k1);
    enc.writeBits(k1, low);
  }
}

void IntegerCoder::encode(Encoder& enc, int32_t pred, int32_t real, uint32_t context) {
  int32_t corr = int32_t(uint32_t(real) - uint32_t(pred));
  if (mCorrRange) {
    if (corr < mCorrMin) {
      corr = int32_t(uint32_t(corr) + mCorrRange);
    } else if (corr > mCorrMax) {
      corr = int32_t(uint32_t(corr) - mCorrRange);
    }
  }
  writeCorrector(enc, corr, mBits[context]);
}

// ---- median of five -------------------------------------------------------------------------

void Median5::add(int32_t v) {
  int32_t* s = mValues;
  if (mHigh) {
    if (v < s[2]) {
      s[4] = s[3];
      s[3] = s[2];
      if (v < s[0]) {
        s[2] = s[1];
        s[1] = s[0];
        s[0] = v;
      } else if (v < s[1]) {
        s[2] = s[1];
        s[1] = v;
      } else {
        s[2] = v;
      }
    } else {
      if (v < s[3]) {
        s[4] = s[3];
        s[3] = v;
      } else {
        s[4] = v;
      }
      mHigh = false;
    }
  } else {
    if (s[2] < v) {
      s[0] = s[1];
      s[1] = s[2];
      if (s[4] < v) {
        s[2] = s[3];
        s[3] = s[4];
        s[4] = v;
      } else if (s[3] < v) {
        s[2] = s[3];
        s[3] = v;
      } else {
        s[2] = v;
      }
    } else {
      if (s[1] < v) {
        s[0] = s[1];
        s[1] = v;
      } else {
        s[0] = v;
      }
      mHigh = true;
    }
  }
}

}  // namespace tessera::lod::laz
