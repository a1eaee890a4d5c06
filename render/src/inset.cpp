#include <tessera/render/inset.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>

#include <tessera/core/check.h>
#include <tessera/render/frame_target.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/wall_mosaic.h>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include "shaders.h"

namespace tessera::render {

namespace {

constexpr double kGamma = 2.2;
constexpr uint8_t kBorderGrey = 200;

const std::array<double, 256>& linearTable() {
  static const std::array<double, 256> table = [] {
    std::array<double, 256> t{};
    for (int i = 0; i < 256; ++i) t[size_t(i)] = std::pow(i / 255.0, kGamma);
    return t;
  }();
  return table;
}

double bandOf(const config::Inset& in) {
  return in.has_blend_band() ? in.blend_band() : in.width() / 20.0;
}

double separationOf(const config::Inset& in) {
  return in.has_eye_separation() ? in.eye_separation() : sync::kDefaultEyeSeparation;
}

/// The context's weight of one inset (1 outside it).
double contextWeightOf(const InsetRect& r, double x, double y) {
  if (!r.shown) return 1.0;
  const double d = std::min(std::min(x - r.x0, r.x1 - x), std::min(y - r.y0, r.y1 - y));
  if (d <= 0) return 1.0;
  if (r.band <= 0 || d >= r.band) return 0.0;
  return 1.0 - d / r.band;
}

std::vector<InsetRect> insetRects(const config::WallConfig& wall,
                                  const scene::InsetPlacement& placement) {
  std::vector<InsetRect> rects;
  for (int i = 0; i < wall.insets_size(); ++i) rects.push_back(insetRect(wall, i, placement));
  return rects;
}

double contextWeightOfAll(const std::vector<InsetRect>& rects, double x, double y) {
  double w = 1.0;
  for (const InsetRect& r : rects) w *= contextWeightOf(r, x, y);
  return w;
}

/// Multiplies one pixel's RGB by `w` in linear light.
void weigh(uint8_t* p, double w) {
  if (w >= 1.0) return;
  for (int c = 0; c < 3; ++c) p[c] = w <= 0.0 ? 0 : byteFromLinear(w * linearFromByte(p[c]));
}

/// The slot of inset `index` for `eye` (a stereo inset's left eye for eye 0).
size_t insetSlot(const config::WallConfig& wall, int index, int eye) {
  size_t s = size_t(wall.tiles_size());
  for (int i = 0; i < index; ++i) s += wall.insets(i).stereo() ? 2 : 1;
  return s + (wall.insets(index).stereo() && eye > 0 ? 1 : 0);
}

/// The mosaic of the weighted tiles with its bezels weighted as the context; the pixel size of
/// the wall picture and its extent's left and top edges.
struct ContextMosaic {
  Image image;
  glm::dvec2 ppm{0.0};
  double left = 0, top = 0;
};

ContextMosaic contextMosaic(const config::WallConfig& wall, std::span<const Image> slots,
                            const scene::InsetPlacement& placement) {
  ContextMosaic m;
  m.image = assembleWallMosaic(wall, slots.first(size_t(wall.tiles_size())));
  const config::Tile& first = wall.tiles(0);
  m.ppm = glm::dvec2(first.pixel_width() / first.width(), first.pixel_height() / first.height());
  const glm::dvec4 e = wallExtent(wall);
  m.left = e.x;
  m.top = e.w;
  const std::vector<InsetRect> rects = insetRects(wall, placement);
  // Bezels: the pixels no tile covers.
  std::vector<uint8_t> covered(size_t(m.image.width) * m.image.height, 0);
  for (const config::Tile& t : wall.tiles()) {
    const glm::ivec2 off = tileOffsetInWhole(wall, t);
    for (int y = std::max(0, off.y);
         y < std::min(int(m.image.height), off.y + int(t.pixel_height())); ++y)
      for (int x = std::max(0, off.x);
           x < std::min(int(m.image.width), off.x + int(t.pixel_width())); ++x)
        covered[size_t(y) * m.image.width + size_t(x)] = 1;
  }
  for (uint32_t y = 0; y < m.image.height; ++y)
    for (uint32_t x = 0; x < m.image.width; ++x) {
      if (covered[size_t(y) * m.image.width + x]) continue;
      const double wx = m.left + (x + 0.5) / m.ppm.x, wy = m.top - (y + 0.5) / m.ppm.y;
      weigh(&m.image.rgba[(size_t(y) * m.image.width + x) * 4], contextWeightOfAll(rects, wx, wy));
    }
  return m;
}

}  // namespace

double linearFromByte(uint8_t v) {
  return linearTable()[v];
}

uint8_t byteFromLinear(double light) {
  if (!(light > 0.0)) return 0;
  if (light >= 1.0) return 255;
  return uint8_t(std::lround(255.0 * std::pow(light, 1.0 / kGamma)));
}

std::vector<WallSlot> wallSlots(const config::WallConfig& wall) {
  std::vector<WallSlot> slots;
  for (int i = 0; i < wall.tiles_size(); ++i) {
    const config::Tile& t = wall.tiles(i);
    if (!wall.stereo()) {
      slots.push_back(WallSlot{t, -1, 0, i});
      continue;
    }
    if (wall.eyes_on_one_node()) {  // one node, both eyes side by side
      WallSlot s{t, -1, kBothEyes, i};
      s.tile.set_pixel_width(2 * t.pixel_width());
      slots.push_back(s);
      continue;
    }
    for (int eye : {-1, 1}) {
      WallSlot s{t, -1, eye, i};
      s.tile.set_name(t.name() + (eye < 0 ? "/left" : "/right"));
      slots.push_back(s);
    }
  }
  for (int i = 0; i < wall.insets_size(); ++i) {
    const config::Inset& in = wall.insets(i);
    WallSlot s;
    s.inset = i;
    s.tile.set_x(in.x());
    s.tile.set_y(in.y());
    s.tile.set_width(in.width());
    s.tile.set_height(in.height());
    s.tile.set_pixel_width(in.pixel_width());
    s.tile.set_pixel_height(in.pixel_height());
    if (!in.stereo()) {
      s.tile.set_name(in.name());
      slots.push_back(s);
      continue;
    }
    for (int eye : {-1, 1}) {
      s.eye = eye;
      s.tile.set_name(in.name() + (eye < 0 ? "/left" : "/right"));
      slots.push_back(s);
    }
  }
  return slots;
}

InsetRect insetRect(const config::WallConfig& wall, int index,
                    const scene::InsetPlacement& placement) {
  TESSERA_CHECK(index >= 0 && index < wall.insets_size(),
                "render::insetRect(): index of one of the wall's insets");
  const config::Inset& in = wall.insets(index);
  double x0 = in.x(), y0 = in.y();
  bool shown = true;
  for (const scene::InsetCentre& c : placement.centres()) {
    if (c.name() != in.name() || !std::isfinite(c.x()) || !std::isfinite(c.y())) continue;
    x0 = c.x() - 0.5 * in.width();
    y0 = c.y() - 0.5 * in.height();
    shown = !c.hidden();
  }
  const glm::dvec4 e = wallExtent(wall);
  x0 = std::max(e.x, std::min(x0, e.z - in.width()));
  y0 = std::max(e.y, std::min(y0, e.w - in.height()));
  return InsetRect{x0, y0, x0 + in.width(), y0 + in.height(), bandOf(in), shown};
}

std::optional<std::string> insetPlacementProblem(const config::WallConfig& wall,
                                                 const scene::InsetCentre& centre) {
  const config::Inset* in = nullptr;
  std::string names;
  for (const config::Inset& i : wall.insets()) {
    if (i.name() == centre.name()) in = &i;
    names += (names.empty() ? "" : ", ") + i.name();
  }
  if (!in)
    return "the wall has no inset '" + centre.name().substr(0, 64) +
           "' (its insets: " + (names.empty() ? "none" : names) + ")";
  if (!std::isfinite(centre.x()) || !std::isfinite(centre.y()))
    return "inset '" + in->name() + "': x and y must be finite (metres)";
  const glm::dvec4 e = wallExtent(wall);
  const double eps = 1e-9;
  const double x0 = centre.x() - 0.5 * in->width(), y0 = centre.y() - 0.5 * in->height();
  if (!(x0 >= e.x - eps && y0 >= e.y - eps && x0 + in->width() <= e.z + eps &&
        y0 + in->height() <= e.w + eps)) {
    char what[320];
    std::snprintf(what, sizeof what,
                  "inset '%s' centred at (%.6g, %.6g) spans [%.6g, %.6g] x [%.6g, %.6g] m, "
                  "outside the wall's extent [%.6g, %.6g] x [%.6g, %.6g] m",
                  in->name().c_str(), centre.x(), centre.y(), x0, x0 + in->width(), y0,
                  y0 + in->height(), e.x, e.z, e.y, e.w);
    return std::string(what);
  }
  return std::nullopt;
}

double contextWeight(const config::WallConfig& wall, const scene::InsetPlacement& placement,
                     double x, double y) {
  return contextWeightOfAll(insetRects(wall, placement), x, y);
}

double insetWeight(const InsetRect& rect, double x, double y) {
  if (!rect.shown) return 0.0;
  if (!(x > rect.x0 && x < rect.x1 && y > rect.y0 && y < rect.y1)) return 0.0;
  return 1.0 - contextWeightOf(rect, x, y);
}

std::vector<Image> eyePictures(const config::WallConfig& wall, std::span<const Image> slots,
                               int eye) {
  const std::vector<WallSlot> layout = wallSlots(wall);
  TESSERA_CHECK(slots.size() == layout.size(), "render::eyePictures(): one picture a slot");
  std::vector<Image> out;
  const int seen = eye > 0 ? 1 : -1;
  for (size_t i = 0; i < layout.size(); ++i) {
    const WallSlot& s = layout[i];
    if (s.eye == kBothEyes) {  // the eye's half of the node's picture
      const Image& pair = slots[i];
      TESSERA_CHECK(pair.width % 2 == 0 && pair.rgba.size() == size_t(pair.width) * pair.height * 4,
                    "render::eyePictures(): a picture of both eyes, twice a tile's width");
      Image half;
      half.width = pair.width / 2;
      half.height = pair.height;
      half.rgba.resize(size_t(half.width) * half.height * 4);
      const size_t row = size_t(half.width) * 4, x0 = seen > 0 ? row : 0;
      for (uint32_t y = 0; y < half.height; ++y)
        std::memcpy(&half.rgba[y * row], &pair.rgba[y * 2 * row + x0], row);
      out.push_back(std::move(half));
      continue;
    }
    if (s.inset < 0 && wall.stereo() && s.eye != seen) continue;
    out.push_back(slots[i]);
  }
  return out;
}

WallSlot eyeOfSlot(const config::WallConfig& wall, const WallSlot& both, int eye) {
  TESSERA_CHECK(both.eye == kBothEyes && both.tile_index >= 0 &&
                    both.tile_index < wall.tiles_size() && (eye == -1 || eye == 1),
                "render::eyeOfSlot(): a slot of both eyes of one of the wall's tiles, eye -1 or 1");
  return WallSlot{wall.tiles(both.tile_index), -1, eye, both.tile_index};
}

void copyEyeIntoPair(uint32_t eye_buffer, uint32_t pair_buffer, uint32_t width, uint32_t height,
                     int eye) {
  const GLsizeiptr row = GLsizeiptr(width) * 4;
  for (uint32_t y = 0; y < height; ++y)
    glCopyNamedBufferSubData(eye_buffer, pair_buffer, GLintptr(y) * row,
                             GLintptr(y) * 2 * row + (eye > 0 ? row : 0), row);
}

config::WallConfig monoWall(const config::WallConfig& wall) {
  config::WallConfig mono = wall;
  mono.set_stereo(false);
  return mono;
}

ViewSetup slotView(const config::WallConfig& wall, const WallSlot& slot,
                   const scene::InsetPlacement& placement, const config::Camera& camera,
                   const sync::ViewerHead* head) {
  TESSERA_CHECK(slot.eye != kBothEyes,
                "render::slotView(): one eye of a slot of both eyes (eyeOfSlot())");
  const sync::ViewerHead h = head ? *head : sync::viewerHead(wall, scene::Settings());
  if (slot.inset < 0) {
    // The config's tile (a stereo slot's copy is named after its eye), so a room's net finds it.
    const config::Tile& t = slot.tile_index >= 0 ? wall.tiles(slot.tile_index) : slot.tile;
    return tileView(wall, t, camera,
                    sync::eyeOffset(wall, h, slot.eye, sync::wallEyeSeparation(wall)));
  }
  const InsetRect r = insetRect(wall, slot.inset, placement);
  config::Tile t = slot.tile;
  t.set_x(r.x0);
  t.set_y(r.y0);
  ViewSetup v = tileView(wall, t, camera,
                         sync::eyeOffset(wall, h, slot.eye, separationOf(wall.insets(slot.inset))));
  v.origin = glm::ivec2(0);  // a picture of its own, at another density than the wall's
  return v;
}

void applySlotWeights(const config::WallConfig& wall, const WallSlot& slot,
                      const scene::InsetPlacement& placement, Image& image) {
  const config::Tile& t = slot.tile;
  TESSERA_CHECK(image.width == t.pixel_width() && image.height == t.pixel_height() &&
                    image.rgba.size() == size_t(image.width) * image.height * 4,
                "render::applySlotWeights(): a picture of the slot's pixel size");
  if (wall.insets_size() == 0) return;
  if (slot.inset < 0) {
    const std::vector<InsetRect> rects = insetRects(wall, placement);
    for (uint32_t y = 0; y < image.height; ++y) {
      const double wy = t.y() + t.height() - (y + 0.5) * t.height() / t.pixel_height();
      for (uint32_t x = 0; x < image.width; ++x) {
        const double wx = t.x() + (x + 0.5) * t.width() / t.pixel_width();
        weigh(&image.rgba[(size_t(y) * image.width + x) * 4], contextWeightOfAll(rects, wx, wy));
      }
    }
    return;
  }
  const InsetRect r = insetRect(wall, slot.inset, placement);
  const config::Inset& in = wall.insets(slot.inset);
  const double ppm_x = in.pixel_width() / in.width(), ppm_y = in.pixel_height() / in.height();
  for (uint32_t y = 0; y < image.height; ++y) {
    const double wy = r.y1 - (y + 0.5) / ppm_y;
    for (uint32_t x = 0; x < image.width; ++x) {
      const double wx = r.x0 + (x + 0.5) / ppm_x;
      uint8_t* p = &image.rgba[(size_t(y) * image.width + x) * 4];
      if (in.border() > 0 && r.shown) {
        // The frame: `border` pixels just inside the band's inner edge.
        const double dx = std::min(x + 0.5, image.width - x - 0.5) - r.band * ppm_x;
        const double dy = std::min(y + 0.5, image.height - y - 0.5) - r.band * ppm_y;
        const double d = std::min(dx, dy);
        if (d >= 0 && d < in.border()) {
          p[0] = p[1] = p[2] = kBorderGrey;
          continue;
        }
      }
      weigh(p, insetWeight(r, wx, wy));
    }
  }
}

InsetPass::InsetPass() : mProgram(GlProgram::compute(shaders::kInset, "inset.comp")) {}

void InsetPass::run(uint32_t image_buffer, const config::WallConfig& wall, const WallSlot& slot,
                    const scene::InsetPlacement& placement) {
  TESSERA_CHECK(wall.insets_size() <= 64, "render::InsetPass::run(): at most 64 insets");
  const config::Tile& t = slot.tile;
  if (t.pixel_width() != mWidth || t.pixel_height() != mHeight) {
    mWidth = t.pixel_width();
    mHeight = t.pixel_height();
    mOut = GlBuffer(size_t(mWidth) * mHeight * 4, nullptr);
  }
  // The picture's top-left corner on the wall and its pixel; rectangles relative to the corner,
  // in double precision here, so single precision only spans the picture.
  std::vector<glm::vec4> rects;
  std::vector<float> bands;
  glm::dvec2 corner, pixel;
  float border = 0.0f;
  glm::vec2 band_pixels(0.0f);
  if (slot.inset < 0) {
    corner = glm::dvec2(t.x(), t.y() + t.height());
    pixel = glm::dvec2(t.width() / t.pixel_width(), t.height() / t.pixel_height());
    for (const InsetRect& r : insetRects(wall, placement)) {
      if (!r.shown) continue;  // switched off: no hole in the context
      rects.emplace_back(r.x0 - corner.x, r.y0 - corner.y, r.x1 - corner.x, r.y1 - corner.y);
      bands.push_back(float(r.band));
    }
  } else {
    const InsetRect r = insetRect(wall, slot.inset, placement);
    const config::Inset& in = wall.insets(slot.inset);
    corner = glm::dvec2(r.x0, r.y1);
    pixel = glm::dvec2(in.width() / in.pixel_width(), in.height() / in.pixel_height());
    // Switched off: an empty rectangle, inside which no pixel lies (the picture black).
    rects.emplace_back(r.shown ? glm::vec4(0.0, r.y0 - r.y1, r.x1 - r.x0, 0.0) : glm::vec4(0.0f));
    bands.push_back(float(r.band));
    border = r.shown ? float(in.border()) : 0.0f;
    band_pixels = glm::vec2(r.band / pixel.x, r.band / pixel.y);
  }
  if (rects.empty()) {  // no insets: the picture as it is (a band of 0 around nothing)
    rects.emplace_back(0.0f);
    bands.push_back(0.0f);
  }
  const GlBufferTexture source(image_buffer, GL_R32UI);
  source.bind(2);
  mProgram.set("uSize", glm::ivec2(int(mWidth), int(mHeight)));
  mProgram.set("uPixel", glm::vec2(pixel));
  mProgram.set("uCount", wall.insets_size() == 0 ? 0 : int(rects.size()));
  mProgram.set("uRects", std::span<const glm::vec4>(rects));
  mProgram.set("uBands", std::span<const float>(bands));
  mProgram.set("uInset", slot.inset < 0 ? 0 : 1);
  mProgram.set("uBorder", border);
  mProgram.set("uBandPixels", band_pixels);
  mProgram.use();
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, mOut.name());
  glDispatchCompute((mWidth + 15) / 16, (mHeight + 15) / 16, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT |
                  GL_PIXEL_BUFFER_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
}

Image InsetPass::read() const {
  return readImageBuffer(mOut, mWidth, mHeight);
}

Image assembleInsetWall(const config::WallConfig& wall, std::span<const Image> slots,
                        const scene::InsetPlacement& placement) {
  if (wall.stereo()) return assembleWallEye(wall, slots, placement, -1);
  const std::vector<WallSlot> layout = wallSlots(wall);
  TESSERA_CHECK(slots.size() == layout.size(), "render::assembleInsetWall(): one picture a slot");
  if (wall.insets_size() == 0) return assembleWallMosaic(wall, slots);
  ContextMosaic m = contextMosaic(wall, slots, placement);
  Image& out = m.image;
  const size_t n = size_t(out.width) * out.height;
  std::vector<double> sum(n * 3, 0.0);
  std::vector<uint32_t> count(n, 0);
  std::vector<double> coverage(n, 0.0);
  for (int i = 0; i < wall.insets_size(); ++i) {
    const config::Inset& in = wall.insets(i);
    const Image& img = slots[insetSlot(wall, i, in.stereo() ? -1 : 0)];
    TESSERA_CHECK(img.width == in.pixel_width() && img.height == in.pixel_height() &&
                      img.rgba.size() == size_t(img.width) * img.height * 4,
                  "render::assembleInsetWall(): an inset picture of its pixel size");
    const InsetRect r = insetRect(wall, i, placement);
    if (!r.shown) continue;  // switched off: its slot is black, the context whole
    std::fill(sum.begin(), sum.end(), 0.0);
    std::fill(count.begin(), count.end(), 0u);
    // Each inset pixel's light to the wall pixel its centre falls in (a box filter).
    for (uint32_t y = 0; y < img.height; ++y) {
      const double wy = r.y1 - (y + 0.5) * in.height() / img.height;
      const long my = long(std::floor((m.top - wy) * m.ppm.y));
      if (my < 0 || my >= long(out.height)) continue;
      for (uint32_t x = 0; x < img.width; ++x) {
        const double wx = r.x0 + (x + 0.5) * in.width() / img.width;
        const long mx = long(std::floor((wx - m.left) * m.ppm.x));
        if (mx < 0 || mx >= long(out.width)) continue;
        const size_t k = size_t(my) * out.width + size_t(mx);
        const uint8_t* p = &img.rgba[(size_t(y) * img.width + x) * 4];
        for (int c = 0; c < 3; ++c) sum[k * 3 + size_t(c)] += linearFromByte(p[c]);
        ++count[k];
      }
    }
    for (size_t k = 0; k < n; ++k) {
      if (count[k] == 0) continue;
      // The mean light of the inset's pixels there, times the part of the wall pixel it covers.
      const double px = double(k % out.width), py = double(k / out.width);
      const double ax0 = m.left + px / m.ppm.x, ax1 = m.left + (px + 1) / m.ppm.x;
      const double ay1 = m.top - py / m.ppm.y, ay0 = m.top - (py + 1) / m.ppm.y;
      const double cover = std::max(0.0, std::min(ax1, r.x1) - std::max(ax0, r.x0)) *
                           std::max(0.0, std::min(ay1, r.y1) - std::max(ay0, r.y0)) * m.ppm.x *
                           m.ppm.y;
      uint8_t* q = &out.rgba[k * 4];
      for (int c = 0; c < 3; ++c)
        q[c] = byteFromLinear(linearFromByte(q[c]) +
                              cover * sum[k * 3 + size_t(c)] / double(count[k]));
    }
  }
  return out;
}

Image assembleWallEye(const config::WallConfig& wall, std::span<const Image> slots,
                      const scene::InsetPlacement& placement, int eye) {
  const std::vector<Image> pictures = eyePictures(wall, slots, eye);
  return assembleInsetWall(monoWall(wall), pictures, placement);
}

Image insetDetail(const config::WallConfig& wall, std::span<const Image> slots,
                  const scene::InsetPlacement& placement, int index, int eye) {
  if (wall.stereo())  // the context of the inset's eye (a mono inset: the left's)
    return insetDetail(monoWall(wall), eyePictures(wall, slots, eye), placement, index, eye);
  TESSERA_CHECK(index >= 0 && index < wall.insets_size(),
                "render::insetDetail(): index of one of the wall's insets");
  TESSERA_CHECK(slots.size() == wallSlots(wall).size(),
                "render::insetDetail(): one picture a slot");
  const config::Inset& in = wall.insets(index);
  const Image& img = slots[insetSlot(wall, index, eye)];
  TESSERA_CHECK(img.width == in.pixel_width() && img.height == in.pixel_height() &&
                    img.rgba.size() == size_t(img.width) * img.height * 4,
                "render::insetDetail(): an inset picture of its pixel size");
  const ContextMosaic m = contextMosaic(wall, slots, placement);
  const InsetRect r = insetRect(wall, index, placement);
  Image out = img;
  for (uint32_t y = 0; y < img.height; ++y) {
    const double wy = r.y1 - (y + 0.5) * in.height() / img.height;
    const long my =
        std::clamp(long(std::floor((m.top - wy) * m.ppm.y)), 0L, long(m.image.height) - 1);
    for (uint32_t x = 0; x < img.width; ++x) {
      const double wx = r.x0 + (x + 0.5) * in.width() / img.width;
      const long mx =
          std::clamp(long(std::floor((wx - m.left) * m.ppm.x)), 0L, long(m.image.width) - 1);
      const uint8_t* c = &m.image.rgba[(size_t(my) * m.image.width + size_t(mx)) * 4];
      uint8_t* p = &out.rgba[(size_t(y) * img.width + x) * 4];
      for (int k = 0; k < 3; ++k)
        p[k] = byteFromLinear(linearFromByte(c[k]) + linearFromByte(p[k]));
      p[3] = 255;
    }
  }
  return out;
}

std::string insetPicturePath(const std::string& screenshot, const std::string& name, int eye) {
  const size_t slash = screenshot.find_last_of('/');
  const size_t dot = screenshot.find_last_of('.');
  const bool ext = dot != std::string::npos && (slash == std::string::npos || dot > slash);
  const std::string stem = ext ? screenshot.substr(0, dot) : screenshot;
  return stem + "-inset-" + name +
         (eye < 0   ? "-left"
          : eye > 0 ? "-right"
                    : "") +
         (ext ? screenshot.substr(dot) : std::string());
}

void checkPathInsets(const config::CameraPath& path, const config::WallConfig& wall,
                     const std::string& file) {
  for (int i = 0; i < path.actions_size(); ++i) {
    if (!path.actions(i).has_set_inset()) continue;
    if (const auto why = insetPlacementProblem(wall, path.actions(i).set_inset()))
      throw RenderError(file + ": actions[" + std::to_string(i) + "].setInset: " + *why);
  }
}

}  // namespace tessera::render
