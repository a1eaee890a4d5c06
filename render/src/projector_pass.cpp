#include <tessera/render/projector_pass.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <png.h>
#include <pugixml.hpp>
#include <zip.h>

#include <tessera/core/check.h>
#include <tessera/render/frame_target.h>
#include <tessera/core/file_checks.h>
#include <tessera/core/parallel.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/tile_frustum.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/vec3.h>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include "shaders.h"

namespace tessera::render {
namespace {

constexpr const char* kFn = "render::loadProjectorMaps()";

[[noreturn]] void fail(const std::string& file, const std::string& field, const std::string& what) {
  throw RenderError(std::string(kFn) + ": " + file + ": " + (field.empty() ? "" : field + ": ") +
                    what);
}

std::vector<uint8_t> readFile(const std::string& path, const std::string& field) {
  if (const auto why = notRegularFile(path)) fail(path, field, "cannot open: " + *why);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, field, "cannot open");
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

/// Grey levels of a PNG (its first channel), 0..1, top row first.
std::vector<float> decodeMask(std::span<const uint8_t> bytes, const std::string& name,
                              const std::string& field, uint32_t width, uint32_t height) {
  png_image img;
  std::memset(&img, 0, sizeof img);
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&img, bytes.data(), bytes.size()))
    fail(name, field, std::string("not a PNG: ") + img.message);
  if (img.width != width || img.height != height) {
    png_image_free(&img);
    fail(name, field,
         "is " + std::to_string(img.width) + " x " + std::to_string(img.height) +
             " pixels; the tile's projector has " + std::to_string(width) + " x " +
             std::to_string(height));
  }
  img.format = PNG_FORMAT_GRAY;  // 8 bits; RGB is reduced to its luminance by libpng
  std::vector<uint8_t> grey(size_t(width) * height);
  if (!png_image_finish_read(&img, nullptr, grey.data(), 0, nullptr))
    fail(name, field, std::string("unreadable PNG: ") + img.message);
  std::vector<float> out(grey.size());
  for (size_t i = 0; i < grey.size(); ++i) out[i] = grey[i] / 255.0f;
  return out;
}

/// readPfm() with the field in its message.
FloatImage pfmOf(std::span<const uint8_t> bytes, const std::string& name, const std::string& field) {
  try {
    return readPfm(bytes, name);
  } catch (const RenderError& e) {
    const std::string prefix = "render::readPfm(): " + name + ": ";
    std::string what = e.what();
    if (what.rfind(prefix, 0) == 0) what = what.substr(prefix.size());
    fail(name, field, what);
  }
}

/// A warp from a PFM: (u, v) per vertex from the first two channels.
void setWarp(ProjectorMap& map, const FloatImage& pfm, const std::string& name,
             const std::string& field) {
  if (pfm.channels != 3) fail(name, field, "a warp needs three channels (PF), got one (Pf)");
  if (pfm.width < 2 || pfm.height < 2)
    fail(name, field,
         "a warp needs at least 2 x 2 vertices, got " + std::to_string(pfm.width) + " x " +
             std::to_string(pfm.height));
  map.grid_width = pfm.width;
  map.grid_height = pfm.height;
  map.warp.resize(size_t(pfm.width) * pfm.height);
  for (size_t i = 0; i < map.warp.size(); ++i)
    map.warp[i] = glm::vec2(pfm.values[i * 3], pfm.values[i * 3 + 1]);
}

/// The entries of a zip file by name.
class ZipFile {
 public:
  ZipFile(const std::string& path) : mPath(path) {
    if (const auto why = notRegularFile(path)) fail(path, "", "cannot open: " + *why);
    int err = 0;
    mZip = zip_open(path.c_str(), ZIP_RDONLY, &err);
    if (!mZip) {
      zip_error_t e;
      zip_error_init_with_code(&e, err);
      const std::string what = zip_error_strerror(&e);
      zip_error_fini(&e);
      fail(path, "", "not a readable MPCDI zip: " + what);
    }
  }
  ~ZipFile() {
    if (mZip) zip_discard(mZip);
  }
  ZipFile(const ZipFile&) = delete;
  ZipFile& operator=(const ZipFile&) = delete;

