// mesh_lod: the mesh patch hierarchy, build and drawing, in one process.
//
// Build, against the patch-LOD thesis' timings (../shared/papers/patch-lod-annotation-thesis.txt,
// Table 6.3.1: the bunny, 69,451 triangles, in 13.1 s; its largest, Kawara, 5.59 M, in 1595 s):
//   the bunny reconstruction, and a mesh of --large-levels midpoint subdivisions of it (each
//   level 4x the triangles; new vertices displaced along the normal by a hashed 2% of the edge
//   so the surface keeps detail to simplify: 4 levels make 17.8 M triangles); seconds, triangles
//   per second, bytes per triangle on disk, peak memory (VmHWM). The large mesh is built from
//   memory (the builder alone), from a binary PLY of it written to --out first (the whole
//   `tessera-lod build`, reading the file included), and from the PLY in blocks within
//   --blocks-mb (the build for meshes beyond the memory budget; --copies N puts N copies side by
//   side in the PLY, for 10^8 triangles and more).
// Drawing, on the large mesh, one view at --size and each tile of --wall:
//   frame time and PSNR against the full-resolution cut, across pixel thresholds (0 = every
//   leaf); and the mesh pass's triangles per second against a bare glDrawElements of the same
//   leaf patches in the same context (MeshPass::drawBare: GL's depth test, a constant colour).
// Prints CSV; writes OUT/mesh_lod_build.csv, OUT/mesh_lod_frames.csv, OUT/mesh_lod_wall.csv and
// OUT/mesh_lod.png.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <unordered_map>
#include <vector>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/cli.h>
#include <tessera/lod/mesh.h>
#include <tessera/lod/mesh_builder.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/mesh_pass.h>
#include <tessera/render/tile_frustum.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/config.h>

#include "../lod/src/huge_pages.h"
#include "bench_images.h"

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// Peak resident memory of this process since the last reset, bytes (Linux VmHWM).
uint64_t peakBytes() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
  return 0;
}
void resetPeak() {
  std::ofstream("/proc/self/clear_refs") << "5";
}

/// `m` as a binary little-endian PLY (float positions, uchar-int face lists), as scan archives
/// hold meshes; positions relative to the mesh's origin. `copies` > 1 writes that many copies
/// side by side along x (1.1 box widths apart), one mesh of copies x the triangles.
void writeMeshPly(const fs::path& path, const lod::Mesh& m, int copies = 1) {
  std::ofstream out(path, std::ios::binary);
  const auto [lo, hi] = m.bounds();
  const double gap = 1.1 * (hi.x - lo.x);
  out << "ply\nformat binary_little_endian 1.0\ncomment written by bench/mesh_lod\n"
      << "element vertex " << m.positions.size() * size_t(copies)
      << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "element face " << m.triangles.size() * size_t(copies)
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  std::vector<char> buf;
  buf.reserve(1 << 20);
  auto flush = [&] {
    out.write(buf.data(), std::streamsize(buf.size()));
    buf.clear();
  };
  for (int c = 0; c < copies; ++c)
    for (const glm::dvec3& v : m.positions) {
      const float f[3] = {float(v.x + c * gap), float(v.y), float(v.z)};
      buf.insert(buf.end(), reinterpret_cast<const char*>(f),
                 reinterpret_cast<const char*>(f) + 12);
      if (buf.size() > (1 << 20) - 16) flush();
    }
  for (int c = 0; c < copies; ++c)
    for (const lod::Triangle& t : m.triangles) {
      buf.push_back(3);
      const int32_t base = int32_t(size_t(c) * m.positions.size());
      const int32_t i[3] = {base + int32_t(t.x), base + int32_t(t.y), base + int32_t(t.z)};
      buf.insert(buf.end(), reinterpret_cast<const char*>(i),
                 reinterpret_cast<const char*>(i) + 12);
      if (buf.size() > (1 << 20) - 16) flush();
    }
  flush();
  if (!out) throw std::runtime_error("bench/mesh_lod: cannot write " + path.string());
}

