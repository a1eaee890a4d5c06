// poster: posters (render/poster.h) of the bunny's registered range scans with eye-dome lighting,
// square sizes from 2k to 16k and beyond one frame target, against a single render at the largest
// square one frame target holds, in one process on one context. Each run renders the picture
// settled and writes its PNG (the poster in strips, the single render whole); the figures are
// megapixels a second end to end and the peak resident memory of the run (llvmpipe keeps GL
// buffers in host memory, so this is GPU memory too). The poster of the single render's size is
// compared with it pixel by pixel. Prints CSV; writes OUT/poster.csv and OUT/poster.png.
// Goal: a poster's memory stays within --memory-mb whatever its size, and its throughput within
// a small factor of the single render's.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/stopwatch.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/poster.h>
#include <tessera/render/view_renderer.h>

namespace {

namespace fs = std::filesystem;
using namespace tessera;

/// Resets the process's peak resident set (Linux: "5" to clear_refs), so the next
/// peakResidentMiB() is this run's.
void resetPeakResident() {
  std::ofstream("/proc/self/clear_refs") << "5";
}

/// VmHWM: the peak resident set since the last reset, MiB.
double peakResidentMiB() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  return 0.0;
}

/// The bunny from the front, its bounding sphere filling the view's height.
render::ViewSetup viewOf(const lod::PointStore& store, uint32_t w, uint32_t h) {
  const lod::StoreSummary& sum = store.summary();
  const glm::dvec3 centre = sum.origin + 0.5 * (sum.bbox_min + sum.bbox_max);
  const double radius = 0.5 * glm::length(sum.bbox_max - sum.bbox_min);
  const double fovy = glm::radians(40.0);
  const double distance = radius / std::sin(fovy / 2) * 0.8;
  render::ViewSetup v;
  v.view = glm::lookAt(centre + glm::dvec3(0.0, 0.1, 1.0) * distance, centre, {0, 1, 0});
  v.projection = glm::perspective(fovy, double(w) / h, distance * 0.05, distance * 4);
  v.width = w;
  v.height = h;
  v.eye_world = centre + glm::dvec3(0.0, 0.1, 1.0) * distance;
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "poster: posters of 2k to 16k squares against one render at the largest square a "
      "frame target holds: megapixels a second and peak memory. Prints CSV; writes "
      "poster.csv and poster.png into --out."};
  std::string out = std::string(TESSERA_BENCH_RESULTS_DIR) + "/poster";
  std::vector<uint32_t> sizes = {2048, 4096, 8192, 11520, 16384};
  uint32_t single = 11520, part = render::kDefaultPosterPart;
  double memory_mb = 1024.0;
  int repeats = 1;
  app.add_option("--out", out, "Results folder (inputs built there once)")->capture_default_str();
  app.add_option("--sizes", sizes, "Poster sides, pixels")
      ->check(CLI::Range(16u, render::kMaxPosterSide))
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--single", single,
                 "The single render's side (11520: the largest square whose frame target with "
                 "the eye-dome lighting's band stays within 2^27 pixels; 0: none)")
      ->check(CLI::Range(0u, 11584u))
      ->capture_default_str();
  app.add_option("--part", part, "Poster parts' largest side")
      ->check(CLI::Range(16u, render::kMaxPosterPart))
      ->capture_default_str();
  app.add_option("--memory-mb", memory_mb, "Poster memory bound, MiB")
      ->check(CLI::Range(16.0, 1e6))
      ->capture_default_str();
  app.add_option("--repeats", repeats, "Rounds (the best time and the largest peak kept)")
      ->check(CLI::Range(1, 20))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    fs::create_directories(fs::path(out) / "inputs");
    const fs::path store_path = fs::path(out) / "inputs" / "bunny-scans.tlod";
    if (!fs::exists(store_path)) {
      lod::BuildOptions b;
      b.quiet = true;
      lod::buildStore({std::string(TESSERA_DATA_DIR) + "/stanford-bunny/scans/bun.conf"},
                      store_path, b);
    }
    auto store = lod::PointStore::open(store_path);
    render::ModelInstance inst{store.get(), render::storeModel(*store)};
    auto ctx = render::GlContext::createHeadless();
    render::RenderOptions o;
    // Every level the pixels ask for: the method measured alone, without the pixel budget.
    o.budget_per_covered_pixel = 0.0;
    o.edl.strength = 1.0f;
    struct Run {
      std::string method;
      uint32_t side;
      double best_s = 1e300, peak_mib = 0.0;
      std::string layout;
      uint64_t bound_bytes = 0;
    };
    std::vector<Run> runs;
    for (uint32_t s : sizes) runs.push_back({"poster", s, 1e300, 0.0, "", 0});
    if (single > 0) runs.push_back({"single", single, 1e300, 0.0, "", 0});
    for (int round = 0; round < repeats; ++round) {
      for (Run& r : runs) {
        const fs::path png = fs::path(out) / (r.method + "-" + std::to_string(r.side) + ".png");
        const render::ViewSetup view = viewOf(*store, r.side, r.side);
        resetPeakResident();
        const auto start = std::chrono::steady_clock::now();
        if (r.method == "poster") {
          const render::PosterPlan plan =
              render::planPoster(r.side, r.side, part, uint64_t(memory_mb * 1048576.0));
          render::PngStripWriter writer(png.string(), r.side, r.side);
          render::renderPoster({&inst, 1}, view, o, plan,
                               [&](std::span<const uint8_t> rgba, uint32_t, uint32_t rows) {
                                 writer.writeRows(rgba, rows);
                               });
          writer.finish();
          r.layout = std::to_string(plan.columns) + "x" + std::to_string(plan.rows);
          r.bound_bytes = plan.peakBytes();
        } else {
          render::ViewRenderer renderer(r.side, r.side);
          const render::Image img = renderer.renderSettled({&inst, 1}, view, o);
          render::writePng(png.string(), img);
          r.layout = "1x1";
        }
        const double seconds = msSince(start) / 1000.0;
        r.best_s = std::min(r.best_s, seconds);
        r.peak_mib = std::max(r.peak_mib, peakResidentMiB());
        std::fprintf(stderr, "%s %u: %.1f s, peak %.0f MiB\n", r.method.c_str(), r.side, seconds,
                     peakResidentMiB());
      }
    }
    // Accuracy: the poster at the single render's size against it.
    std::string accuracy = "";
    if (single > 0 && std::find(sizes.begin(), sizes.end(), single) != sizes.end()) {
      const render::Image a =
          render::readPng((fs::path(out) / ("poster-" + std::to_string(single) + ".png")).string());
      const render::Image b =
          render::readPng((fs::path(out) / ("single-" + std::to_string(single) + ".png")).string());
      size_t differ = 0, visible = 0;
      for (size_t i = 0; i < a.rgba.size(); i += 4) {
        int d = 0;
        for (int c = 0; c < 3; ++c)
          d = std::max(d, std::abs(int(a.rgba[i + c]) - int(b.rgba[i + c])));
        differ += d > 0;
        visible += d > 2;
      }
      std::ostringstream s;
      s << differ << " of " << a.rgba.size() / 4 << " pixels differ, " << visible
        << " by more than 2 levels";
      accuracy = s.str();
      std::fprintf(stderr, "poster %u against the single render: %s\n", single, accuracy.c_str());
    }
    const fs::path csv_path = fs::path(out) / "poster.csv";
    std::ofstream csv(csv_path);
    const std::string header = "method,side,megapixels,parts,seconds,mpx_per_s,peak_mib,bound_mib";
    csv << header << "\n";
    std::cout << header << "\n";
    for (const Run& r : runs) {
      const double mpx = double(r.side) * r.side / 1e6;
      char line[256];
      std::snprintf(line, sizeof line, "%s,%u,%.1f,%s,%.2f,%.2f,%.0f,%.0f", r.method.c_str(),
                    r.side, mpx, r.layout.c_str(), r.best_s, mpx / r.best_s, r.peak_mib,
                    r.bound_bytes / 1048576.0);
      csv << line << "\n";
      std::cout << line << std::endl;
    }
    csv.close();
    const fs::path gp = fs::path(out) / "poster.gp";
    std::ofstream g(gp);
    g << "set terminal pngcairo size 1000,450 font 'sans,10' noenhanced\n"
      << "set output '" << (fs::path(out) / "poster.png").string() << "'\n"
      << "set datafile separator ','\nset multiplot layout 1,2 title \"Posters of the bunny "
         "scans with eye-dome lighting (parts of up to "
      << part << " px, " << memory_mb << " MiB bound; llvmpipe, 2 cores)"
      << (accuracy.empty()
              ? ""
              : "\\n" + std::to_string(single) + " px poster against one render: " + accuracy)
      << "\"\nset grid\nset key top left\nset xlabel 'side, pixels'\nset logscale x 2\nset offsets "
         "graph 0.04, graph 0.04, 0, 0\n"
      << "set xtics (512, 1024, 2048, 4096, 8192, 11520, 16384, 32768)\n"
      << "set ylabel 'megapixels a second'\nset yrange [0:*]\n"
      << "plot '< grep ^poster " << csv_path.string()
      << "' using 2:6 with linespoints pt 7 title 'poster', '< grep ^single " << csv_path.string()
      << "' using 2:6 with points pt 9 ps 2 title 'one render'\n"
      << "set ylabel 'peak resident MiB'\n"
      << "plot '< grep ^poster " << csv_path.string()
      << "' using 2:7 with linespoints pt 7 title 'poster', '< grep ^single " << csv_path.string()
      << "' using 2:7 with points pt 9 ps 2 title 'one render', " << memory_mb
      << " with lines dt 2 title 'poster bound'\nunset multiplot\n";
    g.close();
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + gp.string() + "'").c_str()) != 0)
      std::cerr << "poster: gnuplot failed; the CSV is there\n";
    std::cerr << "reproduce: ./build/dev/bench/poster --out " << out << "\n";
  } catch (const std::exception& e) {
    std::cerr << "poster: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
