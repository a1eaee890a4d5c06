// ASTM E57 (E2807) point clouds, read from the published format: the file header, pages of 1024
// bytes each ending in its CRC-32C (big-endian; a mismatch names the page), the XML section
// (pugixml) describing each data3D scan, and each scan's compressed vector section: data
// packets of one bytestream per prototype field, bit-packed as the bitpack codec writes them
// (Integer and ScaledInteger packed at ceil(log2(max - min + 1)) bits, least significant bit
// first; Float 32 or 64 bits), index and empty packets skipped. Every scan's pose (rotation
// quaternion, translation) is applied in double; cartesian or spherical coordinates;
// cartesianInvalidState / sphericalInvalidState points skipped and counted; intensity and
// colour normalised by their declared limits; rowIndex / columnIndex kept as the scan's grid.
// Each scan is a ScanInfo of the source and its points carry its index. Images (images2D) are
// skipped and said.
#include <pugixml.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <optional>

#include "byte_source.h"
#include "crc32c.h"
#include "reader_util.h"
#include "readers.h"

namespace tessera::lod::detail {
namespace {

constexpr const char* kWho = "lod::readE57()";

uint64_t le64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = v << 8 | p[i];
  return v;
}
uint32_t le32(const uint8_t* p) {
  return uint32_t(p[0]) | p[1] << 8 | p[2] << 16 | uint32_t(p[3]) << 24;
}
uint16_t le16(const uint8_t* p) {
  return uint16_t(p[0] | p[1] << 8);
}

/// The file's pages: physical offsets (CRC bytes included) read as logical bytes, each page's
/// CRC checked when first read.
class Pages {
 public:
  Pages(ByteSource& src, uint64_t page_size) : mSrc(src), mPageSize(page_size), mPage(page_size) {}

  /// `n` logical bytes from physical offset `at` into `out`; returns the physical offset after.
  uint64_t read(uint64_t at, uint8_t* out, size_t n) {
    const uint64_t payload = mPageSize - 4;
    while (n > 0) {
      const uint64_t index = at / mPageSize, within = at % mPageSize;
      if (within >= payload) {  // a checksum's bytes: the next page's first
        at = (index + 1) * mPageSize;
        continue;
      }
      load(index);
      const size_t take = size_t(std::min<uint64_t>(n, payload - within));
      std::memcpy(out, mPage.data() + within, take);
      out += take;
      n -= take;
      at += take;
      if (at % mPageSize == payload) at += 4;
    }
    return at;
  }

 private:
  void load(uint64_t index) {
    if (index == mLoaded) return;
    const uint64_t offset = index * mPageSize;
    if (offset + mPageSize > mSrc.size())
      fail(kWho, mSrc.name(), "page " + std::to_string(index),
           "past the end of the file (" + std::to_string(mSrc.size()) + " bytes): truncated");
    if (mSrc.readAt(offset, mPage.data(), mPageSize) != mPageSize)
      fail(kWho, mSrc.name(), "page " + std::to_string(index), "cannot be read");
    const uint8_t* c = mPage.data() + mPageSize - 4;
    const uint32_t stored = uint32_t(c[0]) << 24 | c[1] << 16 | c[2] << 8 | uint32_t(c[3]);
    if (crc32c(mPage.data(), mPageSize - 4) != stored)
      fail(kWho, mSrc.name(),
           "page " + std::to_string(index) + " (byte " + std::to_string(offset) + ")",
           "its CRC-32C does not match: the file is damaged");
    mLoaded = index;
  }
  ByteSource& mSrc;
  uint64_t mPageSize;
  std::vector<uint8_t> mPage;
  uint64_t mLoaded = UINT64_MAX;
};

/// One field of a scan's prototype and how its bytestream decodes.
struct Field {
  std::string name;
  enum class Kind { kFloat32, kFloat64, kInteger, kScaled } kind = Kind::kInteger;
  int64_t minimum = 0, maximum = 0;  ///< integers and scaled integers: raw range
  double scale = 1.0, offset = 0.0;
  unsigned bits = 0;           ///< integers: bits a value takes
  std::vector<uint8_t> bytes;  ///< undecoded bytes of its stream
  size_t byte = 0;             ///< next byte to read in `bytes`
  unsigned bit = 0;            ///< next bit within bytes[byte]

