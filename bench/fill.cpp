// fill: what closing surfaces costs, discs against the pull-push fill (Marroquim,
// Kraus, Cavalcanti 2007; FillPass), in one process on one context, at 1920x1080, on
//   cube    10^7 points uniformly random in the unit cube (tests/support/random_cube.h), the
//           camera of bench/paraview_peer, one grey (the depth pass alone);
//   bunny   the virtual bunny scan (bench_inputs.h; --points, or --store), eye-dome lighting;
//   autzen  the Autzen LiDAR (RGB, scan lines), seen whole from the south and above.
// For each input and splat scale (--scales, default 0.5 1 2 4) three ways of drawing the same
// cut (the LOD cut and coverage stop depend on the splat scale, not on the fill):
//   none      1 px points, nothing filled (SurfaceFill::kNone): the cost baseline;
//   discs     each point a disc (today's SurfaceFill::kDiscs);
//   pullpush  1 px points with their splat footprints, then FillPass (SurfaceFill::kPullPush).
// Per variant: points drawn; frame ms (wall clock of ViewRenderer::render(), cut selection to
// readback, best of --frames frames in each of --rounds rounds interleaved over the variants);
// the passes' ms; against the full render (every leaf, discs at scale 2, today's picture): the
// share of its inside pixels (covered with all 5x5 neighbours) left open, and the silhouette
// IoU; and PSNR against the discs at the same scale.
// Prints CSV; writes OUT/fill.csv, OUT/fill.png (gnuplot: frame time over the baseline, and
// open pixels, against the splat scale), OUT/fill_crops.png (1 px points | discs | pull-push at
// scale 2, crops enlarged 3x) and each variant's picture at scale 2.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/stopwatch.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/view_renderer.h>

#include "../tests/support/random_cube.h"
#include "bench_images.h"
#include "bench_inputs.h"
#include "bench_views.h"

namespace {

using namespace tessera;
namespace fs = std::filesystem;

struct Input {
  std::string name;
  fs::path store;
  render::ViewSetup view;
  /// Shading; splat scale and fill set per variant. No pixel budget: every level the pixels
  /// ask for, the fill measured alone.
  render::RenderOptions options = [] {
    render::RenderOptions o;
    o.budget_per_covered_pixel = 0.0;
    return o;
  }();
  std::vector<uint32_t> crop;     ///< top-left of the 160x100 crop
};

/// Autzen seen whole from the south and above (tessera-render's fitted camera for flat data).
render::ViewSetup flatView(const lod::PointStore& s, uint32_t w, uint32_t h) {
  const auto& sum = s.summary();
  const glm::dvec3 lo = sum.origin + sum.bbox_min, hi = sum.origin + sum.bbox_max;
  const glm::dvec3 c = 0.5 * (lo + hi);
  const double r = 0.5 * glm::length(hi - lo);
  render::ViewSetup v;
  v.eye_world = c + glm::dvec3(0, -1.6 * r, 1.2 * r);
  v.view = glm::lookAt(v.eye_world, c, glm::dvec3(0, 0, 1));
  v.projection = glm::perspective(glm::radians(45.0), double(w) / h, 0.01 * r, 10.0 * r);
  v.width = w;
  v.height = h;
  return v;
}

bool covered(const render::Image& img, size_t i) {
  return img.rgba[i * 4] != 0 || img.rgba[i * 4 + 1] != 0 || img.rgba[i * 4 + 2] != 0;
}

/// Pixels of `ref` covered together with their 5x5 neighbourhood.
std::vector<bool> insideOf(const render::Image& ref) {
  std::vector<bool> in(size_t(ref.width) * ref.height, false);
  for (uint32_t y = 2; y + 2 < ref.height; ++y)
    for (uint32_t x = 2; x + 2 < ref.width; ++x) {
      bool all = true;
      for (int dy = -2; dy <= 2 && all; ++dy)
        for (int dx = -2; dx <= 2 && all; ++dx)
          all = covered(ref, size_t(int(y) + dy) * ref.width + size_t(int(x) + dx));
      in[size_t(y) * ref.width + x] = all;
    }
  return in;
}

struct Accuracy {
  double open = 0, iou = 1;
};

Accuracy accuracy(const render::Image& img, const render::Image& ref,
                  const std::vector<bool>& inside) {
  size_t n = 0, open = 0, both = 0, either = 0;
  for (size_t i = 0; i < inside.size(); ++i) {
    const bool a = covered(img, i), b = covered(ref, i);
    both += a && b;
    either += a || b;
    if (inside[i]) {
      ++n;
      open += !a;
    }
  }
  return {n ? double(open) / double(n) : 0.0, either ? double(both) / double(either) : 1.0};
}

const char* fillName(render::SurfaceFill f) {
  return f == render::SurfaceFill::kNone    ? "none"
         : f == render::SurfaceFill::kDiscs ? "discs"
                                            : "pullpush";
}

struct Result {
  uint64_t points = 0;
  double best_ms = 1e300;
  render::RenderStats stats;  ///< of the best frame
  render::Image image;
};

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  CLI::App app{"fill: discs against 1 px points and the pull-push fill, cost and accuracy"};
  bench::StoreInputs input;
  input.points = 10'000'000;
  input.addOptions(app);
  uint64_t cube_points = 10'000'000;
  std::vector<double> scales{0.5, 1.0, 2.0, 4.0};
  std::vector<std::string> inputs{"cube", "bunny", "autzen"};
  int rounds = 2, frames = 2;
  app.add_option("--cube-points", cube_points, "Points of the random cube")->capture_default_str();
  app.add_option("--scales", scales, "Splat scales")->capture_default_str();
  app.add_option("--inputs", inputs, "Inputs: cube, bunny, autzen")->capture_default_str();
  app.add_option("--rounds", rounds, "Interleaved rounds (best kept)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--frames", frames, "Timed frames per variant and round")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    const fs::path out(input.out);
    fs::create_directories(out / "inputs");
    auto ctx = render::GlContext::createHeadless();
    const uint32_t W = 1920, H = 1080;
    std::vector<Input> all;
    for (const std::string& name : inputs) {
      Input in;
      in.name = name;
      if (name == "cube") {
        const fs::path dir = out / "inputs" / ("fill-cube-" + std::to_string(cube_points));
        fs::create_directories(dir);
        in.store = dir / "cube.tlod";
        if (!fs::exists(in.store)) {
          std::fprintf(stderr, "fill: building the %llu-point cube\n",
                       (unsigned long long)cube_points);
          in.store = test::randomCubeStore(dir, cube_points);
        }
        in.view = bench::cubeView(bench::cubeCamera(), W, H);
        in.crop = {880, 480};
      } else if (name == "bunny") {
        in.store = input.storePath();
        in.view = bench::bigBunnyView(W, H);
        in.options.edl.strength = 1.0f;
        in.crop = {860, 380};
      } else if (name == "autzen") {
        in.store = out / "inputs" / "autzen.tlod";
        if (!fs::exists(in.store)) {
          lod::BuildOptions o;
          o.quiet = true;
          lod::buildStore({fs::path(TESSERA_DATA_DIR) / "lidar/autzen_trim.las"}, in.store, o);
        }
        in.crop = {880, 500};
      } else {
        throw std::runtime_error("fill: unknown input '" + name + "' (cube, bunny, autzen)");
      }
      all.push_back(std::move(in));
    }