  std::vector<uint8_t> read(const std::string& entry, const std::string& field) const {
    zip_stat_t st;
    if (zip_stat(mZip, entry.c_str(), 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE))
      fail(mPath, field, "the zip has no file '" + entry + "'");
    if (st.size > (uint64_t(1) << 31)) fail(mPath, field, "'" + entry + "' is over 2 GiB");
    zip_file_t* f = zip_fopen(mZip, entry.c_str(), 0);
    if (!f) fail(mPath, field, "cannot open '" + entry + "' in the zip");
    std::vector<uint8_t> bytes(st.size);
    const zip_int64_t got = zip_fread(f, bytes.data(), st.size);
    zip_fclose(f);
    if (got < 0 || uint64_t(got) != st.size) fail(mPath, field, "'" + entry + "' is damaged");
    return bytes;
  }

 private:
  std::string mPath;
  zip_t* mZip = nullptr;
};

pugi::xml_node child(const pugi::xml_node& n, const char* name, const std::string& file,
                     const std::string& path) {
  const pugi::xml_node c = n.child(name);
  if (!c) fail(file, path + "/" + name, "missing element");
  return c;
}

/// A 3D warp's points (the screen's frame: the wall frame, metres) as (u, v) of the tile: the
/// ray from the eye through each point meets the tile's plane there.
void warp3dToUv(ProjectorMap& map, const FloatImage& pfm, const config::WallConfig& wall,
                const config::Tile& tile, const std::string& name, const std::string& field) {
  const TilePlane plane = tilePlane(tile);
  const glm::dvec3 eye = sync::vec(wall.eye());
  map.grid_width = pfm.width;
  map.grid_height = pfm.height;
  map.warp.resize(size_t(pfm.width) * pfm.height);
  for (size_t i = 0; i < map.warp.size(); ++i) {
    const glm::dvec3 p(pfm.values[i * 3], pfm.values[i * 3 + 1], pfm.values[i * 3 + 2]);
    const double den = glm::dot(p - eye, plane.normal);
    if (!(den < 0))
      fail(name, field,
           "vertex " + std::to_string(i) + " is not in front of the eye towards the tile '" +
               tile.name() + "'");
    const double t = glm::dot(plane.origin - eye, plane.normal) / den;
    map.warp[i] = glm::vec2(plane.uv(eye + (p - eye) * t));
  }
}

