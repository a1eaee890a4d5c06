// Text as people write it, for the overlay's labels: shaped with HarfBuzz (ligatures, combining
// marks, Arabic joining, right-to-left runs), each character from an installed font that has it
// (fontconfig: DejaVu Sans first, then whatever covers the rest, e.g. Noto Sans CJK for Japanese
// and Chinese, Symbola for emoji), glyphs rasterised by FreeType into one glyph atlas (an R8
// texture) that the overlay pass samples. A character no installed font has is drawn as the
// first font's missing-glyph box, never as '?', and said once in the log.
//
// Bidirectional text is ordered by a simplified rule: the line's direction is that of its first
// strong character; runs of right-to-left script (Hebrew, Arabic, Syriac, Thaana, N'Ko) are
// shaped right to left; in a right-to-left line the runs are laid out from the right.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

namespace tessera::render {

/// One glyph of a shaped line, at TextShaper::kPixelSize: its quad from the line's top-left pen
/// position (y down), and where it lies in the atlas (u, v in [0, 1], v = 0 at the top).
struct ShapedGlyph {
  glm::vec2 lo{0.0f}, hi{0.0f};
  glm::vec2 uv0{0.0f}, uv1{0.0f};
};

struct ShapedLine {
  std::vector<ShapedGlyph> glyphs;  ///< only glyphs with ink (not spaces)
  float width = 0.0f;               ///< the advance of the whole line, pixels at kPixelSize
};

class TextShaper {
 public:
  /// The size glyphs are rasterised at; labels scale them to their height.
  static constexpr float kPixelSize = 32.0f;

  /// Needs a current GL context (the atlas texture). Throws RenderError when FreeType or
  /// fontconfig cannot start or no font is installed at all.
  TextShaper();
  ~TextShaper();
  TextShaper(const TextShaper&) = delete;
  TextShaper& operator=(const TextShaper&) = delete;

  /// One line of UTF-8 (no line breaks; malformed bytes read as U+FFFD), laid out left to
  /// right; its new glyphs enter the atlas. Cached by text.
  const ShapedLine& shape(std::string_view line);

  /// The atlas texture the glyphs' uv refer to.
  uint32_t texture() const;

  /// Between frames: when the atlas is nearly full it starts over (the cache with it).
  void beginFrame();

  /// Code points no installed font has, met so far (each said once in the log).
  std::vector<uint32_t> missing() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> mImpl;
};

}  // namespace tessera::render
