#include <tessera/render/point_rasterizer.h>

#include <png.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <string>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/render/gl_context.h>

#include "shaders.h"
#include "shared_layout.h"

namespace tessera::render {
namespace {

uint32_t compileCompute(const char* source, const char* name) {
  GLuint shader = glCreateShader(GL_COMPUTE_SHADER);
  // The shared layout goes first; #line keeps the shader's own line numbers in messages.
  const char* sources[] = {"#version 450 core\n", shaders::kSharedLayout, "\n#line 1\n", source};
  glShaderSource(shader, 4, sources, nullptr);
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

/// Dispatches `count` points in slices of at most 65535 work groups of 128 (GL's guaranteed
/// minimum, llvmpipe's limit); `setSlice(first, n)` sets each slice's uniforms and bindings.
template <typename F>
void dispatchSlices(uint32_t count, F&& setSlice) {
  constexpr uint32_t kMaxPoints = 65535u * 128u;
  for (uint32_t done = 0; done < count; done += kMaxPoints) {
    const uint32_t n = std::min(kMaxPoints, count - done);
    setSlice(done, n);
    glDispatchCompute((n + 127) / 128, 1, 1);
  }
}

/// Milliseconds since the previous lap (or construction), with the GL work finished.
class GpuLap {
 public:
  double operator()() {
    glFinish();
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - mStart).count();
    mStart = now;
    return ms;
  }

 private:
  std::chrono::steady_clock::time_point mStart = std::chrono::steady_clock::now();
};

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

namespace {

uint32_t packColor(const glm::vec3& c) {
  const glm::uvec3 u = glm::uvec3(glm::clamp(c, 0.0f, 1.0f) * 255.0f + 0.5f);
  return u.r | u.g << 8 | u.b << 16 | 0xFF000000u;
}

}  // namespace

void PointRasterizer::beginEnsembles() {
  if (!mSpbrProgram) {
    mSpbrProgram = compileCompute(shaders::kSpbrRaster, "spbr_raster.comp");
    mAccumulateProgram = compileCompute(shaders::kSpbrAccumulate, "spbr_accumulate.comp");
    mAccum = makeBuffer(size_t(mWidth) * mHeight * 12);
    mNoNormals = makeBuffer(16);
  }
  const GLuint zero = 0;
  glClearNamedBufferData(mAccum, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
}

RasterTimings PointRasterizer::drawEnsembles(std::span<const DrawBatch> batches, uint32_t first,
                                             uint32_t count, uint32_t total, uint32_t max_layers,
                                             const glm::vec3& background,
                                             const RasterShading& shading, bool slant_off,
                                             bool one_layer) {
  RasterTimings timings;
  GpuLap lap;
  const size_t plane = size_t(mWidth) * mHeight;
  const uint32_t layers = one_layer ? count : std::max<uint32_t>(1, std::min(max_layers, count));
  if (!one_layer && layers > mLayers) {
    GLuint old[] = {mLayerDepth, mLayerColors};
    glDeleteBuffers(2, old);
    mLayerDepth = makeBuffer(plane * layers * 4);
    mLayerColors = makeBuffer(plane * layers * 4);
    mLayers = layers;
  }
  const GLint u_clip = glGetUniformLocation(mSpbrProgram, "uClip");
  const GLint u_count = glGetUniformLocation(mSpbrProgram, "uCount");
  const GLint u_disc = glGetUniformLocation(mSpbrProgram, "uDiscK");
  const GLint u_k = glGetUniformLocation(mSpbrProgram, "uK");
  const GLint u_group_first = glGetUniformLocation(mSpbrProgram, "uGroupFirst");
  const GLint u_group_count = glGetUniformLocation(mSpbrProgram, "uGroupCount");
  const GLint u_seed = glGetUniformLocation(mSpbrProgram, "uSeed");
  const GLint u_pass = glGetUniformLocation(mSpbrProgram, "uPass");
  const GLint u_eye = glGetUniformLocation(mSpbrProgram, "uEyeLocal");
  const int passes = shading.uniform_color != 0 ? 1 : 2;
  for (uint32_t group = first; group < first + count; group += layers) {
    const uint32_t n = std::min(layers, first + count - group);
    if (one_layer && mLayers == 0) {
      mLayerDepth = makeBuffer(plane * 4);
      mLayerColors = makeBuffer(plane * 4);
      mLayers = 1;
    }
    const uint32_t cleared = one_layer ? 1 : n;
    const GLuint all_ones = 0xFFFFFFFFu;
    glClearNamedBufferSubData(mLayerDepth, GL_R32UI, 0, GLsizeiptr(plane * cleared * 4),
                              GL_RED_INTEGER, GL_UNSIGNED_INT, &all_ones);
    if (passes == 2) {
      glClearNamedBufferSubData(mLayerColors, GL_R32UI, 0, GLsizeiptr(plane * cleared * 4),
                                GL_RED_INTEGER, GL_UNSIGNED_INT, &all_ones);
    }
    glUseProgram(mSpbrProgram);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_DEPTH, mLayerDepth);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_COLORS, mLayerColors);
    glUniform2i(glGetUniformLocation(mSpbrProgram, "uSize"), GLint(mWidth), GLint(mHeight));
    glUniform1ui(glGetUniformLocation(mSpbrProgram, "uTotal"), total);
    glUniform1i(glGetUniformLocation(mSpbrProgram, "uMaxRadius"), 16);
    glUniform1i(glGetUniformLocation(mSpbrProgram, "uSlantOff"), slant_off ? 1 : 0);
    glUniform1i(glGetUniformLocation(mSpbrProgram, "uOneLayer"), one_layer ? 1 : 0);
    glUniform1ui(u_group_first, group);
    glUniform1ui(u_group_count, n);
    for (int pass = 0; pass < passes; ++pass) {
      glUniform1i(u_pass, pass);
      for (const DrawBatch& b : batches) {
        if (b.count == 0 || b.spbr_k <= 0.0f) continue;
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_POINTS,
                         b.buffer ? b.buffer : mPoints);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_NORMALS,
                         b.normals ? b.normals : mNoNormals);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_RATIOS,
                         b.density_ratios ? b.density_ratios : mNoNormals);
        glUniform1i(glGetUniformLocation(mSpbrProgram, "uHasRatios"), b.density_ratios ? 1 : 0);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_CELLS,
                         b.cells ? b.cells : mNoNormals);
        glUniform1i(glGetUniformLocation(mSpbrProgram, "uHasCells"), b.cells ? 1 : 0);
        glUniform1f(glGetUniformLocation(mSpbrProgram, "uJitterK"), b.jitter_k);
        glUniform1ui(glGetUniformLocation(mSpbrProgram, "uCopyCap"), total);
        glUniformMatrix4fv(u_clip, 1, GL_FALSE, &b.clip_from_local[0][0]);
        glUniform1f(u_disc, b.disc_k);
        glUniform1f(u_k, b.spbr_k);
        glUniform1ui(u_seed, b.seed);
        glUniform3fv(u_eye, 1, &b.eye_local[0]);
        glUniform1ui(glGetUniformLocation(mSpbrProgram, "uColorOverride"), b.color_override);
        // Batches with buffer 0 start at `first` in the rasterizer's own buffer: offset the
        // binding instead of the index, so point indices (and so ensembles) stay per batch.
        if (!b.buffer && b.first) {
          glBindBufferRange(GL_SHADER_STORAGE_BUFFER, 0, mPoints, GLintptr(b.first) * 16,
                            GLsizeiptr(b.count) * 16);
        }
        dispatchSlices(b.count, [&](uint32_t done, uint32_t c) {
          glUniform1ui(u_count, c);
          // Later slices of a huge batch: a bound range keeps indices within the slice; the
          // seed changes with the slice so their points stay independent.
          if (done) {
            glBindBufferRange(GL_SHADER_STORAGE_BUFFER, 0, b.buffer ? b.buffer : mPoints,
                              GLintptr(b.first + done) * 16, GLsizeiptr(c) * 16);
            glUniform1ui(u_seed, b.seed ^ (done * 0x9E3779B9u));
          }
        });
      }
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      (pass == 0 ? timings.depth_ms : timings.color_ms) += lap();
    }
    glUseProgram(mAccumulateProgram);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_DEPTH, mLayerDepth);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_COLORS, mLayerColors);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_ACCUM, mAccum);
    glUniform2i(glGetUniformLocation(mAccumulateProgram, "uSize"), GLint(mWidth), GLint(mHeight));
    glUniform1ui(glGetUniformLocation(mAccumulateProgram, "uLayers"), cleared);
    glUniform1ui(glGetUniformLocation(mAccumulateProgram, "uBackground"), packColor(background));
    glUniform1ui(glGetUniformLocation(mAccumulateProgram, "uUniformColor"), shading.uniform_color);
    glUniform1i(glGetUniformLocation(mAccumulateProgram, "uMode"), 0);
    glDispatchCompute((mWidth + 15) / 16, (mHeight + 15) / 16, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    timings.resolve_ms += lap();
  }
  return timings;
}