    std::ofstream csv(out / "fill.csv");
    const std::string header =
        "input,splat_scale,fill,points,frame_ms,depth_ms,color_ms,fill_ms,resolve_ms,screen_ms,"
        "ratio_to_none,ratio_to_none_at_2,open_inside_pct,iou_vs_full,psnr_vs_discs_db";
    csv << header << "\n";
    std::cout << header << "\n";
    const std::vector<render::SurfaceFill> fills{
        render::SurfaceFill::kNone, render::SurfaceFill::kDiscs, render::SurfaceFill::kPullPush};
    std::vector<render::Image> crops;
    for (Input& in : all) {
      auto store = lod::PointStore::open(in.store);
      if (in.name == "autzen") in.view = flatView(*store, W, H);
      render::ModelInstance inst{store.get(), render::storeModel(*store)};
      render::StreamerOptions so;
      so.budget_bytes = 8ull << 30;
      render::ViewRenderer r(W, H, nullptr, so);
      // The full render: every leaf, discs at scale 2.
      render::RenderOptions full = in.options;
      full.lod_pixels = 1e-9;
      full.coverage_stop = false;
      full.fill = render::SurfaceFill::kDiscs;
      full.splat_scale = 2.0f;
      const render::Image ref = r.renderSettled({&inst, 1}, in.view, full);
      const std::vector<bool> inside = insideOf(ref);
      render::writePng((out / ("fill-" + in.name + "-full.png")).string(), ref);
      std::map<std::pair<double, int>, Result> res;
      for (int round = 0; round < rounds; ++round)
        for (double scale : scales)
          for (render::SurfaceFill f : fills) {
            render::RenderOptions o = in.options;
            o.splat_scale = float(scale);
            o.fill = f;
            Result& rr = res[{scale, int(f)}];
            render::RenderStats st;
            rr.image = r.renderSettled({&inst, 1}, in.view, o, &st);
            for (int k = 0; k < frames; ++k) {
              const auto t = std::chrono::steady_clock::now();
              rr.image = r.render({&inst, 1}, in.view, o, &st);
              const double ms = msSince(t);
              if (ms < rr.best_ms) {
                rr.best_ms = ms;
                rr.stats = st;
              }
            }
            rr.points = st.points;
            std::fprintf(stderr, "fill: %s scale %.1f %s: %.0f ms (round %d)\n", in.name.c_str(),
                         scale, fillName(f), rr.best_ms, round + 1);
          }
      const double none_at_2 = res.count({2.0, int(render::SurfaceFill::kNone)})
                                   ? res[{2.0, int(render::SurfaceFill::kNone)}].best_ms
                                   : 0.0;
      for (double scale : scales)
        for (render::SurfaceFill f : fills) {
          const Result& rr = res[{scale, int(f)}];
          const Result& none = res[{scale, int(render::SurfaceFill::kNone)}];
          const Result& discs = res[{scale, int(render::SurfaceFill::kDiscs)}];
          const Accuracy a = accuracy(rr.image, ref, inside);
          const render::RenderStats& s = rr.stats;
          char line[512];
          std::snprintf(line, sizeof line,
                        "%s,%g,%s,%llu,%.1f,%.1f,%.1f,%.1f,%.1f,%.1f,%.3f,%.3f,%.4f,%.4f,%.2f",
                        in.name.c_str(), scale, fillName(f), (unsigned long long)rr.points,
                        rr.best_ms, s.depth_ms, s.color_ms, s.fill_ms, s.resolve_ms, s.screen_ms,
                        rr.best_ms / none.best_ms, none_at_2 > 0 ? rr.best_ms / none_at_2 : 0.0,
                        100.0 * a.open, a.iou, bench::psnr(rr.image, discs.image));
          csv << line << "\n";
          std::cout << line << std::endl;
          if (scale == 2.0) {
            render::writePng((out / ("fill-" + in.name + "-" + fillName(f) + "-s2.png")).string(),
                             rr.image);
            crops.push_back(bench::crop(rr.image, in.crop[0], in.crop[1], 160, 100, 3));
          }
        }
    }
    csv.close();
    if (!crops.empty()) render::writePng((out / "fill_crops.png").string(), bench::grid(crops, 3));

