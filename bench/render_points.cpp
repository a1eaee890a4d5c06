// render_points: the point pass against its baselines, in one run, on one context, with the same
// resident points at 1920x1080: (a) bare GL_POINTS into a depth-tested framebuffer,
// (b) a bare compute atomicMin scatter (one pass, one pixel per point), (c) the renderer's point
// pass (PointPass: depth pass, colour pass; then ResolvePass). Points come from a .tlod store's
// leaves. Prints CSV, writes OUT/render_points.csv and OUT/render_points.png.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/lod/point_store.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/gl_objects.h>
#include <tessera/render/point_pass.h>
#include <tessera/render/screen_passes.h>

namespace {

using namespace tessera;
using Clock = std::chrono::steady_clock;

const char* kVertex = R"(
layout(location = 0) in vec3 aPos;
layout(location = 1) in uint aRgba;
uniform mat4 uClip;
flat out uint vRgba;
void main() { gl_Position = uClip * vec4(aPos, 1.0); vRgba = aRgba; })";
const char* kFragment = R"(
flat in uint vRgba;
out vec4 color;
void main() { color = unpackUnorm4x8(vRgba); })";
// (b) reads each point from a storage buffer; (b') as a buffer texture's texel, as the
// renderer's point pass does, since llvmpipe gathers texels with vector code and reads a storage
// buffer lane by lane: the scatter as fast as this machine does it, the fairer baseline.
const char* kScatterFromBuffer = R"(
layout(std430, binding = 0) readonly buffer Points { Point points[]; };
vec3 positionOf(uint i) { return points[i].position; })";
const char* kScatterFromTexels = R"(
layout(binding = 0) uniform usamplerBuffer uPoints;
vec3 positionOf(uint i) { return uintBitsToFloat(texelFetch(uPoints, int(i)).xyz); })";
const char* kScatter = R"(
layout(local_size_x = 128) in;
layout(std430, binding = 1) buffer Depth { uint depth[]; };
uniform mat4 uClip; uniform uint uFirst; uniform uint uCount; uniform ivec2 uSize;
void main() {
  if (gl_GlobalInvocationID.x >= uCount) return;
  uint i = uFirst + gl_GlobalInvocationID.x;
  vec4 c = uClip * vec4(positionOf(i), 1.0);
  if (c.w <= 0.0) return;
  vec3 ndc = c.xyz / c.w;
  ivec2 q = ivec2(floor((ndc.xy * 0.5 + 0.5) * vec2(uSize)));
  if (q.x < 0 || q.y < 0 || q.x >= uSize.x || q.y >= uSize.y || ndc.z < -1.0 || ndc.z > 1.0) return;
  atomicMin(depth[uint(q.y) * uint(uSize.x) + uint(q.x)], floatBitsToUint(ndc.z * 0.5 + 0.5));
})";