/// One midpoint subdivision: every triangle into four, shared edges sharing their midpoint, which
/// moves along the vertex normals' mean by a hashed +-2% of the edge length.
lod::Mesh subdivide(const lod::Mesh& in) {
  lod::Mesh out;
  out.origin = in.origin;
  out.positions = in.positions;
  std::vector<glm::dvec3> normals(in.positions.size(), glm::dvec3(0.0));
  for (const lod::Triangle& t : in.triangles) {
    const glm::dvec3 f =
        glm::cross(in.positions[t.y] - in.positions[t.x], in.positions[t.z] - in.positions[t.x]);
    for (int k = 0; k < 3; ++k) normals[t[k]] += f;
  }
  std::unordered_map<uint64_t, uint32_t> mid;
  mid.reserve(in.triangles.size() * 2);
  auto midpoint = [&](uint32_t a, uint32_t b) {
    const uint64_t key = uint64_t(std::min(a, b)) << 32 | std::max(a, b);
    auto [it, added] = mid.try_emplace(key, uint32_t(out.positions.size()));
    if (added) {
      const glm::dvec3 pa = in.positions[a], pb = in.positions[b];
      glm::dvec3 n = normals[a] + normals[b];
      const double len = glm::length(n);
      n = len > 0 ? n / len : glm::dvec3(0.0);
      uint64_t h = key * 0x9E3779B97F4A7C15ull;
      h ^= h >> 29;
      const double u = double(h % 2001) / 1000.0 - 1.0;  // [-1, 1]
      out.positions.push_back(0.5 * (pa + pb) + n * (0.02 * u * glm::length(pb - pa)));
    }
    return it->second;
  };
  out.triangles.reserve(in.triangles.size() * 4);
  for (const lod::Triangle& t : in.triangles) {
    const uint32_t ab = midpoint(t.x, t.y), bc = midpoint(t.y, t.z), ca = midpoint(t.z, t.x);
    out.triangles.push_back({t.x, ab, ca});
    out.triangles.push_back({ab, t.y, bc});
    out.triangles.push_back({ca, bc, t.z});
    out.triangles.push_back({ab, bc, ca});
  }
  return out;
}

struct BuildRow {
  std::string mesh;
  uint64_t triangles;
  double seconds, tri_per_s, bytes_per_tri, peak_mb;
  double thesis_rate;  ///< the thesis' build rate for its comparable model, triangles/s
};

