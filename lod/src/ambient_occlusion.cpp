#include <tessera/lod/ambient_occlusion.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <unordered_map>

#include <tessera/core/check.h>
#include <tessera/core/parallel.h>
#include <tessera/core/symmetric_eigen.h>

#include "morton.h"
#include "splitmix.h"

namespace tessera::lod {
namespace {

constexpr const char* kWho = "lod::ambientOcclusion()";
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

/// Eq. 4's cubic Hermite falloff: 0 at d = 0, 1 from t_max on.
inline double smoothstep01(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

inline double unitFloat(uint64_t bits) {
  return double(bits >> 11) * 0x1.0p-53;
}

glm::dvec3 features(ScanProjection proj, const glm::dvec3& p) {
  switch (proj) {
    case ScanProjection::kOrthographic:
      return p;
    case ScanProjection::kPerspective:
      return {p.x / -p.z, p.y / -p.z, 0.0};
    case ScanProjection::kPanoramic: {
      // The virtual scanner's panorama: azimuth 0..2 pi from -z towards +x, elevation up.
      double az = std::atan2(p.x, -p.z);
      if (az < 0) az += 2.0 * std::numbers::pi;
      double len = glm::length(p);
      return {az, len > 0 ? std::asin(std::clamp(p.y / len, -1.0, 1.0)) : 0.0, 0.0};
    }
  }
  return p;
}

/// Solves the symmetric system A x = b (n <= 3) by Gaussian elimination with partial pivoting;
/// false when singular.
bool solve(double a[3][3], double b[3], int n, double x[3]) {
  for (int c = 0; c < n; ++c) {
    int piv = c;
    for (int r = c + 1; r < n; ++r)
      if (std::abs(a[r][c]) > std::abs(a[piv][c])) piv = r;
    if (std::abs(a[piv][c]) < 1e-30) return false;
    std::swap(a[c], a[piv]);
    std::swap(b[c], b[piv]);
    for (int r = c + 1; r < n; ++r) {
      double f = a[r][c] / a[c][c];
      for (int k = c; k < n; ++k) a[r][k] -= f * a[c][k];
      b[r] -= f * b[c];
    }
  }
  for (int c = n - 1; c >= 0; --c) {
    double s = b[c];
    for (int k = c + 1; k < n; ++k) s -= a[c][k] * x[k];
    x[c] = s / a[c][c];
  }
  return true;
}

struct Fit {
  glm::dvec3 col{0.0}, row{0.0};
  double col0 = 0, row0 = 0, rms = std::numeric_limits<double>::infinity();
};

/// Least-squares affine map from the projection's coordinates to (column, row) over the grid's
/// points.
Fit fitProjection(const RangeMap& m, ScanProjection proj) {
  const int dims = proj == ScanProjection::kOrthographic ? 3 : 2;
  Fit fit;
  glm::dvec3 mean_f(0.0);
  glm::dvec2 mean_c(0.0);
  size_t n = 0;
  std::vector<std::pair<glm::dvec3, glm::dvec2>> samples;
  const size_t stride = std::max<size_t>(1, m.pixels() / 200000);
  for (size_t px = 0; px < m.pixels(); px += stride) {
    if (!m.valid[px]) continue;
    glm::dvec3 p(m.positions[px]);
    if (proj == ScanProjection::kPerspective && !(p.z < 0)) return fit;  // not in front
    glm::dvec3 f = features(proj, p);
    glm::dvec2 c(double(px % m.columns), double(px / m.columns));
    samples.push_back({f, c});
    mean_f += f;
    mean_c += c;
    ++n;
  }
  if (n < 4) return fit;
  mean_f /= double(n);
  mean_c /= double(n);
  double a[3][3] = {}, bc[3] = {}, br[3] = {};
  for (auto& [f, c] : samples) {
    glm::dvec3 d = f - mean_f;
    glm::dvec2 e = c - mean_c;
    for (int i = 0; i < dims; ++i) {
      for (int j = 0; j < dims; ++j) a[i][j] += d[i] * d[j];
      bc[i] += d[i] * e.x;
      br[i] += d[i] * e.y;
    }
  }
  // A little ridge: a planar scan has no spread in depth, and its depth coefficient is then 0.
  const double ridge = 1e-12 * (a[0][0] + a[1][1] + a[2][2]) + 1e-300;
  for (int i = 0; i < dims; ++i) a[i][i] += ridge;
  double a2[3][3];
  std::copy(&a[0][0], &a[0][0] + 9, &a2[0][0]);
  double xc[3] = {}, xr[3] = {};
  if (!solve(a, bc, dims, xc) || !solve(a2, br, dims, xr)) return fit;
  fit.col = {xc[0], xc[1], xc[2]};
  fit.row = {xr[0], xr[1], xr[2]};
  fit.col0 = mean_c.x - glm::dot(fit.col, mean_f);
  fit.row0 = mean_c.y - glm::dot(fit.row, mean_f);
  double err = 0;
  for (auto& [f, c] : samples) {
    glm::dvec2 q(glm::dot(fit.col, f) + fit.col0, glm::dot(fit.row, f) + fit.row0);
    glm::dvec2 e = q - c;
    err += glm::dot(e, e);
  }
  fit.rms = std::sqrt(err / double(n));
  return fit;
}

/// rad(p) and normals of every valid pixel (section 5: rad(p) = 2 sqrt(d_k^2 / k); on a grid of
/// spacing s the k nearest points fill a disc of area k s^2, so rad = 2 s / sqrt(pi) = 1.128 s,
/// with s the median distance to the valid 4-neighbours). Normals: PCA over the 5x5 window's
/// points within 4 rad, the [HDD92] estimate restricted to grid neighbours.
void estimateGeometry(RangeMap& m, int threads) {
  const int W = int(m.columns), H = int(m.rows);
  m.radius.assign(m.pixels(), 0.0f);
  m.normals.assign(m.pixels(), glm::vec3(0.0f));
  auto at = [&](int x, int y) -> int {
    if (x < 0 || y < 0 || x >= W || y >= H) return -1;
    int i = y * W + x;
    return m.valid[size_t(i)] ? i : -1;
  };
  const unsigned workers = threadCount(threads);
  parallelFor(size_t(H), workers, [&](size_t yy) {
    int y = int(yy);
    for (int x = 0; x < W; ++x) {
      int i = y * W + x;
      if (!m.valid[size_t(i)]) continue;
      glm::vec3 p = m.positions[size_t(i)];
      std::array<float, 4> d{};
      int k = 0;
      const int nb[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
      for (auto& o : nb) {
        int j = at(x + o[0], y + o[1]);
        if (j >= 0) d[k++] = glm::length(m.positions[size_t(j)] - p);
      }
      std::sort(d.begin(), d.begin() + k);
      // The second smallest: one neighbour across a depth jump does not inflate the radius.
      float s = k == 0 ? 0.0f : d[k >= 2 ? 1 : 0];
      m.radius[size_t(i)] = 1.128f * s;
    }
  });
  // Pixels without neighbours (and the degenerate) take the map's median radius.
  std::vector<float> radii;
  for (size_t i = 0; i < m.pixels(); ++i)
    if (m.valid[i] && m.radius[i] > 0) radii.push_back(m.radius[i]);
  float median = 0;
  if (!radii.empty()) {
    std::nth_element(radii.begin(), radii.begin() + ptrdiff_t(radii.size() / 2), radii.end());
    median = radii[radii.size() / 2];
  }
  for (size_t i = 0; i < m.pixels(); ++i) {
    if (!m.valid[i]) continue;
    if (!(m.radius[i] > 0)) m.radius[i] = median;
    m.radius[i] = std::min(m.radius[i], 8.0f * median);  // isolated points across a gap
  }
  parallelFor(size_t(H), workers, [&](size_t yy) {
    int y = int(yy);
    for (int x = 0; x < W; ++x) {
      int i = y * W + x;
      if (!m.valid[size_t(i)]) continue;
      glm::dvec3 p(m.positions[size_t(i)]);
      const double reach = 4.0 * m.radius[size_t(i)];
      const glm::dvec3 toward = m.towardScanner(p);
      // Candidates: the centred 5x5 window and the four 3x3 windows with p at a corner; the
      // flattest wins (least mean squared distance to its plane), the 5x5 unless a corner is
      // much flatter. On a crease the 5x5 mixes both faces; one corner window lies on p's own.
      const int windows[5][4] = {
          {-2, 2, -2, 2}, {0, 2, 0, 2}, {-2, 0, 0, 2}, {0, 2, -2, 0}, {-2, 0, -2, 0}};
      glm::dvec3 normal = toward;
      double best = std::numeric_limits<double>::max();
      for (int wi = 0; wi < 5; ++wi) {
        const int* w = windows[wi];
        glm::dvec3 pts[25];
        glm::dvec3 sum(0.0);
        int n = 0;
        for (int dy = w[2]; dy <= w[3]; ++dy)
          for (int dx = w[0]; dx <= w[1]; ++dx) {
            int j = at(x + dx, y + dy);
            if (j < 0) continue;
            glm::dvec3 q(m.positions[size_t(j)]);
            if (glm::length(q - p) > reach) continue;
            pts[n++] = q;
            sum += q;
          }
        if (n < 4) continue;
        glm::dvec3 c = sum / double(n);
        glm::dmat3 cov(0.0);
        for (int k = 0; k < n; ++k) cov += glm::outerProduct(pts[k] - c, pts[k] - c);
        const glm::dvec3 e = tessera::smallestEigenvector(cov);
        if (!(glm::length(e) > 0.5)) continue;  // NaN
        double residual = 0;
        for (int k = 0; k < n; ++k) residual += glm::dot(pts[k] - c, e) * glm::dot(pts[k] - c, e);
        residual /= n;
        if (wi > 0) residual *= 4.0;  // 9 points against 25: the 5x5 is less noisy
        if (residual < best) {
          best = residual;
          normal = e;
        }
      }
      if (glm::dot(normal, toward) < 0) normal = -normal;
      m.normals[size_t(i)] = glm::vec3(normal);
    }
  });
}

/// Fills the projection of a map whose grid is given: the model whose least-squares fit puts
/// the points nearest their own pixels.
void chooseProjection(RangeMap& m) {
  Fit best;
  ScanProjection which = ScanProjection::kOrthographic;
  for (ScanProjection p :
       {ScanProjection::kOrthographic, ScanProjection::kPerspective, ScanProjection::kPanoramic}) {
    Fit f = fitProjection(m, p);
    if (f.rms < best.rms) {
      best = f;
      which = p;
    }
  }
  m.projection = which;
  m.col_axis = best.col;
  m.row_axis = best.row;
  m.col_offset = best.col0;
  m.row_offset = best.row0;
  m.fit_rms_px = best.rms;
  if (which == ScanProjection::kOrthographic) {
    glm::dvec3 v = glm::cross(best.col, best.row);
    m.view = glm::length(v) > 0 ? glm::normalize(v) : glm::dvec3(0, 0, 1);
    if (m.view.z < 0) m.view = -m.view;  // scanners look along -z
  }
}

/// The paper's fallback for scans without a depth map: orthographic projection along -z of the
/// scanner frame into a grid of the declared size, or of about one point per pixel. Where two
/// points fall in a pixel the nearer the scanner holds it; the other shares its values.
void projectScan(RangeMap& m, const std::vector<glm::dvec3>& local, std::vector<uint32_t>& pixel_of,
                 const std::string& source) {
  if (local.size() < 3)
    throw AoError(std::string(kWho) + ": " + source + ": scan '" + m.name +
                  "' has no range grid and " + std::to_string(local.size()) +
                  " points: too few to project into one");
  glm::dvec2 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  for (auto& p : local) {
    lo = glm::min(lo, glm::dvec2(p));
    hi = glm::max(hi, glm::dvec2(p));
  }
  glm::dvec2 ext = hi - lo;
  if (!(ext.x > 0) || !(ext.y > 0))
    throw AoError(std::string(kWho) + ": " + source + ": scan '" + m.name +
                  "' has no range grid and its points have no extent across the view axis: "
                  "it cannot be projected into one");
  double pitch;
  if (m.columns > 0 && m.rows > 0) {
    pitch = std::max(ext.x / (m.columns - 0.5), ext.y / (m.rows - 0.5));
  } else {
    pitch = std::sqrt(ext.x * ext.y / double(local.size()));
    m.columns = uint32_t(std::min(65535.0, std::floor(ext.x / pitch) + 1));
    m.rows = uint32_t(std::min(65535.0, std::floor(ext.y / pitch) + 1));
    pitch = std::max(ext.x / (m.columns - 0.5), ext.y / (m.rows - 0.5));
  }
  m.projection = ScanProjection::kOrthographic;
  m.projected = true;
  m.col_axis = {1.0 / pitch, 0, 0};
  m.row_axis = {0, -1.0 / pitch, 0};
  m.col_offset = -lo.x / pitch;
  m.row_offset = hi.y / pitch;
  m.view = {0, 0, 1};
  m.valid.assign(m.pixels(), 0);
  m.positions.assign(m.pixels(), glm::vec3(kNaN));
  pixel_of.resize(local.size());
  for (size_t i = 0; i < local.size(); ++i) {
    glm::dvec2 c = m.pixelOf(local[i]);
    uint32_t x = uint32_t(std::clamp(std::lround(c.x), 0l, long(m.columns) - 1));
    uint32_t y = uint32_t(std::clamp(std::lround(c.y), 0l, long(m.rows) - 1));
    size_t px = size_t(y) * m.columns + x;
    pixel_of[i] = uint32_t(px);
    if (!m.valid[px] || local[i].z > m.positions[px].z) {
      m.valid[px] = 1;
      m.positions[px] = glm::vec3(local[i]);
    }
  }
  m.fit_rms_px = 0;
}

glm::dvec3 toLocal(const RigidPose& pose, const glm::dvec3& world) {
  return glm::conjugate(pose.rotation) * (world - pose.translation);
}

void checkValue(double v, const char* name, bool allow_zero) {
  if (!std::isfinite(v) || v < 0 || (!allow_zero && v == 0))
    throw AoError(std::string(kWho) + ": " + name + " must be a " +
                  (allow_zero ? "non-negative" : "positive") + " finite number (got " +
                  std::to_string(v) + ")");
}

/// Builds the per-scan maps of a set whose points are known (positions relative to `origin`).
/// `grid` holds each point's (column, row), 0xFFFF when its scan has none.
void buildMaps(ScanSet& set, std::vector<ScanInfo> infos, const std::vector<glm::u16vec2>& grid,
               const RangeMapOptions& options) {
  const std::string source = set.source.string();
  set.maps.clear();
  set.pixel_of_point.assign(set.size(), kNoPixel);
  for (size_t s = 0; s < infos.size(); ++s) {
    RangeMap m;
    m.name = infos[s].name;
    m.pose = infos[s].pose;
    m.columns = infos[s].grid_columns;
    m.rows = infos[s].grid_rows;
    std::vector<size_t> members;
    std::vector<glm::dvec3> local;
    bool gridded = true;
    uint32_t max_c = 0, max_r = 0;
    for (size_t i = 0; i < set.size(); ++i) {
      if (set.scan_of_point[i] != s) continue;
      members.push_back(i);
      local.push_back(toLocal(m.pose, set.origin + set.positions[i]));
      if (grid.empty() || grid[i].x == 0xFFFF) {
        gridded = false;
      } else {
        max_c = std::max<uint32_t>(max_c, grid[i].x);
        max_r = std::max<uint32_t>(max_r, grid[i].y);
      }
    }
    if (gridded && !members.empty()) {
      if (m.columns <= max_c || m.rows <= max_r) {
        m.columns = std::max(m.columns, max_c + 1);
        m.rows = std::max(m.rows, max_r + 1);
      }
      m.valid.assign(m.pixels(), 0);
      m.positions.assign(m.pixels(), glm::vec3(kNaN));
      for (size_t k = 0; k < members.size(); ++k) {
        size_t i = members[k];
        size_t px = size_t(grid[i].y) * m.columns + grid[i].x;
        set.pixel_of_point[i] = uint32_t(px);
        if (!m.valid[px]) {
          m.valid[px] = 1;
          m.positions[px] = glm::vec3(local[k]);
        }
      }
      chooseProjection(m);
    } else {
      if (!options.allow_projection)
        throw AoError(std::string(kWho) + ": " + source + ": scan '" + m.name +
                      "' has no range grid (and projecting its points into one is turned off)");
      std::vector<uint32_t> pix;
      projectScan(m, local, pix, source);
      for (size_t k = 0; k < members.size(); ++k) set.pixel_of_point[members[k]] = pix[k];
    }
    estimateGeometry(m, options.threads);
    set.maps.push_back(std::move(m));
  }
}

double sceneDiagonal(const ScanSet& s) {
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  for (auto& p : s.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  return s.positions.empty() ? 0.0 : glm::length(hi - lo);
}

/// d_min, d_max of eq. 10 over every central (perspective, panoramic) map: the nearest and
/// farthest depth scanned.
std::pair<double, double> depthRange(const ScanSet& s) {
  double lo = std::numeric_limits<double>::max(), hi = 0;
  for (auto& m : s.maps) {
    if (m.projection == ScanProjection::kOrthographic) continue;
    for (size_t i = 0; i < m.pixels(); ++i) {
      if (!m.valid[i]) continue;
      double d = glm::length(glm::dvec3(m.positions[i]));
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
  }
  if (hi == 0) return {0.0, 1.0};
  return {lo, hi};
}

/// Eq. 10: closer scanners see finer detail. Orthographic scans keep one resolution: 1.
inline double distanceWeight(const RangeMap& m, const glm::dvec3& local, double d_min,
                             double d_max) {
  if (m.projection == ScanProjection::kOrthographic) return 1.0;
  return std::max(1.0 - std::max(m.depth(local) - d_min, 0.0) / d_max, 0.1);
}

}  // namespace

const char* projectionName(ScanProjection p) {
  switch (p) {
    case ScanProjection::kOrthographic:
      return "orthographic";
    case ScanProjection::kPerspective:
      return "perspective";
    case ScanProjection::kPanoramic:
      return "panoramic";
  }
  return "?";
}

glm::dvec2 RangeMap::pixelOf(const glm::dvec3& local) const {
  glm::dvec3 f = features(projection, local);
  return {glm::dot(col_axis, f) + col_offset, glm::dot(row_axis, f) + row_offset};
}

glm::dvec3 RangeMap::towardScanner(const glm::dvec3& local) const {
  if (projection == ScanProjection::kOrthographic) return view;
  double len = glm::length(local);
  return len > 0 ? -local / len : glm::dvec3(0, 0, 1);
}

double RangeMap::depth(const glm::dvec3& local) const {
  return projection == ScanProjection::kOrthographic ? 0.0 : glm::length(local);
}

glm::dvec2 RangeMap::pixelSize(const glm::dvec3& local) const {
  // Pixels per world unit across the view direction, from the fitted map's derivatives.
  switch (projection) {
    case ScanProjection::kOrthographic: {
      glm::dvec3 c = col_axis - glm::dot(col_axis, view) * view;
      glm::dvec3 r = row_axis - glm::dot(row_axis, view) * view;
      return {1.0 / std::max(glm::length(c), 1e-300), 1.0 / std::max(glm::length(r), 1e-300)};
    }
    case ScanProjection::kPerspective: {
      double z = std::max(-local.z, 1e-12);
      return {z / std::max(glm::length(glm::dvec2(col_axis)), 1e-300),
              z / std::max(glm::length(glm::dvec2(row_axis)), 1e-300)};
    }
    case ScanProjection::kPanoramic: {
      double len = glm::length(local);
      double horiz = std::max(std::sqrt(local.x * local.x + local.z * local.z), 1e-12);
      return {horiz / std::max(std::abs(col_axis.x), 1e-300),
              len / std::max(std::abs(row_axis.y), 1e-300)};
    }
  }
  return {1.0, 1.0};
}

glm::dvec3 ScanSet::normal(size_t i) const {
  const RangeMap& m = maps[scan_of_point[i]];
  return m.pose.rotation * glm::dvec3(m.normals[pixel_of_point[i]]);
}

ScanSet loadScans(const std::filesystem::path& path, const RangeMapOptions& options) {
  auto reader = openPointReader(path);
  const SourceInfo& info = reader->info();
  ScanSet set;
  set.source = path;
  set.origin = info.origin;
  std::vector<ScanInfo> scans = info.scans;
  if (scans.empty())
    throw AoError(std::string(kWho) + ": " + path.string() + ": " + formatName(info.format) +
                  " file with no range scans: ambient occlusion needs scans with poses (a "
                  "Stanford .conf, a range-grid PLY or an E57)");
  const bool has_index = info.attributes & kScanIndex;
  const bool has_grid = info.attributes & kGridPosition;
  std::vector<glm::u16vec2> grid;
  PointBatch batch;
  while (reader->next(batch)) {
    for (size_t i = 0; i < batch.size(); ++i) {
      set.positions.push_back(batch.positions[i]);
      uint16_t s = has_index ? batch.scan_indices[i] : 0;
      if (s >= scans.size())
        throw AoError(std::string(kWho) + ": " + path.string() + ": point " +
                      std::to_string(set.positions.size() - 1) + " names scan " +
                      std::to_string(s) + " of " + std::to_string(scans.size()));
      set.scan_of_point.push_back(s);
      grid.push_back(has_grid ? batch.grid_positions[i] : glm::u16vec2(0xFFFF));
    }
  }
  if (set.positions.empty())
    throw AoError(std::string(kWho) + ": " + path.string() + ": no points");
  buildMaps(set, std::move(scans), grid, options);
  return set;
}

ScanSet makeScanSet(const std::vector<GridScan>& scans, const RangeMapOptions& options) {
  ScanSet set;
  set.source = "memory";
  std::vector<ScanInfo> infos;
  std::vector<glm::u16vec2> grid;
  for (size_t s = 0; s < scans.size(); ++s) {
    const GridScan& g = scans[s];
    TESSERA_CHECK(
        g.points.size() == size_t(g.columns) * g.rows && g.columns < 65535 && g.rows < 65535,
        "lod::makeScanSet(): points must be columns x rows, below 65535 each");
    ScanInfo info;
    info.name = g.name;
    info.pose = g.pose;
    info.grid_columns = g.columns;
    info.grid_rows = g.rows;
    infos.push_back(info);
    for (uint32_t r = 0; r < g.rows; ++r)
      for (uint32_t c = 0; c < g.columns; ++c) {
        const glm::vec3& p = g.points[size_t(r) * g.columns + c];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
        set.positions.push_back(g.pose.apply(glm::dvec3(p)));
        set.scan_of_point.push_back(uint16_t(s));
        grid.emplace_back(c, r);
      }
  }
  if (scans.empty() || set.positions.empty())
    throw AoError(std::string(kWho) + ": memory: no scans with points");
  buildMaps(set, std::move(infos), grid, options);
  return set;
}

AoOptions resolveAoOptions(const ScanSet& scans, AoOptions o) {
  checkValue(o.t_max, "t_max", true);
  checkValue(o.radius, "radius", true);
  checkValue(o.border_px, "border distance t_p", false);
  checkValue(o.grid_cell, "grid cell", true);
  if (!std::isfinite(o.angle_bias) || o.angle_bias < 0 || o.angle_bias >= 0.5)
    throw AoError(std::string(kWho) + ": angle bias must be in [0, 0.5) (got " +
                  std::to_string(o.angle_bias) + ")");
  if (o.samples < 1 || o.samples > 4096)
    throw AoError(std::string(kWho) + ": samples must be 1..4096 (got " +
                  std::to_string(o.samples) + ")");
  if (o.neighbours != 1 && o.neighbours != 3 && o.neighbours != 5)
    throw AoError(std::string(kWho) + ": neighbours must be 1, 3 or 5 (got " +
                  std::to_string(o.neighbours) + ")");
  if (o.t_max == 0) o.t_max = 0.05 * sceneDiagonal(scans);
  if (o.radius == 0) o.radius = 0.5 * o.t_max;
  if (!(o.t_max > 0))
    throw AoError(std::string(kWho) + ": " + scans.source.string() +
                  ": the points have no extent: give t_max");
  if (o.grid_cell == 0) {
    std::vector<float> r;
    for (auto& m : scans.maps)
      for (size_t i = 0; i < m.pixels(); i += 7)
        if (m.valid[i]) r.push_back(m.radius[i]);
    double med = 0;
    if (!r.empty()) {
      std::nth_element(r.begin(), r.begin() + ptrdiff_t(r.size() / 2), r.end());
      med = r[r.size() / 2];
    }
    o.grid_cell = med > 0 ? 2.0 * med : o.t_max / 8;
  }
  return o;
}

void computeSsao(RangeMap& m, uint32_t scan_index, const AoOptions& o) {
  const int W = int(m.columns), H = int(m.rows);
  std::vector<float> raw(m.pixels(), kNaN);
  const double inv_t = 1.0 / o.t_max;
  parallelFor(size_t(H), threadCount(o.threads), [&](size_t yy) {
    int y = int(yy);
    for (int x = 0; x < W; ++x) {
      size_t i = size_t(y) * W + size_t(x);
      if (!m.valid[i]) continue;
      glm::dvec3 p(m.positions[i]);
      glm::dvec3 n(m.normals[i]);
      // The disk of eq. 3: the sphere of radius r_s around p moved onto the view axis at p's
      // depth, so its image is a circle (an ellipse where pixels are not square).
      glm::dvec2 size = m.pixelSize(p);
      double rx = o.radius / size.x, ry = o.radius / size.y;
      uint64_t state =
          splitmix64(o.seed * 0x9E3779B97F4A7C15ull ^ (uint64_t(scan_index) << 40) ^ uint64_t(i));
      double occlusion = 0;
      for (int k = 0; k < o.samples; ++k) {
        uint64_t h1 = splitmix64(state + 2 * uint64_t(k));
        uint64_t h2 = splitmix64(state + 2 * uint64_t(k) + 1);
        double r = std::sqrt(unitFloat(h1)), th = 2.0 * std::numbers::pi * unitFloat(h2);
        long sx = x + std::lround(r * std::cos(th) * rx);
        long sy = y + std::lround(r * std::sin(th) * ry);
        if ((sx == x && sy == y) || sx < 0 || sy < 0 || sx >= W || sy >= H) continue;
        size_t j = size_t(sy) * W + size_t(sx);
        if (!m.valid[j]) continue;  // nothing scanned there: open space
        glm::dvec3 v = glm::dvec3(m.positions[j]) - p;
        double d = glm::length(v);
        if (!(d > 0)) continue;
        // Eq. 3-5 as a visibility: a sample is open when it is far (rho = 1, eq. 4) or not above
        // the tangent plane (w = 1, eq. 5); its occlusion is (1 - rho)(1 - w). The literal
        // product rho * w darkens a plane to 0.7 (samples nearer than t_max have rho < 1).
        // With an angle bias beta, elevations below asin(beta) count as the tangent plane
        // (AoOptions::angle_bias).
        double rho = smoothstep01(d * inv_t);
        const double w =
            1.0 - std::max(glm::dot(n, v) / d - o.angle_bias, 0.0) / (1.0 - o.angle_bias);
        occlusion += (1.0 - rho) * (1.0 - w);
      }
      raw[i] = float(1.0 - occlusion / o.samples);
    }
  });
  if (!o.blur) {
    m.ssao = std::move(raw);
    return;
  }
  // Section 4's 5x5 Gaussian (binomial 1 4 6 4 1), over valid pixels on the same surface
  // (within 6 rad(p)): blurring across a depth edge would mix two surfaces' AO.
  m.ssao.assign(m.pixels(), kNaN);
  const float g[5] = {1, 4, 6, 4, 1};
  parallelFor(size_t(H), threadCount(o.threads), [&](size_t yy) {
    int y = int(yy);
    for (int x = 0; x < W; ++x) {
      size_t i = size_t(y) * W + size_t(x);
      if (!m.valid[i]) continue;
      glm::vec3 p = m.positions[i];
      float reach = 6.0f * m.radius[i];
      float sum = 0, wsum = 0;
      for (int dy = -2; dy <= 2; ++dy) {
        int qy = y + dy;
        if (qy < 0 || qy >= H) continue;
        for (int dx = -2; dx <= 2; ++dx) {
          int qx = x + dx;
          if (qx < 0 || qx >= W) continue;
          size_t j = size_t(qy) * W + size_t(qx);
          if (!m.valid[j] || glm::length(m.positions[j] - p) > reach) continue;
          float w = g[dx + 2] * g[dy + 2];
          sum += w * raw[j];
          wsum += w;
        }
      }
      m.ssao[i] = sum / wsum;
    }
  });
}

void computeBorders(RangeMap& m, int threads) {
  const int W = int(m.columns), H = int(m.rows);
  auto depthAt = [&](size_t i) {
    glm::dvec3 p(m.positions[i]);
    return m.projection == ScanProjection::kOrthographic ? glm::dot(p, m.view) : -glm::length(p);
  };
  // |Laplacian| of depth; pixels missing a 4-neighbour are edges (the scanned area's rim).
  std::vector<float> lap(m.pixels(), -1.0f);
  std::vector<uint8_t> edge(m.pixels(), 1);
  std::vector<float> values;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      size_t i = size_t(y) * W + size_t(x);
      if (!m.valid[i]) continue;
      if (x == 0 || y == 0 || x == W - 1 || y == H - 1) continue;
      size_t nb[4] = {i - 1, i + 1, i - size_t(W), i + size_t(W)};
      bool full = true;
      double s = 0;
      for (size_t j : nb) {
        if (!m.valid[j]) {
          full = false;
          break;
        }
        s += depthAt(j);
      }
      if (!full) continue;
      lap[i] = float(std::abs(4.0 * depthAt(i) - s));
      values.push_back(lap[i]);
    }
  float threshold = std::numeric_limits<float>::infinity();
  if (!values.empty()) {
    auto k = values.begin() + ptrdiff_t(double(values.size()) * 0.95);
    std::nth_element(values.begin(), k, values.end());
    threshold = *k;
  }
  for (size_t i = 0; i < m.pixels(); ++i) {
    if (lap[i] < 0) continue;  // invalid or rim: an edge
    // The 95th percentile of eq. 12's edge map, but never below 2 rad(p): a smooth scan's
    // curvature is not a depth discontinuity.
    edge[i] = lap[i] > std::max(threshold, 2.0f * m.radius[i]) ? 1 : 0;
  }
  // Exact squared Euclidean distance transform (Felzenszwalb and Huttenlocher 2012): columns,
  // then rows, each a lower envelope of parabolas.
  const float inf = 1e20f;
  std::vector<float> f(m.pixels());
  for (size_t i = 0; i < m.pixels(); ++i) f[i] = edge[i] ? 0.0f : inf;
  const float zinf = std::numeric_limits<float>::infinity();
  auto pass = [&](size_t count, size_t stride, size_t lines, size_t line_stride) {
    parallelFor(lines, threadCount(threads), [&](size_t l) {
      std::vector<float> in(count), out(count), z(count + 1);
      std::vector<int> v(count);
      for (size_t q = 0; q < count; ++q) in[q] = f[l * line_stride + q * stride];
      int k = 0;
      v[0] = 0;
      z[0] = -zinf;
      z[1] = zinf;
      auto meet = [&](int q, int r) {
        return ((in[size_t(q)] + float(q) * float(q)) - (in[size_t(r)] + float(r) * float(r))) /
               float(2 * q - 2 * r);
      };
      for (int q = 1; q < int(count); ++q) {
        float s = meet(q, v[size_t(k)]);
        while (s <= z[size_t(k)]) {  // z[0] = -inf stops this at k = 0
          --k;
          s = meet(q, v[size_t(k)]);
        }
        ++k;
        v[size_t(k)] = q;
        z[size_t(k)] = s;
        z[size_t(k) + 1] = zinf;
      }
      k = 0;
      for (int q = 0; q < int(count); ++q) {
        while (z[size_t(k) + 1] < float(q)) ++k;
        int r = v[size_t(k)];
        out[size_t(q)] = float(q - r) * float(q - r) + in[size_t(r)];
      }
      for (size_t q = 0; q < count; ++q) f[l * line_stride + q * stride] = out[q];
    });
  };
  pass(size_t(H), size_t(W), size_t(W), 1);  // columns
  pass(size_t(W), 1, size_t(H), size_t(W));  // rows
  m.border_px.assign(m.pixels(), 0.0f);
  for (size_t i = 0; i < m.pixels(); ++i) m.border_px[i] = std::sqrt(std::min(f[i], inf));
}

std::vector<float> ownSsao(const ScanSet& s) {
  std::vector<float> out(s.size());
  for (size_t i = 0; i < s.size(); ++i)
    out[i] = s.maps[s.scan_of_point[i]].ssao[s.pixel_of_point[i]];
  return out;
}

std::vector<float> integrateMvao(const ScanSet& s, const AoOptions& o,
                                 std::vector<float>* own_share) {
  const auto [d_min, d_max] = depthRange(s);
  const int half = o.neighbours / 2;
  std::vector<float> out(s.size());
  if (own_share) own_share->assign(s.size(), 1.0f);
  const size_t block = 4096;
  parallelFor((s.size() + block - 1) / block, threadCount(o.threads), [&](size_t b) {
    for (size_t i = b * block; i < std::min(s.size(), (b + 1) * block); ++i) {
      const uint32_t si = s.scan_of_point[i];
      double own_w = 0;
      const RangeMap& own = s.maps[si];
      const uint32_t own_px = s.pixel_of_point[i];
      const glm::dvec3 world = s.origin + s.positions[i];
      const double rad_i = own.radius[own_px];
      // Direction towards scanner i in the registered frame (eq. 7's b - p).
      const glm::dvec3 toward_i = own.pose.rotation * own.towardScanner(toLocal(own.pose, world));
      const glm::dvec3 normal_i = own.pose.rotation * glm::dvec3(own.normals[own_px]);
      double sum = 0, wsum = 0;
      for (size_t j = 0; j < s.maps.size(); ++j) {
        const RangeMap& m = s.maps[j];
        const int W = int(m.columns), H = int(m.rows);
        // Eq. 6: p_i into scan j's frame, projected into its grid.
        const glm::dvec3 q = toLocal(m.pose, world);
        // A scanner acquires only surfaces that face it: where p_i's surface faces away from
        // scanner j, p_ij would have w_n = 0 (eq. 11), and the projection is not worth making.
        if (j != si &&
            glm::dot(glm::conjugate(m.pose.rotation) * normal_i, m.towardScanner(q)) <= 0)
          continue;
        long cx, cy;
        if (j == si) {
          cx = long(own_px % m.columns);
          cy = long(own_px / m.columns);
        } else {
          glm::dvec2 c = m.pixelOf(q);
          if (!(c.x > -1.5 && c.y > -1.5 && c.x < W + 0.5 && c.y < H + 0.5)) continue;
          // proj() returns the acquired point: the nearest of the 3x3 pixels around the
          // fitted position (the fit is within a pixel or two of the scanner's own mapping).
          long bx = std::lround(c.x), by = std::lround(c.y);
          double best = std::numeric_limits<double>::max();
          cx = -1;
          for (long dy = -1; dy <= 1; ++dy)
            for (long dx = -1; dx <= 1; ++dx) {
              long x = bx + dx, y = by + dy;
              if (x < 0 || y < 0 || x >= W || y >= H) continue;
              size_t k = size_t(y) * size_t(W) + size_t(x);
              if (!m.valid[k]) continue;
              double d = glm::length(glm::dvec3(m.positions[k]) - q);
              if (d < best) {
                best = d;
                cx = x;
                cy = y;
              }
            }
          if (cx < 0) continue;
        }
        const size_t pij = size_t(cy) * size_t(W) + size_t(cx);
        const glm::dvec3 p_ij(m.positions[pij]);
        // Eq. 7: near p_i (within twice the larger radius) and facing scanner i.
        const double t = std::max(rad_i, double(m.radius[pij]));
        if (j != si && glm::length(q - p_ij) >= 2.0 * t) continue;
        const glm::dvec3 toward_i_j = glm::conjugate(m.pose.rotation) * toward_i;
        if (glm::dot(glm::dvec3(m.normals[pij]), toward_i_j) <= 0) continue;
        // Eq. 8 with N = (2 half + 1)^2 grid neighbours of p_ij, each weighted by eq. 9.
        const double reach = (3.0 * half + 0.5) * m.radius[pij];
        for (long dy = -half; dy <= half; ++dy)
          for (long dx = -half; dx <= half; ++dx) {
            long x = cx + dx, y = cy + dy;
            if (x < 0 || y < 0 || x >= W || y >= H) continue;
            size_t k = size_t(y) * size_t(W) + size_t(x);
            if (!m.valid[k]) continue;
            const glm::dvec3 pk(m.positions[k]);
            if (k != pij && glm::length(pk - p_ij) > reach) continue;
            const glm::dvec3 nk(m.normals[k]);
            const double w_d = distanceWeight(m, pk, d_min, d_max);               // eq. 10
            const double w_n = std::max(glm::dot(nk, m.towardScanner(pk)), 0.0);  // eq. 11
            const double alpha = rad_i / std::max(double(m.radius[k]), 1e-30);
            const double w_b = std::min(m.border_px[k] / (o.border_px * alpha), 1.0);  // eq. 12
            const double w = w_d * w_n * w_b;
            sum += w * m.ssao[k];
            wsum += w;
            if (j == si) own_w += w;
          }
      }
      out[i] = wsum > 0 ? float(sum / wsum) : own.ssao[own_px];
      if (own_share && wsum > 0) (*own_share)[i] = float(own_w / wsum);
    }
  });
  return out;
}

struct MvaoGrid::Impl {
  glm::dvec3 lo;
  double cell;
  std::unordered_map<uint64_t, glm::dvec2> cells;  // Morton key -> (sum SSAO * w, sum w)
  uint64_t key(const glm::ivec3& c) const {
    return mortonEncode(uint64_t(std::clamp(c.x, 0, 0x1FFFFF)),
                        uint64_t(std::clamp(c.y, 0, 0x1FFFFF)),
                        uint64_t(std::clamp(c.z, 0, 0x1FFFFF)));
  }
};

MvaoGrid::MvaoGrid(const glm::dvec3& lo, double cell) : mImpl(std::make_shared<Impl>()) {
  TESSERA_CHECK(cell > 0 && std::isfinite(cell), "lod::MvaoGrid(): cell must be positive");
  // One cell of margin so trilinear lookups never step below the grid's origin.
  mImpl->lo = lo - glm::dvec3(cell);
  mImpl->cell = cell;
}

void MvaoGrid::addScan(const RangeMap& m, const glm::dvec3& origin, double d_min, double d_max) {
  for (size_t i = 0; i < m.pixels(); ++i) {
    if (!m.valid[i]) continue;
    const glm::dvec3 pk(m.positions[i]);
    // Section 6: eq. 9 without w_b; the grid's averaging stands in for it.
    const double w = distanceWeight(m, pk, d_min, d_max) *
                     std::max(glm::dot(glm::dvec3(m.normals[i]), m.towardScanner(pk)), 0.0);
    if (!(w > 0)) continue;
    const glm::dvec3 p = m.pose.apply(pk) - origin;
    const glm::ivec3 c(glm::floor((p - mImpl->lo) / mImpl->cell));
    glm::dvec2& acc = mImpl->cells[mImpl->key(c)];
    acc += glm::dvec2(w * m.ssao[i], w);
  }
}

float MvaoGrid::value(const glm::dvec3& p) const {
  // Trilinear between the 8 cell centres around p: the nearest cell alone shows the voxels.
  const glm::dvec3 g = (p - mImpl->lo) / mImpl->cell - 0.5;
  const glm::ivec3 base(glm::floor(g));
  const glm::dvec3 f = g - glm::dvec3(base);
  double sum = 0, wsum = 0;
  for (int k = 0; k < 8; ++k) {
    glm::ivec3 c = base + glm::ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);
    auto it = mImpl->cells.find(mImpl->key(c));
    if (it == mImpl->cells.end() || !(it->second.y > 0)) continue;
    double t = (k & 1 ? f.x : 1 - f.x) * (k & 2 ? f.y : 1 - f.y) * (k & 4 ? f.z : 1 - f.z);
    sum += t * it->second.x / it->second.y;
    wsum += t;
  }
  return wsum > 0 ? float(sum / wsum) : -1.0f;
}

size_t MvaoGrid::cells() const {
  return mImpl->cells.size();
}

std::vector<float> gridMvao(const ScanSet& s, const AoOptions& o) {
  glm::dvec3 lo(std::numeric_limits<double>::max());
  for (auto& p : s.positions) lo = glm::min(lo, p);
  const auto [d_min, d_max] = depthRange(s);
  MvaoGrid grid(lo, o.grid_cell);
  for (const RangeMap& m : s.maps) grid.addScan(m, s.origin, d_min, d_max);
  std::vector<float> out(s.size());
  parallelFor(s.size(), threadCount(o.threads), [&](size_t i) {
    float v = grid.value(s.positions[i]);
    out[i] = v >= 0 ? v : s.maps[s.scan_of_point[i]].ssao[s.pixel_of_point[i]];
  });
  return out;
}

std::vector<float> computeAmbientOcclusion(ScanSet& s, AoMethod method, const AoOptions& o) {
  for (size_t j = 0; j < s.maps.size(); ++j) computeSsao(s.maps[j], uint32_t(j), o);
  switch (method) {
    case AoMethod::kSsao:
      return ownSsao(s);
    case AoMethod::kMvao:
      for (auto& m : s.maps) computeBorders(m, o.threads);
      return integrateMvao(s, o);
    case AoMethod::kGrid:
      return gridMvao(s, o);
  }
  return {};
}

bool grazingPoint(const ScanSet& s, size_t i) {
  const RangeMap& m = s.maps[s.scan_of_point[i]];
  const size_t px = s.pixel_of_point[i];
  const glm::dvec3 p(m.positions[px]);
  return glm::dot(glm::dvec3(m.normals[px]), m.towardScanner(p)) < 0.5;  // > 60 degrees
}

bool borderPoint(const ScanSet& s, size_t i) {
  const RangeMap& m = s.maps[s.scan_of_point[i]];
  return !m.border_px.empty() && m.border_px[s.pixel_of_point[i]] <= 8.0f;
}

}  // namespace tessera::lod
