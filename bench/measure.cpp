// Measuring, speed against accuracy, each against its baseline in one process:
//  - pick latency: the full-resolution pick (interact/surface_pick.h, down to the leaves) against
//    the view-level pick the navigation uses (interact/point_pick.h), on the Autzen LiDAR built
//    with exact leaves, over random rays looking down at the ground; also how far each lands
//    from the real input point nearest the ray (the accuracy the refinement buys);
//  - area: time and error of surfaceArea() against its refinement levels on a spherical cap (48
//    great-circle arcs, the reference Girard's spherical excess), analytic and through a point
//    store of the sphere, against the baseline of the loop's flat minimum-area triangulation.
// Writes DIR/measure_pick.csv, DIR/measure_area.csv and DIR/measure.png.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <string>

#include <CLI/CLI.hpp>

#include <tessera/core/stopwatch.h>
#include <tessera/core/cli.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/annotate/measurement.h>
#include <tessera/interact/point_pick.h>
#include <tessera/interact/surface_pick.h>

#include "bench_stats.h"

namespace fs = std::filesystem;
using namespace tessera;
using Clock = std::chrono::steady_clock;

namespace {

std::vector<glm::dvec3> latitudeLoop(double polar, int n) {
  std::vector<glm::dvec3> loop;
  for (int i = 0; i < n; ++i) {
    const double phi = 2.0 * M_PI * i / n;
    loop.push_back({std::sin(polar) * std::cos(phi), std::sin(polar) * std::sin(phi),
                    std::cos(polar)});
  }
  return loop;
}

/// Girard: the area of the unit-sphere polygon bounded by great-circle arcs through `loop`.
double sphericalArea(const std::vector<glm::dvec3>& loop) {
  const size_t n = loop.size();
  double sum = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const glm::dvec3 v = loop[i], a = loop[(i + n - 1) % n], b = loop[(i + 1) % n];
    const glm::dvec3 ta = glm::normalize(a - v * glm::dot(a, v)),
                     tb = glm::normalize(b - v * glm::dot(b, v));
    sum += std::acos(std::clamp(glm::dot(ta, tb), -1.0, 1.0));
  }
  return sum - double(n - 2) * M_PI;
}

