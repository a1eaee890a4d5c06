// paraview_peer: Tessera against the peer a user would pick instead: ParaView 5.11's
// pvbatch drawing 1 px OpenGL points, on the same 10^7 and 5x10^7 points uniformly random in the
// unit cube, from the same camera (ParaView's reset camera: the bounding sphere fills the 30
// degree view, looking along (1, -0.8, 0.6)), 1920x1080, on this machine, runs interleaved
// (ParaView, then each Tessera variant, round after round) so load from other work hits both.
//
// Tessera variants, each on a fresh store and renderer every round:
//   full      every leaf (lod-px 1e-9, coverage stop off): the reference picture
//   coverage  the defaults: lod-px 1, the coverage stop (lod_selector.h)
//   budget    the defaults and a point budget per view (--budget, as Potree users set one)
//   pullpush, pullpush-budget   coverage and budget with 1 px points and the pull-push fill
//             (SurfaceFill::kPullPush; the three above draw discs)
// For each: the first picture (store opened cold, every chunk of the cut resident), then the
// frame time (best and median of --frames frames: cut selection, raster, readback), the points
// drawn and the silhouette IoU against the full render. The summary's speed-up is the median
// over rounds of each round's ParaView frame over the variant's (best frames). ParaView: load
// (reader), first render, frame time (a camera nudge and Render() with glFinish, best and median).
// ParaView runs only when pvbatch is on PATH (Debian `paraview`; under xvfb-run without a display);
// otherwise its rows are left out with a message.
//
// Prints CSV; writes OUT/paraview_peer.csv (every run), OUT/paraview_peer_summary.csv (medians
// over rounds) and OUT/paraview_peer.png (gnuplot). Inputs are generated once into OUT/inputs:
// the points as binary PLY (built into cube-N.tlod, then removed) and as legacy VTK for ParaView.
#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <numbers>
#include <random>
#include <sstream>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/stopwatch.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/view_renderer.h>

#include "bench_views.h"

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// `n` points uniformly random in [0, 1]^3, the same for a given n every run.
lod::PointBatch cubePoints(uint64_t n) {
  lod::PointBatch b;
  b.reset(0);
  b.positions.resize(n);
  std::mt19937_64 rng(n);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (glm::dvec3& p : b.positions) p = {u(rng), u(rng), u(rng)};
  return b;
}

/// Legacy VTK polydata (binary, big-endian): the points as float and one poly-vertex cell.
void writeVtk(const fs::path& path, const lod::PointBatch& b) {
  std::ofstream f(path, std::ios::binary);
  const uint64_t n = b.positions.size();
  f << "# vtk DataFile Version 3.0\ntessera random cube\nBINARY\nDATASET POLYDATA\nPOINTS " << n
    << " float\n";
  auto put = [&](uint32_t v) {
    v = __builtin_bswap32(v);
    f.write(reinterpret_cast<const char*>(&v), 4);
  };
  for (const glm::dvec3& p : b.positions)
    for (int c = 0; c < 3; ++c) put(std::bit_cast<uint32_t>(float(p[c])));
  f << "\nVERTICES 1 " << n + 1 << "\n";
  put(uint32_t(n));
  for (uint64_t i = 0; i < n; ++i) put(uint32_t(i));
  f << "\n";
  if (!f) throw std::runtime_error("paraview_peer: cannot write " + path.string());
}

struct Inputs {
  fs::path store, vtk;
};