  /// Bits still to decode.
  uint64_t bitsLeft() const { return (bytes.size() - byte) * 8 - bit; }
  unsigned width() const {
    return kind == Kind::kFloat32 ? 32 : kind == Kind::kFloat64 ? 64 : bits;
  }
  double next() {
    if (kind == Kind::kFloat32 || kind == Kind::kFloat64) {
      const size_t n = kind == Kind::kFloat32 ? 4 : 8;  // byte-aligned in their streams
      double v;
      if (n == 4) {
        float f;
        std::memcpy(&f, &bytes[byte], 4);
        v = f;
      } else {
        std::memcpy(&v, &bytes[byte], 8);
      }
      byte += n;
      return v;
    }
    uint64_t raw = 0;
    for (unsigned got = 0; got < bits;) {
      const unsigned take = std::min(bits - got, 8 - bit);
      const uint64_t part = (bytes[byte] >> bit) & ((1u << take) - 1u);
      raw |= part << got;
      got += take;
      bit += take;
      if (bit == 8) bit = 0, ++byte;
    }
    const int64_t value = minimum + int64_t(raw);
    return kind == Kind::kScaled ? double(value) * scale + offset : double(value);
  }
  void compact() {
    if (byte > (1u << 16)) {
      bytes.erase(bytes.begin(), bytes.begin() + std::ptrdiff_t(byte));
      byte = 0;
    }
  }
};

struct Scan {
  std::string name;
  RigidPose pose;
  uint64_t records = 0;
  uint64_t section = 0;  ///< physical offset of its compressed vector section
  std::vector<Field> fields;
  double intensity_min = 0, intensity_max = 1;
  std::array<double, 3> color_min{0, 0, 0}, color_max{255, 255, 255};
};

double number(const pugi::xml_node& n, double fallback) {
  if (!n) return fallback;
  const char* text = n.child_value();
  if (!text || !*text) return 0.0;  // E57 writes an empty element for 0
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  return end != text && std::isfinite(v) ? v : fallback;
}

int64_t integerAttr(const pugi::xml_node& n, const char* name, int64_t fallback) {
  const pugi::xml_attribute a = n.attribute(name);
  return a ? a.as_llong(fallback) : fallback;
}

class E57Reader final : public PointReader {
 public:
  explicit E57Reader(ByteSource src) : mSrc(std::move(src)) {
    uint8_t h[48];
    if (mSrc.readAt(0, h, 48) != 48 || std::memcmp(h, "ASTM-E57", 8) != 0)
      fail(kWho, mSrc.name(), "byte 0", "not an E57 file (missing 'ASTM-E57' signature)");
    const uint32_t major = le32(h + 8);
    const uint64_t length = le64(h + 16), xml_at = le64(h + 24), xml_length = le64(h + 32),
                   page = le64(h + 40);
    if (major != 1)
      fail(kWho, mSrc.name(), "byte 8", "E57 version " + std::to_string(major) + " (this reads 1)");
    if (page != 1024)
      fail(kWho, mSrc.name(), "byte 40", "page size " + std::to_string(page) + " (E57 uses 1024)");
    if (length != mSrc.size())
      fail(kWho, mSrc.name(), "byte 16",
           "the header says " + std::to_string(length) + " bytes, the file has " +
               std::to_string(mSrc.size()) + ": truncated or padded");
    if (xml_length == 0 || xml_length > (64u << 20) || xml_at >= length)
      fail(kWho, mSrc.name(), "byte 24", "no XML section within the file");
    mPages.emplace(mSrc, page);
    std::string xml(size_t(xml_length), '\0');
    mPages->read(xml_at, reinterpret_cast<uint8_t*>(xml.data()), xml.size());
    pugi::xml_document doc;
    const pugi::xml_parse_result parsed = doc.load_buffer(xml.data(), xml.size());
    if (!parsed)
      fail(kWho, mSrc.name(), "XML byte " + std::to_string(parsed.offset),
           std::string("malformed XML: ") + parsed.description());
    const pugi::xml_node root = doc.child("e57Root");
    if (!root) fail(kWho, mSrc.name(), "XML", "no e57Root element");
    if (root.child("images2D") && root.child("images2D").first_child())
      mInfo.format_detail = "images2D skipped; ";
    for (const pugi::xml_node& child : root.child("data3D").children("vectorChild"))
      mScans.push_back(scanOf(child, mScans.size()));
    mInfo.format = Format::kE57;
    mInfo.format_detail +=
        "E57 1." + std::to_string(le32(h + 12)) + ", " + std::to_string(mScans.size()) + " scans";
    mInfo.has_declared_points = true;
    mInfo.attributes = kScanIndex;
    for (const Scan& s : mScans) {
      mInfo.declared_points += s.records;
      ScanInfo si;
      si.name = s.name;
      si.path = mSrc.name();
      si.pose = s.pose;
      si.points = s.records;
      mInfo.scans.push_back(si);
      for (const Field& f : s.fields) {
        if (f.name == "intensity") mInfo.attributes |= kIntensity;
        if (f.name == "colorRed") mInfo.attributes |= kColor;
        if (f.name == "rowIndex" || f.name == "columnIndex") mInfo.attributes |= kGridPosition;
      }
    }
    // A mix of scans with and without an attribute: the ones without get a default.
    for (size_t i = 0; i < mScans.size(); ++i) {
      uint32_t columns = 0, rows = 0;
      for (const Field& f : mScans[i].fields) {
        if (f.name == "columnIndex") columns = uint32_t(f.maximum + 1);
        if (f.name == "rowIndex") rows = uint32_t(f.maximum + 1);
      }
      mInfo.scans[i].grid_columns = columns;
      mInfo.scans[i].grid_rows = rows;
    }
  }

