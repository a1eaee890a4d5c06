// Text on the wall as people write it: labels in Japanese, Arabic (right to left), Greek with
// accents and an emoji are drawn from fonts that have their characters (no box, no '?'), each
// line as wide as HarfBuzz shapes it with the font fontconfig picks for it (an independent
// shaping in this test), right-to-left text laid out from the right, and a character no font has
// drawn as a visible box and reported.
#include <gtest/gtest.h>

#include <ft2build.h>
#include FT_FREETYPE_H
#include <fontconfig/fontconfig.h>
#include <hb-ft.h>
#include <hb.h>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/render/gl_context.h>
#include <tessera/render/image.h>
#include <tessera/render/overlay_pass.h>
#include <tessera/render/view_renderer.h>

#include "../../render/src/text_shaper.h"

namespace tessera::render {
namespace {

/// The advance of `text` shaped by HarfBuzz with the font fontconfig matches for `sample` (a
/// character of the text), at TextShaper::kPixelSize: the test's own shaping.
double referenceAdvance(const std::string& text, uint32_t sample, bool rtl = false) {
  FcConfig* config = FcInitLoadConfigAndFonts();
  FcPattern* pattern = FcPatternCreate();
  FcCharSet* set = FcCharSetCreate();
  FcCharSetAddChar(set, sample);
  FcPatternAddCharSet(pattern, FC_CHARSET, set);
  FcPatternAddString(
      pattern, FC_FAMILY,
      reinterpret_cast<const FcChar8*>(sample < 0x3000 ? "DejaVu Sans" : "sans-serif"));
  FcConfigSubstitute(config, pattern, FcMatchPattern);
  FcDefaultSubstitute(pattern);
  FcResult result;
  FcPattern* found = FcFontMatch(config, pattern, &result);
  FcChar8* file = nullptr;
  int index = 0;
  FcPatternGetString(found, FC_FILE, 0, &file);
  FcPatternGetInteger(found, FC_INDEX, 0, &index);
  FT_Library lib;
  FT_Init_FreeType(&lib);
  FT_Face face;
  EXPECT_EQ(FT_New_Face(lib, reinterpret_cast<const char*>(file), index, &face), 0) << file;
  FT_Set_Pixel_Sizes(face, 0, FT_UInt(TextShaper::kPixelSize));
  hb_font_t* font = hb_ft_font_create_referenced(face);
  hb_buffer_t* buffer = hb_buffer_create();
  hb_buffer_add_utf8(buffer, text.c_str(), -1, 0, -1);
  hb_buffer_set_direction(buffer, rtl ? HB_DIRECTION_RTL : HB_DIRECTION_LTR);
  hb_buffer_guess_segment_properties(buffer);
  hb_shape(font, buffer, nullptr, 0);
  unsigned n = 0;
  const hb_glyph_position_t* pos = hb_buffer_get_glyph_positions(buffer, &n);
  const hb_glyph_info_t* info = hb_buffer_get_glyph_infos(buffer, &n);
  double advance = 0;
  for (unsigned i = 0; i < n; ++i) {
    advance += pos[i].x_advance / 64.0;
    EXPECT_NE(info[i].codepoint, 0u) << file << " lacks a character of " << text;
  }
  hb_buffer_destroy(buffer);
  hb_font_destroy(font);
  FT_Done_FreeType(lib);
  FcPatternDestroy(found);
  FcCharSetDestroy(set);
  FcPatternDestroy(pattern);
  FcConfigDestroy(config);
  return advance;
}

class OverlayText : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { sContext = GlContext::createHeadless().release(); }
  static void TearDownTestSuite() { delete sContext; }
  static GlContext* sContext;

