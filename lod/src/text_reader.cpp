// XYZ / PTS / TXT / CSV point lists: one point per line, values separated by spaces, tabs,
// commas or semicolons. An optional first line holding a single integer is a point count (PTS);
// an optional header line of names (x y z r g b ...) says what the columns are; without one the
// column count decides: 3 = x y z, 4 = x y z i, 6 = x y z r g b, 7 = x y z i r g b.
#include <algorithm>
#include <array>
#include <cctype>

#include "byte_source.h"
#include "reader_util.h"
#include "readers.h"

namespace tessera::lod::detail {
namespace {

constexpr const char* kComponent = "lod::readText()";
constexpr std::string_view kSeps = " \t,;\r";

enum Column : int {
  kColX,
  kColY,
  kColZ,
  kColI,
  kColR,
  kColG,
  kColB,
  kColNx,
  kColNy,
  kColNz,
  kColCount
};

bool isComment(std::string_view line) {
  size_t b = line.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) return true;  // blank
  return line[b] == '#' || line.substr(b, 2) == "//";
}

int columnFor(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  static const std::pair<const char*, int> kNames[] = {
      {"x", kColX},    {"y", kColY},   {"z", kColZ},   {"i", kColI},     {"intensity", kColI},
      {"r", kColR},    {"red", kColR}, {"g", kColG},   {"green", kColG}, {"b", kColB},
      {"blue", kColB}, {"nx", kColNx}, {"ny", kColNy}, {"nz", kColNz}};
  for (auto& [name, col] : kNames) {
    if (s == name) return col;
  }
  return -1;
}

class TextReader final : public PointReader {
 public:
  explicit TextReader(ByteSource source) : mSrc(std::move(source)) { sniff(); }
  bool next(PointBatch& batch, size_t max_points) override;

 private:
  void sniff();
  void setPositional(size_t columns, uint64_t line);
  bool nextDataLine(std::string_view& line);