Inputs cubeInputs(const fs::path& dir, uint64_t n) {
  fs::create_directories(dir);
  const std::string tag = "cube-" + std::to_string(n);
  Inputs in{dir / (tag + ".tlod"), dir / (tag + ".vtk")};
  if (fs::exists(in.store) && fs::exists(in.vtk)) return in;
  std::fprintf(stderr, "paraview_peer: generating %llu points...\n", (unsigned long long)n);
  const lod::PointBatch b = cubePoints(n);
  writeVtk(in.vtk, b);
  const fs::path ply = dir / (tag + ".ply");
  lod::writePly(ply, b, glm::dvec3(0.0));
  lod::BuildOptions o;
  o.quiet = true;
  const auto t = Clock::now();
  lod::buildStore({ply}, in.store, o);
  std::fprintf(stderr, "paraview_peer: built %s in %.1f s\n", in.store.c_str(),
               msSince(t) / 1000.0);
  fs::remove(ply);
  return in;
}

bool covered(const uint8_t* p) {
  return p[0] > 16 || p[1] > 16 || p[2] > 16;
}

double silhouetteIou(const render::Image& a, const render::Image& b) {
  size_t both = 0, either = 0;
  for (size_t i = 0; i + 3 < a.rgba.size() && i + 3 < b.rgba.size(); i += 4) {
    const bool pa = covered(&a.rgba[i]), pb = covered(&b.rgba[i]);
    both += pa && pb;
    either += pa || pb;
  }
  return either ? double(both) / double(either) : 1.0;
}