void loadMpcdi(const config::WallConfig& wall, std::vector<ProjectorMap>& maps,
               bool with_blend) {
  const std::string& file = wall.mpcdi();
  const ZipFile zip(file);
  const std::vector<uint8_t> xml = zip.read("mpcdi.xml", "mpcdi.xml");
  pugi::xml_document doc;
  const pugi::xml_parse_result parsed = doc.load_buffer(xml.data(), xml.size());
  if (!parsed)
    fail(file, "mpcdi.xml", std::string("not XML: ") + parsed.description() + " at byte " +
                                std::to_string(parsed.offset));
  const pugi::xml_node root = child(doc, "MPCDI", file, "mpcdi.xml");
  const std::string profile = root.attribute("profile").as_string();
  if (profile != "2d" && profile != "3d")
    fail(file, "MPCDI@profile",
         "is '" + profile + "': only the 2d and 3d profiles' warps and blends are read");
  const pugi::xml_node display = child(root, "display", file, "MPCDI");
  std::map<std::string, int> tile_of;
  for (int i = 0; i < wall.tiles_size(); ++i) tile_of[wall.tiles(i).name()] = i;
  std::map<std::string, bool> seen;
  for (const pugi::xml_node buffer : display.children("buffer")) {
    for (const pugi::xml_node region : buffer.children("region")) {
      const std::string id = region.attribute("id").as_string();
      const std::string where = "region '" + id + "'";
      const auto it = tile_of.find(id);
      if (it == tile_of.end())
        fail(file, where, "the wall has no tile of that name (a region's id names its tile)");
      const config::Tile& tile = wall.tiles(it->second);
      const uint32_t xr = region.attribute("xResolution").as_uint(),
                     yr = region.attribute("yResolution").as_uint();
      if (xr != tile.pixel_width() || yr != tile.pixel_height())
        fail(file, where + "@xResolution",
             std::to_string(xr) + " x " + std::to_string(yr) + " but tile '" + id + "' has " +
                 std::to_string(tile.pixel_width()) + " x " + std::to_string(tile.pixel_height()) +
                 " pixels");
      seen[id] = true;
    }
  }
  const pugi::xml_node files = child(root, "files", file, "MPCDI");
  for (const pugi::xml_node fileset : files.children("fileset")) {
    const std::string id = fileset.attribute("region").as_string();
    const std::string where = "fileset '" + id + "'";
    if (!seen.count(id)) fail(file, where, "names no region of the display");
    const int index = tile_of.at(id);
    const config::Tile& tile = wall.tiles(index);
    ProjectorMap& map = maps[size_t(index)];
    if (const pugi::xml_node warp = fileset.child("geometryWarpFile")) {
      const std::string entry = child(warp, "path", file, where + "/geometryWarpFile").text().get();
      const std::string field = where + "/geometryWarpFile " + entry;
      const FloatImage pfm = pfmOf(zip.read(entry, field), file, field);
      if (pfm.channels != 3) fail(file, field, "a warp needs three channels (PF)");
      if (pfm.width < 2 || pfm.height < 2) fail(file, field, "a warp needs at least 2 x 2 vertices");
      if (!tile.warp().empty()) continue;  // the tile's own warp wins
      if (profile == "3d")
        warp3dToUv(map, pfm, wall, tile, file, field);
      else
        setWarp(map, pfm, file, field);
    }
    if (const pugi::xml_node alpha = fileset.child("alphaMap"); alpha && with_blend) {
      const std::string entry = child(alpha, "path", file, where + "/alphaMap").text().get();
      const std::string field = where + "/alphaMap " + entry;
      double embedded = 2.2;
      if (const pugi::xml_node g = alpha.child("gammaEmbedded")) {
        embedded = g.text().as_double(NAN);
        if (!std::isfinite(embedded) || embedded <= 0 || embedded > 10)
          fail(file, where + "/alphaMap/gammaEmbedded", "must be in (0, 10]");
      }
      std::vector<float> mask =
          decodeMask(zip.read(entry, field), file + ": " + entry, field, map.width, map.height);
      if (!tile.blend().empty()) continue;  // the tile's own blend wins
      // The map holds the weight with the gamma embedded: linear light is a^gamma.
      for (float& a : mask) a = float(std::pow(double(a), embedded));
      map.blend = std::move(mask);
    }
  }
}

/// The distance of (s, t) from the nearest edge of the projector's outermost pixel centres (so
/// its edge pixels are dark and its light fades to nothing where its picture ends), s, t units.
double edgeDistance(const glm::dvec2& st, const ProjectorMap& m) {
  const double hx = 0.5 / m.width, hy = 0.5 / m.height;
  return std::max(0.0, std::min(std::min(st.x - hx, 1.0 - hx - st.x),
                                std::min(st.y - hy, 1.0 - hy - st.y)));
}

bool inUnit(const glm::dvec2& p) {
  return p.x >= 0 && p.x <= 1 && p.y >= 0 && p.y <= 1;
}

glm::dvec4 decode(const uint8_t* p) {
  return glm::dvec4(p[0], p[1], p[2], p[3]) / 255.0;
}

