#include <tessera/render/gl_objects.h>

#include <glm/gtc/type_ptr.hpp>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/render/gl_buffer.h>
#include <tessera/render/gl_context.h>

#include "shaders.h"

namespace tessera::render {
namespace {

GLuint compileStage(GLenum stage, const char* source, const char* label,
                    const std::string& defines = {}) {
  GLuint shader = glCreateShader(stage);
  // The shared layout goes first; #line keeps the shader's own line numbers in messages.
  const char* sources[] = {"#version 450 core\n", defines.c_str(), shaders::kSharedLayout,
                           "\n#line 1\n", source};
  glShaderSource(shader, 5, sources, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[4096];
    glGetShaderInfoLog(shader, sizeof log, nullptr, log);
    glDeleteShader(shader);
    throw RenderError(std::string("render: ") + label + " does not compile: " + log);
  }
  return shader;
}

GLuint link(std::initializer_list<GLuint> stages, const char* label) {
  GLuint program = glCreateProgram();
  for (GLuint s : stages) glAttachShader(program, s);
  glLinkProgram(program);
  for (GLuint s : stages) glDeleteShader(s);
  GLint ok = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[4096];
    glGetProgramInfoLog(program, sizeof log, nullptr, log);
    glDeleteProgram(program);
    throw RenderError(std::string("render: ") + label + " does not link: " + log);
  }
  return program;
}

}  // namespace

GlProgram GlProgram::compute(const char* source, const char* label, const std::string& defines) {
  GlProgram p;
  p.mName = link({compileStage(GL_COMPUTE_SHADER, source, label, defines)}, label);
  return p;
}

GlProgram GlProgram::graphics(const char* vertex, const char* fragment, const char* label,
                             const std::string& defines) {
  GlProgram p;
  const GLuint vs = compileStage(GL_VERTEX_SHADER, vertex, label, defines);
  GLuint fs = 0;
  try {
    fs = compileStage(GL_FRAGMENT_SHADER, fragment, label, defines);
  } catch (...) {
    glDeleteShader(vs);
    throw;
  }
  p.mName = link({vs, fs}, label);
  return p;
}

GlProgram::~GlProgram() {
  if (mName) glDeleteProgram(mName);
}

void GlProgram::use() const {
  glUseProgram(mName);
}

int GlProgram::location(const char* uniform) const {
  for (const auto& [n, loc] : mLocations)
    if (n == uniform) return loc;
  const int loc = glGetUniformLocation(mName, uniform);
  mLocations.emplace_back(uniform, loc);
  return loc;
}

void GlProgram::set(const char* u, int v) const {
  glProgramUniform1i(mName, location(u), v);
}
void GlProgram::set(const char* u, uint32_t v) const {
  glProgramUniform1ui(mName, location(u), v);
}
void GlProgram::set(const char* u, float v) const {
  glProgramUniform1f(mName, location(u), v);
}
void GlProgram::set(const char* u, const glm::ivec2& v) const {
  glProgramUniform2i(mName, location(u), v.x, v.y);
}
void GlProgram::set(const char* u, const glm::ivec4& v) const {
  glProgramUniform4i(mName, location(u), v.x, v.y, v.z, v.w);
}
void GlProgram::set(const char* u, const glm::vec2& v) const {
  glProgramUniform2f(mName, location(u), v.x, v.y);
}
void GlProgram::set(const char* u, const glm::vec3& v) const {
  glProgramUniform3f(mName, location(u), v.x, v.y, v.z);
}
void GlProgram::set(const char* u, const glm::vec4& v) const {
  glProgramUniform4f(mName, location(u), v.x, v.y, v.z, v.w);
}
void GlProgram::set(const char* u, const glm::mat4& v) const {
  glProgramUniformMatrix4fv(mName, location(u), 1, GL_FALSE, glm::value_ptr(v));
}

void GlProgram::set(const char* u, std::span<const glm::vec4> v) const {
  glProgramUniform4fv(mName, location(u), GLsizei(v.size()), glm::value_ptr(v[0]));
}
void GlProgram::set(const char* u, std::span<const uint32_t> v) const {
  glProgramUniform1uiv(mName, location(u), GLsizei(v.size()), v.data());
}
void GlProgram::set(const char* u, std::span<const float> v) const {
  glProgramUniform1fv(mName, location(u), GLsizei(v.size()), v.data());
}