RasterTimings PointRasterizer::renderBlended(std::span<const DrawBatch> batches,
                                             const glm::vec3& background, bool weighted_blended) {
  RasterTimings timings;
  GpuLap lap;
  if (!mOitProgram) {
    mOitProgram = compileCompute(shaders::kOitAccumulate, "oit_accumulate.comp");
    mOitResolveProgram = compileCompute(shaders::kOitResolve, "oit_resolve.comp");
    mOitSums = makeBuffer(size_t(mWidth) * mHeight * 20);
  }
  const float zero = 0.0f;
  glClearNamedBufferData(mOitSums, GL_R32F, GL_RED, GL_FLOAT, &zero);
  glUseProgram(mOitProgram);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_ACCUM, mOitSums);
  glUniform2i(glGetUniformLocation(mOitProgram, "uSize"), GLint(mWidth), GLint(mHeight));
  glUniform1i(glGetUniformLocation(mOitProgram, "uMode"), weighted_blended ? 1 : 0);
  glUniform1i(glGetUniformLocation(mOitProgram, "uMaxRadius"), 16);
  for (const DrawBatch& b : batches) {
    if (b.count == 0 || b.point_alpha <= 0.0f) continue;
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_POINTS,
                     b.buffer ? b.buffer : mPoints);
    glUniformMatrix4fv(glGetUniformLocation(mOitProgram, "uClip"), 1, GL_FALSE,
                       &b.clip_from_local[0][0]);
    glUniform1f(glGetUniformLocation(mOitProgram, "uDiscK"), b.disc_k);
    glUniform1f(glGetUniformLocation(mOitProgram, "uAlpha"), b.point_alpha);
    glUniform1ui(glGetUniformLocation(mOitProgram, "uColorOverride"), b.color_override);
    dispatchSlices(b.count, [&](uint32_t done, uint32_t c) {
      if (done) {
        glBindBufferRange(GL_SHADER_STORAGE_BUFFER, 0, b.buffer ? b.buffer : mPoints,
                          GLintptr(b.first + done) * 16, GLsizeiptr(c) * 16);
      }
      glUniform1ui(glGetUniformLocation(mOitProgram, "uCount"), c);
    });
  }
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  timings.depth_ms = lap();
  glUseProgram(mOitResolveProgram);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, mImage);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_ACCUM, mOitSums);
  glUniform2i(glGetUniformLocation(mOitResolveProgram, "uSize"), GLint(mWidth), GLint(mHeight));
  const glm::vec3 bg = glm::clamp(background, 0.0f, 1.0f) * 255.0f;
  glUniform3f(glGetUniformLocation(mOitResolveProgram, "uBackground"), bg.r, bg.g, bg.b);
  glDispatchCompute((mWidth + 15) / 16, (mHeight + 15) / 16, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
  timings.resolve_ms = lap();
  return timings;
}