size_t coveredPixels(const render::Image& a) {
  size_t n = 0;
  for (size_t i = 0; i + 3 < a.rgba.size(); i += 4) n += covered(&a.rgba[i]);
  return n;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  if (v.empty()) return 0.0;
  const size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

struct Run {
  uint64_t points = 0;  ///< drawn
  double first_s = 0, load_s = 0, best_ms = 0, median_ms = 0;
  double iou = 1.0;
  render::Image image;
};

Run runTessera(const fs::path& store_path, const render::ViewSetup& view,
               const render::RenderOptions& options, int frames) {
  Run run;
  const auto t = Clock::now();
  auto store = lod::PointStore::open(store_path, 2ull << 30);
  render::ModelInstance inst{store.get(), render::storeModel(*store)};
  render::StreamerOptions so;
  so.budget_bytes = 16ull << 30;
  render::ViewRenderer r(view.width, view.height, nullptr, so);
  render::RenderStats st;
  run.image = r.renderSettled({&inst, 1}, view, options, &st);
  run.first_s = msSince(t) / 1000.0;
  std::vector<double> ms;
  for (int i = 0; i < frames; ++i) {
    const auto f = Clock::now();
    run.image = r.render({&inst, 1}, view, options, &st);
    ms.push_back(msSince(f));
  }
  run.points = st.points;
  run.best_ms = *std::min_element(ms.begin(), ms.end());
  run.median_ms = median(ms);
  return run;
}

constexpr const char* kPvScript =
    R"(# pvbatch script written by bench/paraview_peer: 1 px points of a
# legacy VTK file, one camera; prints PVRESULT,load_s,first_s,best_ms,median_ms,points
import sys, time
t0 = time.time()
from paraview.simple import *
vtk, png = sys.argv[1], sys.argv[2]
e, t, u = [float(x) for x in sys.argv[3:6]], [float(x) for x in sys.argv[6:9]], [float(x) for x in sys.argv[9:12]]
fovy, w, h, frames = float(sys.argv[12]), int(sys.argv[13]), int(sys.argv[14]), int(sys.argv[15])
reader = LegacyVTKReader(FileNames=[vtk])
reader.UpdatePipeline()
t_load = time.time()
view = CreateView('RenderView')
view.ViewSize = [w, h]
view.OrientationAxesVisibility = 0
try:
    view.UseColorPaletteForBackground = 0
except AttributeError:
    pass
view.Background = [0, 0, 0]
d = Show(reader, view)
d.SetRepresentationType('Points')
d.ColorArrayName = ['POINTS', '']
d.PointSize = 1
d.AmbientColor = [200 / 255.0] * 3
d.DiffuseColor = [200 / 255.0] * 3
d.Ambient = 1.0
d.Diffuse = 0.0
view.CameraPosition, view.CameraFocalPoint, view.CameraViewUp = e, t, u
view.CameraViewAngle = fovy
rw = view.GetRenderWindow()
Render(view)
rw.WaitForCompletion()
t_first = time.time()
ms = []
cam = GetActiveCamera()
for i in range(frames):
    f = time.time()
    cam.Azimuth(1e-3 if i % 2 == 0 else -1e-3)
    Render(view)
    rw.WaitForCompletion()
    ms.append((time.time() - f) * 1000.0)
view.CameraPosition, view.CameraFocalPoint, view.CameraViewUp = e, t, u
SaveScreenshot(png, view, ImageResolution=[w, h])
ms.sort()
n = reader.GetDataInformation().GetNumberOfPoints()
print('PVRESULT,%.3f,%.3f,%.1f,%.1f,%d' % (t_load - t0, t_first - t0, ms[0], ms[len(ms) // 2], n))
)";

bool onPath(const std::string& tool) {
  return std::system(("command -v " + tool + " > /dev/null 2>&1").c_str()) == 0;
}

/// One pvbatch process; false (with a message) if it failed.
bool runParaView(const fs::path& out, const fs::path& vtk, const bench::CubeCamera& c, uint32_t w,
                 uint32_t h, int frames, Run& run) {
  const fs::path script = out / "paraview_peer.py";
  std::ofstream(script) << kPvScript;
  const fs::path png = out / "paraview_peer-paraview.png";
  const fs::path log = out / "paraview_peer-pvbatch.log";
  std::ostringstream cmd;
  if (!std::getenv("DISPLAY")) cmd << "xvfb-run -a -s '-screen 0 " << w << "x" << h << "x24' ";
  cmd << "pvbatch '" << script.string() << "' '" << vtk.string() << "' '" << png.string() << "'";
  for (const glm::dvec3& v : {c.eye, c.target, c.up}) cmd << " " << v.x << " " << v.y << " " << v.z;
  cmd << " " << c.fovy << " " << w << " " << h << " " << frames << " > '" << log.string()
      << "' 2>&1";
  // xvfb-run sometimes hands over its display before the server accepts connections: retry.
  int rc = 0;
  for (int attempt = 1; attempt <= 3; ++attempt) {
    const auto t = Clock::now();
    rc = std::system(cmd.str().c_str());
    const double wall = msSince(t) / 1000.0;
    std::ifstream in(log);
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("PVRESULT,", 0) != 0) continue;
      unsigned long long n = 0;
      if (std::sscanf(line.c_str(), "PVRESULT,%lf,%lf,%lf,%lf,%llu", &run.load_s, &run.first_s,
                      &run.best_ms, &run.median_ms, &n) == 5) {
        run.points = n;
        run.image = render::readPng(png.string());
        std::fprintf(stderr, "paraview_peer: pvbatch took %.1f s in all\n", wall);
        return true;
      }
    }
  }
  std::fprintf(stderr, "paraview_peer: pvbatch failed (exit %d); see %s\n", rc, log.c_str());
  return false;
}

void chart(const fs::path& out) {
  const fs::path gp = out / "paraview_peer.gp";
  std::ofstream g(gp);
  g << "set terminal pngcairo size 1100,480 font 'sans,10' noenhanced\n"
    << "set output '" << (out / "paraview_peer.png").string() << "'\n"
    << "set datafile separator ','\nset multiplot layout 1,2\n"
    << "set title 'Frame time, random points in a cube, 1920x1080 (llvmpipe, 2 cores)'\n"
    << "set style data histograms\nset style histogram clustered gap 1\n"
    << "set style fill solid 0.85 border -1\nset logscale y\nset ylabel 'ms per frame (log)'\n"
    << "set grid ytics\nset key top left\nset yrange [10:1e6]\n"
    << "plot '" << (out / "paraview_peer_chart.csv").string()
    << "' using 2:xtic(1) title 'ParaView 5.11, 1 px points', '' using 3 title 'Tessera, every "
       "leaf', '' using 4 title 'Tessera, coverage stop (default)', '' using 5 title 'Tessera, "
       "coverage stop + point budget', '' using 9 title 'Tessera, coverage stop, pull-push fill', "
       "'' using 10 title 'Tessera, pull-push fill + budget'\n"
    << "set title 'Points drawn per frame'\nset ylabel 'points (log)'\nset yrange [1e5:1e9]\n"
    << "plot '" << (out / "paraview_peer_chart.csv").string()
    << "' using 6:xtic(1) title 'ParaView and Tessera every leaf', '' using 7 title 'Tessera, "
       "coverage stop', '' using 8 title 'Tessera, coverage stop + budget'\n"
    << "unset multiplot\n";
  g.close();
  const std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp.string() + "'";
  if (std::system(cmd.c_str()) != 0)
    std::fprintf(stderr, "paraview_peer: gnuplot failed; the CSV is complete\n");
}

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  CLI::App app{"paraview_peer: Tessera against ParaView pvbatch on random points in a cube"};
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  std::vector<uint64_t> sizes{10'000'000, 50'000'000};
  int rounds = 3, frames = 3;
  uint64_t budget = 1'000'000;
  bool no_paraview = false;
  app.add_option("--out", out, "Folder for inputs, CSV and chart")->capture_default_str();
  app.add_option("--points", sizes, "Cube sizes (points)")->capture_default_str();
  app.add_option("--rounds", rounds, "Interleaved rounds (medians kept)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--frames", frames, "Timed frames per run")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--budget", budget, "Point budget of the budget variant")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_flag("--no-paraview", no_paraview, "Leave ParaView out even when pvbatch is on PATH");
  CLI11_PARSE(app, argc, argv);
  try {
    const fs::path dir(out);
    fs::create_directories(dir);
    const bool paraview =
        !no_paraview && onPath("pvbatch") && (std::getenv("DISPLAY") || onPath("xvfb-run"));
    if (!paraview)
      std::fprintf(stderr,
                   "paraview_peer: pvbatch (Debian package paraview; xvfb-run without a display) "
                   "not found or --no-paraview: measuring Tessera alone\n");
    const uint32_t w = 1920, h = 1080;
    const bench::CubeCamera cam = bench::cubeCamera();
    const render::ViewSetup view = bench::cubeView(cam, w, h);
    auto ctx = render::GlContext::createHeadless();
    render::RenderOptions full;
    full.lod_pixels = 1e-9;
    full.coverage_stop = false;
    full.fill = render::SurfaceFill::kDiscs;  // the reference picture: discs as before
    render::RenderOptions coverage;
    coverage.fill = render::SurfaceFill::kDiscs;
    render::RenderOptions budgeted = coverage;
    budgeted.point_budget = budget;
    render::RenderOptions pullpush = coverage;
    pullpush.fill = render::SurfaceFill::kPullPush;
    render::RenderOptions pullpush_budget = pullpush;
    pullpush_budget.point_budget = budget;
    const std::array<std::pair<const char*, render::RenderOptions>, 5> variants{
        {{"full", full},
         {"coverage", coverage},
         {"budget", budgeted},
         {"pullpush", pullpush},
         {"pullpush-budget", pullpush_budget}}};

    std::ofstream csv(dir / "paraview_peer.csv");
    const std::string header =
        "points,round,renderer,variant,points_drawn,covered_px,load_s,first_picture_s,"
        "frame_best_ms,frame_median_ms,iou_vs_full";
    csv << header << "\n";
    std::cout << header << "\n";
    // (points, variant) -> per-round best frame ms, points drawn, IoU.
    std::map<std::pair<uint64_t, std::string>, std::vector<std::array<double, 3>>> all;
    auto row = [&](uint64_t n, int round, const char* who, const std::string& variant,
                   const Run& r) {
      char line[512];
      std::snprintf(line, sizeof line, "%llu,%d,%s,%s,%llu,%zu,%.3f,%.3f,%.1f,%.1f,%.4f",
                    (unsigned long long)n, round, who, variant.c_str(),
                    (unsigned long long)r.points, coveredPixels(r.image), r.load_s, r.first_s,
                    r.best_ms, r.median_ms, r.iou);
      csv << line << "\n";
      std::cout << line << std::endl;
      all[{n, variant}].push_back({r.best_ms, double(r.points), r.iou});
    };
    for (uint64_t n : sizes) {
      const Inputs in = cubeInputs(dir / "inputs", n);
      for (int round = 1; round <= rounds; ++round) {
        Run pv;
        const bool pv_ok = paraview && runParaView(dir, in.vtk, cam, w, h, frames, pv);
        Run reference;
        for (const auto& [name, options] : variants) {
          Run r = runTessera(in.store, view, options, frames);
          if (std::string(name) == "full") reference = r;
          r.iou = silhouetteIou(r.image, reference.image);
          row(n, round, "tessera", name, r);
          if (round == 1)
            render::writePng(
                (dir / ("paraview_peer-" + std::to_string(n) + "-" + name + ".png")).string(),
                r.image);
        }
        if (pv_ok) {
          pv.iou = silhouetteIou(pv.image, reference.image);
          row(n, round, "paraview", "paraview", pv);
        }
      }
    }
    csv.close();

    // Medians over rounds, the speed-ups against ParaView, and the chart's table.
    std::ofstream sum(dir / "paraview_peer_summary.csv");
    std::ofstream tab(dir / "paraview_peer_chart.csv");
    sum << "points,variant,points_drawn,frame_ms,iou_vs_full,speedup_vs_paraview\n";
    std::cout << "\npoints,variant,points_drawn,frame_ms,iou_vs_full,speedup_vs_paraview\n";
    for (uint64_t n : sizes) {
      auto med = [&](const std::string& v, int i) {
        std::vector<double> x;
        for (const auto& r : all[{n, v}]) x.push_back(r[size_t(i)]);
        return median(x);
      };
      const double pv_ms = med("paraview", 0);
      // The speed-up of each round's interleaved pair, then their median: the machine's load
      // changes between rounds, less within one.
      auto speedup = [&](const std::string& v) {
        const auto& pv = all[{n, "paraview"}];
        const auto& t = all[{n, v}];
        std::vector<double> x;
        for (size_t i = 0; i < pv.size() && i < t.size(); ++i) x.push_back(pv[i][0] / t[i][0]);
        return median(x);
      };
      for (const char* v :
           {"paraview", "full", "coverage", "budget", "pullpush", "pullpush-budget"}) {
        if (all[{n, v}].empty()) continue;
        char line[256];
        std::snprintf(line, sizeof line, "%llu,%s,%.0f,%.1f,%.4f,%.2f", (unsigned long long)n, v,
                      med(v, 1), med(v, 0), med(v, 2), speedup(v));
        sum << line << "\n";
        std::cout << line << "\n";
      }
      char line[256];
      std::snprintf(line, sizeof line, "%.0fx10^6,%.1f,%.1f,%.1f,%.1f,%.0f,%.0f,%.0f,%.1f,%.1f",
                    double(n) / 1e6, pv_ms > 0 ? pv_ms : 1e-9, med("full", 0), med("coverage", 0),
                    med("budget", 0), med("full", 1), med("coverage", 1), med("budget", 1),
                    med("pullpush", 0), med("pullpush-budget", 0));
      tab << line << "\n";
    }
    sum.close();
    tab.close();
    chart(dir);
    std::fprintf(stderr, "paraview_peer: wrote %s/paraview_peer.csv, _summary.csv, .png\n",
                 out.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "paraview_peer: %s\n", e.what());
    return 1;
  }
}
