#include <tessera/lod/point_writer.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <tessera/core/check.h>

#include "atomic_file.h"
#include "las_file.h"

namespace tessera::lod {
namespace {

/// Accumulates bytes in the byte order asked for.
class Bytes {
 public:
  explicit Bytes(bool big_endian) : mBig(big_endian) {}
  template <typename T>
  void put(T v) {
    uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (mBig) std::reverse(b, b + sizeof(T));
    mData.insert(mData.end(), b, b + sizeof(T));
  }
  void text(const std::string& s) { mData.insert(mData.end(), s.begin(), s.end()); }
  void zeros(size_t n) { mData.insert(mData.end(), n, 0); }
  std::vector<uint8_t>& data() { return mData; }

 private:
  bool mBig;
  std::vector<uint8_t> mData;
};

std::string fmt(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

}  // namespace

void writePly(const std::filesystem::path& path, const PointBatch& pts, const glm::dvec3& origin,
              const PlyWriteOptions& o) {
  const AttributeMask a = pts.attributes;
  const bool ascii = o.encoding == PlyEncoding::kAscii;
  const char* enc = ascii                                         ? "ascii"
                    : o.encoding == PlyEncoding::kBinaryBigEndian ? "binary_big_endian"
                                                                  : "binary_little_endian";
  const char* ptype = o.double_positions ? "double" : "float";
  const char* ctype = o.ushort_colors ? "ushort" : "uchar";
  std::string h = std::string("ply\nformat ") + enc +
                  " 1.0\ncomment written by tessera\nelement vertex " + std::to_string(pts.size()) +
                  "\nproperty " + ptype + " x\nproperty " + ptype + " y\nproperty " + ptype +
                  " z\n";
  if (a & kNormal) h += "property float nx\nproperty float ny\nproperty float nz\n";
  if (a & kColor)
    h += std::string("property ") + ctype + " red\nproperty " + ctype + " green\nproperty " +
         ctype + " blue\n";
  if (a & kAlpha) h += std::string("property ") + ctype + " alpha\n";
  if (a & kIntensity) h += "property float intensity\n";
  if (a & kConfidence) h += "property float confidence\n";
  if (!pts.triangles.empty())
    h += "element face " + std::to_string(pts.triangles.size()) +
         "\nproperty list uchar int vertex_indices\n";
  h += "end_header\n";

  AtomicFile file(path, "lod::writePly()");
  Bytes b(o.encoding == PlyEncoding::kBinaryBigEndian);
  b.text(h);
  auto color = [&](uint8_t c) {
    if (o.ushort_colors) {
      b.put<uint16_t>(uint16_t(c * 257));
    } else {
      b.put<uint8_t>(c);
    }
  };
  for (size_t i = 0; i < pts.size(); ++i) {
    glm::dvec3 p = origin + pts.positions[i];
    if (ascii) {
      std::string line = fmt(p.x) + " " + fmt(p.y) + " " + fmt(p.z);
      if (a & kNormal)
        line +=
            " " + fmt(pts.normals[i].x) + " " + fmt(pts.normals[i].y) + " " + fmt(pts.normals[i].z);
      int scale = o.ushort_colors ? 257 : 1;
      if (a & kColor) {
        for (int c = 0; c < 3; ++c) line += " " + std::to_string(pts.colors[i][c] * scale);
      }
      if (a & kAlpha) line += " " + std::to_string(pts.colors[i].a * scale);
      if (a & kIntensity) line += " " + fmt(pts.intensities[i]);
      if (a & kConfidence) line += " " + fmt(pts.confidences[i]);
      b.text(line + "\n");
    } else {
      for (int c = 0; c < 3; ++c) {
        if (o.double_positions) {
          b.put<double>(p[c]);
        } else {
          b.put<float>(float(p[c]));
        }
      }
      if (a & kNormal) {
        for (int c = 0; c < 3; ++c) b.put<float>(pts.normals[i][c]);
      }
      if (a & kColor) {
        for (int c = 0; c < 3; ++c) color(pts.colors[i][c]);
      }
      if (a & kAlpha) color(pts.colors[i].a);
      if (a & kIntensity) b.put<float>(pts.intensities[i]);
      if (a & kConfidence) b.put<float>(pts.confidences[i]);
    }
    if (b.data().size() > (1u << 22)) {
      file.write(b.data());
      b.data().clear();
    }
  }
  for (const Triangle& t : pts.triangles) {
    if (ascii) {
      b.text("3 " + std::to_string(t.x) + " " + std::to_string(t.y) + " " + std::to_string(t.z) +
             "\n");
    } else {
      b.put<uint8_t>(3);
      b.put<int32_t>(int32_t(t.x));
      b.put<int32_t>(int32_t(t.y));
      b.put<int32_t>(int32_t(t.z));
    }
  }
  file.write(b.data());
  file.commit();
}

void writeLas(const std::filesystem::path& path, const PointBatch& pts, const glm::dvec3& origin,
              const LasWriteOptions& o) {
  TESSERA_CHECK(o.minor_version >= 2 && o.minor_version <= 4,
                "lod::writeLas(): minor version must be 2..4");
  TESSERA_CHECK(o.point_format >= 0 && o.point_format <= 10,
                "lod::writeLas(): point format must be 0..10");
  TESSERA_CHECK(o.point_format <= 5 || o.minor_version == 4,
                "lod::writeLas(): formats 6-10 need LAS 1.4");
  const int f = o.point_format;
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  for (const auto& p : pts.positions) {
    lo = glm::min(lo, origin + p);
    hi = glm::max(hi, origin + p);
  }
  if (pts.size() == 0) lo = hi = origin;
  const glm::dvec3 offset = glm::round(0.5 * (lo + hi));
  detail::LasFileWriter out(path,
                            detail::newLasParts(f, o.extra_bytes, o.scale, offset, o.minor_version),
                            o.laz, 0, "lod::writeLas()");
  const size_t record = out.recordLength();
  const AttributeMask a = pts.attributes;
  const bool rgb = f == 2 || f == 3 || f == 5 || f == 7 || f == 8 || f == 10;
  Bytes b(false);
  const size_t n = pts.size();
  for (size_t i = 0; i < n; ++i) {
    const glm::dvec3 q = glm::round((origin + pts.positions[i] - offset) / o.scale);
    const size_t start = b.data().size();
    for (int c = 0; c < 3; ++c) {
      b.put<int32_t>(int32_t(std::clamp(q[c], -2147483648.0, 2147483647.0)));
    }
    b.put<uint16_t>(a & kIntensity ? uint16_t(std::clamp(pts.intensities[i], 0.f, 65535.f)) : 0);
    const uint8_t cls = a & kClassification ? pts.classifications[i] : 1;
    if (f <= 5) {
      b.put<uint8_t>(0x09);  // return 1 of 1
      b.put<uint8_t>(cls & 0x1F);
      b.put<int8_t>(0);                                                    // scan angle rank
      b.put<uint8_t>(0);                                                   // user data
      b.put<uint16_t>(0);                                                  // point source id
      if (f == 1 || f == 3 || f == 4 || f == 5) b.put<double>(double(i));  // GPS time
    } else {
      b.put<uint8_t>(0x11);  // return 1 of 1
      b.put<uint8_t>(0);     // flags
      b.put<uint8_t>(cls);
      b.put<uint8_t>(0);   // user data
      b.put<int16_t>(0);   // scan angle
      b.put<uint16_t>(0);  // point source id
      b.put<double>(double(i));
    }
    if (rgb) {
      for (int c = 0; c < 3; ++c) {
        const uint8_t v = a & kColor ? pts.colors[i][c] : 0;
        b.put<uint16_t>(o.eight_bit_colors ? v : uint16_t(v * 257));
      }
    }
    if (f == 8 || f == 10) b.put<uint16_t>(0);  // NIR
    // Waveform packet fields (formats 4, 5, 9, 10) and extra bytes: zeros.
    b.zeros(record - (b.data().size() - start));
    if (b.data().size() > (1u << 22) || i + 1 == n) {
      out.add(b.data().data(), b.data().size() / record);
      b.data().clear();
    }
  }
  out.commit();
}

}  // namespace tessera::lod