int run(int argc, char** argv) {
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  int rays = 200;
  CLI::App app{"bench/measure: full-resolution picks against the view-level pick, and surface "
               "area against its refinement levels"};
  app.add_option("--out", out, "Output folder")->capture_default_str();
  app.add_option("--rays", rays, "Random picks")->check(CLI::Range(10, 100000));
  if (auto code = cli::parse(app, argc, argv, "measure")) return *code;
  const fs::path res(out);
  fs::create_directories(res / "measure-inputs");

  // ---- picks on the Autzen LiDAR
  const fs::path las = fs::path(TESSERA_DATA_DIR) / "lidar/autzen_trim.las";
  const fs::path store_path = res / "measure-inputs/autzen-exact.tlod";
  lod::BuildOptions bo;
  bo.quiet = true;
  bo.leaf_max = 4096;
  bo.exact_leaves = true;
  lod::buildStore({las}, store_path, bo);
  auto store = lod::PointStore::open(store_path);
  render::ModelInstance m;
  m.store = store.get();
  m.model = render::storeModel(*store);
  std::vector<glm::dvec3> input;
  {
    auto reader = lod::openPointReader(las);
    lod::PointBatch b;
    while (reader->next(b))
      for (const glm::dvec3& p : b.positions) input.push_back(reader->info().origin + p);
  }
  std::mt19937 rng(17);
  interact::PickOptions po;
  po.pixel_angle = 0.5e-3;  // about a 1920-pixel-wide wall tile seen at 60 degrees
  std::vector<double> full_ms, view_ms, full_err, view_err;
  // Warm the caches once (pages and chunks), then time.
  for (int pass = 0; pass < 2; ++pass) {
    for (int i = 0; i < rays; ++i) {
      const glm::dvec3 target = input[rng() % input.size()];
      const glm::dvec3 eye = target + glm::dvec3(20.0, -35.0, 300.0);
      const glm::dvec3 dir = glm::normalize(target - eye);
      auto t0 = Clock::now();
      const auto full = interact::pickSurface(std::span(&m, 1), eye, dir, po);
      const double f_ms = msSince(t0);
      t0 = Clock::now();
      const auto coarse = interact::pickPoint(std::span(&m, 1), eye, dir, po);
      const double v_ms = msSince(t0);
      if (pass == 0 || !full || !coarse) continue;
      full_ms.push_back(f_ms);
      view_ms.push_back(v_ms);
      // The error: distance to the input point nearest to the ray's hit region (the sample a
      // user pointed at is the input's, not a subsample's).
      auto nearest = [&](const glm::dvec3& p) {
        double best = 1e300;
        for (const glm::dvec3& q : input) best = std::min(best, glm::length(q - p));
        return best;
      };
      full_err.push_back(nearest(full->point.world));
      view_err.push_back(nearest(*coarse));
    }
  }
  {
    std::ofstream csv(res / "measure_pick.csv");
    csv << "method,median_ms,p99_ms,median_error_ft,p99_error_ft\n";
    auto row = [&](const char* name, const std::vector<double>& t, const std::vector<double>& e) {
      csv << name << "," << bench::percentile(t, 0.5) << "," << bench::percentile(t, 0.99) << ","
          << bench::percentile(e, 0.5) << "," << bench::percentile(e, 0.99) << "\n";
      std::printf("pick %-28s median %.3f ms, p99 %.3f ms; to the nearest input point: median "
                  "%.4f ft, p99 %.4f ft\n",
                  name, bench::percentile(t, 0.5), bench::percentile(t, 0.99),
                  bench::percentile(e, 0.5), bench::percentile(e, 0.99));
    };
    row("full-resolution (leaves)", full_ms, full_err);
    row("view-level (baseline)", view_ms, view_err);
  }

  // ---- area of a spherical cap
  const std::vector<glm::dvec3> loop = latitudeLoop(M_PI / 4, 48);
  const double reference = sphericalArea(loop);
  lod::PointBatch sphere;
  sphere.reset(0);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int i = 0; i < 400000; ++i)
    sphere.positions.push_back(glm::normalize(glm::dvec3(g(rng), g(rng), g(rng))));
  lod::writePly(res / "measure-inputs/sphere.ply", sphere, glm::dvec3(0.0));
  lod::BuildOptions so;
  so.quiet = true;
  lod::buildStore({res / "measure-inputs/sphere.ply"}, res / "measure-inputs/sphere.tlod", so);
  auto sphere_store = lod::PointStore::open(res / "measure-inputs/sphere.tlod");
  render::ModelInstance sm;
  sm.store = sphere_store.get();
  const annotate::SurfaceProjector analytic = [](const glm::dvec3& p) -> std::optional<glm::dvec3> {
    return glm::normalize(p);
  };
  const annotate::SurfaceProjector scanned = interact::pointSurfaceProjector(sm);
  std::vector<annotate::SurfacePoint> picks;
  for (const glm::dvec3& p : loop) picks.push_back({p, 0.0});
  std::ofstream csv(res / "measure_area.csv");
  csv << "surface,levels,triangles,ms,relative_error,relative_bound\n";
  for (const auto& [name, projector] :
       {std::pair{"analytic", &analytic}, std::pair{"point store", &scanned}}) {
    for (int levels = 0; levels <= 6; ++levels) {
      annotate::AreaOptions o;
      o.max_levels = levels;
      o.relative_tolerance = 0.0;  // exactly `levels` refinements
      o.max_triangles = size_t(1) << 20;
      const auto t0 = Clock::now();
      const annotate::AreaMeasurement a = annotate::surfaceArea(picks, *projector, o);
      const double ms = msSince(t0);
      const double err = std::abs(a.value - reference) / reference;
      csv << name << "," << a.levels << "," << a.triangles.size() << "," << ms << "," << err
          << "," << a.uncertainty / reference << "\n";
      std::printf("area %-12s levels %d: %7zu triangles %9.2f ms, error %.2e (bound %.2e)%s\n",
                  name, a.levels, a.triangles.size(), ms, err, a.uncertainty / reference,
                  levels == 0 ? "  <- flat minimum-area triangulation (baseline)" : "");
    }
  }
  csv.close();

  std::ofstream gp(res / "measure.gp");
  gp << "set terminal pngcairo size 1400,520 font ',11'\nset output '" << (res / "measure.png").string()
     << "'\nset datafile separator ','\nset multiplot layout 1,2\nset grid\nset format xy '%g'\n"
     << "set title 'Pick on the Autzen LiDAR (" << rays << " rays, exact leaves)'\n"
     << "set style data histograms\nset style fill solid 0.7\nset ylabel 'milliseconds / feet'\n"
     << "set logscale y\nset key top left\n"
     << "plot '" << (res / "measure_pick.csv").string()
     << "' every ::1 using 2:xtic(1) title 'median time (ms)', '' every ::1 using 4 title "
        "'median distance to the nearest input point (ft)'\n"
     << "unset style\nset style data linespoints\n"
     << "set title 'Area of a spherical cap (48 arcs) against refinement'\n"
     << "set xlabel 'milliseconds'\nset ylabel 'relative error'\nset logscale xy\nset key "
        "bottom left\n"
     << "plot '" << (res / "measure_area.csv").string()
     << "' every ::1::7 using 4:5 title 'analytic surface: error' lw 2, '' every ::1::7 using "
        "4:6 title 'analytic: stated bound' dt 2, '' every ::8 using 4:5 title 'point store: "
        "error' lw 2, '' every ::8 using 4:6 title 'point store: stated bound' dt 2\n"
     << "unset multiplot\n";
  gp.close();
  std::string gnuplot = TESSERA_GNUPLOT;
  if (gnuplot.empty()) gnuplot = "gnuplot";
  if (std::system(("'" + gnuplot + "' '" + (res / "measure.gp").string() + "'").c_str()))
    std::cerr << "measure: gnuplot failed; the CSVs are still there\n";
  std::printf("wrote %s\n", (res / "measure.png").string().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cli::runMain("measure", [&] { return run(argc, argv); }); }