/// The picture's bilinear sample at (s, t) (0..1 over it), between pixel centres, clamped; with
/// `gamma`, of the pixels' light (value^gamma) instead of their values.
glm::dvec3 sample(const Image& img, const glm::dvec2& st, double gamma = 1.0) {
  const glm::dvec2 p = st * glm::dvec2(img.width, img.height) - 0.5;
  const glm::ivec2 p0 = glm::ivec2(glm::floor(p));
  const glm::dvec2 f = p - glm::dvec2(p0);
  auto at = [&](int x, int y) {
    x = std::clamp(x, 0, int(img.width) - 1);
    y = std::clamp(y, 0, int(img.height) - 1);
    const glm::dvec3 v(decode(&img.rgba[(size_t(y) * img.width + x) * 4]));
    return gamma == 1.0 ? v : glm::pow(v, glm::dvec3(gamma));
  };
  return glm::mix(glm::mix(at(p0.x, p0.y), at(p0.x + 1, p0.y), f.x),
                  glm::mix(at(p0.x, p0.y + 1), at(p0.x + 1, p0.y + 1), f.x), f.y);
}

}  // namespace

glm::dvec2 ProjectorMap::warpAt(const glm::dvec2& st) const {
  if (warp.empty()) return st;
  const glm::dvec2 g = st * glm::dvec2(grid_width - 1, grid_height - 1);
  const glm::ivec2 c = glm::clamp(glm::ivec2(glm::floor(g)), glm::ivec2(0),
                                  glm::ivec2(grid_width - 2, grid_height - 2));
  const glm::dvec2 f = g - glm::dvec2(c);
  auto v = [&](int i, int j) { return glm::dvec2(warp[size_t(j) * grid_width + i]); };
  return glm::mix(glm::mix(v(c.x, c.y), v(c.x + 1, c.y), f.x),
                  glm::mix(v(c.x, c.y + 1), v(c.x + 1, c.y + 1), f.x), f.y);
}

WarpInverse::WarpInverse(const ProjectorMap& map) : mMap(&map) {
  if (map.warp.empty()) return;
  mLo = glm::dvec2(1e300);
  mHi = glm::dvec2(-1e300);
  for (const glm::vec2& v : map.warp) {
    mLo = glm::min(mLo, glm::dvec2(v));
    mHi = glm::max(mHi, glm::dvec2(v));
  }
  mHi = glm::max(mHi, mLo + 1e-9);
  mBuckets = int(std::max(map.grid_width, map.grid_height)) * 2;
  mCells.resize(size_t(mBuckets) * mBuckets);
  const uint32_t gw = map.grid_width;
  for (uint32_t j = 0; j + 1 < map.grid_height; ++j) {
    for (uint32_t i = 0; i + 1 < gw; ++i) {
      glm::dvec2 lo(1e300), hi(-1e300);
      for (uint32_t k = 0; k < 4; ++k) {
        const glm::dvec2 v(map.warp[size_t(j + k / 2) * gw + i + k % 2]);
        lo = glm::min(lo, v);
        hi = glm::max(hi, v);
      }
      const glm::ivec2 b0 = glm::clamp(glm::ivec2((lo - mLo) / (mHi - mLo) * double(mBuckets)),
                                       0, mBuckets - 1),
                       b1 = glm::clamp(glm::ivec2((hi - mLo) / (mHi - mLo) * double(mBuckets)),
                                       0, mBuckets - 1);
      for (int y = b0.y; y <= b1.y; ++y)
        for (int x = b0.x; x <= b1.x; ++x) mCells[size_t(y) * mBuckets + x].push_back(j * gw + i);
    }
  }
}

