#include "text_shaper.h"

#include <ft2build.h>
#include FT_FREETYPE_H
#include <fontconfig/fontconfig.h>
#include <hb-ft.h>
#include <hb.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <unordered_map>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/render/gl_context.h>
#include <tessera/render/gl_objects.h>

namespace tessera::render {
namespace {

/// The first font tried: the overlay's look (Debian's fonts-dejavu-core), which also has Greek,
/// Cyrillic, Hebrew and Arabic.
constexpr const char* kPrimaryFamily = "DejaVu Sans";
constexpr uint32_t kAtlasSide = 2048;
constexpr size_t kMostCachedLines = 4096;

/// The next code point of UTF-8 `s` from `i` (advanced); U+FFFD for a malformed sequence.
uint32_t nextCodePoint(std::string_view s, size_t& i) {
  const auto b = uint8_t(s[i++]);
  if (b < 0x80) return b;
  const int extra = b >= 0xF8 ? -1 : b >= 0xF0 ? 3 : b >= 0xE0 ? 2 : b >= 0xC0 ? 1 : -1;
  if (extra < 0) return 0xFFFD;
  uint32_t cp = b & (0x3F >> extra);
  for (int k = 0; k < extra; ++k) {
    if (i >= s.size() || (uint8_t(s[i]) & 0xC0) != 0x80) return 0xFFFD;
    cp = cp << 6 | (uint8_t(s[i++]) & 0x3F);
  }
  return cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF) ? 0xFFFD : cp;
}

/// The direction a character asks for: +1 left to right (letters of most scripts), -1 right to
/// left (Hebrew, Arabic, Syriac, Thaana, N'Ko and their presentation forms), 0 neutral (spaces,
/// punctuation, digits, symbols, marks: they go with the run around them).
int directionOf(uint32_t cp) {
  if ((cp >= 0x0590 && cp <= 0x08FF) || (cp >= 0xFB1D && cp <= 0xFDFF) ||
      (cp >= 0xFE70 && cp <= 0xFEFF) || (cp >= 0x10800 && cp <= 0x10FFF) ||
      (cp >= 0x1E800 && cp <= 0x1EFFF))
    return (cp >= 0x0660 && cp <= 0x0669) || (cp >= 0x06F0 && cp <= 0x06F9) ? 0 : -1;
  if (cp < 0x80) return (cp | 0x20) >= 'a' && (cp | 0x20) <= 'z' ? 1 : 0;
  if (cp >= 0x0300 && cp <= 0x036F) return 0;    // combining marks
  if (cp >= 0x2000 && cp <= 0x2BFF) return 0;    // punctuation, symbols, arrows
  if (cp >= 0x3000 && cp <= 0x303F) return 0;    // CJK punctuation
  if (cp >= 0x1F000 && cp <= 0x1FAFF) return 0;  // emoji
  if (cp >= 0xFE00 && cp <= 0xFE0F) return 0;    // variation selectors
  if (cp == 0x200D || cp == 0xA0) return 0;
  return 1;
}

struct Font {
  FT_Face face = nullptr;
  hb_font_t* hb = nullptr;
  std::string file;
};

struct GlyphSlot {
  bool ink = false;
  glm::vec2 bearing{0.0f};  ///< bitmap left, and top above the baseline
  glm::vec2 size{0.0f};
  glm::vec2 uv0{0.0f}, uv1{0.0f};
};

}  // namespace

struct TextShaper::Impl {
  FT_Library library = nullptr;
  FcConfig* config = nullptr;
  std::vector<Font> fonts;                               // [0]: the primary font
  std::map<std::string, int> font_by_file;               // file#index -> fonts[]
  std::unordered_map<uint32_t, int> font_of;             // code point -> fonts[], -1: none has it
  std::map<std::pair<int, uint32_t>, GlyphSlot> glyphs;  // (font, glyph index) -> atlas slot
  std::unordered_map<std::string, ShapedLine> lines;
  std::set<uint32_t> missing;
  GlTexture atlas;
  uint32_t shelf_x = 1, shelf_y = 1, shelf_height = 0;  // the packer's cursor
  float ascent = 0.0f;                                  // the primary font's, pixels
  hb_buffer_t* buffer = nullptr;

  ~Impl() {
    if (buffer) hb_buffer_destroy(buffer);
    for (Font& f : fonts) {
      if (f.hb) hb_font_destroy(f.hb);
      if (f.face) FT_Done_Face(f.face);
    }
    if (library) FT_Done_FreeType(library);
    if (config) FcConfigDestroy(config);
  }

