// GL objects as move-only values (resources follow their owner): programs with their uniform locations
// cached, 2D textures and framebuffers. Each is created and destroyed only with its context
// current on the calling thread; GlBuffer (gl_buffer.h) is the buffer of the same family.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/render/gl_buffer.h>

namespace tessera::render {

/// A linked GL program. Uniform locations are looked up once per name and kept (a program has
/// a few dozen at most: a linear search over the names seen beats a hash map there). Setters
/// use glProgramUniform*, so the program need not be bound.
class GlProgram {
 public:
  GlProgram() = default;
  /// A compute shader: `#version 450`, then shaders/shared_layout.h, then `source` (with #line 1,
  /// so messages keep the file's line numbers). `defines` (lines of `#define NAME VALUE`) go
  /// right after #version: variants of one source. Throws RenderError naming `label` and GL's
  /// log.
  static GlProgram compute(const char* source, const char* label, const std::string& defines = {});
  /// A vertex and a fragment shader, each prefixed like compute() (`defines` in both).
  static GlProgram graphics(const char* vertex, const char* fragment, const char* label,
                            const std::string& defines = {});
  ~GlProgram();
  GlProgram(GlProgram&& o) noexcept { *this = std::move(o); }
  GlProgram& operator=(GlProgram&& o) noexcept {
    std::swap(mName, o.mName);
    std::swap(mLocations, o.mLocations);
    return *this;
  }
  GlProgram(const GlProgram&) = delete;
  GlProgram& operator=(const GlProgram&) = delete;

  void use() const;
  uint32_t name() const { return mName; }
  explicit operator bool() const { return mName != 0; }
  /// The uniform's location (-1 when the program has none of that name: GL then ignores sets).
  int location(const char* uniform) const;

  void set(const char* uniform, int v) const;
  void set(const char* uniform, uint32_t v) const;
  void set(const char* uniform, float v) const;
  void set(const char* uniform, const glm::ivec2& v) const;
  void set(const char* uniform, const glm::ivec4& v) const;
  void set(const char* uniform, const glm::vec2& v) const;
  void set(const char* uniform, const glm::vec3& v) const;
  void set(const char* uniform, const glm::vec4& v) const;
  void set(const char* uniform, const glm::mat4& v) const;
  /// Arrays from element 0 (uniform names the array).
  void set(const char* uniform, std::span<const glm::vec4> v) const;
  void set(const char* uniform, std::span<const uint32_t> v) const;
  void set(const char* uniform, std::span<const float> v) const;

 private:
  uint32_t mName = 0;
  mutable std::vector<std::pair<std::string, int>> mLocations;
};

/// An immutable 2D texture, clamped at its edges: linear filtering, or nearest for an integer
/// format (read with texelFetch).
class GlTexture {
 public:
  GlTexture() = default;
  /// `format`: GL_RGBA8 or GL_R8 (uploadable), or GL_RG32UI (written by shaders); `levels` mip
  /// levels, each half the one before (rounded down). Throws RenderError when GL refuses the size.
  GlTexture(uint32_t width, uint32_t height, uint32_t format, uint32_t levels = 1);
  ~GlTexture();
  GlTexture(GlTexture&& o) noexcept { *this = std::move(o); }
  GlTexture& operator=(GlTexture&& o) noexcept {
    std::swap(mName, o.mName);
    std::swap(mWidth, o.mWidth);
    std::swap(mHeight, o.mHeight);
    std::swap(mFormat, o.mFormat);
    return *this;
  }
  GlTexture(const GlTexture&) = delete;
  GlTexture& operator=(const GlTexture&) = delete;

  /// Replaces the whole image: width * height pixels of the texture's format, top row first
  /// (texture row 0 is the image's top row: v = 0 at the top).
  void upload(const void* pixels);
  /// Replaces the `w` x `h` pixels at (`x`, `y`) (y from the top row), rows tightly packed.
  void uploadRegion(uint32_t x, uint32_t y, uint32_t w, uint32_t h, const void* pixels);
  uint32_t name() const { return mName; }
  uint32_t width() const { return mWidth; }
  uint32_t height() const { return mHeight; }
  explicit operator bool() const { return mName != 0; }

 private:
  uint32_t mName = 0, mWidth = 0, mHeight = 0, mFormat = 0;
};

class GlBuffer;

/// A buffer's words seen as a texture (GL_TEXTURE_BUFFER; GLSL usamplerBuffer or samplerBuffer,
/// read with texelFetch), no copy made. llvmpipe gathers texels with vector code where it reads
/// a storage buffer lane by lane: about 1.7x faster for the neighbourhood reads of the screen
/// passes. Valid while the buffer lives; a view of a later buffer needs a new one.
class GlBufferTexture {
 public:
  GlBufferTexture() = default;
  /// `format`: GL_R32UI, GL_R32F, GL_RG32UI, GL_RG32F or GL_RGBA32UI: one texel per that many bytes of
  /// `buffer`. Throws RenderError when the buffer holds more texels than GL allows.
  GlBufferTexture(const GlBuffer& buffer, uint32_t format);
  /// The same for a buffer known by its GL name (the GPU cache's chunk buffers).
  GlBufferTexture(uint32_t buffer_name, uint32_t format);
  ~GlBufferTexture();
  GlBufferTexture(GlBufferTexture&& o) noexcept { std::swap(mName, o.mName); }
  GlBufferTexture& operator=(GlBufferTexture&& o) noexcept {
    std::swap(mName, o.mName);
    return *this;
  }
  GlBufferTexture(const GlBufferTexture&) = delete;
  GlBufferTexture& operator=(const GlBufferTexture&) = delete;

  /// Binds the view to texture unit `unit`.
  void bind(uint32_t unit) const;
  uint32_t name() const { return mName; }

 private:
  uint32_t mName = 0;
};

/// A framebuffer object with a colour texture and optionally a depth texture of its own.
class GlFramebuffer {
 public:
  GlFramebuffer() = default;
  /// RGBA8 colour, and a DEPTH_COMPONENT32F depth texture when `depth`. Throws RenderError when
  /// the framebuffer is incomplete.
  GlFramebuffer(uint32_t width, uint32_t height, bool depth);
  ~GlFramebuffer();
  GlFramebuffer(GlFramebuffer&& o) noexcept { *this = std::move(o); }
  GlFramebuffer& operator=(GlFramebuffer&& o) noexcept {
    std::swap(mName, o.mName);
    std::swap(mColor, o.mColor);
    std::swap(mDepth, o.mDepth);
    return *this;
  }
  GlFramebuffer(const GlFramebuffer&) = delete;
  GlFramebuffer& operator=(const GlFramebuffer&) = delete;

  uint32_t name() const { return mName; }
  const GlTexture& color() const { return mColor; }
  uint32_t width() const { return mColor.width(); }
  uint32_t height() const { return mColor.height(); }

 private:
  uint32_t mName = 0;
  GlTexture mColor;
  uint32_t mDepth = 0;  ///< texture name
};

}  // namespace tessera::render
