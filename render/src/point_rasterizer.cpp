#include <tessera/render/point_rasterizer.h>

#include <png.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/render/gl_context.h>

#include "shaders.h"

namespace tessera::render {
namespace {

uint32_t compileCompute(const char* source, const char* name) {
  GLuint shader = glCreateShader(GL_COMPUTE_SHADER);
  const char* sources[] = {"#version 450 core\n", source};
  glShaderSource(shader, 2, sources, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[4096];
    glGetShaderInfoLog(shader, sizeof log, nullptr, log);
    glDeleteShader(shader);
    throw RenderError(std::string("render::PointRasterizer: ") + name +
                      " does not compile: " + log);
  }
  GLuint program = glCreateProgram();
  glAttachShader(program, shader);
  glLinkProgram(program);
  glDeleteShader(shader);
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[4096];
    glGetProgramInfoLog(program, sizeof log, nullptr, log);
    glDeleteProgram(program);
    throw RenderError(std::string("render::PointRasterizer: ") + name + " does not link: " + log);
  }
  return program;
}

uint32_t makeBuffer(size_t bytes) {
  GLuint b = 0;
  glCreateBuffers(1, &b);
  glNamedBufferStorage(b, GLsizeiptr(std::max<size_t>(bytes, 16)), nullptr,
                       GL_DYNAMIC_STORAGE_BIT | GL_MAP_READ_BIT);
  return b;
}

}  // namespace

PointRasterizer::PointRasterizer(uint32_t width, uint32_t height) : mWidth(width), mHeight(height) {
  mRasterProgram = compileCompute(shaders::kPointRaster, "point_raster.comp");
  mResolveProgram = compileCompute(shaders::kPointResolve, "point_resolve.comp");
  const size_t pixels = size_t(width) * height;
  mDepth = makeBuffer(pixels * 4);
  mColors = makeBuffer(pixels * 4);
  mImage = makeBuffer(pixels * 4);
}

PointRasterizer::~PointRasterizer() {
  GLuint buffers[] = {mPoints, mDepth, mColors, mImage};
  glDeleteBuffers(4, buffers);
  glDeleteProgram(mRasterProgram);
  glDeleteProgram(mResolveProgram);
}

void PointRasterizer::setPoints(std::span<const GpuPoint> points) {
  if (mPoints) glDeleteBuffers(1, &mPoints);
  glCreateBuffers(1, &mPoints);
  glNamedBufferStorage(mPoints, GLsizeiptr(std::max<size_t>(points.size_bytes(), 16)),
                       points.empty() ? nullptr : points.data(), 0);
}

RasterTimings PointRasterizer::render(std::span<const DrawBatch> batches,
                                      const glm::vec3& background, const RasterShading& shading) {
  RasterTimings timings;
  auto t = std::chrono::steady_clock::now();
  auto lap = [&t] {
    glFinish();
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - t).count();
    t = now;
    return ms;
  };
  const GLuint all_ones = 0xFFFFFFFFu;
  glClearNamedBufferData(mDepth, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &all_ones);
  glClearNamedBufferData(mColors, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &all_ones);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, mDepth);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, mColors);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, mImage);
  glUseProgram(mRasterProgram);
  const GLint u_clip = glGetUniformLocation(mRasterProgram, "uClip");
  const GLint u_first = glGetUniformLocation(mRasterProgram, "uFirst");
  const GLint u_count = glGetUniformLocation(mRasterProgram, "uCount");
  const GLint u_size = glGetUniformLocation(mRasterProgram, "uSize");
  const GLint u_radius = glGetUniformLocation(mRasterProgram, "uRadius");
  const GLint u_pass = glGetUniformLocation(mRasterProgram, "uPass");
  const GLint u_spacing = glGetUniformLocation(mRasterProgram, "uSpacingK");
  glUniform2i(u_size, GLint(mWidth), GLint(mHeight));
  const int passes = shading.uniform_color != 0 ? 1 : 2;
  for (int pass = 0; pass < passes; ++pass) {
    glUniform1i(u_pass, pass);
    for (const DrawBatch& b : batches) {
      if (b.count == 0) continue;
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, b.buffer ? b.buffer : mPoints);
      glUniform1f(u_spacing, b.spacing_k);
      glUniformMatrix4fv(u_clip, 1, GL_FALSE, &b.clip_from_local[0][0]);
      glUniform1i(u_radius, b.splat_radius);
      // At most 65535 work groups per dispatch (GL's guaranteed minimum, llvmpipe's limit).
      const uint32_t kMaxPoints = 65535u * 128u;
      for (uint32_t done = 0; done < b.count; done += kMaxPoints) {
        const uint32_t count = std::min(kMaxPoints, b.count - done);
        glUniform1ui(u_first, b.first + done);
        glUniform1ui(u_count, count);
        glDispatchCompute((count + 127) / 128, 1, 1);
      }
    }
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    (pass == 0 ? timings.depth_ms : timings.color_ms) = lap();
  }
  glUseProgram(mResolveProgram);
  glUniform2i(glGetUniformLocation(mResolveProgram, "uSize"), GLint(mWidth), GLint(mHeight));
  glm::uvec3 bg = glm::uvec3(glm::clamp(background, 0.0f, 1.0f) * 255.0f + 0.5f);
  glUniform1ui(glGetUniformLocation(mResolveProgram, "uBackground"),
               bg.r | bg.g << 8 | bg.b << 16 | 0xFF000000u);
  glUniform1ui(glGetUniformLocation(mResolveProgram, "uUniformColor"), shading.uniform_color);
  glUniform1f(glGetUniformLocation(mResolveProgram, "uEdlStrength"), shading.edl_strength);
  glUniform1i(glGetUniformLocation(mResolveProgram, "uEdlRadius"), shading.edl_radius);
  glUniform1f(glGetUniformLocation(mResolveProgram, "uP22"), float(shading.projection[2][2]));
  glUniform1f(glGetUniformLocation(mResolveProgram, "uP32"), float(shading.projection[3][2]));
  glDispatchCompute((mWidth + 15) / 16, (mHeight + 15) / 16, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
  timings.resolve_ms = lap();
  return timings;
}

Image PointRasterizer::read() const {
  Image img;
  img.width = mWidth;
  img.height = mHeight;
  img.rgba.resize(size_t(mWidth) * mHeight * 4);
  glGetNamedBufferSubData(mImage, 0, GLsizeiptr(img.rgba.size()), img.rgba.data());
  return img;
}

void writePng(const std::string& path, const Image& image) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw RenderError("render::writePng(): cannot create " + path);
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    std::fclose(f);
    throw RenderError("render::writePng(): writing " + path + " failed (disk full?)");
  }
  png_init_io(png, f);
  png_set_IHDR(png, info, image.width, image.height, 8, PNG_COLOR_TYPE_RGBA, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (uint32_t y = 0; y < image.height; ++y) {
    png_write_row(png, const_cast<png_bytep>(image.rgba.data() + size_t(y) * image.width * 4));
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  if (std::fclose(f) != 0) throw RenderError("render::writePng(): closing " + path + " failed");
}

}  // namespace tessera::render
