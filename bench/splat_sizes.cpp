// splat_sizes: closing scanned surfaces on close views, in one run on one context
// against the baseline of discs sized by the node's mean spacing. Two real scans seen close: the
// Stanford bunny's range scans (a close-up of the back) and Autzen's airborne LiDAR (the issue's
// close view of the ground, whose scan lines lie several spacings apart). For each method:
//   open_pct   pixels left open inside the surface's footprint (the pixels the reference covers,
//              eroded by 4 px; on Autzen only the ground: the picture's bottom 40%, as the
//              test SplatSizes.AutzenCloseUpHasNoOpenPixelInTheGround), percent;
//   frame_ms   one frame once everything is resident (best of --repeats);
//   settle_ms  the first picture from cold (renderSettled(): loader, splat sizes, frames).
// The reference is the default (own splat sizes, discs up to 32 px); the pull-push fill
// (FillPass, Marroquim et al. 2007) reaches 16 px at no cost per splat area. Prints CSV; writes
// OUT/splat_sizes.csv, OUT/splat_sizes.png (open pixels and frame time per method) and
// OUT/splat_sizes_views.png (each view before, with own sizes within 8 px, and today's default;
// open pixels red, half size).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/stopwatch.h>
#include <tessera/core/cli.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/store_cache.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/chunk_streamer.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/image.h>
#include <tessera/render/view_renderer.h>

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Method {
  std::string name;
  bool own_sizes;
  int max_radius;
  render::SurfaceFill fill = render::SurfaceFill::kDiscs;
};

struct Scene {
  std::string name;
  fs::path input;
  glm::dvec3 eye, target, up;
  double ground_rows;  ///< > 0: the bottom share of the picture that is only ground
};

render::ViewSetup viewOf(const Scene& s, const lod::PointStore& store, uint32_t w, uint32_t h) {
  const auto& sum = store.summary();
  const double radius = 0.5 * glm::length(sum.bbox_max - sum.bbox_min);
  render::ViewSetup v;
  v.view = glm::lookAt(s.eye, s.target, s.up);
  v.projection = glm::perspective(glm::radians(45.0), double(w) / h, 1e-3 * radius,
                                  glm::length(s.eye - s.target) + 4 * radius);
  v.width = w;
  v.height = h;
  v.eye_world = s.eye;
  return v;
}

/// Covered pixels of `depth` (raster order, bottom row first), as 0/1.
std::vector<uint8_t> covered(const std::vector<uint32_t>& depth) {
  std::vector<uint8_t> c(depth.size());
  for (size_t i = 0; i < depth.size(); ++i) c[i] = depth[i] != 0xFFFFFFFFu;
  return c;
}