  ByteSource mSrc;
  std::vector<int> mMap;  // column index -> Column (or -1: ignored)
  size_t mColumns = 0;
  uint64_t mSkipLines = 0;  // count and header lines, re-skipped after rewind
  bool mDone = false;
};

void TextReader::setPositional(size_t columns, uint64_t line) {
  static const std::vector<int> k3 = {kColX, kColY, kColZ}, k4 = {kColX, kColY, kColZ, kColI},
                                k6 = {kColX, kColY, kColZ, kColR, kColG, kColB},
                                k7 = {kColX, kColY, kColZ, kColI, kColR, kColG, kColB};
  switch (columns) {
    case 3:
      mMap = k3;
      break;
    case 4:
      mMap = k4;
      break;
    case 6:
      mMap = k6;
      break;
    case 7:
      mMap = k7;
      break;
    default:
      fail(kComponent, mSrc.name(), atLine(line),
           std::to_string(columns) +
               " values per line; expected 3 (x y z), 4 (x y z i), 6 (x y z r g b), "
               "7 (x y z i r g b), or a header line naming the columns");
  }
}

// Reads the first lines to find the count line, a header line and the column layout, then
// rewinds so next() parses from the top.
void TextReader::sniff() {
  std::string_view line;
  bool seen_count = false;
  for (;;) {
    if (!mSrc.readLine(line)) {
      if (!seen_count || mInfo.declared_points > 0) {
        fail(kComponent, mSrc.name(), atLine(mSrc.lineNumber() + 1),
             "no points in file" +
                 (seen_count ? "; the count line declares " + std::to_string(mInfo.declared_points)
                             : std::string()));
      }
      break;
    }
    if (isComment(line)) continue;
    std::string_view rest = line;
    std::vector<std::string_view> toks;
    for (auto t = nextToken(rest, kSeps); !t.empty(); t = nextToken(rest, kSeps)) toks.push_back(t);
    uint64_t count = 0;
    if (!seen_count && mMap.empty() && toks.size() == 1 && parseUint(toks[0], count)) {
      seen_count = true;
      mInfo.declared_points = count;
      mInfo.has_declared_points = true;
      mSkipLines = mSrc.lineNumber();
      continue;
    }
    double v;
    // A line of separators only (",,") has no token: setPositional() or next() reject it.
    if (!toks.empty() && !parseDouble(toks[0], v) && mMap.empty()) {
      // A header line of column names.
      for (auto t : toks) mMap.push_back(columnFor(std::string(t)));
      if (std::count(mMap.begin(), mMap.end(), kColX) != 1 ||
          std::count(mMap.begin(), mMap.end(), kColY) != 1 ||
          std::count(mMap.begin(), mMap.end(), kColZ) != 1) {
        fail(kComponent, mSrc.name(), atLine(mSrc.lineNumber()),
             "header line " + shown(line) + " does not name columns x, y and z");
      }
      mSkipLines = mSrc.lineNumber();
      continue;
    }
    if (mMap.empty()) setPositional(toks.size(), mSrc.lineNumber());
    break;
  }
  mColumns = mMap.size();
  auto has = [&](int c) { return std::find(mMap.begin(), mMap.end(), c) != mMap.end(); };
  AttributeMask a = 0;
  if (has(kColI)) a |= kIntensity;
  if (has(kColR) && has(kColG) && has(kColB)) a |= kColor;
  if (has(kColNx) && has(kColNy) && has(kColNz)) a |= kNormal;
  mInfo.format = Format::kText;
  mInfo.format_detail =
      std::to_string(mColumns) + " columns" + (mInfo.has_declared_points ? " with count line" : "");
  mInfo.attributes = a;
  mSrc.rewind();
  for (uint64_t i = 0; i < mSkipLines; ++i) mSrc.readLine(line);
}

bool TextReader::nextDataLine(std::string_view& line) {
  while (mSrc.readLine(line)) {
    if (!isComment(line)) return true;
  }
  return false;
}

bool TextReader::next(PointBatch& batch, size_t max_points) {
  batch.reset(mInfo.attributes);
  if (mDone || mColumns == 0) return false;
  std::string_view line;
  std::array<double, kColCount> v{};
  max_points = std::max<size_t>(1, max_points);
  while (batch.size() < max_points) {
    if (!nextDataLine(line)) {
      mDone = true;
      uint64_t total = mStats.points + batch.size() + mStats.skippedTotal();
      if (mInfo.has_declared_points && total < mInfo.declared_points) {
        fail(kComponent, mSrc.name(), atLine(mSrc.lineNumber()),
             "file ends after " + std::to_string(total) + " points; the count line declares " +
                 std::to_string(mInfo.declared_points));
      }
      break;
    }
    uint64_t lineno = mSrc.lineNumber();
    std::string_view rest = line;
    size_t col = 0;
    v.fill(0.0);
    for (auto t = nextToken(rest, kSeps); !t.empty(); t = nextToken(rest, kSeps), ++col) {
      if (col >= mColumns) {
        fail(kComponent, mSrc.name(), atLine(lineno),
             "more than " + std::to_string(mColumns) + " values (as on the first data line)");
      }
      double d;
      if (!parseDouble(t, d)) {
        fail(kComponent, mSrc.name(), atLine(lineno),
             "value " + std::to_string(col + 1) + " is not a number: " + shown(t));
      }
      if (mMap[col] >= 0) v[size_t(mMap[col])] = d;
    }
    if (col != mColumns) {
      fail(kComponent, mSrc.name(), atLine(lineno),
           std::to_string(col) + " values; expected " + std::to_string(mColumns) +
               " as on the first data line");
    }
    if (mInfo.has_declared_points &&
        mStats.points + batch.size() + mStats.skippedTotal() >= mInfo.declared_points) {
      fail(kComponent, mSrc.name(), atLine(lineno),
           "more points than the " + std::to_string(mInfo.declared_points) +
               " the count line declares");
    }
    if (!finite3(v[kColX], v[kColY], v[kColZ])) {
      mStats.skip("non-finite coordinate", atLine(lineno));
      continue;
    }
    batch.positions.emplace_back(v[kColX], v[kColY], v[kColZ]);
    if (batch.attributes & kIntensity) batch.intensities.push_back(float(v[kColI]));
    if (batch.attributes & kColor) {
      auto c8 = [](double c) {
        return uint8_t(std::clamp(std::isfinite(c) ? c : 0.0, 0.0, 255.0));
      };
      batch.colors.emplace_back(c8(v[kColR]), c8(v[kColG]), c8(v[kColB]), 255);
    }
    if (batch.attributes & kNormal) batch.normals.emplace_back(v[kColNx], v[kColNy], v[kColNz]);
  }
  mStats.points += batch.size();
  return !batch.empty();
}

}  // namespace

std::unique_ptr<PointReader> openText(ByteSource source) {
  return std::make_unique<TextReader>(std::move(source));
}

}  // namespace tessera::lod::detail