std::optional<glm::dvec2> WarpInverse::operator()(const glm::dvec2& uv) const {
  const ProjectorMap& m = *mMap;
  if (m.warp.empty()) return inUnit(uv) ? std::optional<glm::dvec2>(uv) : std::nullopt;
  if (uv.x < mLo.x || uv.y < mLo.y || uv.x > mHi.x || uv.y > mHi.y) return std::nullopt;
  const glm::ivec2 b =
      glm::clamp(glm::ivec2((uv - mLo) / (mHi - mLo) * double(mBuckets)), 0, mBuckets - 1);
  const uint32_t gw = m.grid_width;
  for (const uint32_t cell : mCells[size_t(b.y) * mBuckets + b.x]) {
    const uint32_t i = cell % gw, j = cell / gw;
    const glm::dvec2 p00(m.warp[size_t(j) * gw + i]), p10(m.warp[size_t(j) * gw + i + 1]),
        p01(m.warp[size_t(j + 1) * gw + i]), p11(m.warp[size_t(j + 1) * gw + i + 1]);
    // Newton's method on the bilinear map from the cell's centre.
    glm::dvec2 f(0.5);
    for (int it = 0; it < 12; ++it) {
      const glm::dvec2 p = glm::mix(glm::mix(p00, p10, f.x), glm::mix(p01, p11, f.x), f.y);
      const glm::dvec2 du = glm::mix(p10 - p00, p11 - p01, f.y),
                       dv = glm::mix(p01 - p00, p11 - p10, f.x);
      const double det = du.x * dv.y - du.y * dv.x;
      if (std::abs(det) < 1e-300) break;
      const glm::dvec2 r = uv - p;
      f += glm::dvec2(r.x * dv.y - r.y * dv.x, du.x * r.y - du.y * r.x) / det;
    }
    const glm::dvec2 p = glm::mix(glm::mix(p00, p10, f.x), glm::mix(p01, p11, f.x), f.y);
    if (f.x >= -1e-9 && f.x <= 1 + 1e-9 && f.y >= -1e-9 && f.y <= 1 + 1e-9 &&
        glm::length(p - uv) < 1e-9) {
      return glm::clamp((glm::dvec2(i, j) + glm::clamp(f, 0.0, 1.0)) /
                            glm::dvec2(gw - 1, m.grid_height - 1),
                        0.0, 1.0);
    }
  }
  return std::nullopt;
}

FloatImage readPfm(std::span<const uint8_t> bytes, const std::string& name) {
  // Header: "PF" or "Pf", width height, scale (negative: little-endian), each ended by white
  // space; then the floats, rows bottom to top.
  size_t pos = 0;
  auto token = [&](const char* what) {
    while (pos < bytes.size() && std::isspace(bytes[pos])) ++pos;
    std::string t;
    while (pos < bytes.size() && !std::isspace(bytes[pos]) && t.size() < 32) t += char(bytes[pos++]);
    if (t.empty()) throw RenderError("render::readPfm(): " + name + ": no " + what + " in the header");
    return t;
  };
  const std::string magic = token("PF/Pf tag");
  if (magic != "PF" && magic != "Pf")
    throw RenderError("render::readPfm(): " + name + ": not a PFM (it starts with '" + magic +
                      "', not PF or Pf)");
  FloatImage img;
  img.channels = magic == "PF" ? 3 : 1;
  auto number = [&](const char* what) {
    const std::string t = token(what);
    char* end = nullptr;
    const double v = std::strtod(t.c_str(), &end);
    if (*end != 0 || !std::isfinite(v))
      throw RenderError("render::readPfm(): " + name + ": the " + what + " '" + t +
                        "' is not a number");
    return v;
  };
  const double w = number("width"), h = number("height"), scale = number("scale");
  if (!(w >= 1 && h >= 1 && w <= 65536 && h <= 65536 && w == std::floor(w) && h == std::floor(h)))
    throw RenderError("render::readPfm(): " + name + ": width and height must be 1..65536");
  if (scale == 0) throw RenderError("render::readPfm(): " + name + ": the scale is 0");
  ++pos;  // the single white space character after the scale
  img.width = uint32_t(w);
  img.height = uint32_t(h);
  const size_t count = size_t(img.width) * img.height * img.channels;
  if (bytes.size() < pos || bytes.size() - pos != count * 4)
    throw RenderError("render::readPfm(): " + name + ": " + std::to_string(img.width) + " x " +
                      std::to_string(img.height) + " x " + std::to_string(img.channels) +
                      " floats need " + std::to_string(count * 4) + " bytes of data, the file has " +
                      std::to_string(bytes.size() > pos ? bytes.size() - pos : 0));
  const bool little = scale < 0;
  img.values.resize(count);
  const size_t row = size_t(img.width) * img.channels;
  for (uint32_t y = 0; y < img.height; ++y) {
    for (size_t k = 0; k < row; ++k) {
      uint32_t bits;
      std::memcpy(&bits, &bytes[pos + ((size_t(y) * row) + k) * 4], 4);
      if (little != (std::endian::native == std::endian::little)) bits = __builtin_bswap32(bits);
      float v;
      std::memcpy(&v, &bits, 4);
      if (!std::isfinite(v))
        throw RenderError("render::readPfm(): " + name + ": value " + std::to_string(k) +
                          " of row " + std::to_string(y) + " (from the bottom) is not finite");
      img.values[size_t(img.height - 1 - y) * row + k] = v;
    }
  }
  return img;
}