  /// The font in `file` (face `index`), opened once; -1 when FreeType cannot read it.
  int open(const std::string& file, int index) {
    const std::string key = file + "#" + std::to_string(index);
    if (auto it = font_by_file.find(key); it != font_by_file.end()) return it->second;
    Font f;
    f.file = file;
    int id = -1;
    if (FT_New_Face(library, file.c_str(), index, &f.face) == 0) {
      if (FT_IS_SCALABLE(f.face)) {
        FT_Set_Pixel_Sizes(f.face, 0, FT_UInt(kPixelSize));
      } else if (f.face->num_fixed_sizes > 0) {
        FT_Select_Size(f.face, 0);  // bitmap-only fonts: their one size
      }
      f.hb = hb_ft_font_create_referenced(f.face);
      fonts.push_back(f);
      id = int(fonts.size() - 1);
    } else {
      std::fprintf(stderr, "render: cannot read the font %s; its characters are skipped\n",
                   file.c_str());
    }
    font_by_file[key] = id;
    return id;
  }

  /// The best installed font for `pattern` (fontconfig's match), or "".
  std::pair<std::string, int> match(FcPattern* pattern) {
    FcConfigSubstitute(config, pattern, FcMatchPattern);
    FcDefaultSubstitute(pattern);
    FcResult result = FcResultNoMatch;
    FcPattern* found = FcFontMatch(config, pattern, &result);
    std::pair<std::string, int> out{"", 0};
    if (found) {
      FcChar8* file = nullptr;
      int index = 0;
      if (FcPatternGetString(found, FC_FILE, 0, &file) == FcResultMatch) out.first = (char*)file;
      if (FcPatternGetInteger(found, FC_INDEX, 0, &index) == FcResultMatch) out.second = index;
      FcPatternDestroy(found);
    }
    return out;
  }

  /// The font that draws `cp`: the primary if it has it, else the one fontconfig finds for it.
  int fontFor(uint32_t cp) {
    if (FT_Get_Char_Index(fonts[0].face, cp) != 0) return 0;
    if (auto it = font_of.find(cp); it != font_of.end()) return it->second;
    int id = -1;
    FcPattern* pattern = FcPatternCreate();
    FcCharSet* set = FcCharSetCreate();
    FcCharSetAddChar(set, cp);
    FcPatternAddCharSet(pattern, FC_CHARSET, set);
    FcPatternAddString(pattern, FC_FAMILY, reinterpret_cast<const FcChar8*>("sans-serif"));
    const auto [file, index] = match(pattern);
    FcCharSetDestroy(set);
    FcPatternDestroy(pattern);
    if (!file.empty()) {
      const int candidate = open(file, index);
      if (candidate >= 0 && FT_Get_Char_Index(fonts[size_t(candidate)].face, cp) != 0)
        id = candidate;
    }
    if (id < 0 && missing.insert(cp).second)
      std::fprintf(stderr, "render: no installed font has U+%04X; it is drawn as a box\n", cp);
    font_of[cp] = id;
    return id;
  }

  /// The atlas slot of glyph `index` of font `font`, rasterised on first use; no ink when the
  /// atlas is full (beginFrame() starts it over).
  const GlyphSlot& glyph(int font, uint32_t index) {
    const auto key = std::make_pair(font, index);
    if (auto it = glyphs.find(key); it != glyphs.end()) return it->second;
    GlyphSlot slot;
    FT_Face face = fonts[size_t(font)].face;
    if (FT_Load_Glyph(face, index, FT_LOAD_RENDER | FT_LOAD_TARGET_LIGHT) == 0) {
      const FT_Bitmap& bm = face->glyph->bitmap;
      const uint32_t w = bm.width, h = bm.rows;
      // Bitmap-only fonts at another size: scaled to the pixel size.
      const float scale = FT_IS_SCALABLE(face) || face->size->metrics.y_ppem == 0
                              ? 1.0f
                              : kPixelSize / float(face->size->metrics.y_ppem);
      if (w > 0 && h > 0 && w < kAtlasSide / 2 && h < kAtlasSide / 2 &&
          bm.pixel_mode == FT_PIXEL_MODE_GRAY) {
        if (shelf_x + w + 1 > kAtlasSide) {
          shelf_x = 1;
          shelf_y += shelf_height + 1;
          shelf_height = 0;
        }
        if (shelf_y + h + 1 <= kAtlasSide) {
          std::vector<uint8_t> pixels(size_t(w) * h);
          for (uint32_t r = 0; r < h; ++r)
            std::copy_n(bm.buffer + std::ptrdiff_t(r) * bm.pitch, w, &pixels[size_t(r) * w]);
          atlas.uploadRegion(shelf_x, shelf_y, w, h, pixels.data());
          slot.ink = true;
          slot.bearing =
              glm::vec2(float(face->glyph->bitmap_left), float(face->glyph->bitmap_top)) * scale;
          slot.size = glm::vec2(float(w), float(h)) * scale;
          slot.uv0 = glm::vec2(float(shelf_x), float(shelf_y)) / float(kAtlasSide);
          slot.uv1 = glm::vec2(float(shelf_x + w), float(shelf_y + h)) / float(kAtlasSide);
          shelf_x += w + 1;
          shelf_height = std::max(shelf_height, h);
        }
      }
    }
    return glyphs.emplace(key, slot).first->second;
  }