  bool next(PointBatch& batch, size_t max_points) override {
    batch.reset(mInfo.attributes);
    while (batch.size() < max_points && mScan < mScans.size()) {
      Scan& s = mScans[mScan];
      if (!mStarted) start(s);
      if (mDone >= s.records) {
        ++mScan;
        mStarted = false;
        continue;
      }
      // Enough bits in every stream for one record, else the next packet.
      bool ready = true;
      for (const Field& f : s.fields) ready = ready && f.bitsLeft() >= f.width();
      if (!ready) {
        packet(s);
        continue;
      }
      decode(s, batch);
      ++mDone;
    }
    return !batch.empty();
  }

 private:
  Scan scanOf(const pugi::xml_node& n, size_t index) {
    Scan s;
    s.name = n.child("name").child_value();
    if (s.name.empty()) s.name = "scan " + std::to_string(index);
    const std::string where = "data3D[" + std::to_string(index) + "] (" + s.name + ")";
    if (const pugi::xml_node pose = n.child("pose")) {
      const pugi::xml_node r = pose.child("rotation"), t = pose.child("translation");
      glm::dquat q(number(r.child("w"), 1.0), number(r.child("x"), 0.0), number(r.child("y"), 0.0),
                   number(r.child("z"), 0.0));
      const double len = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
      if (!(len > 0.5 && len < 2.0))
        fail(kWho, mSrc.name(), where + " pose", "the rotation is not a unit quaternion");
      s.pose.rotation = q / len;
      s.pose.translation = {number(t.child("x"), 0.0), number(t.child("y"), 0.0),
                            number(t.child("z"), 0.0)};
    }
    const pugi::xml_node points = n.child("points");
    if (std::string(points.attribute("type").value()) != "CompressedVector")
      fail(kWho, mSrc.name(), where, "its points are not a CompressedVector");
    s.records = uint64_t(integerAttr(points, "recordCount", -1));
    s.section = uint64_t(integerAttr(points, "fileOffset", -1));
    if (integerAttr(points, "recordCount", -1) < 0 || s.section >= mSrc.size())
      fail(kWho, mSrc.name(), where, "recordCount or fileOffset missing or out of the file");
    for (const pugi::xml_node& f : points.child("prototype").children()) {
      Field field;
      field.name = f.name();
      const std::string type = f.attribute("type").value();
      if (type == "Float") {
        field.kind = std::string(f.attribute("precision").value()) == "single"
                         ? Field::Kind::kFloat32
                         : Field::Kind::kFloat64;
      } else if (type == "Integer" || type == "ScaledInteger") {
        field.kind = type == "Integer" ? Field::Kind::kInteger : Field::Kind::kScaled;
        field.minimum = integerAttr(f, "minimum", INT64_MIN);
        field.maximum = integerAttr(f, "maximum", INT64_MAX);
        if (field.maximum < field.minimum)
          fail(kWho, mSrc.name(), where + " " + field.name, "maximum below minimum");
        const unsigned __int128 range = (unsigned __int128)(field.maximum - field.minimum) + 1;
        while (field.bits < 64 && ((unsigned __int128)1 << field.bits) < range) ++field.bits;
        field.scale = f.attribute("scale").as_double(1.0);
        field.offset = f.attribute("offset").as_double(0.0);
      } else {
        fail(kWho, mSrc.name(), where + " " + field.name,
             "a " + type + " field in the prototype is not supported");
      }
      s.fields.push_back(std::move(field));
    }
    auto has = [&](const char* name) {
      return std::any_of(s.fields.begin(), s.fields.end(),
                         [&](const Field& f) { return f.name == name; });
    };
    if (!(has("cartesianX") && has("cartesianY") && has("cartesianZ")) &&
        !(has("sphericalRange") && has("sphericalAzimuth") && has("sphericalElevation")))
      fail(kWho, mSrc.name(), where, "neither cartesian nor spherical coordinates");
    if (const pugi::xml_node l = n.child("intensityLimits")) {
      s.intensity_min = number(l.child("intensityMinimum"), 0.0);
      s.intensity_max = number(l.child("intensityMaximum"), 1.0);
    } else {
      for (const Field& f : s.fields)
        if (f.name == "intensity" && f.kind != Field::Kind::kFloat32 &&
            f.kind != Field::Kind::kFloat64)
          s.intensity_min = double(f.minimum), s.intensity_max = double(f.maximum);
    }
    if (const pugi::xml_node l = n.child("colorLimits")) {
      const char* lo[3] = {"colorRedMinimum", "colorGreenMinimum", "colorBlueMinimum"};
      const char* hi[3] = {"colorRedMaximum", "colorGreenMaximum", "colorBlueMaximum"};
      for (int c = 0; c < 3; ++c) {
        s.color_min[size_t(c)] = number(l.child(lo[c]), 0.0);
        s.color_max[size_t(c)] = number(l.child(hi[c]), 255.0);
      }
    }
    return s;
  }

