// loader_pool: how long a full-resolution view of the 10^8-point virtual bunny scan takes to
// settle from cold (ViewRenderer::renderSettled(): every leaf resident and drawn), against the
// chunk streamer's loader threads (StreamerOptions::loader_threads) and whether the loader
// measures every chunk's see-through density as the baseline loader does
// (StreamerOptions::measure_every_chunk) or only the chunks drawn see-through (none here).
// The baseline, one loader thread measuring every chunk, is the simplest loader; every
// configuration runs in this one process, interleaved over the repeats, each with a store
// opened anew (no hierarchy page in memory) and the file in the page cache. The settled images
// are compared byte for byte with the baseline's. Per run: settle_ms, of which last_frame_ms is
// the frame that finds everything resident (upload_ms: its upload of the last chunks) and the
// rest the loader's work with the frames before; frame_ms is one more frame, drawing alone;
// cpu_s the CPU time of all the process's threads while settling (a machine shared with other
// work stretches wall-clock times, hardly CPU times).
// Prints CSV; writes OUT/loader_pool.csv (every run), OUT/loader_pool_best.csv (best run of
// each configuration) and OUT/loader_pool.png.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <thread>
#include <vector>

#include <sys/resource.h>

#include <CLI/CLI.hpp>

#include <tessera/render/pass_timing.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/view_renderer.h>

#include <tessera/core/stopwatch.h>
#include "bench_inputs.h"
#include "bench_views.h"

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Run {
  uint32_t threads = 0;
  bool every_chunk = false;  ///< the loader measures every chunk (the baseline)
  double settle_ms = 0;      ///< cold streamer and store to the settled image
  double frame_ms = 0;       ///< one more frame, everything resident
  double cpu_s = 0;          ///< CPU time of every thread of the process while settling
  render::RenderStats stats;
  render::Image image;
};

/// User and system CPU time of the whole process (llvmpipe's threads and the loader's too).
double cpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

Run settle(const fs::path& store_path, uint32_t threads, bool every_chunk,
           const render::ViewSetup& view, const render::RenderOptions& options) {
  Run run;
  run.threads = threads;
  run.every_chunk = every_chunk;
  auto store = lod::PointStore::open(store_path);  // no hierarchy page of an earlier run
  render::ModelInstance inst{store.get(), render::storeModel(*store)};
  render::StreamerOptions so;
  so.budget_bytes = 8ull << 30;  // the whole cut stays resident
  so.loader_threads = threads;
  so.measure_every_chunk = every_chunk;
  render::ViewRenderer r(view.width, view.height, nullptr, so);
  const double cpu0 = cpuSeconds();
  auto t = Clock::now();
  run.image = r.renderSettled({&inst, 1}, view, options, &run.stats);
  run.settle_ms = msSince(t);
  run.cpu_s = cpuSeconds() - cpu0;
  t = Clock::now();
  r.draw({&inst, 1}, view, options);
  run.frame_ms = msSince(t);
  return run;
}