GlTexture::GlTexture(uint32_t width, uint32_t height, uint32_t format, uint32_t levels)
    : mWidth(width), mHeight(height), mFormat(format) {
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (width == 0 || height == 0 || width > uint32_t(max_size) || height > uint32_t(max_size))
    throw RenderError("render::GlTexture: " + std::to_string(width) + "x" + std::to_string(height) +
                      " pixels (1.." + std::to_string(max_size) + " each way)");
  glCreateTextures(GL_TEXTURE_2D, 1, &mName);
  glTextureStorage2D(mName, GLsizei(levels), format, GLsizei(width), GLsizei(height));
  // Integer textures are incomplete (read as zero) with linear filtering.
  const bool integer = format == GL_RG32UI;
  glTextureParameteri(mName, GL_TEXTURE_MIN_FILTER,
                      integer ? GL_NEAREST_MIPMAP_NEAREST : GL_LINEAR);
  glTextureParameteri(mName, GL_TEXTURE_MAG_FILTER, integer ? GL_NEAREST : GL_LINEAR);
  glTextureParameteri(mName, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTextureParameteri(mName, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}

GlTexture::~GlTexture() {
  if (mName) glDeleteTextures(1, &mName);
}

void GlTexture::upload(const void* pixels) {
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTextureSubImage2D(mName, 0, 0, 0, GLsizei(mWidth), GLsizei(mHeight),
                      mFormat == GL_R8 ? GL_RED : GL_RGBA, GL_UNSIGNED_BYTE, pixels);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
}

void GlTexture::uploadRegion(uint32_t x, uint32_t y, uint32_t w, uint32_t h, const void* pixels) {
  if (w == 0 || h == 0) return;
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTextureSubImage2D(mName, 0, GLint(x), GLint(y), GLsizei(w), GLsizei(h),
                      mFormat == GL_R8 ? GL_RED : GL_RGBA, GL_UNSIGNED_BYTE, pixels);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
}

GlBufferTexture::GlBufferTexture(const GlBuffer& buffer, uint32_t format)
    : GlBufferTexture(buffer.name(), format) {}

GlBufferTexture::GlBufferTexture(uint32_t buffer_name, uint32_t format) {
  GLint max_texels = 0;
  glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_texels);
  GLint64 bytes = 0;
  glGetNamedBufferParameteri64v(buffer_name, GL_BUFFER_SIZE, &bytes);
  const GLint64 texel_bytes =
      format == GL_RG32UI || format == GL_RG32F ? 8 : format == GL_RGBA32UI ? 16 : 4;
  if (bytes / texel_bytes > max_texels)
    throw RenderError("render::GlBufferTexture: " + std::to_string(bytes / texel_bytes) +
                      " texels (at most " + std::to_string(max_texels) + ")");
  glCreateTextures(GL_TEXTURE_BUFFER, 1, &mName);
  glTextureBuffer(mName, format, buffer_name);
}

GlBufferTexture::~GlBufferTexture() {
  if (mName) glDeleteTextures(1, &mName);
}

void GlBufferTexture::bind(uint32_t unit) const {
  glBindTextureUnit(unit, mName);
}

GlFramebuffer::GlFramebuffer(uint32_t width, uint32_t height, bool depth)
    : mColor(width, height, GL_RGBA8) {
  glCreateFramebuffers(1, &mName);
  glNamedFramebufferTexture(mName, GL_COLOR_ATTACHMENT0, mColor.name(), 0);
  if (depth) {
    glCreateTextures(GL_TEXTURE_2D, 1, &mDepth);
    glTextureStorage2D(mDepth, 1, GL_DEPTH_COMPONENT32F, GLsizei(width), GLsizei(height));
    glNamedFramebufferTexture(mName, GL_DEPTH_ATTACHMENT, mDepth, 0);
  }
  const GLenum status = glCheckNamedFramebufferStatus(mName, GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    glDeleteFramebuffers(1, &mName);
    if (mDepth) glDeleteTextures(1, &mDepth);
    throw RenderError("render::GlFramebuffer: " + std::to_string(width) + "x" +
                      std::to_string(height) + " is incomplete (status " + std::to_string(status) +
                      ")");
  }
}

GlFramebuffer::~GlFramebuffer() {
  if (mName) glDeleteFramebuffers(1, &mName);
  if (mDepth) glDeleteTextures(1, &mDepth);
}

}  // namespace tessera::render
