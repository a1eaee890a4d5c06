// render_lod: the renderer's speed against its accuracy on the 10^8-point virtual bunny scan
//, in one run on one context:
//  (1) lod-px in {0.5, 1, 2, 4, 8}: frame time (all chunks resident) and PSNR to the
//      full-resolution image (every leaf drawn), with points drawn and GPU bytes resident;
//  (2) the 2x2 wall (configs/walls/2x2.json): per tile, with its own streamer as a wall node
//      has, the frame time and the bytes it holds resident against the whole store's size.
// Eye-dome lighting is on (the scan has no colour), so PSNR sees shape, not just silhouette.
// Prints CSV; writes OUT/render_lod.csv, OUT/render_wall.csv and OUT/render_lod.png.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/render/pass_timing.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/view_renderer.h>
#include <tessera/sync/config.h>

#include <tessera/core/stopwatch.h>
#include "bench_images.h"
#include "bench_inputs.h"
#include "bench_views.h"

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Measure {
  render::Image image;
  render::RenderStats stats;
  double settle_ms = 0;  ///< from a cold streamer to every chunk resident
  double frame_ms = 0;   ///< best of `repeats` frames once resident (wall clock, no readback)
};

Measure measure(std::span<const render::ModelInstance> models, const render::ViewSetup& view,
                const render::RenderOptions& options, uint64_t budget, int repeats) {
  Measure m;
  render::StreamerOptions so;
  so.budget_bytes = budget;
  render::ViewRenderer r(view.width, view.height, nullptr, so);
  auto t = Clock::now();
  m.image = r.renderSettled(models, view, options, &m.stats);
  m.settle_ms = msSince(t);
  m.frame_ms = 1e300;
  for (int i = 0; i < repeats; ++i) {
    t = Clock::now();
    r.draw(models, view, options, &m.stats);
    m.frame_ms = std::min(m.frame_ms, msSince(t));
  }
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  CLI::App app{"render_lod: frame time against PSNR for LOD thresholds; per-tile cost of a wall"};
  bench::StoreInputs in;
  std::string wall_path = TESSERA_CONFIG_DIR "/walls/2x2.json";
  int repeats = 3;
  in.addOptions(app);
  app.add_option("--wall", wall_path, "Wall for the per-tile part")->capture_default_str();
  app.add_option("--repeats", repeats, "Timed frames per measure (best kept)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  const std::string& out = in.out;
  try {
    const std::string store_path = in.storePath();
    auto store = lod::PointStore::open(store_path);
    const uint64_t store_bytes = store->summary().file_bytes;
    auto ctx = render::GlContext::createHeadless();
    render::ModelInstance inst{store.get(), render::storeModel(*store)};
    const config::Camera cam = bench::bigBunnyCamera();
    const render::ViewSetup view = bench::bigBunnyView();
    render::RenderOptions options;
    // Every level the pixels ask for: the method measured alone, without the pixel budget.
    options.budget_per_covered_pixel = 0.0;
    options.edl.strength = 1.0f;
    const uint64_t big_budget = 8ull << 30;

    std::fprintf(stderr, "render_lod: full-resolution reference (every leaf)...\n");
    render::RenderOptions full = options;
    full.lod_pixels = 1e-9;
    full.coverage_stop = false;
    const Measure ref = measure({&inst, 1}, view, full, big_budget, 1);
    std::ofstream csv(fs::path(out) / "render_lod.csv");
    const std::string header =
        "lod_px,points,nodes,resident_bytes,settle_ms,frame_ms,depth_ms,color_ms,resolve_ms,"
        "psnr_db,psnr_4x4_db";
    csv << header << "\n";
    std::cout << header << "\n";
    auto row = [&](const std::string& lod, const Measure& m, double p, double p4) {
      char line[512];
      std::snprintf(line, sizeof line, "%s,%llu,%zu,%llu,%.1f,%.1f,%.1f,%.1f,%.1f,%.2f,%.2f",
                    lod.c_str(), (unsigned long long)m.stats.points, m.stats.nodes,
                    (unsigned long long)m.stats.stream.resident_bytes, m.settle_ms, m.frame_ms,
                    m.stats.depth_ms, m.stats.color_ms, m.stats.resolve_ms, p, p4);
      csv << line << "\n";
      std::cout << line << std::endl;
    };
    row("full", ref, 99.0, 99.0);
    render::writePng((fs::path(out) / "render_lod-full.png").string(), ref.image);
    for (double lod : {0.5, 1.0, 2.0, 4.0, 8.0}) {
      render::RenderOptions o = options;
      o.lod_pixels = lod;
      const Measure m = measure({&inst, 1}, view, o, big_budget, repeats);
      char name[32];
      std::snprintf(name, sizeof name, "%g", lod);
      row(name, m, bench::psnr(m.image, ref.image), bench::psnr(m.image, ref.image, 4));
      render::writePng((fs::path(out) / ("render_lod-" + std::string(name) + ".png")).string(),
                       m.image);
    }
    csv.close();

    // The wall: each tile streams on its own, as a node would.
    config::WallConfig wall = sync::loadWallConfig(wall_path);
    std::ofstream wcsv(fs::path(out) / "render_wall.csv");
    const std::string wheader =
        "tile,width,height,points,nodes,gpu_bytes,resident_store_bytes,store_bytes,"
        "store_fraction,settle_ms,frame_ms";
    wcsv << wheader << "\n";
    std::cout << "\n" << wheader << "\n";
    auto wrow = [&](const std::string& name, const render::ViewSetup& v) {
      const Measure m = measure({&inst, 1}, v, options, big_budget, repeats);
      char line[512];
      std::snprintf(line, sizeof line, "%s,%u,%u,%llu,%zu,%llu,%llu,%llu,%.4f,%.1f,%.1f",
                    name.c_str(), v.width, v.height, (unsigned long long)m.stats.points,
                    m.stats.nodes, (unsigned long long)m.stats.stream.resident_bytes,
                    (unsigned long long)m.stats.stream.resident_disk_bytes,
                    (unsigned long long)store_bytes,
                    double(m.stats.stream.resident_disk_bytes) / double(store_bytes), m.settle_ms,
                    m.frame_ms);
      wcsv << line << "\n";
      std::cout << line << std::endl;
    };
    for (const auto& tile : wall.tiles()) wrow(tile.name(), render::tileView(wall, tile, cam));
    wrow("whole", render::wholeWallView(wall, cam));
    wcsv.close();

    // Chart: frame time against PSNR, and per-tile resident bytes against the store.
    const fs::path gp = fs::path(out) / "render_lod.gp";
    std::ofstream g(gp);
    g << "set terminal pngcairo size 1200,460 font 'sans,10' noenhanced\n"
      << "set output '" << (fs::path(out) / "render_lod.png").string() << "'\n"
      << "set datafile separator ','\nset multiplot layout 1,2\n"
      << "set title 'LOD threshold: frame time against accuracy (1920x1080, "
      << store->summary().points / 1000000 << " M point store)'\n"
      << "set xlabel 'frame time, ms (llvmpipe, 2 cores)'\nset ylabel 'PSNR to full resolution, "
         "dB'\nset grid\nset key bottom right\n"
      << "plot '" << (fs::path(out) / "render_lod.csv").string()
      << "' every ::2 using 6:10 with linespoints pt 7 ps 1.2 title 'per pixel', '' every ::2 "
         "using 6:11 with linespoints pt 5 ps 1.2 title 'over 4x4 blocks', '' every ::2 using "
         "6:11:(sprintf('%s px', stringcolumn(1))) with labels offset 2,0.8 notitle\n"
      << "set title '2x2 wall: what each tile holds resident (MB)'\nset xlabel ''\nset ylabel "
         "'MB'\nset style data histograms\nset style fill solid 0.8 border -1\nset yrange [0:*]\n"
      << "set key top left\n"
      << "plot '" << (fs::path(out) / "render_wall.csv").string()
      << "' every ::1 using ($7/1e6):xtic(1) title 'its chunks, compressed as in the store', '' "
         "every ::1 using ($8/1e6) title 'the whole store', '' every ::1 using ($6/1e6) title "
         "'its GPU buffers (16 B/point)'\n"
      << "unset multiplot\n";
    g.close();
    const std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp.string() + "'";
    if (std::system(cmd.c_str()) != 0)
      std::fprintf(stderr, "render_lod: gnuplot failed; the CSV is complete\n");
    std::fprintf(stderr, "render_lod: wrote %s/render_lod.csv, render_wall.csv, render_lod.png\n",
                 out.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "render_lod: %s\n", e.what());
    return 1;
  }
}