std::vector<uint8_t> writePfm(const FloatImage& img) {
  const std::string head = std::string(img.channels == 3 ? "PF" : "Pf") + "\n" +
                           std::to_string(img.width) + " " + std::to_string(img.height) +
                           "\n-1.0\n";
  std::vector<uint8_t> out(head.begin(), head.end());
  const size_t row = size_t(img.width) * img.channels;
  for (uint32_t y = img.height; y-- > 0;) {
    const uint8_t* p = reinterpret_cast<const uint8_t*>(&img.values[size_t(y) * row]);
    out.insert(out.end(), p, p + row * 4);
  }
  return out;
}

bool hasProjectors(const config::WallConfig& wall) {
  if (!wall.mpcdi().empty()) return true;
  return std::any_of(wall.tiles().begin(), wall.tiles().end(), [](const config::Tile& t) {
    return !t.blend().empty() || !t.warp().empty();
  });
}

std::vector<ProjectorMap> loadProjectorMaps(const config::WallConfig& wall, bool with_blend,
                                           int only_blend) {
  std::vector<ProjectorMap> maps(size_t(wall.tiles_size()));
  for (int i = 0; i < wall.tiles_size(); ++i) {
    const config::Tile& t = wall.tiles(i);
    ProjectorMap& m = maps[size_t(i)];
    m.width = t.pixel_width();
    m.height = t.pixel_height();
    m.gamma = t.gamma() > 0 ? t.gamma() : 2.2;
    const std::string f = "tiles[" + std::to_string(i) + "]";
    if (!t.warp().empty()) {
      const FloatImage pfm = pfmOf(readFile(t.warp(), f + ".warp"), t.warp(), f + ".warp");
      setWarp(m, pfm, t.warp(), f + ".warp");
    }
    if (with_blend && !t.blend().empty() && t.blend() != "auto") {
      m.blend = decodeMask(readFile(t.blend(), f + ".blend"), t.blend(), f + ".blend", m.width,
                           m.height);
    }
  }
  if (!wall.mpcdi().empty()) loadMpcdi(wall, maps, with_blend);
  if (with_blend) {
    for (int i = 0; i < wall.tiles_size(); ++i)
      if (wall.tiles(i).blend() == "auto" && (only_blend < 0 || only_blend == i))
        maps[size_t(i)].blend = autoBlend(wall, maps, i);
  }
  return maps;
}

std::vector<float> autoBlend(const config::WallConfig& wall, std::span<const ProjectorMap> maps,
                             int index) {
  TESSERA_CHECK(maps.size() == size_t(wall.tiles_size()), "one map per tile");
  const ProjectorMap& me = maps[size_t(index)];
  const TilePlane plane = tilePlane(wall.tiles(index));
  struct Other {
    TilePlane plane;
    WarpInverse inverse;
    const ProjectorMap* map;
  };
  std::vector<Other> others;
  for (int j = 0; j < wall.tiles_size(); ++j) {
    if (j == index) continue;
    const TilePlane p = tilePlane(wall.tiles(j));
    if (samePlane(plane, p)) others.push_back({p, WarpInverse(maps[size_t(j)]), &maps[size_t(j)]});
  }
  std::vector<float> w(size_t(me.width) * me.height, 1.0f);
  parallelFor(me.height, threadCount(), [&](size_t y) {
    for (uint32_t x = 0; x < me.width; ++x) {
      const glm::dvec2 st((x + 0.5) / me.width, (y + 0.5) / me.height);
      const double mine = edgeDistance(st, me);
      const glm::dvec3 p = plane.at(me.warpAt(st).x, me.warpAt(st).y);
      double sum = mine;
      int reaching = 1;
      for (const Other& o : others) {
        const glm::dvec2 uv = o.plane.uv(p);
        if (!inUnit(uv)) continue;
        if (const auto s = o.inverse(uv)) {
          sum += edgeDistance(*s, *o.map);
          ++reaching;
        }
      }
      // Where every projector reaching the point is at its edge (a lone projector's border),
      // they share it.
      w[y * me.width + x] = sum > 0 ? float(mine / sum) : 1.0f / float(reaching);
    }
  });
  return w;
}