/// Reads the whole file once, so that the first configuration does not pay for the disk.
void warmPageCache(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> buf(8 << 20);
  while (in.read(buf.data(), std::streamsize(buf.size())) || in.gcount() > 0) {
  }
}

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  CLI::App app{"loader_pool: settle time of a full-resolution view against loader threads"};
  bench::StoreInputs in;
  std::vector<uint32_t> threads_list{1, 2, 4};
  int repeats = 2;
  double lod_px = 1e-9;
  in.addOptions(app);
  app.add_option("--threads", threads_list, "Loader threads to compare (the cores are added)")
      ->delimiter(',')
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--repeats", repeats, "Runs of each configuration (best kept)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--lod-px", lod_px, "LOD threshold, pixels (default: every leaf)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  const std::string& out = in.out;
  try {
    const std::string store_path = in.storePath();
    const uint32_t cores = std::max(1u, std::thread::hardware_concurrency());
    if (std::find(threads_list.begin(), threads_list.end(), cores) == threads_list.end())
      threads_list.push_back(cores);
    std::sort(threads_list.begin(), threads_list.end());
    uint64_t store_points = 0;
    {
      auto store = lod::PointStore::open(store_path);
      store_points = store->summary().points;
      std::fprintf(stderr, "loader_pool: %s, %llu points, %.1f MB; %u cores\n", store_path.c_str(),
                   (unsigned long long)store->summary().points, store->summary().file_bytes / 1e6,
                   cores);
    }
    warmPageCache(store_path);
    auto ctx = render::GlContext::createHeadless();
    const render::ViewSetup view = bench::bigBunnyView();
    render::RenderOptions options;
    // Every level the pixels ask for: the method measured alone, without the pixel budget.
    options.budget_per_covered_pixel = 0.0;
    options.edl.strength = 1.0f;
    options.lod_pixels = lod_px;

    std::ofstream csv(fs::path(out) / "loader_pool.csv");
    const std::string header =
        "repeat,loader_threads,measure,settle_ms,last_frame_ms,upload_ms,frames,points,gpu_mb,"
        "frame_ms,cpu_s,same_image";
    csv << header << "\n";
    std::cout << header << "\n";
    render::Image baseline;
    std::map<std::pair<bool, uint32_t>, double> best;  // (every chunk, threads) -> ms
    double frame_ms = 1e300;                           // drawing alone, everything resident
    for (int rep = 0; rep < repeats; ++rep) {
      for (bool every : {true, false}) {
        for (uint32_t threads : threads_list) {
          const Run r = settle(store_path, threads, every, view, options);
          if (baseline.rgba.empty()) baseline = r.image;  // 1 thread, every chunk: the first
          char line[512];
          std::snprintf(line, sizeof line, "%d,%u,%s,%.1f,%.1f,%.1f,%zu,%llu,%.1f,%.1f,%.2f,%d",
                        rep, threads, every ? "every_chunk" : "see_through_only", r.settle_ms,
                        r.stats.totalMs(), r.stats.upload_ms, r.stats.frames,
                        (unsigned long long)r.stats.points, r.stats.stream.resident_bytes / 1e6,
                        r.frame_ms, r.cpu_s, r.image.rgba == baseline.rgba ? 1 : 0);
          csv << line << "\n";
          std::cout << line << std::endl;
          auto [it, added] = best.try_emplace({every, threads}, r.settle_ms);
          if (!added) it->second = std::min(it->second, r.settle_ms);
          frame_ms = std::min(frame_ms, r.frame_ms);
        }
      }
    }
    csv.close();

    const fs::path best_csv = fs::path(out) / "loader_pool_best.csv";
    std::ofstream b(best_csv);
    b << "loader_threads,every_chunk_s,see_through_only_s,frame_s\n";
    std::cout << "\nloader_threads,every_chunk_s,see_through_only_s,frame_s (best of " << repeats
              << ")\n";
    for (uint32_t threads : threads_list) {
      char line[128];
      std::snprintf(line, sizeof line, "%u,%.2f,%.2f,%.2f", threads, best[{true, threads}] / 1e3,
                    best[{false, threads}] / 1e3, frame_ms / 1e3);
      b << line << "\n";
      std::cout << line << "\n";
    }
    b.close();
    const double target_s = best[{true, threads_list.front()}] / 2e3;

    // Chart: best settle time per configuration, and half the baseline (the goal).
    const fs::path gp = fs::path(out) / "loader_pool.gp";
    std::ofstream g(gp);
    char title[256];
    std::snprintf(title, sizeof title,
                  "Full-resolution view of the %.0f M point store settling from cold (1920x1080, "
                  "llvmpipe, %u cores)",
                  double(store_points) / 1e6, cores);
    g << "set terminal pngcairo size 900,460 font 'sans,10' noenhanced\n"
      << "set output '" << (fs::path(out) / "loader_pool.png").string() << "'\n"
      << "set datafile separator ','\nset title '" << title << "'\n"
      << "set xlabel 'loader threads'\nset ylabel 'settle time, s (best of " << repeats
      << ")'\nset grid ytics\nset yrange [0:*]\nset key top right\n"
      << "set xrange [-0.5:" << threads_list.size() - 0.5 << "]\n"
      << "set style data histograms\nset style histogram clustered gap 1\n"
      << "set style fill solid 0.8 border -1\n"
      << "plot '" << best_csv.string()
      << "' every ::1 using 2:xtic(1) title 'density measured for every chunk (before)', '' "
         "every ::1 using 3 title 'only for chunks drawn see-through (now)', '' every ::1 using 4 "
         "lc rgb 'grey' title 'one frame, everything resident (drawing alone)', "
      << target_s << " with lines lw 2 dt 2 lc rgb 'black' title 'half of 1 thread, before'\n";
    g.close();
    const std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp.string() + "'";
    if (std::system(cmd.c_str()) != 0)
      std::fprintf(stderr, "loader_pool: gnuplot failed; the CSV is complete\n");
    std::fprintf(stderr,
                 "loader_pool: wrote %s/loader_pool.csv, loader_pool_best.csv, loader_pool.png\n",
                 out.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "loader_pool: %s\n", e.what());
    return 1;
  }
}
