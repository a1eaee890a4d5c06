// Wavefront OBJ meshes: `v x y z [w]` or `v x y z r g b` (colour in 0..1, or 0..255 when a
// channel exceeds 1), `f` with any number of corners (i, i/t, i//n, i/t/n; negative indices
// count back from the last vertex) triangulated as fans. Other statements are ignored.
#include <algorithm>
#include <limits>

#include "byte_source.h"
#include "reader_util.h"
#include "readers.h"

namespace tessera::lod::detail {
namespace {

constexpr const char* kComponent = "lod::readObj()";
constexpr uint32_t kDropped = std::numeric_limits<uint32_t>::max();

class ObjReader final : public PointReader {
 public:
  explicit ObjReader(ByteSource source) : mSrc(std::move(source)) { sniff(); }
  bool next(PointBatch& batch, size_t max_points) override;

 private:
  void sniff();
  void vertex(std::string_view rest, PointBatch& batch);
  void face(std::string_view rest, PointBatch& batch);

  ByteSource mSrc;
  std::vector<uint32_t> mRemap;  // file vertex (0-based) -> delivered index or kDropped
  uint32_t mKept = 0;
  bool mDone = false;
  std::vector<int64_t> mCorners;
};

// Finds whether vertices carry colours (first `v` line decides) and counts nothing else:
// the file is then parsed from the top.
void ObjReader::sniff() {
  std::string_view line;
  mInfo.format = Format::kObj;
  mInfo.format_detail = "Wavefront OBJ";
  while (mSrc.readLine(line)) {
    std::string_view rest = line;
    if (nextToken(rest, " \t\r") != "v") continue;
    int n = 0;
    for (auto t = nextToken(rest, " \t\r"); !t.empty(); t = nextToken(rest, " \t\r")) ++n;
    if (n >= 6) mInfo.attributes |= kColor;
    break;
  }
  mSrc.rewind();
}

void ObjReader::vertex(std::string_view rest, PointBatch& batch) {
  double v[7] = {0, 0, 0, 1, 1, 1, 1};
  int n = 0;
  for (auto t = nextToken(rest, " \t\r"); !t.empty(); t = nextToken(rest, " \t\r"), ++n) {
    if (n >= 7 || !parseDouble(t, v[n])) {
      fail(kComponent, mSrc.name(), atLine(mSrc.lineNumber()), "bad vertex value " + shown(t));
    }
  }
  if (n < 3)
    fail(kComponent, mSrc.name(), atLine(mSrc.lineNumber()),
         "vertex with fewer than 3 coordinates");
  if (mRemap.size() >= kDropped - 1)
    fail(kComponent, mSrc.name(), atLine(mSrc.lineNumber()), "too many vertices");
  if (!finite3(v[0], v[1], v[2])) {
    mStats.skip("non-finite coordinate", atLine(mSrc.lineNumber()));
    mRemap.push_back(kDropped);
    return;
  }
  mRemap.push_back(mKept++);
  batch.positions.emplace_back(v[0], v[1], v[2]);
  if (batch.attributes & kColor) {
    glm::u8vec4 c(255);
    if (n >= 6) {
      bool unit = v[3] <= 1.0 && v[4] <= 1.0 && v[5] <= 1.0;
      for (int k = 0; k < 3; ++k) {
        double x = unit ? v[3 + k] * 255.0 : v[3 + k];
        c[k] = uint8_t(std::clamp(std::isfinite(x) ? std::round(x) : 0.0, 0.0, 255.0));
      }
    }
    batch.colors.push_back(c);
  }
}

void ObjReader::face(std::string_view rest, PointBatch& batch) {
  mCorners.clear();
  for (auto t = nextToken(rest, " \t\r"); !t.empty(); t = nextToken(rest, " \t\r")) {
    std::string_view idx = t.substr(0, t.find('/'));
    int64_t i = 0;
    auto r = std::from_chars(idx.data(), idx.data() + idx.size(), i);
    if (r.ec != std::errc() || r.ptr != idx.data() + idx.size() || i == 0) {
      fail(kComponent, mSrc.name(), atLine(mSrc.lineNumber()), "bad face index " + shown(t));
    }
    mCorners.push_back(i < 0 ? int64_t(mRemap.size()) + i : i - 1);
  }
  if (mCorners.size() < 3) {
    mStats.skip("face with fewer than 3 vertices", atLine(mSrc.lineNumber()));
    return;
  }
  for (int64_t c : mCorners) {
    if (c < 0 || c >= int64_t(mRemap.size()) || mRemap[size_t(c)] == kDropped) {
      mStats.skip("face with an out-of-range or skipped vertex", atLine(mSrc.lineNumber()));
      return;
    }
  }
  for (size_t k = 1; k + 1 < mCorners.size(); ++k) {
    batch.triangles.emplace_back(mRemap[size_t(mCorners[0])], mRemap[size_t(mCorners[k])],
                                 mRemap[size_t(mCorners[k + 1])]);
  }
}

bool ObjReader::next(PointBatch& batch, size_t max_points) {
  batch.reset(mInfo.attributes);
  if (mDone) return false;
  max_points = std::max<size_t>(1, max_points);
  std::string_view line;
  while (batch.size() < max_points && batch.triangles.size() < max_points) {
    if (!mSrc.readLine(line)) {
      mDone = true;
      break;
    }
    std::string_view rest = line;
    std::string_view key = nextToken(rest, " \t\r");
    if (key == "v") {
      vertex(rest, batch);
    } else if (key == "f") {
      face(rest, batch);
    }
  }
  mStats.points += batch.size();
  mStats.triangles += batch.triangles.size();
  return !batch.empty();
}

}  // namespace

std::unique_ptr<PointReader> openObj(ByteSource source) {
  return std::make_unique<ObjReader>(std::move(source));
}

}  // namespace tessera::lod::detail