double PointRasterizer::resolveEnsembles(uint32_t accumulated) {
  const auto t = std::chrono::steady_clock::now();
  glUseProgram(mAccumulateProgram);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, mImage);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_ACCUM, mAccum);
  glUniform2i(glGetUniformLocation(mAccumulateProgram, "uSize"), GLint(mWidth), GLint(mHeight));
  glUniform1i(glGetUniformLocation(mAccumulateProgram, "uMode"), 1);
  glUniform1ui(glGetUniformLocation(mAccumulateProgram, "uAccumulated"), accumulated);
  glDispatchCompute((mWidth + 15) / 16, (mHeight + 15) / 16, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
  glFinish();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

PointRasterizer::~PointRasterizer() {
  // Every object this class creates (glDelete* ignores the zero names of those never made).
  GLuint buffers[] = {mPoints,      mDepth, mColors,    mImage,  mLayerDepth,
                      mLayerColors, mAccum, mNoNormals, mOitSums};
  glDeleteBuffers(GLsizei(std::size(buffers)), buffers);
  for (GLuint program : {mSpbrProgram, mAccumulateProgram, mRasterProgram, mResolveProgram,
                         mOitProgram, mOitResolveProgram})
    glDeleteProgram(program);
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
  GpuLap lap;
  const GLuint all_ones = 0xFFFFFFFFu;
  glClearNamedBufferData(mDepth, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &all_ones);
  glClearNamedBufferData(mColors, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &all_ones);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_DEPTH, mDepth);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_COLORS, mColors);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_IMAGE, mImage);
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
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, TESSERA_BINDING_POINTS,
                       b.buffer ? b.buffer : mPoints);
      glUniform1f(u_spacing, b.spacing_k);
      glUniform1ui(glGetUniformLocation(mRasterProgram, "uColorOverride"), b.color_override);
      glUniformMatrix4fv(u_clip, 1, GL_FALSE, &b.clip_from_local[0][0]);
      glUniform1i(u_radius, b.splat_radius);
      dispatchSlices(b.count, [&](uint32_t done, uint32_t count) {
        glUniform1ui(u_first, b.first + done);
        glUniform1ui(u_count, count);
      });
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

