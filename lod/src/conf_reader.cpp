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
#include <cctype>
#include <fstream>

#include <tessera/core/file_checks.h>

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

/// .conf files may list .conf files; deeper than this is refused (a listing loop without a
/// cycle by path, e.g. ever longer names, would otherwise recurse until the stack ends).
constexpr size_t kMaxConfNesting = 8;

bool isConfName(const std::filesystem::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return ext == ".conf";
}

class ConfReader final : public PointReader {
 public:
  /// `src` holds the listing; scans are found beside `conf`. `chain`: the .conf files being
  /// read around this one, outermost first (their scans include this one).
  ConfReader(ByteSource src, const std::filesystem::path& conf,
             std::vector<std::filesystem::path> chain);
  bool next(PointBatch& batch, size_t max_points) override;

 private:
  /// Refuses a scan that is a .conf already being read (a cycle) or nested too deep.
  void checkNesting(const ScanInfo& scan, uint64_t line) const;
  /// A scan's reader; a nested .conf gets the chain, so its own cycles are found.
  std::unique_ptr<PointReader> openScan(const ScanInfo& scan) const;

  std::string mName;
  std::vector<std::filesystem::path> mChain;  // outer .confs, then this one
  size_t mScan = 0;
  std::unique_ptr<PointReader> mCurrent;
  uint64_t mBase = 0;  // points delivered by earlier scans (offsets triangle indices)
  PointBatch mTmp;
};

void ConfReader::checkNesting(const ScanInfo& scan, uint64_t line) const {
  if (!isConfName(scan.path)) return;
  if (const auto same = sameFileAs(scan.path, mChain)) {
    std::string loop;
    for (const auto& p : mChain) loop += p.string() + " -> ";
    fail(kComponent, mName, atLine(line),
         "scan " + shown(scan.name) + " is " + same->string() +
             ", a .conf already being read: the listing is a cycle (" + loop + scan.path.string() +
             ")");
  }
  if (mChain.size() >= kMaxConfNesting)
    fail(kComponent, mName, atLine(line),
         "scan " + shown(scan.name) + ": .conf files nested more than " +
             std::to_string(kMaxConfNesting) + " deep");
}

std::unique_ptr<PointReader> ConfReader::openScan(const ScanInfo& scan) const {
  if (!isConfName(scan.path)) return openPointReader(scan.path);
  return openStanfordConf(scan.path, mChain);
}

ConfReader::ConfReader(ByteSource src, const std::filesystem::path& conf,
                       std::vector<std::filesystem::path> chain)
    : mName(conf.string()), mChain(std::move(chain)) {
  mChain.push_back(conf);
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
      checkNesting(scan, src.lineNumber());
      std::unique_ptr<PointReader> r;
      try {
        r = openScan(scan);
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
    if (!mCurrent) mCurrent = openScan(scan);
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

std::unique_ptr<PointReader> openStanfordConf(const std::filesystem::path& conf,
                                              std::vector<std::filesystem::path> chain) {
  return std::make_unique<ConfReader>(ByteSource::openFile(conf, kComponent), conf,
                                      std::move(chain));
}

std::unique_ptr<PointReader> openStanfordConf(ByteSource listing,
                                              const std::filesystem::path& conf) {
  return std::make_unique<ConfReader>(std::move(listing), conf,
                                      std::vector<std::filesystem::path>{});
}

}  // namespace tessera::lod::detail