Image applyProjector(const ProjectorMap& map, const Image& rendered) {
  TESSERA_CHECK(rendered.width == map.width && rendered.height == map.height,
                "render::applyProjector(): a picture of the projector's size");
  Image out = rendered;
  for (uint32_t y = 0; y < map.height; ++y) {
    for (uint32_t x = 0; x < map.width; ++x) {
      const size_t i = size_t(y) * map.width + x;
      glm::dvec3 rgb = decode(&rendered.rgba[i * 4]);
      if (!map.warp.empty()) {
        const glm::dvec2 uv = map.warpAt({(x + 0.5) / map.width, (y + 0.5) / map.height});
        rgb = inUnit(uv) ? sample(rendered, uv) : glm::dvec3(0.0);
      }
      if (!map.blend.empty()) rgb *= std::pow(std::max(0.0f, map.blend[i]), 1.0 / map.gamma);
      for (int c = 0; c < 3; ++c)
        out.rgba[i * 4 + c] = uint8_t(std::lround(std::clamp(rgb[c], 0.0, 1.0) * 255.0));
      out.rgba[i * 4 + 3] = 255;
    }
  }
  return out;
}

Image recomposeScreen(const config::WallConfig& wall, std::span<const Image> pictures,
                      std::span<const ProjectorMap> maps) {
  TESSERA_CHECK(pictures.size() == size_t(wall.tiles_size()) && maps.size() == pictures.size(),
                "render::recomposeScreen(): one picture and one map per tile");
  for (size_t i = 0; i < pictures.size(); ++i)
    TESSERA_CHECK(pictures[i].width == maps[i].width && pictures[i].height == maps[i].height &&
                      pictures[i].rgba.size() == size_t(maps[i].width) * maps[i].height * 4,
                  "render::recomposeScreen(): each picture of its tile's size");
  std::vector<TilePlane> planes;
  std::vector<WarpInverse> inverses;
  for (int i = 0; i < wall.tiles_size(); ++i) {
    planes.push_back(tilePlane(wall.tiles(i)));
    inverses.emplace_back(maps[size_t(i)]);
  }
  // The light at a point of the screen, in linear light; `gamma` of the first projector there.
  auto light = [&](const glm::dvec3& p, const TilePlane& on, double& gamma) {
    glm::dvec3 sum(0.0);
    gamma = 0;
    for (size_t j = 0; j < planes.size(); ++j) {
      if (!samePlane(on, planes[j])) continue;
      const glm::dvec2 uv = planes[j].uv(p);
      if (!inUnit(uv)) continue;
      const auto st = inverses[j](uv);
      if (!st) continue;
      if (gamma == 0) gamma = maps[j].gamma;
      sum += sample(pictures[j], *st, maps[j].gamma);  // light blurs linearly
    }
    return sum;
  };
  auto put = [&](uint8_t* px, const glm::dvec3& sum, double gamma) {
    if (gamma == 0) {
      px[0] = px[1] = px[2] = kBezelGrey;
    } else {
      for (int c = 0; c < 3; ++c)
        px[c] = uint8_t(
            std::lround(std::clamp(std::pow(sum[c], 1.0 / gamma), 0.0, 1.0) * 255.0));
    }
    px[3] = 255;
  };
  Image out;
  if (isRoom(wall)) {
    const glm::uvec2 size = roomNetSize(wall);
    out.width = size.x;
    out.height = size.y;
    out.rgba.assign(size_t(out.width) * out.height * 4, 0);
    for (size_t i = 0; i < out.rgba.size(); i += 4) put(&out.rgba[i], {}, 0);
    for (int i = 0; i < wall.tiles_size(); ++i) {
      const config::Tile& t = wall.tiles(i);
      const glm::ivec2 off = roomNetOffset(wall, t);
      parallelFor(t.pixel_height(), threadCount(), [&](size_t y) {
        for (uint32_t x = 0; x < t.pixel_width(); ++x) {
          const glm::dvec3 p =
              planes[size_t(i)].at((x + 0.5) / t.pixel_width(), (y + 0.5) / t.pixel_height());
          double gamma;
          const glm::dvec3 sum = light(p, planes[size_t(i)], gamma);
          put(&out.rgba[((y + off.y) * out.width + off.x + x) * 4], sum, gamma);
        }
      });
    }
    return out;
  }
  config::Camera camera;
  camera.mutable_eye()->set_z(1.0);
  camera.mutable_up()->set_y(1.0);
  const ViewSetup whole = wholeWallView(wall, camera);
  const glm::dvec4 e = wallExtent(wall);
  out.width = whole.width;
  out.height = whole.height;
  out.rgba.resize(size_t(out.width) * out.height * 4);
  const TilePlane wall_plane;  // z = 0
  parallelFor(out.height, threadCount(), [&](size_t y) {
    for (uint32_t x = 0; x < out.width; ++x) {
      const glm::dvec3 p(e.x + (x + 0.5) / whole.pixels_per_metre.x,
                         e.w - (y + 0.5) / whole.pixels_per_metre.y, 0.0);
      double gamma;
      const glm::dvec3 sum = light(p, wall_plane, gamma);
      put(&out.rgba[(y * out.width + x) * 4], sum, gamma);
    }
  });
  return out;
}