  void start(Scan& s) {
    mStarted = true;
    mDone = 0;
    for (Field& f : s.fields) f.bytes.clear(), f.byte = 0, f.bit = 0;
    if (s.records == 0) return;
    uint8_t h[32];
    mPages->read(s.section, h, 32);
    if (h[0] != 1)
      fail(kWho, mSrc.name(), "byte " + std::to_string(s.section),
           "not a compressed vector section (section id " + std::to_string(h[0]) + ")");
    mNextPacket = le64(h + 16);  // dataPhysicalOffset
    if (mNextPacket == 0 || mNextPacket >= mSrc.size())
      fail(kWho, mSrc.name(), "byte " + std::to_string(s.section),
           "its data lies outside the file");
  }

  /// The next packet of the scan's section: a data packet's bytestreams appended to its fields.
  void packet(Scan& s) {
    const uint64_t at = mNextPacket;
    if (at >= mSrc.size())
      fail(kWho, mSrc.name(), "byte " + std::to_string(at),
           "the scan " + s.name + " ends after " + std::to_string(mDone) + " of its " +
               std::to_string(s.records) + " records");
    uint8_t h[4];
    mPages->read(at, h, 4);
    const size_t length = size_t(le16(h + 2)) + 1;
    std::vector<uint8_t> p(length);
    mNextPacket = mPages->read(at, p.data(), length);
    if (h[0] == 0 || h[0] == 2) return;  // index or empty packet
    if (h[0] != 1 || length < 6)
      fail(kWho, mSrc.name(), "byte " + std::to_string(at),
           "unknown packet type " + std::to_string(h[0]));
    const size_t streams = le16(p.data() + 4);
    if (streams != s.fields.size() || 6 + 2 * streams > length)
      fail(kWho, mSrc.name(), "byte " + std::to_string(at),
           std::to_string(streams) + " bytestreams for " + std::to_string(s.fields.size()) +
               " fields");
    size_t offset = 6 + 2 * streams;
    for (size_t i = 0; i < streams; ++i) {
      const size_t n = le16(p.data() + 6 + 2 * i);
      if (offset + n > length)
        fail(kWho, mSrc.name(), "byte " + std::to_string(at), "a bytestream runs past its packet");
      Field& f = s.fields[i];
      f.compact();
      f.bytes.insert(f.bytes.end(), p.begin() + std::ptrdiff_t(offset),
                     p.begin() + std::ptrdiff_t(offset + n));
      offset += n;
    }
  }

