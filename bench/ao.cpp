// ao: screen-space ambient occlusion (render/ao_pass.h AoPass) against a ray-traced reference
// and beside eye-dome lighting, in one run on one context. The Stanford bunny reconstruction
// (bun_zipper.ply) is drawn with the mesh pass at --size (1920x1080 by default); its depth plane is
// copied once. The reference, per covered pixel: the pixel's primary ray cast with Embree on the
// same triangles gives the surface point and its geometric normal, then --rays stratified
// cosine-weighted rays of length R (16 x 16 strata on the projected disc) give
//   visibility = 1 - mean over the rays of w(t),  w(t) = clamp((R - t) / (kAoFalloff R), 0, 1)
// for a ray meeting the surface at distance t (1 for none): the pass's own falloff (full
// occlusion to 0.75 R, none at R), as an ambient obscurance (Zhukov, Iones, Kronin 1998).
// Its sampling error is estimated from its two halves (alternate strata).
// Then, round by round (interleaved, the best kept): EDL (EdlOptions{}) and the AO pass in
// several settings (slices 1, 2, 4, 8 in one frame; 2 slices accumulated over 4 and 16 frames;
// half resolution; without the denoise), each timed for its last frame, its visibility
// (readVisibility()) compared to the reference: mean absolute error and 95th percentile over the
// pixels both cover. The same passes are timed on the Autzen LiDAR (points, lod-px 1, seen from
// above at 40 degrees; no reference). Prints CSV; writes OUT/ao.csv, OUT/ao.png (error against
// milliseconds, EDL's time marked), OUT/ao_pictures.png (the pass's shading, the reference, the
// error) and each picture on its own.
// Goal: the default settings cost at most 1.5x an EDL pass.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <embree3/rtcore.h>
#include <glm/gtc/matrix_transform.hpp>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/core/cli.h>
#include <tessera/core/parallel.h>
#include <tessera/core/stopwatch.h>
#include <tessera/lod/mesh.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/ao_pass.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/mesh_pass.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/view_renderer.h>

#include "bench_images.h"

namespace {

namespace fs = std::filesystem;
using namespace tessera;

/// The reference's falloff weight of a hit at distance t (ao_pass.h kAoFalloff).
double falloff(double t, double r) {
  return std::clamp((r - t) / (double(render::kAoFalloff) * r), 0.0, 1.0);
}

/// A frame's depth plane and image, copied once, restored into `target` before each pass.
struct SavedFrame {
  render::GlBuffer depth, image;
  SavedFrame(const render::FrameTarget& from)
      : depth(from.pixels() * 4, nullptr), image(from.pixels() * 4, nullptr) {
    glCopyNamedBufferSubData(from.depth().name(), depth.name(), 0, 0, GLsizeiptr(depth.bytes()));
    glCopyNamedBufferSubData(from.image().name(), image.name(), 0, 0, GLsizeiptr(image.bytes()));
  }
  void restore(render::FrameTarget& to) const {
    glCopyNamedBufferSubData(depth.name(), to.depth().name(), 0, 0, GLsizeiptr(depth.bytes()));
    glCopyNamedBufferSubData(image.name(), to.image().name(), 0, 0, GLsizeiptr(image.bytes()));
    glFinish();  // the copies are not the pass's time
  }
};

struct Setting {
  std::string name;
  render::AoOptions options;
  int frames = 1;
};

struct Errors {
  double mean = 0.0, p95 = 0.0;
};

Errors compare(const std::vector<float>& got, const std::vector<float>& want) {
  std::vector<float> e;
  for (size_t i = 0; i < got.size(); ++i)
    if (got[i] >= 0.0f && want[i] >= 0.0f) e.push_back(std::abs(got[i] - want[i]));
  if (e.empty()) return {};
  double sum = 0.0;
  for (float x : e) sum += x;
  std::sort(e.begin(), e.end());
  return {sum / double(e.size()), e[e.size() * 95 / 100]};
}

/// Visibility (0..1, < 0 empty) as grey, raster order to an image (top row first).
render::Image greyImage(const std::vector<float>& v, uint32_t w, uint32_t h, bool error) {
  render::Image img;
  img.width = w;
  img.height = h;
  img.rgba.assign(size_t(w) * h * 4, 255);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      uint8_t* px = &img.rgba[(size_t(h - 1 - y) * w + x) * 4];
      const float f = v[size_t(y) * w + x];
      if (f < 0.0f) {
        px[0] = px[1] = px[2] = 20;
      } else if (error) {  // 0 black, 0.25 and more red to yellow
        const float t = std::clamp(f / 0.25f, 0.0f, 1.0f);
        px[0] = uint8_t(255 * std::min(1.0f, 2 * t));
        px[1] = uint8_t(255 * std::max(0.0f, 2 * t - 1));
        px[2] = 0;
      } else {
        px[0] = px[1] = px[2] = uint8_t(std::clamp(f, 0.0f, 1.0f) * 220.0f + 0.5f);
      }
    }
  return img;
}