  /// `text` as a 32 px white label on black in a 640x120 view: the picture.
  static Image drawn(const std::string& text) {
    ViewSetup v;
    v.width = 640;
    v.height = 120;
    v.view = glm::lookAt(glm::dvec3(0, 0, 1), glm::dvec3(0), glm::dvec3(0, 1, 0));
    v.projection = glm::perspective(glm::radians(40.0), 640.0 / 120.0, 0.1, 10.0);
    v.eye_world = {0, 0, 1};
    Overlay overlay;
    OverlayLabel label;
    label.at = {0, 0, 0};
    label.text = text;
    label.height_px = TextShaper::kPixelSize;
    label.offset_px = {-300.0f, -30.0f};
    label.background = {0, 0, 0, 0};
    overlay.labels.push_back(label);
    ViewRenderer r(v.width, v.height);
    return r.render({}, v, RenderOptions{}, nullptr, &overlay);
  }
  /// Columns with ink (a pixel brighter than 100) and the ink's sum.
  static std::pair<int, int> extent(const Image& img, double* ink = nullptr) {
    int lo = int(img.width), hi = -1;
    double sum = 0;
    for (uint32_t y = 0; y < img.height; ++y)
      for (uint32_t x = 0; x < img.width; ++x) {
        const uint8_t v = img.rgba[(size_t(y) * img.width + x) * 4];
        sum += v;
        if (v > 100) lo = std::min(lo, int(x)), hi = std::max(hi, int(x));
      }
    if (ink) *ink = sum;
    return {lo, hi};
  }
};
GlContext* OverlayText::sContext = nullptr;

TEST_F(OverlayText, EveryScriptIsShapedFromAFontThatHasIt) {
  TextShaper shaper;
  struct Case {
    std::string text;
    uint32_t sample;  // a character whose font shapes the whole string
    bool rtl;
  };
  const std::vector<Case> cases = {
      {"東京の調査で見つかった亀裂です", 0x6771, false},  // 東
      {"الشقوق في العمود", 0x0634, true},                 // Arabic, joined, right to left
      {"Ναός του Ποσειδώνα", 0x03B1, false},              // Greek with accents
  };
  for (const Case& c : cases) {
    const ShapedLine& line = shaper.shape(c.text);
    const double reference = referenceAdvance(c.text, c.sample, c.rtl);
    std::printf("%s: %.1f px (HarfBuzz alone: %.1f), %zu glyphs with ink\n", c.text.c_str(),
                line.width, reference, line.glyphs.size());
    EXPECT_NEAR(line.width, reference, 0.5) << c.text;
    EXPECT_GT(line.glyphs.size(), 6u) << c.text;
  }
  // The emoji from an emoji font, the Latin from the first one.
  const ShapedLine& rabbit = shaper.shape("🐇");
  EXPECT_EQ(rabbit.glyphs.size(), 1u);
  EXPECT_NEAR(rabbit.width, referenceAdvance("🐇", 0x1F407), 0.5);
  EXPECT_TRUE(shaper.missing().empty()) << "U+" << std::hex << shaper.missing()[0];
  // Arabic is laid out from the right: its first letter's glyph is the rightmost.
  const ShapedLine& word = shaper.shape("شقوق");
  const ShapedLine& first = shaper.shape("ش");
  ASSERT_FALSE(word.glyphs.empty());
  ASSERT_FALSE(first.glyphs.empty());
  float rightmost = -1e9f;
  for (const ShapedGlyph& g : word.glyphs) rightmost = std::max(rightmost, g.hi.x);
  EXPECT_GT(rightmost, word.width - 0.5f * first.width);
}

TEST_F(OverlayText, LabelsInEveryScriptAreDrawnWithoutBoxesOrQuestionMarks) {
  const Image question = drawn("??????");
  for (const std::string text :
       {"東京の調査で見つかった亀裂です", "الشقوق في العمود", "Ναός του Ποσειδώνα", "Rabbit 🐇"}) {
    const Image img = drawn(text);
    double ink = 0;
    const auto [lo, hi] = extent(img, &ink);
    TextShaper shaper;
    const float width = shaper.shape(text).width;
    std::printf("%s: ink from x %d to %d (%d px; shaped %.0f px)\n", text.c_str(), lo, hi,
                hi - lo + 1, width);
    EXPECT_GT(ink, 255.0 * 200) << text;
    EXPECT_NEAR(double(hi - lo + 1), double(width), 0.15 * width + 6) << text;
    EXPECT_FALSE(img.rgba == question.rgba) << text;
  }
}

TEST_F(OverlayText, ACharacterNoFontHasIsABoxAndIsSaid) {
  TextShaper shaper;
  const std::string text =
      "a\xF4\x8F\xBF\xBD"
      "b";  // U+10FFFD, a private use character
  const ShapedLine& line = shaper.shape(text);
  ASSERT_EQ(shaper.missing().size(), 1u);
  EXPECT_EQ(shaper.missing()[0], 0x10FFFDu);
  EXPECT_EQ(line.glyphs.size(), 3u) << "a, the box, b";
  const Image img = drawn(text);
  double ink = 0;
  extent(img, &ink);
  const Image ab = drawn("ab");
  double ink_ab = 0;
  extent(ab, &ink_ab);
  EXPECT_GT(ink, ink_ab * 1.2) << "the box has ink of its own";
}

}  // namespace
}  // namespace tessera::render