  void decode(Scan& s, PointBatch& batch) {
    double x = 0, y = 0, z = 0, range = 0, azimuth = 0, elevation = 0, intensity = 0;
    double rgb[3] = {0, 0, 0};
    int64_t invalid = 0, row = 0, column = 0;
    bool spherical = false;
    for (Field& f : s.fields) {
      const double v = f.next();
      const std::string& n = f.name;
      if (n == "cartesianX")
        x = v;
      else if (n == "cartesianY")
        y = v;
      else if (n == "cartesianZ")
        z = v;
      else if (n == "sphericalRange")
        range = v, spherical = true;
      else if (n == "sphericalAzimuth")
        azimuth = v;
      else if (n == "sphericalElevation")
        elevation = v;
      else if (n == "cartesianInvalidState" || n == "sphericalInvalidState")
        invalid = int64_t(v);
      else if (n == "intensity")
        intensity = v;
      else if (n == "colorRed")
        rgb[0] = v;
      else if (n == "colorGreen")
        rgb[1] = v;
      else if (n == "colorBlue")
        rgb[2] = v;
      else if (n == "rowIndex")
        row = int64_t(v);
      else if (n == "columnIndex")
        column = int64_t(v);
    }
    const std::string where = "scan " + s.name + " record " + std::to_string(mDone);
    if (invalid != 0) {
      mStats.skip("invalid state (no position)", where);
      return;
    }
    if (spherical && !(x != 0 || y != 0 || z != 0)) {
      x = range * std::cos(elevation) * std::cos(azimuth);
      y = range * std::cos(elevation) * std::sin(azimuth);
      z = range * std::sin(elevation);
    }
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
      mStats.skip("non-finite coordinate", where);
      return;
    }
    const size_t i = batch.size();
    batch.resize(i + 1);
    batch.positions[i] = s.pose.apply({x, y, z});
    if (batch.attributes & kScanIndex)
      batch.scan_indices[i] = uint16_t(std::min<size_t>(mScan, 65535));
    if (batch.attributes & kIntensity) {
      const double span = s.intensity_max - s.intensity_min;
      batch.intensities[i] = float(
          65535.0 * std::clamp(span > 0 ? (intensity - s.intensity_min) / span : 0.0, 0.0, 1.0));
    }
    if (batch.attributes & kColor) {
      glm::u8vec4 c(200, 200, 200, 255);
      for (int k = 0; k < 3; ++k) {
        const double span = s.color_max[size_t(k)] - s.color_min[size_t(k)];
        c[k] = uint8_t(std::lround(
            255.0 *
            std::clamp(span > 0 ? (rgb[k] - s.color_min[size_t(k)]) / span : 0.0, 0.0, 1.0)));
      }
      batch.colors[i] = c;
    }
    if (batch.attributes & kGridPosition)
      batch.grid_positions[i] = {uint16_t(std::clamp<int64_t>(column, 0, 65535)),
                                 uint16_t(std::clamp<int64_t>(row, 0, 65535))};
    ++mStats.points;
  }

  ByteSource mSrc;
  std::optional<Pages> mPages;
  std::vector<Scan> mScans;
  size_t mScan = 0;
  bool mStarted = false;
  uint64_t mDone = 0;
  uint64_t mNextPacket = 0;
};

}  // namespace

std::unique_ptr<PointReader> openE57(ByteSource source) {
  return std::make_unique<E57Reader>(std::move(source));
}

}  // namespace tessera::lod::detail