double edgeWidth(const Image& img, uint32_t edge) {
  std::vector<double> col(img.width, 0.0);
  for (uint32_t y = 0; y < img.height; ++y)
    for (uint32_t x = 0; x < img.width; ++x)
      col[x] += img.rgba[(size_t(y) * img.width + x) * 4] / double(img.height);
  auto mean = [&](uint32_t x0, uint32_t x1) {
    double s = 0;
    for (uint32_t x = x0; x < x1; ++x) s += col[x];
    return s / double(std::max(1u, x1 - x0));
  };
  const double hi = mean(edge / 4, 3 * edge / 4);
  const double lo = mean(edge + (img.width - edge) / 4, edge + 3 * (img.width - edge) / 4);
  // Where the profile falls through `level`, scanning from the plateau.
  auto crossing = [&](double level) {
    for (uint32_t x = edge / 2; x + 1 < img.width; ++x)
      if (col[x] >= level && col[x + 1] < level)
        return x + (col[x] - level) / (col[x] - col[x + 1]);
    return double(img.width);
  };
  return crossing(lo + 0.1 * (hi - lo)) - crossing(lo + 0.9 * (hi - lo));
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

Image readPng(const std::string& path) {
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.c_str()))
    throw RenderError("render::readPng(): " + path + ": " + png.message);
  png.format = PNG_FORMAT_RGBA;
  if (png.width == 0 || png.height == 0 || png.width > 65536 || png.height > 65536) {
    png_image_free(&png);
    throw RenderError("render::readPng(): " + path + ": " + std::to_string(png.width) + "x" +
                      std::to_string(png.height) + " pixels (1..65536 each way)");
  }
  Image img;
  img.width = png.width;
  img.height = png.height;
  img.rgba.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, img.rgba.data(), 0, nullptr)) {
    const std::string why = png.message;
    png_image_free(&png);
    throw RenderError("render::readPng(): " + path + ": " + why);
  }
  return img;
}

}  // namespace tessera::render