/// The footprint: covered pixels of the reference eroded by `r` pixels, and on ground scenes
/// only the bottom `ground` share of the picture (which shows nothing but ground).
std::vector<uint8_t> footprint(const std::vector<uint32_t>& depth, const render::ViewSetup& v,
                               int r, double ground) {
  const uint32_t W = v.width, H = v.height;
  const std::vector<uint8_t> c = covered(depth);
  std::vector<uint8_t> f(c.size(), 0);
  for (uint32_t y = 0; y < H; ++y)
    for (uint32_t x = 0; x < W; ++x) {
      bool all = true;
      for (int dy = -r; dy <= r && all; ++dy)
        for (int dx = -r; dx <= r && all; ++dx) {
          const int xx = int(x) + dx, yy = int(y) + dy;
          all = xx >= 0 && yy >= 0 && xx < int(W) && yy < int(H) && c[size_t(yy) * W + xx];
        }
      f[size_t(y) * W + x] = all;
    }
  // Rows are in raster order (bottom first): keep the bottom `ground` share of the picture.
  if (ground > 0)
    for (uint32_t y = uint32_t(ground * H); y < H; ++y)
      std::fill_n(f.begin() + std::ptrdiff_t(size_t(y) * W), W, uint8_t(0));
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  CLI::App app{
      "splat_sizes: open pixels and frame time on close views of real scans, splats sized by "
      "the node's spacing against each point's own"};
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  std::string data = TESSERA_DATA_DIR;
  int repeats = 3;
  uint32_t width = 640, height = 480;
  app.add_option("--out", out, "Folder for CSV and charts")->capture_default_str();
  app.add_option("--data", data, "The shared data folder")->capture_default_str();
  app.add_option("--repeats", repeats, "Timed frames per method (best kept)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--width", width, "View width, pixels")->check(CLI::Range(64, 4096));
  app.add_option("--height", height, "View height, pixels")->check(CLI::Range(64, 4096));
  if (const auto code = cli::parse(app, argc, argv, "splat_sizes")) return *code;
  fs::create_directories(out);

  const std::vector<Scene> scenes = {
      {"bunny close-up",
       fs::path(data) / "stanford-bunny/scans/bun.conf",
       {-0.02, 0.13, 0.08},
       {-0.02, 0.12, 0.0},
       {0, 1, 0},
       0.0},
      {"Autzen close-up",
       fs::path(data) / "lidar/autzen_trim.las",
       {636590, 849150, 480},
       {636590, 849216, 430},
       {0, 0, 1},
       6.0},
  };
  const std::vector<Method> methods = {
      {"before: node spacing, discs to 8 px", false, 8},
      {"node spacing, discs to 32 px", false, 32},
      {"own sizes, discs to 8 px", true, 8},
      {"node spacing, pull-push fill", false, 8, render::SurfaceFill::kPullPush},
      {"own sizes, pull-push fill", true, 8, render::SurfaceFill::kPullPush},
      {"default: own sizes, discs to 32 px", true, 32},
  };
  auto ctx = render::GlContext::createHeadless();
  std::ofstream csv(fs::path(out) / "splat_sizes.csv");
  csv << "scene,method,open_pct,frame_ms,settle_ms\n";
  std::printf("scene,method,open_pct,frame_ms,settle_ms\n");
  std::vector<render::Image> shots;
  for (const Scene& scene : scenes) {
    const fs::path store_path = lod::cachedStoreFor(scene.input, "bench/splat_sizes");
    auto store = lod::PointStore::open(store_path);
    const render::ModelInstance inst{store.get(), render::storeModel(*store)};
    const render::ViewSetup view = viewOf(scene, *store, width, height);
    std::vector<uint8_t> foot;
    for (size_t m = methods.size(); m-- > 0;) {  // the reference (last) first
      const Method& method = methods[m];
      render::StreamerOptions so;
      so.point_splat_sizes = method.own_sizes;
      auto streamer = std::make_shared<render::ChunkStreamer>(so);
      render::ViewRenderer r(width, height, streamer);
      render::RenderOptions o;
      // Every level the pixels ask for: the method measured alone, without the pixel budget.
      o.budget_per_covered_pixel = 0.0;
      o.max_splat_radius = method.max_radius;
      o.fill = method.fill;
      o.background = glm::vec3(1, 0, 0);
      o.edl.strength = 1.0f;
      auto t0 = Clock::now();
      render::Image img = r.renderSettled({&inst, 1}, view, o);
      const double settle = msSince(t0);
      double frame = 1e30;
      for (int i = 0; i < repeats; ++i) {
        t0 = Clock::now();
        img = r.render({&inst, 1}, view, o);
        frame = std::min(frame, msSince(t0));
      }
      const std::vector<uint32_t> depth = r.readDepth();
      if (foot.empty()) foot = footprint(depth, view, 4, scene.ground_rows);
      size_t inside = 0, open = 0;
      for (size_t i = 0; i < foot.size(); ++i) {
        if (!foot[i]) continue;
        ++inside;
        open += depth[i] == 0xFFFFFFFFu;
      }
      const double pct = inside ? 100.0 * double(open) / double(inside) : 0.0;
      std::printf("\"%s\",\"%s\",%.4f,%.1f,%.1f\n", scene.name.c_str(), method.name.c_str(), pct,
                  frame, settle);
      csv << '"' << scene.name << "\",\"" << method.name << "\"," << pct << "," << frame << ","
          << settle << "\n";
      shots.push_back(std::move(img));
    }
  }
  csv.close();
  // Each view before, with own sizes within 8 px and with today's default, half size, side by
  // side (rows: scenes).
  const std::vector<size_t> shown = {0, 2, methods.size() - 1};
  const uint32_t hw = width / 2, hh = height / 2, cols = uint32_t(shown.size());
  render::Image sheet;
  sheet.width = hw * cols;
  sheet.height = hh * uint32_t(scenes.size());
  sheet.rgba.assign(size_t(sheet.width) * sheet.height * 4, 255);
  for (size_t s = 0; s < scenes.size(); ++s)
    for (size_t col = 0; col < shown.size(); ++col) {
      // shots are in reverse method order per scene
      const render::Image& img = shots[s * methods.size() + (methods.size() - 1 - shown[col])];
      for (uint32_t y = 0; y < hh; ++y)
        for (uint32_t x = 0; x < hw; ++x)
          for (int c = 0; c < 4; ++c)
            sheet.rgba[((size_t(s) * hh + y) * sheet.width + col * hw + x) * 4 + c] =
                img.rgba[(size_t(2 * y) * img.width + 2 * x) * 4 + c];
    }
  render::writePng(fs::path(out) / "splat_sizes_views.png", sheet);
  std::ofstream gp(fs::path(out) / "splat_sizes.gp");
  gp << "set terminal pngcairo size 1200,460 font 'DejaVu Sans,10'\nset output '"
     << (fs::path(out) / "splat_sizes.png").string() << "'\n"
     << "set datafile separator ','\nset multiplot layout 1,2\nset style data histograms\n"
     << "set style histogram clustered\nset style fill solid 0.8 border -1\nset boxwidth 0.9\n"
     << "set key top left\nset grid ytics\nset xtics rotate by -20\n"
     << "set title 'pixels open inside the footprint (%)'\nset logscale y\n"
     << "plot '< grep bunny " << (fs::path(out) / "splat_sizes.csv").string()
     << "' using ($3+0.001):xtic(2) title 'bunny close-up', '< grep Autzen "
     << (fs::path(out) / "splat_sizes.csv").string()
     << "' using ($3+0.001) title 'Autzen close-up'\n"
     << "unset logscale y\nset title 'frame ms (resident)'\n"
     << "plot '< grep bunny " << (fs::path(out) / "splat_sizes.csv").string()
     << "' using 4:xtic(2) title 'bunny close-up', '< grep Autzen "
     << (fs::path(out) / "splat_sizes.csv").string() << "' using 4 title 'Autzen close-up'\n"
     << "unset multiplot\n";
  gp.close();
  const std::string cmd =
      std::string(TESSERA_GNUPLOT) + " '" + (fs::path(out) / "splat_sizes.gp").string() + "'";
  if (std::system(cmd.c_str()) != 0)
    std::fprintf(stderr, "splat_sizes: gnuplot failed; the CSV is complete\n");
  return 0;
}