  ShapedLine layout(std::string_view text) {
    // Runs of one font and one direction, neutrals joining the run they are in.
    struct Run {
      size_t begin, end;  // bytes
      int font, direction;
    };
    std::vector<Run> runs;
    int line_direction = 0;
    for (size_t i = 0; i < text.size();) {
      const size_t at = i;
      const uint32_t cp = nextCodePoint(text, i);
      const int dir = directionOf(cp);
      if (line_direction == 0) line_direction = dir;
      int font = fontFor(cp);
      if (font < 0) font = 0;  // its missing-glyph box
      if (!runs.empty()) {
        Run& last = runs.back();
        const bool same_dir = dir == 0 || last.direction == 0 || dir == last.direction;
        const bool same_font =
            font == last.font || (dir == 0 && FT_Get_Char_Index(fonts[size_t(last.font)].face, cp));
        if (same_dir && same_font) {
          last.end = i;
          if (last.direction == 0) last.direction = dir;
          continue;
        }
      }
      runs.push_back({at, i, font, dir});
    }
    if (line_direction < 0) std::reverse(runs.begin(), runs.end());
    ShapedLine out;
    float pen = 0.0f;
    for (const Run& r : runs) {
      hb_buffer_clear_contents(buffer);
      hb_buffer_add_utf8(buffer, text.data(), int(text.size()), unsigned(r.begin),
                         int(r.end - r.begin));
      hb_buffer_set_direction(buffer, r.direction < 0 ? HB_DIRECTION_RTL : HB_DIRECTION_LTR);
      hb_buffer_guess_segment_properties(buffer);
      hb_shape(fonts[size_t(r.font)].hb, buffer, nullptr, 0);
      unsigned n = 0;
      const hb_glyph_info_t* info = hb_buffer_get_glyph_infos(buffer, &n);
      const hb_glyph_position_t* pos = hb_buffer_get_glyph_positions(buffer, &n);
      FT_Face face = fonts[size_t(r.font)].face;
      const float unit = FT_IS_SCALABLE(face) || face->size->metrics.y_ppem == 0
                             ? 1.0f / 64.0f
                             : kPixelSize / float(face->size->metrics.y_ppem) / 64.0f;
      for (unsigned g = 0; g < n; ++g) {
        const GlyphSlot& slot = glyph(r.font, info[g].codepoint);
        if (slot.ink) {
          const glm::vec2 origin(pen + float(pos[g].x_offset) * unit,
                                 ascent - float(pos[g].y_offset) * unit);
          ShapedGlyph sg;
          sg.lo = origin + glm::vec2(slot.bearing.x, -slot.bearing.y);
          sg.hi = sg.lo + slot.size;
          sg.uv0 = slot.uv0;
          sg.uv1 = slot.uv1;
          out.glyphs.push_back(sg);
        }
        pen += float(pos[g].x_advance) * unit;
      }
    }
    out.width = pen;
    return out;
  }
};

TextShaper::TextShaper() : mImpl(std::make_unique<Impl>()) {
  Impl& s = *mImpl;
  if (FT_Init_FreeType(&s.library) != 0) throw RenderError("render: FreeType cannot start");
  s.config = FcInitLoadConfigAndFonts();
  if (!s.config) throw RenderError("render: fontconfig cannot load its configuration");
  FcPattern* pattern = FcPatternCreate();
  FcPatternAddString(pattern, FC_FAMILY, reinterpret_cast<const FcChar8*>(kPrimaryFamily));
  const auto [file, index] = s.match(pattern);
  FcPatternDestroy(pattern);
  if (file.empty() || s.open(file, index) != 0)
    throw RenderError(
        "render: no font is installed for the overlay's labels (scripts/deps.sh "
        "installs fonts-dejavu-core, fonts-noto-cjk and fonts-symbola)");
  s.ascent = float(s.fonts[0].face->size->metrics.ascender) / 64.0f;
  s.buffer = hb_buffer_create();
  s.atlas = GlTexture(kAtlasSide, kAtlasSide, GL_R8);
  const std::vector<uint8_t> clear(size_t(kAtlasSide) * kAtlasSide, 0);
  s.atlas.upload(clear.data());
}

TextShaper::~TextShaper() = default;

const ShapedLine& TextShaper::shape(std::string_view line) {
  Impl& s = *mImpl;
  if (auto it = s.lines.find(std::string(line)); it != s.lines.end()) return it->second;
  if (s.lines.size() >= kMostCachedLines) s.lines.clear();
  return s.lines.emplace(std::string(line), s.layout(line)).first->second;
}

uint32_t TextShaper::texture() const {
  return mImpl->atlas.name();
}

void TextShaper::beginFrame() {
  Impl& s = *mImpl;
  if (s.shelf_y < kAtlasSide * 7 / 8) return;
  s.glyphs.clear();
  s.lines.clear();
  s.shelf_x = s.shelf_y = 1;
  s.shelf_height = 0;
}

std::vector<uint32_t> TextShaper::missing() const {
  return {mImpl->missing.begin(), mImpl->missing.end()};
}

}  // namespace tessera::render
