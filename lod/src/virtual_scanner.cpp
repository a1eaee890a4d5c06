#include <tessera/lod/virtual_scanner.h>

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <system_error>
#include <thread>

#include <tessera/core/parallel.h>
#include <tessera/core/check.h>
#include <tessera/core/progress.h>
#include <glm/gtc/quaternion.hpp>

#include "splitmix.h"

namespace tessera::lod {
namespace {

/// Noise depends only on (seed, scanner, cell) / (seed, triangle), never on threads.
uint64_t mix(uint64_t x) { return splitmix64(x); }

double gaussian(uint64_t key) {
  // Box-Muller from two hashed uniforms in (0, 1].
  double u1 = (double(mix(key) >> 11) + 1.0) * 0x1.0p-53;
  double u2 = double(mix(key ^ 0xA5A5A5A5A5A5A5A5ull) >> 11) * 0x1.0p-53;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

struct EmbreeScene {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  EmbreeScene() = default;
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;
  ~EmbreeScene() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

/// One scanner: its pose and how a grid cell maps to a ray in the scanner's frame
/// (scanner at the origin; perspective looks down -z with +y up).
struct Scanner {
  RigidPose pose;
  glm::dmat3 rot;
  bool panoramic = false;
  double tan_half_x = 0, tan_half_y = 0;

  glm::dvec3 localDirection(uint32_t col, uint32_t row, uint32_t cols, uint32_t rows) const {
    double u = (col + 0.5) / cols, v = (row + 0.5) / rows;
    if (panoramic) {
      double az = u * 2.0 * std::numbers::pi;
      double el = (0.5 - v) * (150.0 / 180.0) * std::numbers::pi;  // +75 .. -75 degrees
      return {std::cos(el) * std::sin(az), std::sin(el), -std::cos(el) * std::cos(az)};
    }
    // Row 0 at the top of the image, as in a range image.
    return glm::normalize(
        glm::dvec3((2.0 * u - 1.0) * tan_half_x, (1.0 - 2.0 * v) * tan_half_y, -1.0));
  }
};

/// Rotation whose columns are the scanner's right, up and back axes, looking from eye to target.
glm::dquat lookRotation(const glm::dvec3& eye, const glm::dvec3& target) {
  glm::dvec3 back = glm::normalize(eye - target);
  glm::dvec3 up_hint = std::abs(back.y) > 0.95 ? glm::dvec3(0, 0, 1) : glm::dvec3(0, 1, 0);
  glm::dvec3 right = glm::normalize(glm::cross(up_hint, back));
  glm::dvec3 up = glm::cross(back, right);
  return glm::normalize(glm::quat_cast(glm::dmat3(right, up, back)));
}

std::vector<Scanner> placeScanners(const ScanOptions& o, const glm::dvec3& center, double radius,
                                   const glm::dvec3& half_extent) {
  std::vector<Scanner> out;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < o.scanners; ++i) {
    Scanner s;
    s.panoramic = o.panoramic;
    // Fibonacci sphere: evenly spread directions, deterministic.
    double y = o.scanners == 1 ? 0.0 : 1.0 - 2.0 * (i + 0.5) / o.scanners;
    double r = std::sqrt(std::max(0.0, 1.0 - y * y));
    glm::dvec3 dir(std::cos(golden * i) * r, y * 0.8, std::sin(golden * i) * r);
    dir = glm::normalize(dir);
    if (o.panoramic) {
      // Inside the model's box, spread over its middle third.
      s.pose.translation = center + dir * half_extent * 0.33;
      s.pose.rotation = glm::dquat(1, 0, 0, 0);
    } else {
      double dist = radius * 2.5;
      s.pose.translation = center + dir * dist;
      s.pose.rotation = lookRotation(s.pose.translation, center);
      double half = std::asin(std::min(1.0, radius / dist)) * 1.05;
      double aspect = double(o.columns) / double(o.rows);
      s.tan_half_y = std::tan(half) * (aspect >= 1.0 ? 1.0 : 1.0 / aspect);
      s.tan_half_x = s.tan_half_y * aspect;
    }
    s.rot = glm::mat3_cast(s.pose.rotation);
    out.push_back(s);
  }
  return out;
}

struct Hit {
  glm::vec3 local;  // scanner frame
  bool valid = false;
};

void writeScan(const std::filesystem::path& file, const std::vector<Hit>& hits,
               const ScanOptions& o) {
  uint64_t n = std::count_if(hits.begin(), hits.end(), [](const Hit& h) { return h.valid; });
  std::ofstream out(file, std::ios::binary);
  if (!out) throw std::runtime_error("lod::scanMesh(): cannot write " + file.string());
  out << "ply\nformat " << (o.binary ? "binary_little_endian" : "ascii") << " 1.0\n"
      << "obj_info is_cyberware_data 0\nobj_info is_mesh 0\nobj_info is_warped 0\n"
      << "obj_info is_interlaced 0\nobj_info num_cols " << o.columns << "\nobj_info num_rows "
      << o.rows << "\ncomment tessera virtual scanner" << (o.panoramic ? " (panoramic)" : "")
      << "\n"
      << "element vertex " << n << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "element range_grid " << uint64_t(o.columns) * o.rows
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  std::string buf;
  buf.reserve(1 << 20);
  auto flush = [&] {
    out.write(buf.data(), std::streamsize(buf.size()));
    buf.clear();
  };
  char line[96];
  for (const Hit& h : hits) {
    if (!h.valid) continue;
    if (o.binary) {
      buf.append(reinterpret_cast<const char*>(&h.local), sizeof(glm::vec3));
    } else {
      int len =
          std::snprintf(line, sizeof line, "%.9g %.9g %.9g \n", h.local.x, h.local.y, h.local.z);
      buf.append(line, size_t(len));
    }
    if (buf.size() > (1 << 20)) flush();
  }
  int32_t index = 0;
  for (const Hit& h : hits) {
    if (o.binary) {
      uint8_t count = h.valid ? 1 : 0;
      buf.push_back(char(count));
      if (h.valid) buf.append(reinterpret_cast<const char*>(&index), 4);
    } else if (h.valid) {
      int len = std::snprintf(line, sizeof line, "1 %d\n", index);
      buf.append(line, size_t(len));
    } else {
      buf.append("0\n");
    }
    if (h.valid) ++index;
    if (buf.size() > (1 << 20)) flush();
  }
  flush();
  if (!out)
    throw std::runtime_error("lod::scanMesh(): write failed for " + file.string() +
                             " (disk full?)");
}

}  // namespace

ScanResult scanMesh(const Mesh& mesh, const std::filesystem::path& out_dir, const ScanOptions& o) {
  TESSERA_CHECK(o.scanners >= 1 && o.scanners <= 10000,
                "lod::scanMesh(): scanners must be 1..10000");
  TESSERA_CHECK(o.columns >= 1 && o.rows >= 1 && o.columns <= 65535 && o.rows <= 65535,
                "lod::scanMesh(): resolution must be 1..65535 in each direction");
  TESSERA_CHECK(o.noise_mm >= 0.0 && std::isfinite(o.noise_mm),
                "lod::scanMesh(): noise must be >= 0");
  TESSERA_CHECK(!mesh.triangles.empty(), "lod::scanMesh(): mesh has no triangles");
  TESSERA_CHECK(o.threads >= 0 && o.threads <= kMaxScanThreads,
                "lod::scanMesh(): threads must be 0..." + std::to_string(kMaxScanThreads));
  TESSERA_CHECK(std::isfinite(o.units_per_mm) && o.units_per_mm > 0.0,
                "lod::scanMesh(): units per mm must be a positive number");
  TESSERA_CHECK(o.max_incidence_deg >= 0.0 && o.max_incidence_deg <= 90.0,
                "lod::scanMesh(): max incidence must be 0..90 degrees");

  auto [lo, hi] = mesh.bounds();
  glm::dvec3 center = 0.5 * (lo + hi);
  double radius = 0.5 * glm::length(hi - lo);
  TESSERA_CHECK(radius > 0.0, "lod::scanMesh(): mesh is degenerate (zero extent)");

  EmbreeScene es;
  es.device = rtcNewDevice(nullptr);
  if (!es.device) throw std::runtime_error("lod::scanMesh(): Embree device creation failed");
  es.scene = rtcNewScene(es.device);
  RTCGeometry geom = rtcNewGeometry(es.device, RTC_GEOMETRY_TYPE_TRIANGLE);
  // Embree works in float: vertices relative to the mesh centre keep precision.
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0,
                                                         RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                         mesh.positions.size()));
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    glm::vec3 p(mesh.positions[i] - center);
    vb[3 * i] = p.x;
    vb[3 * i + 1] = p.y;
    vb[3 * i + 2] = p.z;
  }
  auto* ib = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0,
                                                            RTC_FORMAT_UINT3, 3 * sizeof(uint32_t),
                                                            mesh.triangles.size()));
  std::memcpy(ib, mesh.triangles.data(), mesh.triangles.size() * sizeof(Triangle));
  rtcCommitGeometry(geom);
  rtcAttachGeometry(es.scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(es.scene);

  std::filesystem::create_directories(out_dir);
  std::vector<Scanner> scanners = placeScanners(o, center, radius, 0.5 * (hi - lo));
  const double noise = o.noise_mm * o.units_per_mm;
  const double cos_limit = std::cos(o.max_incidence_deg * std::numbers::pi / 180.0);
  const uint64_t cells = uint64_t(o.columns) * o.rows;
  const unsigned threads = threadCount(o.threads);

  ScanResult result;
  result.conf = out_dir / "scans.conf";
  Progress progress("scan", cells * scanners.size(), " rays", o.quiet);
  std::vector<Hit> hits(cells);
  for (size_t si = 0; si < scanners.size(); ++si) {
    const Scanner& sc = scanners[si];
    const glm::dvec3 org = sc.pose.translation - center;  // in Embree's (centred) frame
    std::atomic<uint32_t> next_row{0};
    auto work = [&] {
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
      for (uint32_t row; (row = next_row++) < o.rows;) {
        for (uint32_t col = 0; col < o.columns; ++col) {
          Hit& h = hits[size_t(row) * o.columns + col];
          h.valid = false;
          glm::dvec3 ld = sc.localDirection(col, row, o.columns, o.rows);
          glm::dvec3 wd = sc.rot * ld;
          RTCRayHit rh{};
          rh.ray.org_x = float(org.x);
          rh.ray.org_y = float(org.y);
          rh.ray.org_z = float(org.z);
          rh.ray.dir_x = float(wd.x);
          rh.ray.dir_y = float(wd.y);
          rh.ray.dir_z = float(wd.z);
          rh.ray.tnear = 0.0f;
          rh.ray.tfar = std::numeric_limits<float>::infinity();
          rh.ray.mask = 0xFFFFFFFFu;
          rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
          rtcIntersect1(es.scene, &ctx, &rh);
          if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
          glm::dvec3 n(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
          double nl = glm::length(n);
          if (nl <= 0.0 || std::abs(glm::dot(n / nl, wd)) < cos_limit) continue;
          double t = rh.ray.tfar;
          if (noise > 0.0) {
            uint64_t key = mix(o.seed) ^ mix((uint64_t(si) << 40) ^ (uint64_t(row) << 20) ^ col);
            t += noise * gaussian(key);
          }
          h.local = glm::vec3(ld * t);
          h.valid = true;
        }
      }
    };
    runWorkers(threads, [&](unsigned) { work(); });

    ScanInfo info;
    char name[32];
    std::snprintf(name, sizeof name, "scan_%03zu.ply", si);
    info.name = name;
    info.path = out_dir / name;
    // Written poses are in the mesh's file coordinates.
    info.pose = RigidPose{mesh.origin + sc.pose.translation, sc.pose.rotation};
    info.grid_columns = o.columns;
    info.grid_rows = o.rows;
    info.points =
        uint64_t(std::count_if(hits.begin(), hits.end(), [](const Hit& h) { return h.valid; }));
    writeScan(info.path, hits, o);
    result.points += info.points;
    result.scans.push_back(std::move(info));
    progress.add(cells);
  }
  result.rays = cells * scanners.size();

  std::ofstream conf(result.conf);
  if (!conf) throw std::runtime_error("lod::scanMesh(): cannot write " + result.conf.string());
  auto pose = [](const RigidPose& p) {
    const glm::dquat q = confQuaternion(p);
    char buf[256];
    std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g %.17g %.17g %.17g %.17g", p.translation.x,
                  p.translation.y, p.translation.z, q.x, q.y, q.z, q.w);
    return std::string(buf);
  };
  conf << "camera " << pose(result.scans[0].pose) << "\n";
  for (const ScanInfo& s : result.scans) conf << "bmesh " << s.name << " " << pose(s.pose) << "\n";
  if (!conf) throw std::runtime_error("lod::scanMesh(): write failed for " + result.conf.string());
  return result;
}

}  // namespace tessera::lod