/// The reference visibility per pixel (raster order, -1 where the primary ray misses or the
/// depth is empty) and its estimated sampling error (mean over pixels of |half A - half B| / 2).
std::vector<float> traceReference(const lod::Mesh& mesh, const glm::dvec3& centre,
                                  const render::FrameTarget& target,
                                  const std::vector<uint32_t>& depth, const glm::dmat4& view,
                                  const glm::dmat4& projection, double radius, int rays,
                                  double* half_error) {
  RTCDevice device = rtcNewDevice(nullptr);
  RTCScene scene = rtcNewScene(device);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.positions.size()));
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const glm::vec3 p(mesh.positions[i] - centre);  // the frame the GPU draws in
    vb[3 * i] = p.x, vb[3 * i + 1] = p.y, vb[3 * i + 2] = p.z;
  }
  auto* ib = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), mesh.triangles.size()));
  for (size_t i = 0; i < mesh.triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) ib[3 * i + k] = mesh.triangles[i][k];
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene);

  const uint32_t w = target.width(), h = target.height();
  const glm::dmat4 world_from_clip = glm::inverse(projection * view);
  const glm::dvec3 eye = glm::dvec3(glm::inverse(view)[3]);
  const int side = std::max(1, int(std::lround(std::sqrt(double(rays)))));
  std::vector<float> out(size_t(w) * h, -1.0f);
  std::vector<double> row_half(h, 0.0);
  std::vector<size_t> row_count(h, 0);
  auto cast = [&](const glm::dvec3& org, const glm::dvec3& dir, float tfar, RTCRayHit& rh) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rh = RTCRayHit{};
    rh.ray.org_x = float(org.x), rh.ray.org_y = float(org.y), rh.ray.org_z = float(org.z);
    rh.ray.dir_x = float(dir.x), rh.ray.dir_y = float(dir.y), rh.ray.dir_z = float(dir.z);
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = tfar;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &ctx, &rh);
    return rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
  };
  parallelFor(h, threadCount(), [&](size_t y) {
    for (uint32_t x = 0; x < w; ++x) {
      if (depth[y * w + x] == render::kEmptyDepth) continue;
      const glm::dvec2 ndc(2.0 * (x + 0.5) / w - 1.0, 2.0 * (y + 0.5) / h - 1.0);
      const glm::dvec4 far = world_from_clip * glm::dvec4(ndc, 1.0, 1.0);
      const glm::dvec3 dir = glm::normalize(glm::dvec3(far) / far.w - eye);
      RTCRayHit rh;
      if (!cast(eye, dir, std::numeric_limits<float>::infinity(), rh)) continue;
      glm::dvec3 n = glm::normalize(glm::dvec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z));
      if (glm::dot(n, dir) > 0.0) n = -n;
      const glm::dvec3 point = eye + dir * double(rh.ray.tfar) + n * (radius * 1e-4);
      const glm::dvec3 t1 = glm::normalize(glm::cross(std::abs(n.x) < 0.9 ? glm::dvec3(1, 0, 0)
                                                                          : glm::dvec3(0, 1, 0), n));
      const glm::dvec3 t2 = glm::cross(n, t1);
      double occluded[2] = {0.0, 0.0};
      // A hash of the pixel places each stratum's sample.
      uint64_t state = (uint64_t(y) << 32 | x) * 0x9E3779B97F4A7C15ull + 1;
      auto next = [&] {
        state ^= state >> 33, state *= 0xff51afd7ed558ccdull, state ^= state >> 33;
        return double(state >> 11) / double(1ull << 53);
      };
      for (int j = 0; j < side; ++j)
        for (int i = 0; i < side; ++i) {
          const double u1 = (j + next()) / side, u2 = (i + next()) / side;
          const double r = std::sqrt(u1), phi = 2.0 * std::numbers::pi * u2;
          const glm::dvec3 d =
              t1 * (r * std::cos(phi)) + t2 * (r * std::sin(phi)) + n * std::sqrt(1.0 - u1);
          RTCRayHit sh;
          if (cast(point, d, float(radius), sh)) occluded[(i + j) % 2] += falloff(sh.ray.tfar, radius);
        }
      const double half = double(side * side) / 2.0;
      out[y * w + x] = float(1.0 - (occluded[0] + occluded[1]) / (2.0 * half));
      row_half[y] += std::abs(occluded[0] - occluded[1]) / half / 2.0;
      ++row_count[y];
    }
  });
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);
  double sum = 0.0;
  size_t count = 0;
  for (uint32_t y = 0; y < h; ++y) sum += row_half[y], count += row_count[y];
  *half_error = count ? sum / double(count) : 0.0;
  return out;
}

