// Stanford range-scan sets: a scanalyze `.conf` listing `bmesh FILE tx ty tz qi qj qk qr` per
// scan (translation, then a unit quaternion with the real part last) and an optional `camera`
// line of the same form. Each scan is read with the PLY reader (keeping its range-grid cells),
// moved into the registered frame and tagged with its scan index.
//
// Convention, checked against the published reconstruction bun_zipper.ply: the registered point
// is p' = R(q)^T p + t, i.e. the file's quaternion is the inverse rotation (scanalyze applies
// it to the camera). With this the 10 bunny scans lie a median 0.07 mm from the merged surface;
// with R(q) p + t whole scans land centimetres off (tests/lod/conf_reader_test.cpp).
#include <algorithm>
#include <fstream>

#include "byte_source.h"
#include "reader_util.h"
#include "readers.h"

namespace tessera::lod::detail {
namespace {

constexpr const char* kComponent = "lod::readStanfordConf()";

RigidPose parsePose(std::string_view& rest, const std::string& file, uint64_t line) {
  double v[7];
  for (double& x : v) {
    std::string_view t = nextToken(rest, " \t\r");
    if (!parseDouble(t, x) || !std::isfinite(x)) {
      fail(kComponent, file, atLine(line),
           "expected 7 numbers (tx ty tz qi qj qk qr), got " + shown(t));
    }
  }
  glm::dquat q(v[6], v[3], v[4], v[5]);  // glm: (w, x, y, z)
  double len = glm::length(q);
  if (std::abs(len - 1.0) > 1e-3) {
    fail(kComponent, file, atLine(line),
         "quaternion is not unit length (|q| = " + std::to_string(len) + ")");
  }
  // RigidPose means world = rotation * local + translation: store the conjugate.
  return RigidPose{glm::dvec3(v[0], v[1], v[2]), glm::conjugate(q / len)};
}

class ConfReader final : public PointReader {
 public:
  explicit ConfReader(const std::filesystem::path& conf);
  bool next(PointBatch& batch, size_t max_points) override;

 private:
  std::string mName;
  size_t mScan = 0;
  std::unique_ptr<PointReader> mCurrent;
  uint64_t mBase = 0;  // points delivered by earlier scans (offsets triangle indices)
  PointBatch mTmp;
};

ConfReader::ConfReader(const std::filesystem::path& conf) : mName(conf.string()) {
  ByteSource src = ByteSource::openFile(conf, kComponent);
  std::string_view line;
  AttributeMask common = ~0u;
  while (src.readLine(line, 1 << 16)) {
    std::string_view rest = line;
    std::string_view key = nextToken(rest, " \t\r");
    if (key.empty() || key.front() == '#') continue;
    if (key == "camera") {
      mInfo.camera = parsePose(rest, mName, src.lineNumber());
    } else if (key == "bmesh") {
      std::string_view file = nextToken(rest, " \t\r");
      if (file.empty())
        fail(kComponent, mName, atLine(src.lineNumber()), "bmesh without a file name");
      ScanInfo scan;
      scan.name = std::string(file);
      scan.pose = parsePose(rest, mName, src.lineNumber());
      scan.path = conf.parent_path() / scan.name;
      std::unique_ptr<PointReader> r;
      try {
        r = openPointReader(scan.path);
      } catch (const ReadError& e) {
        fail(kComponent, mName, atLine(src.lineNumber()),
             std::string("scan ") + shown(scan.name) + ": " + e.what());
      }
      const SourceInfo& si = r->info();
      scan.points = si.declared_points;
      if (!si.scans.empty()) {
        scan.grid_columns = si.scans[0].grid_columns;
        scan.grid_rows = si.scans[0].grid_rows;
      }
      common &= si.attributes;
      mInfo.declared_points += si.declared_points;
      mInfo.declared_triangles += si.declared_triangles;
      mInfo.scans.push_back(std::move(scan));
    } else {
      fail(kComponent, mName, atLine(src.lineNumber()),
           "unknown keyword " + shown(key) + " (expected bmesh or camera)");
    }
  }
  if (mInfo.scans.empty()) fail(kComponent, mName, "", "no bmesh lines: no scans to load");
  if (mInfo.scans.size() > 65535) fail(kComponent, mName, "", "more than 65535 scans");
  mInfo.format = Format::kStanfordConf;
  mInfo.format_detail = std::to_string(mInfo.scans.size()) + " range scans";
  mInfo.has_declared_points = true;
  mInfo.attributes = (common & ~kScanIndex) | kScanIndex;
}

bool ConfReader::next(PointBatch& batch, size_t max_points) {
  batch.reset(mInfo.attributes);
  while (mScan < mInfo.scans.size()) {
    const ScanInfo& scan = mInfo.scans[mScan];
    if (!mCurrent) mCurrent = openPointReader(scan.path);
    if (!mCurrent->next(mTmp, max_points)) {
      for (auto& [reason, count] : mCurrent->stats().skipped) {
        mStats.skipped[reason] += count;
        if (!mStats.first_skip_at.count(reason)) {
          mStats.first_skip_at[reason] =
              scan.name + " " + mCurrent->stats().first_skip_at.at(reason);
        }
      }
      mBase += mCurrent->stats().points;
      mCurrent.reset();
      ++mScan;
      continue;
    }
    const glm::dmat3 rot = glm::mat3_cast(scan.pose.rotation);
    const size_t n = mTmp.size();
    batch.resize(n);
    for (size_t i = 0; i < n; ++i)
      batch.positions[i] = rot * mTmp.positions[i] + scan.pose.translation;
    if (batch.attributes & kNormal) {
      for (size_t i = 0; i < n; ++i)
        batch.normals[i] = glm::vec3(rot * glm::dvec3(mTmp.normals[i]));
    }
    auto copy = [&](AttributeMask bit, auto& dst, const auto& src) {
      if (batch.attributes & bit) std::copy(src.begin(), src.begin() + n, dst.begin());
    };
    copy(kColor, batch.colors, mTmp.colors);
    copy(kIntensity, batch.intensities, mTmp.intensities);
    copy(kConfidence, batch.confidences, mTmp.confidences);
    copy(kGridPosition, batch.grid_positions, mTmp.grid_positions);
    copy(kClassification, batch.classifications, mTmp.classifications);
    std::fill(batch.scan_indices.begin(), batch.scan_indices.end(), uint16_t(mScan));
    for (const Triangle& t : mTmp.triangles)
      batch.triangles.push_back(t + Triangle(uint32_t(mBase)));
    mStats.points += n;
    mStats.triangles += mTmp.triangles.size();
    return true;
  }
  return false;
}

}  // namespace

std::unique_ptr<PointReader> openStanfordConf(const std::filesystem::path& conf) {
  return std::make_unique<ConfReader>(conf);
}

}  // namespace tessera::lod::detail