ProjectorPass::ProjectorPass(const ProjectorMap& map)
    : mWidth(map.width),
      mHeight(map.height),
      mProgram(GlProgram::compute(shaders::kProjector, "projector.comp")),
      mOut(size_t(map.width) * map.height * 4, nullptr) {
  TESSERA_CHECK(map.width > 0 && map.height > 0, "render::ProjectorPass: a map with a size");
  mHasBlend = !map.blend.empty();
  mHasWarp = !map.warp.empty();
  mInvGamma = float(1.0 / map.gamma);
  if (mHasBlend) {
    TESSERA_CHECK(map.blend.size() == size_t(map.width) * map.height,
                  "render::ProjectorPass: a weight per pixel");
    mBlend = GlBuffer(map.blend.size() * 4, map.blend.data());
    mBlendTexels = GlBufferTexture(mBlend, GL_R32F);
  }
  if (mHasWarp) {
    mGridWidth = map.grid_width;
    mGridHeight = map.grid_height;
    mWarp = GlBuffer(map.warp.size() * 8, map.warp.data());
    mWarpTexels = GlBufferTexture(mWarp, GL_RG32F);
  }
}

void ProjectorPass::run(uint32_t image_buffer) {
  const GlBufferTexture source(image_buffer, GL_R32UI);
  source.bind(2);
  if (mHasBlend) mBlendTexels.bind(3);
  if (mHasWarp) mWarpTexels.bind(4);
  mProgram.set("uSize", glm::ivec2(int(mWidth), int(mHeight)));
  mProgram.set("uGrid", mHasWarp ? glm::ivec2(int(mGridWidth), int(mGridHeight)) : glm::ivec2(0));
  mProgram.set("uBlendOn", mHasBlend ? 1 : 0);
  mProgram.set("uInvGamma", mInvGamma);
  mProgram.use();
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, mOut.name());
  glDispatchCompute((mWidth + 15) / 16, (mHeight + 15) / 16, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT |
                  GL_PIXEL_BUFFER_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
}

Image ProjectorPass::read() const {
  return readImageBuffer(mOut, mWidth, mHeight);
}

}  // namespace tessera::render