template <typename Fn>
double best(int repeats, Fn&& fn) {
  double b = 1e30;
  for (int r = 0; r < repeats; ++r) {
    glFinish();
    auto t = Clock::now();
    fn();
    glFinish();
    b = std::min(b, std::chrono::duration<double>(Clock::now() - t).count());
  }
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "render_points: GL_POINTS vs compute scatter vs the renderer's point pass, same points, "
      "1920x1080"};
  std::string store_path, out = TESSERA_BENCH_RESULTS_DIR;
  uint64_t max_points = 10'000'000;
  int repeats = 3;
  app.add_option("STORE", store_path, "A .tlod store (its leaves supply the points)")->required();
  app.add_option("--points", max_points, "Points to draw")->capture_default_str();
  app.add_option("--repeat", repeats, "Best of this many frames")->capture_default_str();
  app.add_option("--out", out, "Folder for CSV and chart")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  auto ctx = render::GlContext::createHeadless();
  auto store = lod::PointStore::open(store_path);
  const auto& sum = store->summary();
  glm::dvec3 centre = 0.5 * (sum.bbox_min + sum.bbox_max);
  double radius = 0.5 * glm::length(sum.bbox_max - sum.bbox_min);
  const glm::dvec3 eye = centre + glm::dvec3(0, 0, 2.2 * radius);
  // Leaves until enough points (depth first from the root), then drawn nearest first as the
  // renderer draws its cut (lod_selector.h): positions in the store frame (float).
  std::vector<std::pair<double, lod::NodeId>> leaves;
  uint64_t taken = 0;
  std::vector<lod::NodeId> stack{store->root()};
  while (!stack.empty() && taken < max_points) {
    lod::NodeId id = stack.back();
    stack.pop_back();
    lod::NodeInfo n = store->node(id);
    if (!n.leaf()) {
      for (lod::NodeId c : store->children(id)) stack.push_back(c);
      continue;
    }
    const glm::dvec3 nearest = glm::clamp(eye, n.box_min, n.box_max);
    leaves.emplace_back(glm::length(nearest - eye), id);
    taken += n.points;
  }
  std::stable_sort(leaves.begin(), leaves.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<render::GpuPoint> pts;
  for (const auto& [distance, id] : leaves) {
    auto c = store->loadChunk(id);
    for (size_t i = 0; i < c->size() && pts.size() < max_points; ++i) {
      pts.push_back({glm::vec3(c->offset + glm::dvec3(c->positions[i])), 0xFFC8C8C8u});
    }
  }
  const uint32_t W = 1920, H = 1080;
  glm::mat4 clip(glm::perspective(glm::radians(45.0), double(W) / H, 0.1 * radius, 10 * radius) *
                 glm::lookAt(eye, centre, glm::dvec3(0, 1, 0)));
  const uint32_t n = uint32_t(pts.size());

  GLuint vbo;
  glCreateBuffers(1, &vbo);
  glNamedBufferStorage(vbo, GLsizeiptr(pts.size() * sizeof(render::GpuPoint)), pts.data(), 0);
  // (a) GL_POINTS into an RGBA8 + depth framebuffer.
  GLuint vao, fbo, color_rb, depth_rb;
  glCreateVertexArrays(1, &vao);
  glVertexArrayVertexBuffer(vao, 0, vbo, 0, sizeof(render::GpuPoint));
  glEnableVertexArrayAttrib(vao, 0);
  glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(vao, 0, 0);
  glEnableVertexArrayAttrib(vao, 1);
  glVertexArrayAttribIFormat(vao, 1, 1, GL_UNSIGNED_INT, 12);
  glVertexArrayAttribBinding(vao, 1, 0);
  glCreateRenderbuffers(1, &color_rb);
  glNamedRenderbufferStorage(color_rb, GL_RGBA8, W, H);
  glCreateRenderbuffers(1, &depth_rb);
  glNamedRenderbufferStorage(depth_rb, GL_DEPTH_COMPONENT24, W, H);
  glCreateFramebuffers(1, &fbo);
  glNamedFramebufferRenderbuffer(fbo, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_rb);
  glNamedFramebufferRenderbuffer(fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_rb);
  const auto raster = render::GlProgram::graphics(kVertex, kFragment, "GL_POINTS baseline");
  double t_points = best(repeats, [&] {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, W, H);
    glEnable(GL_DEPTH_TEST);
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    raster.use();
    raster.set("uClip", clip);
    glBindVertexArray(vao);
    glDrawArrays(GL_POINTS, 0, GLsizei(n));
  });
  // (b) bare compute scatter.
  const auto scatter = render::GlProgram::compute(
      (std::string(kScatterFromBuffer) + kScatter).c_str(), "scatter baseline");
  GLuint depth;
  glCreateBuffers(1, &depth);
  glNamedBufferStorage(depth, GLsizeiptr(size_t(W) * H * 4), nullptr, GL_DYNAMIC_STORAGE_BIT);
  auto run_scatter = [&](const render::GlProgram& program) {
    const GLuint ones = 0xFFFFFFFFu;
    glClearNamedBufferData(depth, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &ones);
    program.use();
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, vbo);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, depth);
    program.set("uClip", clip);
    program.set("uSize", glm::ivec2(W, H));
    const uint32_t kMaxPoints = 65535u * 128u;  // work-group count limit per dispatch
    for (uint32_t done = 0; done < n; done += kMaxPoints) {
      const uint32_t count = std::min(kMaxPoints, n - done);
      program.set("uFirst", done);
      program.set("uCount", count);
      glDispatchCompute((count + 127) / 128, 1, 1);
    }
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  };
  double t_scatter = best(repeats, [&] { run_scatter(scatter); });
  // (b') the scatter reading points as texels.
  const auto scatter_texels = render::GlProgram::compute(
      (std::string(kScatterFromTexels) + kScatter).c_str(), "scatter baseline, texels");
  const render::GlBufferTexture point_texels(vbo, GL_RGBA32UI);
  point_texels.bind(0);
  double t_scatter_texels = best(repeats, [&] { run_scatter(scatter_texels); });
  glBindTextureUnit(0, 0);
  // (c) the renderer's point pass.
  render::FrameTarget target(W, H);
  render::PointPass points;
  render::ResolvePass resolve;
  points.setPoints(pts);
  render::DrawBatch batch;
  batch.count = n;
  batch.clip_from_local = clip;
  auto frame = [&](const render::PointShading& shading) {
    target.clearGeometry(shading.pick);
    points.draw(target, {&batch, 1}, shading);
    resolve.run(target, glm::vec3(0), shading.uniform_color);
  };
  render::PointShading colored;  // per-point colours: depth pass + colour pass + resolve
  double t_renderer = best(repeats, [&] { frame(colored); });
  render::PointShading uniform;  // one colour (scans without RGB): depth pass + resolve
  uniform.uniform_color = 0xFFC8C8C8u;
  double t_uniform = best(repeats, [&] { frame(uniform); });

  struct Row {
    const char* name;
    double s;
  } rows[] = {{"(a) GL_POINTS", t_points},
              {"(b) compute scatter", t_scatter},
              {"(b') compute scatter, points as texels", t_scatter_texels},
              {"(c) renderer, RGB points", t_renderer},
              {"(c') renderer, points without RGB", t_uniform}};
  std::filesystem::create_directories(out);
  std::ofstream csv(std::filesystem::path(out) / "render_points.csv");
  csv << "method,points,seconds,mpoints_per_s\n";
  std::printf("method,points,seconds,mpoints_per_s\n");
  for (const Row& r : rows) {
    std::printf("\"%s\",%u,%.4f,%.1f\n", r.name, n, r.s, n / r.s / 1e6);
    csv << '"' << r.name << "\"," << n << "," << r.s << "," << n / r.s / 1e6 << "\n";
  }
  csv.close();
  std::fprintf(stderr,
               "%s\n(c)/(a) = %.1fx, (c')/(a) = %.1fx (goal >= 15x); (c)/(b) = %.0f%%, (c')/(b) = "
               "%.0f%% (goal >= 60%%); against (b'): %.0f%%, %.0f%%\n",
               ctx->description().c_str(), t_points / t_renderer, t_points / t_uniform,
               100.0 * t_scatter / t_renderer, 100.0 * t_scatter / t_uniform,
               100.0 * t_scatter_texels / t_renderer, 100.0 * t_scatter_texels / t_uniform);
  std::ofstream gp(std::filesystem::path(out) / "render_points.gp");
  gp << "set terminal pngcairo size 1400,480 font 'sans,10' noenhanced\nset output '"
     << (std::filesystem::path(out) / "render_points.png").string() << "'\n"
     << "set datafile separator ','\nset style data histograms\nset style fill solid 0.8 border "
        "-1\nset logscale y\n"
     << "set ylabel 'M points/s (log)'\nset title 'Point pass at 1920x1080, " << n
     << " points, llvmpipe, 2 cores'\n"
     << "set grid ytics\nplot '" << (std::filesystem::path(out) / "render_points.csv").string()
     << "' every ::1 using 4:xtic(1) title 'M points/s'\n";
  gp.close();
  std::string cmd = std::string(TESSERA_GNUPLOT) + " '" +
                    (std::filesystem::path(out) / "render_points.gp").string() + "'";
  if (std::system(cmd.c_str()) != 0)
    std::fprintf(stderr, "render_points: gnuplot failed; the CSV is complete\n");
  return 0;
}