/// The bounding box of the covered pixels, grown by 8 and kept inside (image rows, top first).
glm::uvec4 coveredBox(const std::vector<uint32_t>& depth, uint32_t w, uint32_t h) {
  glm::ivec2 lo{int(w), int(h)}, hi{-1, -1};
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x)
      if (depth[size_t(y) * w + x] != render::kEmptyDepth) {
        const glm::ivec2 p(int(x), int(h - 1 - y));
        lo = glm::min(lo, p), hi = glm::max(hi, p);
      }
  lo = glm::max(lo - 8, glm::ivec2(0));
  hi = glm::min(hi + 8, glm::ivec2(int(w) - 1, int(h) - 1));
  return {uint32_t(lo.x), uint32_t(lo.y), uint32_t(hi.x - lo.x + 1), uint32_t(hi.y - lo.y + 1)};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ao: screen-space ambient occlusion against an Embree reference on the bunny mesh "
               "and beside eye-dome lighting (also on Autzen). Prints CSV; writes ao.csv, ao.png "
               "and the pictures into --out."};
  std::string out = std::string(TESSERA_BENCH_RESULTS_DIR) + "/ao";
  std::string size_text = "1920x1080";
  int repeats = 3, rays = 256;
  double radius = 0.01;
  bool lidar = true;
  app.add_option("--out", out, "Results folder (inputs built there once)")->capture_default_str();
  app.add_option("--size", size_text, "Frame size WxH (e.g. 480x270 for a quick run)")
      ->capture_default_str();
  app.add_option("--repeats", repeats, "Timed rounds (best kept)")
      ->check(CLI::Range(1, 50))
      ->capture_default_str();
  app.add_option("--rays", rays, "Reference rays per pixel (a square number)")
      ->check(CLI::Range(4, 65536))
      ->capture_default_str();
  app.add_option("--radius", radius, "AO radius, metres on the bunny")
      ->check(cli::finiteRange(1e-4, 0.1))
      ->capture_default_str();
  app.add_flag("!--no-lidar", lidar, "Skip the Autzen timing");
  CLI11_PARSE(app, argc, argv);
  uint32_t W = 0, H = 0;
  if (std::sscanf(size_text.c_str(), "%ux%u", &W, &H) != 2 || W < 16 || H < 16 || W > 8192 ||
      H > 8192) {
    std::cerr << "ao: --size: WxH with each side in [16, 8192] (got '" << size_text << "')\n";
    return 2;
  }
  render::timePasses(true);
  try {
    fs::create_directories(fs::path(out) / "inputs");
    const std::string data = TESSERA_DATA_DIR;
    auto ctx = render::GlContext::createHeadless();
    std::ofstream csv(fs::path(out) / "ao.csv");
    const std::string header = "scene,setting,slices,frames,half,denoise,ms,edl_ms,ratio,mae,p95";
    csv << header << "\n";
    std::cout << header << "\n";
    std::vector<render::Image> pictures;

    // ---- the bunny mesh: draw, reference, settings ----
    const lod::Mesh mesh = lod::readMesh(data + "/stanford-bunny/reconstruction/bun_zipper.ply");
    const auto [lo, hi] = mesh.bounds();
    const glm::dvec3 centre = 0.5 * (lo + hi);
    std::vector<render::GpuMeshVertex> verts(mesh.positions.size());
    std::vector<glm::dvec3> normals(mesh.positions.size(), glm::dvec3(0.0));
    std::vector<uint32_t> idx;
    for (const lod::Triangle& t : mesh.triangles) {
      const glm::dvec3 f = glm::cross(mesh.positions[t.y] - mesh.positions[t.x],
                                      mesh.positions[t.z] - mesh.positions[t.x]);
      for (int k = 0; k < 3; ++k) normals[t[k]] += f;
      idx.insert(idx.end(), {t.x, t.y, t.z});
    }
    for (size_t i = 0; i < verts.size(); ++i) {
      const glm::vec3 p(mesh.positions[i] - centre);
      const uint32_t n = render::packNormal1010102(glm::vec3(glm::normalize(normals[i])));
      verts[i] = {p, n, 0xFFC8C8C8u, p, n};
    }
    render::GlBuffer vb(verts.size() * sizeof(render::GpuMeshVertex), verts.data());
    render::GlBuffer ib(idx.size() * 4, idx.data());
    // From the front and a little right and above, the bunny filling the view's height.
    const glm::dvec3 eye = glm::normalize(glm::dvec3(0.35, 0.2, 1.0)) * 0.26;
    const glm::dmat4 view = glm::lookAt(eye, glm::dvec3(0.0, -0.005, 0.0), glm::dvec3(0, 1, 0));
    const glm::dmat4 projection = glm::perspective(glm::radians(40.0), double(W) / H, 0.02, 2.0);
    render::FrameTarget target(W, H);
    {
      render::MeshBatch b;
      b.vertices = vb.name();
      b.indices = ib.name();
      b.index_count = uint32_t(idx.size());
      b.clip_from_local = glm::mat4(projection * view);
      b.eye_local = glm::vec3(eye);
      target.clearGeometry(false);
      render::MeshPass().draw(target, {&b, 1}, render::MeshShading{});
      render::ResolvePass().run(target, glm::vec3(0.05f, 0.05f, 0.08f), 0);
    }
    const SavedFrame bunny(target);
    const std::vector<uint32_t> depth = target.readDepth();
    double half_error = 0.0;
    const auto t0 = std::chrono::steady_clock::now();
    const std::vector<float> reference =
        traceReference(mesh, centre, target, depth, view, projection, radius, rays, &half_error);
    const double trace_s = msSince(t0) / 1000.0;
    std::cerr << "ao: reference " << rays << " rays a pixel in " << trace_s
              << " s; its sampling error, estimated from its halves: " << half_error << "\n";

    auto setting = [&](std::string name, int slices, int frames, bool half, bool denoise) {
      Setting s;
      s.name = std::move(name);
      s.options.enabled = true;
      s.options.radius = float(radius);
      s.options.slices = slices;
      s.options.half_resolution = half;
      s.options.denoise = denoise;
      s.frames = frames;
      return s;
    };
    const std::vector<Setting> settings = {
        setting("1 slice", 1, 1, false, true),
        setting("2 slices", 2, 1, false, true),
        setting("4 slices", 4, 1, false, true),
        setting("8 slices", 8, 1, false, true),
        setting("2 slices 4 frames", 2, 4, false, true),
        setting("2 slices 16 frames", 2, 16, false, true),
        setting("2 slices no denoise", 2, 1, false, false),
        setting("half res 2 slices", 2, 1, true, true),
        setting("half res 2 slices 16 frames", 2, 16, true, true),
        setting("half res 4 slices", 4, 1, true, true),
    };
    render::EdlPass edl;
    render::AoPass ao;
    double edl_best = 1e300;
    std::vector<double> best(settings.size(), 1e300);
    std::vector<Errors> errors(settings.size());
    // Each program's first dispatch compiles it (llvmpipe): once, untimed.
    for (const Setting& s : settings) {
      bunny.restore(target);
      ao.run(target, s.options, projection, 0);
    }
    bunny.restore(target);
    edl.run(target, render::EdlOptions{}, projection);
    for (int round = 0; round < repeats; ++round) {
      bunny.restore(target);
      edl_best = std::min(edl_best, edl.run(target, render::EdlOptions{}, projection));
      if (round == 0) {
        const render::Image img = target.readImage();
        render::writePng((fs::path(out) / "ao-bunny-edl.png").string(), img);
      }
      for (size_t k = 0; k < settings.size(); ++k) {
        const Setting& s = settings[k];
        double ms = 0.0;
        for (int f = 0; f < s.frames; ++f) {
          bunny.restore(target);
          ms = ao.run(target, s.options, projection, uint32_t(f));
        }
        best[k] = std::min(best[k], ms);
        if (round > 0) continue;
        const std::vector<float> v = ao.readVisibility();
        errors[k] = compare(v, reference);
        if (k == 7) {  // half res, 2 slices: the pictures
          const glm::uvec4 box = coveredBox(depth, W, H);
          const render::Image shaded = target.readImage();
          render::writePng((fs::path(out) / "ao-bunny.png").string(), shaded);
          std::vector<float> err(v.size(), -1.0f);
          for (size_t i = 0; i < v.size(); ++i)
            if (v[i] >= 0.0f && reference[i] >= 0.0f) err[i] = std::abs(v[i] - reference[i]);
          const render::Image pass_grey = greyImage(v, W, H, false);
          const render::Image ref_grey = greyImage(reference, W, H, false);
          const render::Image err_img = greyImage(err, W, H, true);
          render::writePng((fs::path(out) / "ao-bunny-visibility.png").string(), pass_grey);
          render::writePng((fs::path(out) / "ao-bunny-reference.png").string(), ref_grey);
          render::writePng((fs::path(out) / "ao-bunny-error.png").string(), err_img);
          for (const render::Image* img : {&shaded, &pass_grey, &ref_grey, &err_img})
            pictures.push_back(bench::crop(*img, box.x, box.y, box.z, box.w, 1));
        }
      }
    }
    auto row = [&](const std::string& scene, const Setting* s, double ms, double edl_ms,
                   const Errors* e) {
      char line[384];
      if (s)
        std::snprintf(line, sizeof line, "%s,%s,%d,%d,%d,%d,%.1f,%.1f,%.2f,%s,%s", scene.c_str(),
                      s->name.c_str(), s->options.slices, s->frames, int(s->options.half_resolution),
                      int(s->options.denoise), ms, edl_ms, ms / edl_ms,
                      e ? std::to_string(e->mean).substr(0, 6).c_str() : "",
                      e ? std::to_string(e->p95).substr(0, 6).c_str() : "");
      else
        std::snprintf(line, sizeof line, "%s,edl,,,,,%.1f,%.1f,1.00,,", scene.c_str(), ms, edl_ms);
      csv << line << "\n";
      std::cout << line << std::endl;
    };
    row("bunny", nullptr, edl_best, edl_best, nullptr);
    for (size_t k = 0; k < settings.size(); ++k)
      row("bunny", &settings[k], best[k], edl_best, &errors[k]);

    // ---- Autzen: the same passes' time on LiDAR points ----
    if (lidar) {
      const fs::path store_path = fs::path(out) / "inputs" / "autzen.tlod";
      if (!fs::exists(store_path)) {
        lod::BuildOptions b;
        b.quiet = true;
        lod::buildStore({data + "/lidar/autzen_trim.las"}, store_path, b);
      }
      auto store = lod::PointStore::open(store_path);
      render::ModelInstance inst{store.get(), render::storeModel(*store)};
      const lod::StoreSummary& sum = store->summary();
      const glm::dvec3 c = 0.5 * (sum.bbox_min + sum.bbox_max);
      const double r = 0.5 * glm::length(sum.bbox_max - sum.bbox_min);
      const double fovy = glm::radians(40.0), distance = r / std::sin(fovy / 2) * 0.8;
      const glm::dvec3 e = c + glm::normalize(glm::dvec3(0.0, -0.8, 0.75)) * distance;
      render::ViewSetup v;
      v.view = glm::lookAt(e + sum.origin, c + sum.origin, glm::dvec3(0, 0, 1));
      v.projection = glm::perspective(fovy, double(W) / H, distance * 0.05, distance * 4);
      v.width = W;
      v.height = H;
      v.eye_world = e + sum.origin;
      render::ViewRenderer renderer(W, H);
      renderer.renderSettled({&inst, 1}, v, render::RenderOptions{});
      render::FrameTarget lidar_target(W, H);
      glCopyNamedBufferSubData(renderer.target().depth().name(), lidar_target.depth().name(), 0,
                               0, GLsizeiptr(lidar_target.pixels() * 4));
      glCopyNamedBufferSubData(renderer.target().image().name(), lidar_target.image().name(), 0,
                               0, GLsizeiptr(lidar_target.pixels() * 4));
      const SavedFrame autzen(lidar_target);
      // Autzen is in feet: a radius of 3 ft.
      std::vector<Setting> lidar_settings = {settings[1], settings[7]};
      for (Setting& s : lidar_settings) s.options.radius = 3.0f;
      double lidar_edl = 1e300;
      std::vector<double> lidar_best(lidar_settings.size(), 1e300);
      for (int round = 0; round < repeats; ++round) {
        autzen.restore(lidar_target);
        lidar_edl = std::min(lidar_edl, edl.run(lidar_target, render::EdlOptions{}, v.projection));
        for (size_t k = 0; k < lidar_settings.size(); ++k) {
          autzen.restore(lidar_target);
          lidar_best[k] = std::min(
              lidar_best[k], ao.run(lidar_target, lidar_settings[k].options, v.projection, 0));
          if (round == 0 && k == 1) {
            const render::Image img = lidar_target.readImage();
            render::writePng((fs::path(out) / "ao-autzen.png").string(), img);
          }
        }
      }
      row("autzen", nullptr, lidar_edl, lidar_edl, nullptr);
      for (size_t k = 0; k < lidar_settings.size(); ++k)
        row("autzen", &lidar_settings[k], lidar_best[k], lidar_edl, nullptr);
    }
    csv.close();
    if (!pictures.empty())
      render::writePng((fs::path(out) / "ao_pictures.png").string(), bench::grid(pictures, 2));

    const fs::path gp = fs::path(out) / "ao.gp";
    const std::string csv_path = (fs::path(out) / "ao.csv").string();
    std::ofstream g(gp);
    g << "set terminal pngcairo size 1000,560 font 'sans,10' noenhanced\n"
      << "set output '" << (fs::path(out) / "ao.png").string() << "'\n"
      << "set datafile separator ','\nset grid\nset key top right\n"
      << "set yrange [0:0.1]\n"
      << "set xlabel 'ms per frame at " << W << "x" << H << " (llvmpipe, 2 cores)'\n"
      << "set ylabel 'visibility error against the Embree reference'\n"
      << "set xrange [0:*]\n"
      << "set title 'Screen-space AO on the bunny mesh: error against cost (EDL: "
      << std::to_string(edl_best).substr(0, 5) << " ms, dashed: 1.5x EDL)'\n"
      << "set arrow from " << 1.5 * edl_best << ", graph 0 to " << 1.5 * edl_best
      << ", graph 1 nohead dt 2 lc rgb '#888888'\n"
      << "set arrow from " << edl_best << ", graph 0 to " << edl_best
      << ", graph 1 nohead lc rgb '#888888'\n"
      << "plot '< grep ^bunny, " << csv_path << " | grep -v ,edl,' using 7:10 title 'mean abs' "
      << "with points pt 7 ps 1.2 lc rgb '#1f77b4', "
      << "'' using 7:11 title '95th percentile' with points pt 5 ps 1.2 lc rgb '#ff7f0e', "
      << "'' using 7:11:2 with labels rotate by 40 offset 0.6,0.6 left font 'sans,8' notitle\n";
    g.close();
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + gp.string() + "'").c_str()) != 0)
      std::cerr << "ao: gnuplot failed; the CSV is there\n";
    std::cerr << "ao: reproduce with: build/dev/bench/ao --size " << W << "x" << H << " --rays "
              << rays << " --radius " << radius << "\n";
  } catch (const std::exception& e) {
    std::cerr << "ao: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