    const fs::path gp = out / "fill.gp", data = out / "fill.csv";
    std::ofstream g(gp);
    g << "set terminal pngcairo size 1300,480 font 'sans,10' noenhanced\n"
      << "set output '" << (out / "fill.png").string() << "'\n"
      << "set datafile separator ','\nset multiplot layout 1,2\nset grid\nset logscale x 2\n"
      << "set xrange [0.35:5.5]\nset xlabel 'splat scale (diameter / projected spacing)'\n"
      << "sel(i, f) = strcol(1) eq i && strcol(3) eq f\n"
      << "set title 'Frame time over the 1 px scatter of the same cut (1920x1080, llvmpipe, "
         "2 shared cores)'\n"
      << "set ylabel 'frame ms / 1 px points ms'\nset logscale y\nset key top left\n"
      << "set arrow from graph 0, first 1.5 to graph 1, first 1.5 nohead dt 2 lc rgb 'gray40'\n"
      << "set label 'goal 1.5x' at graph 0.02, first 1.6 tc rgb 'gray40'\n";
    const char* colours[] = {"#1f77b4", "#d62728", "#2ca02c"};
    auto plot = [&](int column, const char* what) {
      g << "plot ";
      for (size_t i = 0; i < all.size(); ++i)
        for (const char* f : {"discs", "pullpush"}) {
          g << (i == 0 && std::string(f) == "discs" ? "'" + data.string() + "'" : "''")
            << " every ::1 using 2:(sel('" << all[i].name << "', '" << f << "') ? $" << column
            << " : 1/0) with points lc rgb '" << colours[i % 3] << "' ps 1.6 pt "
            << (std::string(f) == "discs" ? 6 : 7) << " title '" << all[i].name << ", " << f << what
            << "'";
          g << (i + 1 == all.size() && std::string(f) == "pullpush" ? "\n" : ", ");
        }
    };
    plot(11, "");
    g << "unset arrow\nunset label\nset yrange [0.001:100]\n"
      << "set title 'Pixels left open inside the full render (every leaf, discs at 2)'\n"
      << "set ylabel 'open inside, % (log; none drawn at 0.001)'\nset key top right\n";
    plot(13, "");  // zeros fall below the log axis
    g << "unset multiplot\n";
    g.close();
    const std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp.string() + "'";
    if (std::system(cmd.c_str()) != 0)
      std::fprintf(stderr, "fill: gnuplot failed; the CSV is complete\n");
    std::fprintf(stderr, "fill: wrote %s/fill.csv, fill.png, fill_crops.png\n", out.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fill: %s\n", e.what());
    return 1;
  }
}