/// The thesis' Table 6.3.1: the bunny (69,451 triangles) in 13.1 s; its largest model, Kawara
/// (5,593,696 triangles), in 1595 s: the comparison for the large mesh.
constexpr double kThesisBunnyRate = 69451.0 / 13.1;
constexpr double kThesisLargeRate = 5593696.0 / 1595.0;

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  return cli::runMain("mesh_lod", [&]() -> int {
    CLI::App app{"mesh_lod: the mesh patch hierarchy's build and drawing"};
    std::string out = TESSERA_BENCH_RESULTS_DIR;
    int levels = 4;
    std::string size = "1920x1080";
    int repeats = 3;
    bool build_only = false, pass_only = false, keep_ply = false;
    int copies = 1;
    std::string wall_path = TESSERA_CONFIG_DIR "/walls/2x2.json";
    uint64_t blocks_mb = 2048;
    app.add_option("--out", out, "Folder for the CSV, the chart and the inputs")
        ->capture_default_str();
    app.add_option("--large-levels", levels, "Subdivisions of the bunny for the large mesh")
        ->check(cli::integerRange(1, 5))
        ->capture_default_str();
    app.add_option("--size", size, "View size WxH")->capture_default_str();
    app.add_option("--wall", wall_path, "Wall for the per-tile frames")->capture_default_str();
    app.add_option("--repeats", repeats, "Frames per measurement (the best counts)")
        ->check(cli::integerRange(1, 100))
        ->capture_default_str();
    app.add_option("--copies", copies,
                   "Copies of the large mesh side by side in its PLY (more than 1: the PLY is "
                   "built in blocks only)")
        ->check(cli::integerRange(1, 8))
        ->capture_default_str();
    app.add_option("--blocks-mb", blocks_mb,
                   "--memory-mb of the build in blocks from the PLY (0: no such build)")
        ->capture_default_str();
    app.add_flag("--keep-ply", keep_ply, "Keep the large mesh's PLY in --out");
    app.add_flag("--build-only", build_only, "Measure the builds only (no drawing, no chart)");
    app.add_flag("--pass-only", pass_only,
                 "Only the mesh pass against bare glDrawElements, on the large store an earlier "
                 "run left in --out");
    if (const auto code = cli::parse(app, argc, argv, "mesh_lod")) return *code;
    const cli::Size view_size = cli::parseSize(size, "--size", 8192);
    if (copies > 1 && !build_only)
      throw cli::UsageError("--copies: with --build-only only (the drawing is of one copy)");
    fs::create_directories(out);
    const std::string bunny_path =
        std::string(TESSERA_DATA_DIR) + "/stanford-bunny/reconstruction/bun_zipper.ply";

    const fs::path large_store = fs::path(out) / "mesh_lod_large.tmesh";
    if (pass_only && !fs::exists(large_store))
      throw cli::UsageError("--pass-only: no " + large_store.string() + " (run once without it)");
    // Build.
    std::vector<BuildRow> rows;
    lod::MeshBuildOptions bo;
    bo.quiet = true;
    if (!pass_only) {
      const lod::Mesh bunny = lod::readMesh(bunny_path);
      auto build = [&](const std::string& name, const lod::Mesh* m, const fs::path& input,
                       const fs::path& file, double thesis_rate, uint64_t memory_mb = 0) {
        resetPeak();
        const auto t0 = Clock::now();
        lod::MeshBuildOptions o = bo;
        if (memory_mb > 0) o.memory_mb = memory_mb;
        const lod::MeshBuildReport r =
            m ? lod::buildMeshStore(*m, file, o) : lod::buildMeshStore({input}, file, o);
        const double s = since(t0);
        rows.push_back({name, r.triangles, s, double(r.triangles) / s,
                        double(r.file_bytes) / double(r.triangles), double(peakBytes()) / 1e6,
                        thesis_rate});
        std::fprintf(stderr,
                     "mesh_lod: built %s: %llu triangles in %.2f s (read %.2f, partition %.2f, "
                     "simplify %.2f, write %.2f), %.2f B/triangle, %llu blocks, peak %.0f MB, "
                     "root error %.3g\n",
                     name.c_str(), (unsigned long long)r.triangles, s, r.seconds_read,
                     r.seconds_partition, r.seconds_simplify, r.seconds_write,
                     rows.back().bytes_per_tri, (unsigned long long)r.blocks,
                     rows.back().peak_mb, r.root_error);
      };
      build("bunny", &bunny, {}, fs::path(out) / "mesh_lod_bunny.tmesh", kThesisBunnyRate);
      lod::Mesh large = bunny;
      {
        const auto t0 = Clock::now();
        for (int i = 0; i < levels; ++i) large = subdivide(large);
        // In arrays as lod::readMesh() leaves them (sized once, advised for huge pages), so the
        // build reads what it would read from a file.
        {
          lod::Mesh read_like;
          read_like.origin = large.origin;
          tessera::lod::detail::reserveHuge(read_like.positions, large.positions.size());
          tessera::lod::detail::reserveHuge(read_like.triangles, large.triangles.size());
          read_like.positions = large.positions;
          read_like.triangles = large.triangles;
          large = std::move(read_like);
        }
        std::fprintf(stderr, "mesh_lod: subdivided the bunny %d times: %zu triangles (%.1f s)\n",
                     levels, large.triangles.size(), since(t0));
      }
      const std::string large_name = "bunny x4^" + std::to_string(levels);
      if (copies == 1)
        build(large_name, &large, {}, large_store, kThesisLargeRate);
      // The whole `tessera-lod build` of the same mesh from a PLY file, reading included.
      const fs::path large_ply = fs::path(out) / "mesh_lod_large.ply";
      writeMeshPly(large_ply, large, copies);
      large = lod::Mesh{};  // free it before drawing
      if (copies == 1)
        build("x4^" + std::to_string(levels) + " from PLY", nullptr, large_ply, large_store,
              kThesisLargeRate);
      // The same in blocks, within --blocks-mb (mesh_builder_blocks.cpp).
      if (blocks_mb > 0) {
        const std::string name = (copies > 1 ? std::to_string(copies) + "x " : std::string()) +
                                 "x4^" + std::to_string(levels) + " PLY in blocks";
        build(name, nullptr, large_ply,
              copies == 1 ? fs::path(out) / "mesh_lod_blocks.tmesh" : large_store,
              kThesisLargeRate, blocks_mb);
      }
      if (!keep_ply) fs::remove(large_ply);

      std::ofstream bcsv(fs::path(out) / "mesh_lod_build.csv");
      const char* bhead =
          "mesh,triangles,seconds,triangles_per_s,bytes_per_triangle,peak_mb,thesis_triangles_per_"
          "s,"
          "speedup_per_triangle\n";
      bcsv << bhead;
      std::printf("%s", bhead);
      for (const BuildRow& r : rows) {
        char line[512];
        std::snprintf(line, sizeof line, "%s,%llu,%.3f,%.0f,%.3f,%.0f,%.0f,%.1f\n", r.mesh.c_str(),
                      (unsigned long long)r.triangles, r.seconds, r.tri_per_s, r.bytes_per_tri,
                      r.peak_mb, r.thesis_rate, r.tri_per_s / r.thesis_rate);
        bcsv << line;
        std::printf("%s", line);
      }
      bcsv.close();
      if (build_only) return 0;
    }

    // Drawing.
    auto context = render::GlContext::createHeadless();
    auto store = lod::MeshStore::open(large_store);
    render::ModelInstance m;
    m.mesh = store.get();
    m.model = render::storeModel(*store);
    const auto [lo, hi] = render::worldBounds(m);
    const glm::dvec3 c = 0.5 * (lo + hi);
    const double r = 0.5 * glm::length(hi - lo);
    render::ViewSetup v;
    v.eye_world = c + glm::dvec3(0.3 * r, 0.2 * r, 2.2 * r);
    v.view = glm::lookAt(v.eye_world, c, glm::dvec3(0, 1, 0));
    v.projection = glm::perspective(glm::radians(40.0), double(view_size.width) / view_size.height,
                                    0.1 * r, 10.0 * r);
    v.width = view_size.width;
    v.height = view_size.height;
    render::StreamerOptions so;
    so.budget_bytes = 4ull << 30;
    render::ViewRenderer renderer(v.width, v.height, nullptr, so);
    render::RenderOptions o;
    // Every level the pixels ask for: the method measured alone, without the pixel budget.
    o.budget_per_covered_pixel = 0.0;
    // A settled frame at threshold px, then the best of `repeats` frames of it (no readback).
    auto frameOf = [&](render::ViewRenderer& vr, const render::ViewSetup& view, double px,
                       render::RenderStats& st) {
      o.lod_pixels = px;
      render::Image img = vr.renderSettled({&m, 1}, view, o, &st);
      double best = 1e300;
      for (int i = 0; i < repeats; ++i) {
        img = vr.render({&m, 1}, view, o, &st);
        best = std::min(best, st.totalMs() - st.readback_ms);
      }
      st.frames = 0;
      return std::make_pair(img, best);
    };
    auto frame = [&](double px, render::RenderStats& st) { return frameOf(renderer, v, px, st); };
    render::RenderStats full_st;
    double full_ms = 0.0;
    if (!pass_only) {
      render::Image full;
      std::tie(full, full_ms) = frame(1e-9, full_st);
      render::writePng((fs::path(out) / "mesh_lod_full.png").string(), full);
      std::ofstream fcsv(fs::path(out) / "mesh_lod_frames.csv");
      const char* fhead = "threshold_px,triangles,patches,frame_ms,mesh_ms,psnr_db\n";
      fcsv << fhead;
      std::printf("%s", fhead);
      for (double px : {0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0}) {
        render::RenderStats st;
        const auto [img, ms] = px == 0.0 ? std::make_pair(full, full_ms) : frame(px, st);
        if (px == 0.0) st = full_st;
        if (px == 1.0) render::writePng((fs::path(out) / "mesh_lod_1px.png").string(), img);
        char line[256];
        std::snprintf(line, sizeof line, "%g,%llu,%zu,%.1f,%.1f,%.2f\n", px,
                      (unsigned long long)st.triangles, st.mesh_patches, ms, st.mesh_ms,
                      bench::psnr(img, full));
        fcsv << line;
        std::printf("%s", line);
      }
      fcsv.close();

      // The same per tile of the 2x2 wall, each tile with its own renderer and streamer as its
      // node has, the camera of the view above.
      const config::WallConfig wall = sync::loadWallConfig(wall_path);
      config::Camera cam;
      cam.mutable_eye()->set_x(v.eye_world.x);
      cam.mutable_eye()->set_y(v.eye_world.y);
      cam.mutable_eye()->set_z(v.eye_world.z);
      cam.mutable_target()->set_x(c.x);
      cam.mutable_target()->set_y(c.y);
      cam.mutable_target()->set_z(c.z);
      cam.mutable_up()->set_y(1.0);
      std::ofstream wcsv(fs::path(out) / "mesh_lod_wall.csv");
      const char* whead = "tile,threshold_px,triangles,patches,frame_ms,psnr_db\n";
      wcsv << whead;
      std::printf("%s", whead);
      for (const auto& tile : wall.tiles()) {
        const render::ViewSetup tv = render::tileView(wall, tile, cam);
        render::ViewRenderer tr(tv.width, tv.height, nullptr, so);
        render::RenderStats tile_full_st;
        const auto [tile_full, tile_full_ms] = frameOf(tr, tv, 1e-9, tile_full_st);
        for (double px : {0.0, 0.5, 1.0, 2.0, 4.0}) {
          render::RenderStats st = tile_full_st;
          render::Image img = tile_full;
          double ms = tile_full_ms;
          if (px > 0.0) std::tie(img, ms) = frameOf(tr, tv, px, st);
          char line[256];
          std::snprintf(line, sizeof line, "%s,%g,%llu,%zu,%.1f,%.2f\n", tile.name().c_str(), px,
                        (unsigned long long)st.triangles, st.mesh_patches, ms,
                        bench::psnr(img, tile_full));
          wcsv << line;
          std::printf("%s", line);
        }
      }
      wcsv.close();
    }

    // The pass against a bare glDrawElements: every leaf patch, one context, interleaved.
    std::vector<render::GlBuffer> buffers;
    std::vector<render::MeshBatch> batches;
    uint64_t triangles = 0;
    for (lod::NodeId id = 0; id < store->nodeCount(); ++id) {
      if (store->record(id).child_count) continue;
      const lod::MeshPatch p = store->readPatch(id);
      std::vector<render::GpuMeshVertex> verts(p.positions.size());
      for (size_t i = 0; i < verts.size(); ++i) {
        const uint32_t n = render::packNormal1010102(p.normals[i]);
        verts[i] = {p.positions[i], n, 0xFFC8C8C8u, p.positions[i], n};
      }
      buffers.emplace_back(verts.size() * sizeof(render::GpuMeshVertex), verts.data());
      buffers.emplace_back(p.indices.size() * 4, p.indices.data());
      render::MeshBatch b;
      b.vertices = buffers[buffers.size() - 2].name();
      b.indices = buffers.back().name();
      b.index_count = uint32_t(p.indices.size());
      const glm::dmat4 wl = m.model * glm::translate(glm::dmat4(1.0), p.offset);
      b.clip_from_local = glm::mat4(v.projection * v.view * wl);
      b.eye_local = glm::vec3(glm::inverse(wl) * glm::dvec4(v.eye_world, 1.0));
      batches.push_back(b);
      triangles += p.triangles();
    }
    render::FrameTarget target(v.width, v.height);
    render::MeshPass pass;
    double bare = 1e300, full_pass = 1e300;
    for (int i = 0; i < repeats; ++i) {
      bare = std::min(bare, pass.drawBare(target, batches));
      target.clearGeometry(false);
      full_pass = std::min(full_pass, pass.draw(target, batches, render::MeshShading{}));
    }
    std::ofstream pcsv(fs::path(out) / "mesh_lod_pass.csv");
    const char* phead = "triangles,bare_ms,pass_ms,bare_mtri_s,pass_mtri_s,ratio\n";
    char line[256];
    std::snprintf(line, sizeof line, "%llu,%.1f,%.1f,%.1f,%.1f,%.3f\n",
                  (unsigned long long)triangles, bare, full_pass, triangles / bare / 1e3,
                  triangles / full_pass / 1e3, bare / full_pass);
    pcsv << phead << line;
    std::printf("%s%s", phead, line);
    pcsv.close();
    if (pass_only) return 0;

    const fs::path gp = fs::path(out) / "mesh_lod.gp";
    std::ofstream g(gp);
    g << "set terminal pngcairo size 1650,420 font 'DejaVu Sans,10'\n"
      << "set output '" << (fs::path(out) / "mesh_lod.png").string() << "'\n"
      << "set datafile separator ','\nset key autotitle columnhead\nset grid\n"
      << "set multiplot layout 1,3 title 'Mesh LOD (" << size << ", " << full_st.triangles
      << " triangles at full resolution)'\n"
      << "set title 'Frame time against accuracy (full resolution: " << int(full_ms)
      << " ms)'\nset xlabel 'frame (ms, log scale)'\nset logscale x\n"
      << "set ylabel 'PSNR to the full-resolution cut (dB)'\nset yrange [30:45]\n"
      << "plot '" << (fs::path(out) / "mesh_lod_frames.csv").string()
      << "' using ($1 > 0 ? $4 : 1/0):6:(($1 == 2 || $1 == 8) ? '' : sprintf('%g px', $1)) "
         "with labels offset 0,0.9 notitle, '' using ($1 > 0 ? $4 : 1/0):6 with linespoints pt 7 "
         "title 'cut by pixel threshold'\n"
      << "set title 'Per tile of the 2x2 wall (960x540 each)'\n"
      << "plot for [t in 'tile-0-0 tile-1-0 tile-0-1 tile-1-1'] '"
      << (fs::path(out) / "mesh_lod_wall.csv").string()
      << "' using ($2 > 0 && strcol(1) eq t ? $5 : 1/0):6 with linespoints pt 7 title t\n"
      << "unset logscale x\nset yrange [*:*]\n"
      << "set title 'Build throughput'\nset xlabel ''\nset ylabel 'triangles per second'\n"
      << "set style data histograms\nset style fill solid 0.7\nset logscale y\n"
      << "set yrange [1000:1e7]\nset key below\nset xtics font ',8'\n"
      << "set arrow from graph 0, first 1e6 to graph 1, first 1e6 nohead dt 2 lc rgb 'red'\n"
      << "set label 'goal at 10^7 triangles: 10^6/s' at graph 0.55, first 1.4e6 tc rgb 'red'\n"
      << "plot '" << (fs::path(out) / "mesh_lod_build.csv").string()
      << "' using 4:xtic(1) title 'Tessera (2 cores)', '' using 7 title 'thesis (bunny 13.1 s; "
         "Kawara 5.6 M, 1595 s)'\n"
      << "unset multiplot\n";
    g.close();
    const std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp.string() + "'";
    if (std::system(cmd.c_str()) != 0)
      std::fprintf(stderr, "mesh_lod: gnuplot failed; the CSVs are complete\n");
    return 0;
  });
}
