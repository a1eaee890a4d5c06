// PLY reader: ASCII, binary little and big endian; any scalar type for any property; vertex
// normals, colours (uchar, ushort or float), alpha, intensity, confidence; `face` polygons
// triangulated as fans; `tristrips` (Cyberware and Stanford scanning software) decoded as
// triangle strips; Stanford range grids (`obj_info num_cols/num_rows` + `range_grid` element)
// mapped to per-vertex grid positions; every other element and property skipped by its declared
// size. An element that looks like faces but is not one of these is a ReadError naming it, never
// silently dropped.
#include "readers.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <limits>
#include <type_traits>

#include "byte_source.h"
#include "reader_util.h"

namespace tessera::lod::detail {
namespace {

constexpr const char* kComponent = "lod::readPly()";

enum class PlyType : uint8_t {
  kInt8,
  kUInt8,
  kInt16,
  kUInt16,
  kInt32,
  kUInt32,
  kFloat32,
  kFloat64
};

bool parsePlyType(std::string_view s, PlyType& t) {
  static constexpr std::pair<std::string_view, PlyType> kNames[] = {
      {"char", PlyType::kInt8},      {"int8", PlyType::kInt8},       {"uchar", PlyType::kUInt8},
      {"uint8", PlyType::kUInt8},    {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
      {"ushort", PlyType::kUInt16},  {"uint16", PlyType::kUInt16},   {"int", PlyType::kInt32},
      {"int32", PlyType::kInt32},    {"uint", PlyType::kUInt32},     {"uint32", PlyType::kUInt32},
      {"float", PlyType::kFloat32},  {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
      {"float64", PlyType::kFloat64}};
  for (auto& [name, type] : kNames) {
    if (s == name) {
      t = type;
      return true;
    }
  }
  return false;
}

size_t typeSize(PlyType t) {
  switch (t) {
    case PlyType::kInt8:
    case PlyType::kUInt8:
      return 1;
    case PlyType::kInt16:
    case PlyType::kUInt16:
      return 2;
    case PlyType::kInt32:
    case PlyType::kUInt32:
    case PlyType::kFloat32:
      return 4;
    case PlyType::kFloat64:
      return 8;
  }
  return 0;
}

bool isIntegerType(PlyType t) {
  return t != PlyType::kFloat32 && t != PlyType::kFloat64;
}

double loadScalar(const uint8_t* p, PlyType t, bool swap) {
  switch (t) {
    case PlyType::kInt8:
      return double(int8_t(p[0]));
    case PlyType::kUInt8:
      return double(p[0]);
    case PlyType::kInt16:
      return double(load<int16_t>(p, swap));
    case PlyType::kUInt16:
      return double(load<uint16_t>(p, swap));
    case PlyType::kInt32:
      return double(load<int32_t>(p, swap));
    case PlyType::kUInt32:
      return double(load<uint32_t>(p, swap));
    case PlyType::kFloat32:
      return double(load<float>(p, swap));
    case PlyType::kFloat64:
      return load<double>(p, swap);
  }
  return 0.0;
}

/// Where a vertex property's value goes.
enum class Slot : uint8_t {
  kSkip,
  kX,
  kY,
  kZ,
  kNx,
  kNy,
  kNz,
  kRed,
  kGreen,
  kBlue,
  kAlpha,
  kIntensity,
  kConfidence
};

Slot slotFor(std::string_view n) {
  if (n == "x") return Slot::kX;
  if (n == "y") return Slot::kY;
  if (n == "z") return Slot::kZ;
  if (n == "nx" || n == "normal_x") return Slot::kNx;
  if (n == "ny" || n == "normal_y") return Slot::kNy;
  if (n == "nz" || n == "normal_z") return Slot::kNz;
  if (n == "red" || n == "diffuse_red" || n == "r") return Slot::kRed;
  if (n == "green" || n == "diffuse_green" || n == "g") return Slot::kGreen;
  if (n == "blue" || n == "diffuse_blue" || n == "b") return Slot::kBlue;
  if (n == "alpha" || n == "diffuse_alpha" || n == "a") return Slot::kAlpha;
  if (n == "intensity" || n == "scalar_intensity") return Slot::kIntensity;
  if (n == "confidence" || n == "scalar_confidence") return Slot::kConfidence;
  return Slot::kSkip;
}

struct Property {
  std::string name;
  PlyType type = PlyType::kFloat32;
  bool is_list = false;
  PlyType count_type = PlyType::kUInt8;
  Slot slot = Slot::kSkip;
  size_t offset = 0;  // in a fixed-size binary record
};

/// What the reader makes of an element besides the vertices and the range grid.
enum class ElementKind : uint8_t {
  kOther,   // skipped by size
  kFaces,   // `face`: polygons, triangulated as fans
  kStrips,  // `tristrips`: triangle strips, -1 between strips
};

bool isIndexListName(std::string_view n) {
  return n == "vertex_indices" || n == "vertex_index";
}

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> props;
  bool fixed = true;       // no list properties
  size_t record_size = 0;  // bytes per instance when fixed
  uint64_t line = 0;       // header line declaring it
  ElementKind kind = ElementKind::kOther;
  int index_list = -1;  // the vertex_indices (or vertex_index) list property, if any
};

enum class Encoding { kAscii, kBinaryLE, kBinaryBE };

/// Colour channel to 8 bits from the declared type: uchar as is, ushort >> 8, float in [0,1].
uint8_t colorByte(double v, PlyType t) {
  double c;
  if (t == PlyType::kUInt16 || t == PlyType::kInt16) {
    c = v / 257.0;
  } else if (isIntegerType(t)) {
    c = v;
  } else {
    c = v * 255.0;
  }
  if (!(c >= 0.0)) return 0;
  return uint8_t(std::min(255.0, std::round(c)));
}

/// Calls `store(i, value)` with property values of `n` fixed-size records, `stride` bytes apart,
/// in their declared type: the type and byte order are resolved once per column, not per value.
template <typename T, bool kSwap, typename Store>
void decodeColumn(const uint8_t* p, size_t stride, size_t n, Store& store) {
  for (size_t i = 0; i < n; ++i, p += stride) store(i, load<T>(p, kSwap));
}

template <typename T, typename Store>
void decodeColumn(const uint8_t* p, size_t stride, size_t n, bool swap, Store& store) {
  if (swap) {
    decodeColumn<T, true>(p, stride, n, store);
  } else {
    decodeColumn<T, false>(p, stride, n, store);
  }
}

template <typename Store>
void decodeColumn(const uint8_t* p, size_t stride, size_t n, PlyType t, bool swap, Store store) {
  switch (t) {
    case PlyType::kInt8:
      return decodeColumn<int8_t>(p, stride, n, swap, store);
    case PlyType::kUInt8:
      return decodeColumn<uint8_t>(p, stride, n, swap, store);
    case PlyType::kInt16:
      return decodeColumn<int16_t>(p, stride, n, swap, store);
    case PlyType::kUInt16:
      return decodeColumn<uint16_t>(p, stride, n, swap, store);
    case PlyType::kInt32:
      return decodeColumn<int32_t>(p, stride, n, swap, store);
    case PlyType::kUInt32:
      return decodeColumn<uint32_t>(p, stride, n, swap, store);
    case PlyType::kFloat32:
      return decodeColumn<float>(p, stride, n, swap, store);
    case PlyType::kFloat64:
      return decodeColumn<double>(p, stride, n, swap, store);
  }
}

/// colorByte() for a value still in its declared type; uchar (the common case) needs no work.
template <typename T>
uint8_t colorByteOf(T v, PlyType t) {
  if constexpr (std::is_same_v<T, uint8_t>) {
    return v;
  } else {
    return colorByte(double(v), t);
  }
}

/// Moves point `from` to `to` in every array a PLY batch fills.
void movePoint(PointBatch& b, size_t from, size_t to) {
  const AttributeMask a = b.attributes;
  b.positions[to] = b.positions[from];
  if (a & kNormal) b.normals[to] = b.normals[from];
  if (a & kColor) b.colors[to] = b.colors[from];
  if (a & kIntensity) b.intensities[to] = b.intensities[from];
  if (a & kConfidence) b.confidences[to] = b.confidences[from];
  if (a & kGridPosition) b.grid_positions[to] = b.grid_positions[from];
}

class PlyReader final : public PointReader {
 public:
  PlyReader(ByteSource source) : mSrc(std::move(source)) { parseHeader(); }

  bool next(PointBatch& batch, size_t max_points) override;

 private:
  void parseHeader();
  [[noreturn]] void failHere(const std::string& what) const {
    fail(kComponent, mSrc.name(),
         mEncoding == Encoding::kAscii ? atLine(mSrc.lineNumber()) : atByte(mSrc.offset()), what);
  }
  /// Reads one instance's properties into `values` (indexed by property) and, when `lists` is
  /// given, its list properties into `lists`. Throws on truncation or a bad token.
  void readInstance(const Element& e, uint64_t index, std::vector<double>& values,
                    std::vector<std::vector<double>>* lists);
  /// One property of instance `index`: a scalar into `value`, a list (at most 10^6 values) into
  /// `list` when given.
  void readProperty(const Element& e, uint64_t index, const Property& p, double& value,
                    std::vector<double>* list);
  /// One value of type `t` at the read position, in either encoding.
  double readScalar(const Element& e, uint64_t index, PlyType t);
  /// A list's length, refused when negative or above `limit`.
  uint64_t readListLength(const Element& e, uint64_t index, const Property& p, double limit);
  /// ASCII: moves to the next non-blank line, where instance `index` starts.
  void beginAsciiInstance(const Element& e, uint64_t index);
  /// ASCII: refuses values left on the line after instance `index`.
  void endAsciiInstance(const Element& e, uint64_t index);
  std::string_view nextAsciiToken(const Element& e, uint64_t index);
  double asciiValue(const Element& e, uint64_t index, PlyType t, bool integral);
  [[noreturn]] void truncated(const Element& e, uint64_t index) const;

  /// Counts vertex `file_index` as delivered, or as skipped when a coordinate is not finite.
  bool admitVertex(const glm::dvec3& p, uint64_t file_index) {
    if (!finite3(p.x, p.y, p.z)) {
      skipVertex(file_index);
      return false;
    }
    if (mRemapNeeded) mRemap.push_back(uint32_t(mVerticesKept));
    ++mVerticesKept;
    return true;
  }
  void skipVertex(uint64_t file_index);
  /// Decodes vertex `values` into the batch; false if skipped.
  bool emitVertex(const std::vector<double>& values, PointBatch& batch);
  void readVertices(PointBatch& batch, size_t max_points);
  /// Binary vertices without list properties: whole blocks of records, one column at a time.
  void readFixedVertices(PointBatch& batch, size_t max_points);
  void decodeVertexBlock(const uint8_t* records, size_t n, PointBatch& batch);
  /// Whether file vertex index `d` names a vertex that was read and kept.
  bool usableVertex(double d) const {
    return d >= 0 && d < double(mRemap.size()) && mRemap[size_t(d)] != kDropped;
  }
  /// Triangles of the current face or tristrips element, until `max_triangles` or its end.
  void readTriangles(PointBatch& batch, size_t max_triangles);
  void readFaces(PointBatch& batch, size_t max_triangles);
  void readStrips(PointBatch& batch, size_t max_triangles);
  void addStripIndex(double d, PointBatch& batch);
  void endStrip();
  /// Where in the current list, for skip counts: "tristrips 0, index 57".
  std::string stripPosition(uint64_t position) const;
  /// Upper bound on the triangles of the tristrips elements: one per index the data can hold.
  uint64_t stripTriangleBound() const;
  void readRangeGrid();
  void skipElement(const Element& e);
  void advanceElement();
  bool fillBuffered();

  ByteSource mSrc;
  Encoding mEncoding = Encoding::kAscii;
  bool mSwap = false;
  std::vector<Element> mElements;
  int mVertexElement = -1;
  uint32_t mGridCols = 0, mGridRows = 0;
  bool mBufferGrid = false;  // range grid after the vertices: buffer one scan, attach cells
  int mGridElement = -1;     // the range_grid element checked by parseHeader() (one list)

  // Streaming state.
  size_t mElement = 0;     // element being read
  uint64_t mInstance = 0;  // next instance within it
  uint64_t mVerticesKept = 0;
  std::vector<uint32_t> mRemap;  // file vertex index -> delivered index (or kDropped)
  bool mRemapNeeded = false;     // filled when the file has faces or a range grid
  std::vector<double> mValues;
  std::vector<std::vector<double>> mLists;
  std::string_view mLineRest;    // ASCII: unread part of the current line
  uint64_t mLineOfInstance = 0;  // ASCII: line the current instance started on

  // Triangle strips: one list may hold a whole mesh, so it is decoded index by index and a batch
  // may end inside it.
  struct StripState {
    bool in_list = false;   // inside instance mInstance's index list
    uint64_t left = 0;      // indices of that list not read yet
    uint64_t position = 0;  // position in the list of the next index
    uint64_t length = 0;    // indices of the current strip (since the list's start or a -1)
    double a = 0, b = 0;    // the strip's last two indices
  } mStrip;

  // Range-grid buffering (one scan: at most num_cols * num_rows vertices).
  PointBatch mBuffer;
  std::vector<Triangle> mBufferedTriangles;
  size_t mBufferPos = 0;
  bool mBuffered = false;

  static constexpr uint32_t kDropped = std::numeric_limits<uint32_t>::max();
};

void PlyReader::parseHeader() {
  std::string_view line;
  if (!isPlyMagic(mSrc.data(), mSrc.ensure(kPlyMagicProbe))) {
    fail(kComponent, mSrc.name(), atByte(0), "not a PLY file (missing 'ply' magic line)");
  }
  mSrc.readLine(line);
  bool have_format = false;
  for (;;) {
    if (!mSrc.readLine(line, 1 << 16)) {
      fail(kComponent, mSrc.name(), atLine(mSrc.lineNumber() + 1),
           "file ends inside the header (no end_header)");
    }
    std::string_view rest = line;
    std::string_view key = nextToken(rest);
    auto where = atLine(mSrc.lineNumber());
    if (key == "end_header") break;
    if (key.empty() || key == "comment") continue;
    if (key == "format") {
      std::string_view enc = nextToken(rest);
      std::string_view ver = nextToken(rest);
      if (enc == "ascii") {
        mEncoding = Encoding::kAscii;
      } else if (enc == "binary_little_endian") {
        mEncoding = Encoding::kBinaryLE;
      } else if (enc == "binary_big_endian") {
        mEncoding = Encoding::kBinaryBE;
        mSwap = true;
      } else {
        fail(kComponent, mSrc.name(), where, "unknown format " + shown(enc));
      }
      if (ver != "1.0")
        fail(kComponent, mSrc.name(), where, "unsupported PLY version " + shown(ver));
      mInfo.format_detail = std::string(enc) + " 1.0";
      have_format = true;
    } else if (key == "obj_info") {
      std::string_view name = nextToken(rest);
      std::string_view value = nextToken(rest);
      uint64_t v = 0;
      if ((name == "num_cols" || name == "num_rows") && parseUint(value, v) && v < 65536) {
        (name == "num_cols" ? mGridCols : mGridRows) = uint32_t(v);
      }
    } else if (key == "element") {
      Element e;
      e.name = std::string(nextToken(rest));
      e.line = mSrc.lineNumber();
      if (e.name.empty() || !parseUint(nextToken(rest), e.count)) {
        fail(kComponent, mSrc.name(), where, "malformed element line " + shown(line));
      }
      mElements.push_back(std::move(e));
    } else if (key == "property") {
      if (mElements.empty()) fail(kComponent, mSrc.name(), where, "property before any element");
      Property p;
      std::string_view type = nextToken(rest);
      if (type == "list") {
        p.is_list = true;
        std::string_view ct = nextToken(rest);
        if (!parsePlyType(ct, p.count_type) || !isIntegerType(p.count_type)) {
          fail(kComponent, mSrc.name(), where, "bad list count type " + shown(ct));
        }
        type = nextToken(rest);
      }
      if (!parsePlyType(type, p.type)) {
        fail(kComponent, mSrc.name(), where, "unknown property type " + shown(type));
      }
      p.name = std::string(nextToken(rest));
      if (p.name.empty()) fail(kComponent, mSrc.name(), where, "property without a name");
      mElements.back().props.push_back(std::move(p));
    } else {
      fail(kComponent, mSrc.name(), where, "unknown header keyword " + shown(key));
    }
  }
  if (!have_format) fail(kComponent, mSrc.name(), "header", "no format line");

  for (size_t i = 0; i < mElements.size(); ++i) {
    Element& e = mElements[i];
    for (Property& p : e.props) {
      if (p.is_list) {
        e.fixed = false;
      } else {
        p.offset = e.record_size;
        e.record_size += typeSize(p.type);
      }
    }
    if (e.name == "vertex" && mVertexElement < 0) {
      mVertexElement = int(i);
      for (Property& p : e.props) {
        if (!p.is_list) p.slot = slotFor(p.name);
      }
    }
  }
  if (mVertexElement < 0) fail(kComponent, mSrc.name(), "header", "no vertex element");
  const Element& v = mElements[size_t(mVertexElement)];
  uint32_t have = 0;
  AttributeMask attrs = 0;
  for (const Property& p : v.props) {
    have |= 1u << unsigned(p.slot);
    switch (p.slot) {
      case Slot::kNx:
      case Slot::kNy:
      case Slot::kNz:
        break;
      case Slot::kRed:
      case Slot::kGreen:
      case Slot::kBlue:
        attrs |= kColor;
        break;
      case Slot::kAlpha:
        attrs |= kAlpha | kColor;
        break;
      case Slot::kIntensity:
        attrs |= kIntensity;
        break;
      case Slot::kConfidence:
        attrs |= kConfidence;
        break;
      default:
        break;
    }
  }
  auto has = [&](Slot s) { return (have >> unsigned(s)) & 1u; };
  if (!has(Slot::kX) || !has(Slot::kY) || !has(Slot::kZ)) {
    fail(kComponent, mSrc.name(), "header", "vertex element lacks x, y or z");
  }
  if (has(Slot::kNx) && has(Slot::kNy) && has(Slot::kNz)) attrs |= kNormal;

  bool faces = false, strips = false;
  int grid = -1;
  for (size_t i = 0; i < mElements.size(); ++i) {
    Element& e = mElements[i];
    if (int(i) == mVertexElement) continue;
    for (size_t k = 0; k < e.props.size(); ++k) {
      if (e.props[k].is_list && isIndexListName(e.props[k].name)) e.index_list = int(k);
    }
    if (e.index_list >= 0 && e.name == "face") {
      e.kind = ElementKind::kFaces;
      faces = true;
      // Triangle count is exact only for triangle meshes; fans from polygons come out more.
      mInfo.declared_triangles += e.count;
    }
    if (e.index_list >= 0 && e.name == "tristrips") {
      e.kind = ElementKind::kStrips;
      strips = true;
    }
    if (e.name == "range_grid") {  // grid cells to vertices, not faces
      if (int(i) > mVertexElement && e.props.size() == 1 && e.props[0].is_list) grid = int(i);
      continue;
    }
    // Faces under another name or without an index list would vanish: the mesh would read as a
    // point cloud with nothing said. An empty one loses nothing.
    const bool face_like = e.name.find("face") != std::string::npos ||
                           e.name.find("strip") != std::string::npos || e.index_list >= 0;
    if (face_like && e.kind == ElementKind::kOther && e.count > 0) {
      fail(kComponent, mSrc.name(), atLine(e.line),
           "element " + shown(e.name) + " (" + std::to_string(e.count) +
               " instances) looks like faces but is not read: faces are read from a 'face' "
               "element and triangle strips from a 'tristrips' element, each with a list "
               "property 'vertex_indices' or 'vertex_index'; rename it to one of these, or "
               "remove it to read the vertices alone");
    }
  }
  if (strips) mInfo.declared_triangles += stripTriangleBound();
  if (grid >= 0 && mGridCols > 0 && mGridRows > 0 &&
      uint64_t(mGridCols) * mGridRows == mElements[size_t(grid)].count &&
      v.count <= uint64_t(mGridCols) * mGridRows) {
    mBufferGrid = true;
    mGridElement = grid;
    attrs |= kGridPosition;
    ScanInfo scan;
    scan.name = std::filesystem::path(mSrc.name()).filename().string();
    scan.path = mSrc.name();
    scan.grid_columns = mGridCols;
    scan.grid_rows = mGridRows;
    scan.points = v.count;
    mInfo.scans.push_back(std::move(scan));
  }
  mRemapNeeded = faces || strips || mBufferGrid;
  if (mRemapNeeded && v.count > (uint64_t(1) << 32) - 2) {
    fail(kComponent, mSrc.name(), "header", "more than 2^32 - 2 vertices in a mesh");
  }
  mInfo.format = Format::kPly;
  mInfo.declared_points = v.count;
  mInfo.has_declared_points = true;
  mInfo.attributes = attrs;
  size_t widest = std::max_element(mElements.begin(), mElements.end(), [](auto& a, auto& b) {
                    return a.props.size() < b.props.size();
                  })->props.size();
  mValues.resize(widest);
  mLists.resize(widest);
}

void PlyReader::truncated(const Element& e, uint64_t index) const {
  fail(kComponent, mSrc.name(), atByte(mSrc.offset()),
       "file ends inside " + e.name + " " + std::to_string(index) + " of " +
           std::to_string(e.count) + " declared by the header");
}

std::string_view PlyReader::nextAsciiToken(const Element& e, uint64_t index) {
  for (;;) {
    std::string_view tok = nextToken(mLineRest, " \t\r");
    if (!tok.empty()) return tok;
    std::string_view line;
    if (!mSrc.readLine(line)) truncated(e, index);
    mLineRest = line;
  }
}

double PlyReader::asciiValue(const Element& e, uint64_t index, PlyType t, bool integral) {
  std::string_view tok = nextAsciiToken(e, index);
  double v;
  if (!parseDouble(tok, v) || (integral && (v != std::floor(v) || !std::isfinite(v)))) {
    failHere("bad value " + shown(tok) + " in " + e.name + " " + std::to_string(index));
  }
  (void)t;
  return v;
}

uint64_t PlyReader::stripTriangleBound() const {
  // The data after the header, less the fixed-size records of the other elements, holds the
  // strips; each index adds at most one triangle and takes at least its type's size (binary) or
  // a digit and a separator (ASCII).
  uint64_t rest = mSrc.size() - mSrc.offset();
  size_t index_bytes = 8;
  for (const Element& e : mElements) {
    if (e.kind == ElementKind::kStrips) {
      index_bytes = std::min(index_bytes, typeSize(e.props[size_t(e.index_list)].type));
    } else if (mEncoding != Encoding::kAscii && e.fixed && e.record_size > 0) {
      rest -= e.count > rest / e.record_size ? rest : e.count * e.record_size;
    }
  }
  return rest / (mEncoding == Encoding::kAscii ? 2 : index_bytes);
}

void PlyReader::beginAsciiInstance(const Element& e, uint64_t index) {
  // One instance per line in every writer we know; tolerate instances spanning lines.
  std::string_view line;
  do {
    if (!mSrc.readLine(line)) truncated(e, index);
    mLineRest = line;
  } while (mLineRest.find_first_not_of(" \t\r") == std::string_view::npos);
  mLineOfInstance = mSrc.lineNumber();
}

void PlyReader::endAsciiInstance(const Element& e, uint64_t index) {
  // The next instance starts on a new line: anything left on this one is a bad file.
  std::string_view extra = nextToken(mLineRest, " \t\r");
  if (!extra.empty()) {
    failHere("more values than " + e.name + " " + std::to_string(index) + " declares (" +
             shown(extra) + " is extra)");
  }
}

double PlyReader::readScalar(const Element& e, uint64_t index, PlyType t) {
  if (mEncoding == Encoding::kAscii) return asciiValue(e, index, t, isIntegerType(t));
  const size_t sz = typeSize(t);
  if (mSrc.ensure(sz) < sz) truncated(e, index);
  const double v = loadScalar(mSrc.data(), t, mSwap);
  mSrc.consume(sz);
  return v;
}

uint64_t PlyReader::readListLength(const Element& e, uint64_t index, const Property& p,
                                   double limit) {
  const double n = readScalar(e, index, p.count_type);
  if (n < 0 || n > limit) failHere("bad list length " + std::to_string(n) + " in " + e.name);
  return uint64_t(n);
}

void PlyReader::readProperty(const Element& e, uint64_t index, const Property& p, double& value,
                             std::vector<double>* list) {
  if (!p.is_list) {
    value = readScalar(e, index, p.type);
    return;
  }
  const size_t n = size_t(readListLength(e, index, p, 1e6));
  if (mEncoding == Encoding::kAscii) {
    if (list) list->clear();
    for (size_t k = 0; k < n; ++k) {
      const double x = readScalar(e, index, p.type);
      if (list) list->push_back(x);
    }
    return;
  }
  const size_t isz = typeSize(p.type);
  if (mSrc.ensure(n * isz) < n * isz) truncated(e, index);
  if (list) {
    list->resize(n);
    for (size_t k = 0; k < n; ++k) (*list)[k] = loadScalar(mSrc.data() + k * isz, p.type, mSwap);
  }
  mSrc.consume(n * isz);
}

void PlyReader::readInstance(const Element& e, uint64_t index, std::vector<double>& values,
                             std::vector<std::vector<double>>* lists) {
  if (mEncoding != Encoding::kAscii && e.fixed) {
    if (mSrc.ensure(e.record_size) < e.record_size) truncated(e, index);
    const uint8_t* rec = mSrc.data();
    for (size_t i = 0; i < e.props.size(); ++i) {
      values[i] = loadScalar(rec + e.props[i].offset, e.props[i].type, mSwap);
    }
    mSrc.consume(e.record_size);
    return;
  }
  if (mEncoding == Encoding::kAscii) beginAsciiInstance(e, index);
  for (size_t i = 0; i < e.props.size(); ++i) {
    readProperty(e, index, e.props[i], values[i], lists ? &(*lists)[i] : nullptr);
  }
  if (mEncoding == Encoding::kAscii) endAsciiInstance(e, index);
}

void PlyReader::skipVertex(uint64_t file_index) {
  mStats.skip("non-finite coordinate", mEncoding == Encoding::kAscii
                                           ? atLine(mLineOfInstance)
                                           : "vertex " + std::to_string(file_index));
  if (mRemapNeeded) mRemap.push_back(kDropped);
}

bool PlyReader::emitVertex(const std::vector<double>& values, PointBatch& batch) {
  const Element& v = mElements[size_t(mVertexElement)];
  double xyz[3] = {0, 0, 0};
  float n[3] = {0, 0, 0};
  glm::u8vec4 c(255, 255, 255, 255);
  float intensity = 0.f, confidence = 0.f;
  for (size_t i = 0; i < v.props.size(); ++i) {
    double x = values[i];
    switch (v.props[i].slot) {
      case Slot::kSkip:
        break;
      case Slot::kX:
        xyz[0] = x;
        break;
      case Slot::kY:
        xyz[1] = x;
        break;
      case Slot::kZ:
        xyz[2] = x;
        break;
      case Slot::kNx:
        n[0] = float(x);
        break;
      case Slot::kNy:
        n[1] = float(x);
        break;
      case Slot::kNz:
        n[2] = float(x);
        break;
      case Slot::kRed:
        c.r = colorByte(x, v.props[i].type);
        break;
      case Slot::kGreen:
        c.g = colorByte(x, v.props[i].type);
        break;
      case Slot::kBlue:
        c.b = colorByte(x, v.props[i].type);
        break;
      case Slot::kAlpha:
        c.a = colorByte(x, v.props[i].type);
        break;
      case Slot::kIntensity:
        intensity = float(x);
        break;
      case Slot::kConfidence:
        confidence = float(x);
        break;
    }
  }
  const glm::dvec3 p(xyz[0], xyz[1], xyz[2]);
  if (!admitVertex(p, mInstance)) return false;
  AttributeMask a = batch.attributes;
  batch.positions.push_back(p);
  if (a & kNormal) batch.normals.emplace_back(n[0], n[1], n[2]);
  if (a & kColor) batch.colors.push_back(c);
  if (a & kIntensity) batch.intensities.push_back(intensity);
  if (a & kConfidence) batch.confidences.push_back(confidence);
  if (a & kGridPosition) batch.grid_positions.emplace_back(0xFFFF, 0xFFFF);
  return true;
}

void PlyReader::readVertices(PointBatch& batch, size_t max_points) {
  const Element& v = mElements[size_t(mVertexElement)];
  if (mEncoding != Encoding::kAscii && v.fixed) {
    readFixedVertices(batch, max_points);
    return;
  }
  while (mInstance < v.count && batch.size() < max_points) {
    readInstance(v, mInstance, mValues, nullptr);
    emitVertex(mValues, batch);
    ++mInstance;
  }
}

void PlyReader::readFixedVertices(PointBatch& batch, size_t max_points) {
  const Element& v = mElements[size_t(mVertexElement)];
  // Blocks of about 64 KiB stay in cache while each column is decoded.
  const uint64_t block = std::max<size_t>(1, (size_t(64) << 10) / v.record_size);
  while (mInstance < v.count && batch.size() < max_points) {
    size_t want =
        size_t(std::min({v.count - mInstance, uint64_t(max_points - batch.size()), block}));
    size_t whole = mSrc.ensure(want * v.record_size) / v.record_size;
    decodeVertexBlock(mSrc.data(), whole, batch);
    mSrc.consume(whole * v.record_size);
    if (whole < want) truncated(v, mInstance);
  }
}

// Same results as readInstance() + emitVertex() for each record, in the same order.
void PlyReader::decodeVertexBlock(const uint8_t* records, size_t n, PointBatch& batch) {
  const Element& v = mElements[size_t(mVertexElement)];
  const AttributeMask a = batch.attributes;
  const size_t base = batch.size();
  batch.resize(base + n);
  glm::dvec3* positions = batch.positions.data() + base;
  // Arrays of attributes the batch lacks are empty: no pointer into them.
  glm::vec3* normals = (a & kNormal) ? batch.normals.data() + base : nullptr;
  glm::u8vec4* colors = (a & kColor) ? batch.colors.data() + base : nullptr;
  if (a & kColor) std::fill_n(colors, n, glm::u8vec4(255));
  if (a & kGridPosition) std::fill_n(batch.grid_positions.data() + base, n, glm::u16vec2(0xFFFF));
  for (const Property& p : v.props) {
    const uint8_t* column = records + p.offset;
    auto decode = [&](auto store) { decodeColumn(column, v.record_size, n, p.type, mSwap, store); };
    switch (p.slot) {
      case Slot::kSkip:
        break;
      case Slot::kX:
      case Slot::kY:
      case Slot::kZ: {
        const int axis = int(p.slot) - int(Slot::kX);
        decode([&](size_t i, auto x) { positions[i][axis] = double(x); });
        break;
      }
      case Slot::kNx:
      case Slot::kNy:
      case Slot::kNz: {
        const int axis = int(p.slot) - int(Slot::kNx);
        if (a & kNormal) decode([&](size_t i, auto x) { normals[i][axis] = float(double(x)); });
        break;
      }
      case Slot::kRed:
      case Slot::kGreen:
      case Slot::kBlue:
      case Slot::kAlpha: {
        const int channel = int(p.slot) - int(Slot::kRed);
        decode([&](size_t i, auto x) { colors[i][channel] = colorByteOf(x, p.type); });
        break;
      }
      case Slot::kIntensity:
        decode([&](size_t i, auto x) { batch.intensities[base + i] = float(double(x)); });
        break;
      case Slot::kConfidence:
        decode([&](size_t i, auto x) { batch.confidences[base + i] = float(double(x)); });
        break;
    }
  }
  // Skipped vertices close up the block (rare: usually every index stays where it is).
  size_t kept = base;
  for (size_t i = 0; i < n; ++i) {
    if (!admitVertex(positions[i], mInstance + i)) continue;
    if (kept != base + i) movePoint(batch, base + i, kept);
    ++kept;
  }
  batch.resize(kept);
  mInstance += n;
}

void PlyReader::readTriangles(PointBatch& batch, size_t max_triangles) {
  if (mElements[mElement].kind == ElementKind::kStrips) {
    readStrips(batch, max_triangles);
  } else {
    readFaces(batch, max_triangles);
  }
}

void PlyReader::readFaces(PointBatch& batch, size_t max_triangles) {
  const Element& e = mElements[mElement];
  while (mInstance < e.count && batch.triangles.size() < max_triangles) {
    uint64_t where = mInstance;
    readInstance(e, mInstance++, mValues, &mLists);
    const auto& idx = mLists[size_t(e.index_list)];
    if (idx.size() < 3) {
      mStats.skip("face with fewer than 3 vertices", "face " + std::to_string(where));
      continue;
    }
    if (!std::all_of(idx.begin(), idx.end(), [&](double d) { return usableVertex(d); })) {
      mStats.skip("face with an out-of-range or skipped vertex", "face " + std::to_string(where));
      continue;
    }
    for (size_t k = 1; k + 1 < idx.size(); ++k) {
      batch.triangles.emplace_back(mRemap[size_t(idx[0])], mRemap[size_t(idx[k])],
                                   mRemap[size_t(idx[k + 1])]);
    }
  }
}

void PlyReader::readStrips(PointBatch& batch, size_t max_triangles) {
  const Element& e = mElements[mElement];
  const Property& list = e.props[size_t(e.index_list)];
  while (mInstance < e.count && batch.triangles.size() < max_triangles) {
    if (!mStrip.in_list) {
      if (mEncoding == Encoding::kAscii) beginAsciiInstance(e, mInstance);
      double unused;
      for (int k = 0; k < e.index_list; ++k)
        readProperty(e, mInstance, e.props[size_t(k)], unused, nullptr);
      // No limit but the file: one list often holds the whole mesh. Each index takes a byte at
      // least, so a longer list is a truncated file.
      const uint64_t n = readListLength(e, mInstance, list, 1e18);
      const uint64_t bytes_left = mSrc.size() - mSrc.offset() + mLineRest.size();
      if (n > bytes_left) {
        mSrc.seek(mSrc.size());
        truncated(e, mInstance);
      }
      mStrip = StripState{};
      mStrip.in_list = true;
      mStrip.left = n;
    }
    while (mStrip.left > 0 && batch.triangles.size() < max_triangles) {
      const double d = readScalar(e, mInstance, list.type);
      --mStrip.left;
      addStripIndex(d, batch);
      ++mStrip.position;
    }
    if (mStrip.left > 0) return;  // the batch is full: the list goes on in the next one
    endStrip();
    double unused;
    for (size_t k = size_t(e.index_list) + 1; k < e.props.size(); ++k)
      readProperty(e, mInstance, e.props[k], unused, nullptr);
    if (mEncoding == Encoding::kAscii) endAsciiInstance(e, mInstance);
    mStrip.in_list = false;
    ++mInstance;
  }
}

// Triangle k of a strip v0 v1 v2 ... is (v[k], v[k+1], v[k+2]) for even k and
// (v[k+1], v[k], v[k+2]) for odd k, so every triangle keeps the first one's winding.
void PlyReader::addStripIndex(double d, PointBatch& batch) {
  StripState& s = mStrip;
  // -1 ends a strip; an unsigned 32-bit list writes it as 0xFFFFFFFF (never a vertex: a mesh has
  // at most 2^32 - 2).
  if (d == -1.0 || d == 4294967295.0) {
    endStrip();
    return;
  }
  if (s.length >= 2) {
    const bool odd = (s.length - 2) % 2 == 1;
    const double a = odd ? s.b : s.a, b = odd ? s.a : s.b;
    if (a == b || b == d || a == d) {
      mStats.skip("degenerate strip triangle (a vertex repeated)", stripPosition(s.position));
    } else if (!usableVertex(a) || !usableVertex(b) || !usableVertex(d)) {
      mStats.skip("strip triangle with an out-of-range or skipped vertex",
                  stripPosition(s.position));
    } else {
      batch.triangles.emplace_back(mRemap[size_t(a)], mRemap[size_t(b)], mRemap[size_t(d)]);
    }
  }
  s.a = s.b;
  s.b = d;
  ++s.length;
}

void PlyReader::endStrip() {
  if (mStrip.length == 1 || mStrip.length == 2)
    mStats.skip("strip with fewer than 3 vertices", stripPosition(mStrip.position - mStrip.length));
  mStrip.length = 0;
}

std::string PlyReader::stripPosition(uint64_t position) const {
  return mElements[mElement].name + " " + std::to_string(mInstance) + ", index " +
         std::to_string(position);
}

void PlyReader::readRangeGrid() {
  const Element& e = mElements[mElement];
  auto assign = [&](double d) {
    if (!(d >= 0) || d >= double(mRemap.size())) {  // NaN too: a float list can hold one
      char index[32];  // %g: no integer type holds every float (1e30, nan)
      std::snprintf(index, sizeof index, "%.15g", d);
      failHere("range_grid cell " + std::to_string(mInstance) + " names vertex " + index +
               " outside the " + std::to_string(mRemap.size()) + " vertices");
    }
    uint32_t kept = mRemap[size_t(d)];
    if (kept == kDropped) return;
    mBuffer.grid_positions[kept] =
        glm::u16vec2(uint16_t(mInstance % mGridCols), uint16_t(mInstance / mGridCols));
  };
  if (mEncoding != Encoding::kAscii) {
    // Binary: a tight loop over whole cells in the buffer (count, then that many indices);
    // a range grid has one cell per range-image pixel, so this is the bulk of a scan file.
    const Property& p = e.props[0];
    const size_t csz = typeSize(p.count_type), isz = typeSize(p.type);
    size_t want = size_t(1) << 16;
    while (mInstance < e.count) {
      size_t avail = mSrc.ensure(want);
      want = size_t(1) << 16;
      const uint8_t* b = mSrc.data();
      size_t used = 0;
      if (p.count_type == PlyType::kUInt8 &&
          (p.type == PlyType::kInt32 || p.type == PlyType::kUInt32)) {
        // The Stanford layout (uchar count, int index): most cells are empty single zero bytes.
        while (mInstance < e.count && used < avail) {
          const uint8_t n = b[used];
          if (n == 0) {
            ++used;
            ++mInstance;
            continue;
          }
          if (used + 1 + size_t(n) * 4 > avail) break;
          for (size_t k = 0; k < n; ++k) {
            const uint8_t* q = b + used + 1 + 4 * k;
            assign(p.type == PlyType::kInt32 ? double(load<int32_t>(q, mSwap))
                                             : double(load<uint32_t>(q, mSwap)));
          }
          used += 1 + size_t(n) * 4;
          ++mInstance;
        }
      }
      while (mInstance < e.count && used + csz <= avail) {
        double n = loadScalar(b + used, p.count_type, mSwap);
        if (n < 0 || n > 1e6) failHere("bad list length " + std::to_string(n) + " in range_grid");
        size_t need = csz + size_t(n) * isz;
        if (used + need > avail) break;
        for (size_t k = 0; k < size_t(n); ++k)
          assign(loadScalar(b + used + csz + k * isz, p.type, mSwap));
        used += need;
        ++mInstance;
      }
      if (used == 0) {
        // One cell larger than the window: ask for exactly its size (ensure() grows the buffer).
        if (avail < csz) truncated(e, mInstance);
        double n = loadScalar(b, p.count_type, mSwap);
        if (n < 0 || n > 1e6) failHere("bad list length " + std::to_string(n) + " in range_grid");
        want = csz + size_t(n) * isz;
        if (avail >= want) truncated(e, mInstance);  // cannot happen: it would have been parsed
        if (mSrc.ensure(want) < want) truncated(e, mInstance);
        continue;
      }
      mSrc.consume(used);
    }
    return;
  }
  for (; mInstance < e.count; ++mInstance) {
    readInstance(e, mInstance, mValues, &mLists);
    for (double d : mLists[0]) assign(d);
  }
}

void PlyReader::skipElement(const Element& e) {
  if (mEncoding != Encoding::kAscii && e.fixed) {
    // Compared in records, not bytes: count * record_size can wrap around 64 bits.
    uint64_t left = e.count - mInstance;
    uint64_t room = e.record_size ? (mSrc.size() - mSrc.offset()) / e.record_size : left;
    if (left > room) {
      mSrc.seek(mSrc.size());
      truncated(e, mInstance + room);
    }
    mSrc.seek(mSrc.offset() + left * e.record_size);
    mInstance = e.count;
    return;
  }
  for (; mInstance < e.count; ++mInstance) readInstance(e, mInstance, mValues, nullptr);
}

void PlyReader::advanceElement() {
  ++mElement;
  mInstance = 0;
  if (mElement < mElements.size()) {
    mValues.resize(std::max(mValues.size(), mElements[mElement].props.size()));
  }
}

// Reads the whole scan (vertices, faces, range grid) into mBuffer. Bounded by the grid size.
bool PlyReader::fillBuffered() {
  mBuffer.reset(mInfo.attributes);
  while (mElement < mElements.size()) {
    const Element& e = mElements[mElement];
    if (int(mElement) == mVertexElement) {
      readVertices(mBuffer, std::numeric_limits<size_t>::max());
    } else if (e.kind != ElementKind::kOther) {
      PointBatch tmp;
      readTriangles(tmp, std::numeric_limits<size_t>::max());
      mBufferedTriangles.insert(mBufferedTriangles.end(), tmp.triangles.begin(),
                                tmp.triangles.end());
    } else if (int(mElement) == mGridElement &&
               mRemap.size() == mElements[size_t(mVertexElement)].count) {
      readRangeGrid();
    } else {
      skipElement(e);
    }
    advanceElement();
  }
  mBuffered = true;
  return true;
}

bool PlyReader::next(PointBatch& batch, size_t max_points) {
  batch.reset(mInfo.attributes);
  max_points = std::max<size_t>(1, max_points);
  if (mBufferGrid) {
    if (!mBuffered) fillBuffered();
    size_t n = std::min(max_points, mBuffer.size() - mBufferPos);
    batch.appendRange(mBuffer, mBufferPos, n);
    mBufferPos += n;
    if (mBufferPos == mBuffer.size() && !mBufferedTriangles.empty()) {
      batch.triangles.swap(mBufferedTriangles);
      mBufferedTriangles.clear();
    }
    mStats.points += batch.size();
    mStats.triangles += batch.triangles.size();
    return !batch.empty();
  }
  while (mElement < mElements.size() && batch.empty()) {
    const Element& e = mElements[mElement];
    if (int(mElement) == mVertexElement) {
      readVertices(batch, max_points);
    } else if (e.kind != ElementKind::kOther) {
      readTriangles(batch, max_points);
    } else {
      skipElement(e);
    }
    if (mInstance >= mElements[mElement].count) advanceElement();
  }
  mStats.points += batch.size();
  mStats.triangles += batch.triangles.size();
  return !batch.empty();
}

}  // namespace

std::unique_ptr<PointReader> openPly(ByteSource source) {
  return std::make_unique<PlyReader>(std::move(source));
}

}  // namespace tessera::lod::detail
