// scale: what a user waits for on stores of growing size (10^7, 10^8, 10^9 points of tiled real
// LiDAR, bench/scale.sh), every store in one process, each figure from a freshly opened store
// (its chunk cache empty; the OS page cache as the machine has it):
//  - open: the header and the root hierarchy page;
//  - first picture: open to the first image with points in it (coarse levels stand in);
//  - settled: open to the image whose whole cut is resident, at the defaults a user gets but
//    without the pixel budget (--points-per-pixel 0: every level the pixels ask for, the
//    cut's own growth with the store, which the budget would hide);
//  - frame: one more frame with everything resident, so, and with a budget of 10^6 points;
//  - lasso: a freehand-like lasso (THROUGH) over the middle half of the view, on a fresh store;
//  - measure: a distance between two full-resolution picks (down to the leaves, the cone of a
//    console click: pickUnderPixel's angle a pixel) on a fresh store.
// The view: the whole store seen from ParaView's reset direction at 1920x1080 (bench_views.h).
// --drop-caches drops the OS page cache before each of the three (root only): cold from the
// disk.
// --rounds R measures every store R times, round after round (the stores interleaved, so load
// from other work hits each alike), and reports each figure's median over the rounds.
// Prints CSV; writes OUT/scale_store.csv (medians), OUT/scale_store_rounds.csv (every round) and
// OUT/scale-LABEL.png (the settled picture).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

#include <CLI/CLI.hpp>

#include <tessera/annotate/lasso_selection.h>
#include <tessera/core/stopwatch.h>
#include <tessera/interact/surface_pick.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/image.h>
#include <tessera/render/view_renderer.h>

#include "bench_views.h"

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Row {
  std::string label;
  uint64_t points = 0, file_bytes = 0;
  double open_ms = 0, first_ms = 0, settle_ms = 0, frame_ms = 0, budget_frame_ms = 0;
  uint64_t first_points = 0, settled_points = 0, budget_points = 0;
  size_t settle_frames = 0;
  double lasso_ms = 0;
  uint64_t lasso_selected = 0, lasso_tested = 0;
  double measure_ms = 0, distance_m = 0, uncertainty_m = 0;
};

/// The whole store as ParaView's reset camera frames a box (bench_views.h).
render::ViewSetup storeView(const lod::PointStore& store) {
  const lod::StoreSummary& s = store.summary();
  return bench::cubeView(bench::boxCamera(s.origin + s.bbox_min, s.origin + s.bbox_max));
}

/// The ray from the view's eye through pixel (x, y), y down.
std::pair<glm::dvec3, glm::dvec3> pixelRay(const render::ViewSetup& v, double x, double y) {
  const glm::dmat4 inv = glm::inverse(glm::dmat4(v.projection) * glm::dmat4(v.view));
  const glm::dvec2 ndc(2.0 * x / v.width - 1.0, 1.0 - 2.0 * y / v.height);
  glm::dvec4 a = inv * glm::dvec4(ndc, -1.0, 1.0), b = inv * glm::dvec4(ndc, 1.0, 1.0);
  a /= a.w;
  b /= b.w;
  return {glm::dvec3(a), glm::normalize(glm::dvec3(b - a))};
}

/// Writes the page cache's dirty pages out and drops it (root only): the next reads come from
/// the disk.
void dropPageCache() {
  ::sync();
  std::ofstream f("/proc/sys/vm/drop_caches");
  f << "3\n";
  f.flush();
  if (!f)
    throw std::runtime_error("--drop-caches: cannot write /proc/sys/vm/drop_caches (needs root)");
}

/// `drop`: the OS page cache is dropped before the view's figures, the lasso and the measurement,
/// so each reads the store from the disk.
Row measureStore(const std::string& label, const fs::path& path, const fs::path& out, bool drop) {
  Row row;
  row.label = label;
  render::RenderOptions defaults;
  defaults.budget_per_covered_pixel = 0.0;
  render::StreamerOptions so;
  so.budget_bytes = 8ull << 30;
  {
    if (drop) dropPageCache();
    render::ViewRenderer renderer(1920, 1080, nullptr, so);
    const auto t0 = Clock::now();
    auto store = lod::PointStore::open(path);
    row.open_ms = msSince(t0);
    row.points = store->summary().points;
    row.file_bytes = store->summary().file_bytes;
    const render::ViewSetup view = storeView(*store);
    render::ModelInstance inst{store.get(), render::storeModel(*store)};
    render::RenderStats st;
    for (int i = 0; i < 100000 && st.points == 0; ++i)
      renderer.render({&inst, 1}, view, defaults, &st);
    row.first_ms = msSince(t0);
    row.first_points = st.points;
    const render::Image settled = renderer.renderSettled({&inst, 1}, view, defaults, &st);
    row.settle_ms = msSince(t0);
    row.settle_frames = st.frames;
    row.settled_points = st.points;
    render::writePng((out / ("scale-" + label + ".png")).string(), settled);
    auto t = Clock::now();
    renderer.render({&inst, 1}, view, defaults, &st);
    row.frame_ms = msSince(t);
    render::RenderOptions budget = defaults;
    budget.point_budget = 1'000'000;
    renderer.renderSettled({&inst, 1}, view, budget, &st);
    t = Clock::now();
    renderer.render({&inst, 1}, view, budget, &st);
    row.budget_frame_ms = msSince(t);
    row.budget_points = st.points;
  }
  {
    if (drop) dropPageCache();
    auto store = lod::PointStore::open(path);
    const render::ViewSetup view = storeView(*store);
    annotate::LassoView lv{glm::dmat4(view.view), glm::dmat4(view.projection),
                           glm::uvec2(view.width, view.height)};
    std::vector<glm::dvec2> vertices;
    for (int i = 0; i < 240; ++i) {
      const double a = 2.0 * M_PI * i / 240.0;
      const double r = 1.0 + 0.25 * std::sin(7.0 * a);
      vertices.push_back(
          glm::dvec2(960.0 + 480.0 * r * std::cos(a), 540.0 + 270.0 * r * std::sin(a)));
    }
    const auto t = Clock::now();
    const annotate::LassoResult r =
        annotate::lassoPoints(*store, lv, annotate::LassoPolygon(vertices));
    row.lasso_ms = msSince(t);
    row.lasso_selected = r.selection.count();
    row.lasso_tested = r.stats.elements_tested;
  }
  {
    if (drop) dropPageCache();
    auto store = lod::PointStore::open(path);
    const render::ViewSetup view = storeView(*store);
    render::ModelInstance inst{store.get(), render::storeModel(*store)};
    // The cone a console click searches (pickUnderPixel).
    const interact::PickOptions pick = interact::pickOptionsFor(view);
    const auto t = Clock::now();
    std::optional<interact::SurfacePick> a, b;
    // Two pixels on the ground left and right of the middle; further along the row where a ray
    // finds nothing (the edge of the tiling).
    for (double dx = 0; dx < 400 && !(a && b); dx += 40) {
      const auto [oa, da] = pixelRay(view, 640.0 + dx, 600.0);
      const auto [ob, db] = pixelRay(view, 1280.0 - dx, 600.0);
      if (!a) a = interact::pickSurface({&inst, 1}, oa, da, pick);
      if (!b) b = interact::pickSurface({&inst, 1}, ob, db, pick);
    }
    row.measure_ms = msSince(t);
    if (a && b) {
      row.distance_m = glm::length(a->point.world - b->point.world);
      row.uncertainty_m = a->point.uncertainty + b->point.uncertainty;
    }
  }
  return row;
}

/// One CSV line of `r`.
std::string csvLine(const Row& r) {
  char line[768];
  std::snprintf(line, sizeof line,
                "%s,%llu,%llu,%.1f,%.1f,%llu,%.1f,%zu,%llu,%.1f,%.1f,%llu,%.1f,%llu,%llu,%.1f,"
                "%.4f,%.4f",
                r.label.c_str(), (unsigned long long)r.points, (unsigned long long)r.file_bytes,
                r.open_ms, r.first_ms, (unsigned long long)r.first_points, r.settle_ms,
                r.settle_frames, (unsigned long long)r.settled_points, r.frame_ms,
                r.budget_frame_ms, (unsigned long long)r.budget_points, r.lasso_ms,
                (unsigned long long)r.lasso_tested, (unsigned long long)r.lasso_selected,
                r.measure_ms, r.distance_m, r.uncertainty_m);
  return line;
}

/// The first round's row with every time (and the first picture's points, which depend on
/// timing) replaced by its median over `rounds`.
Row medianRow(const std::vector<Row>& rounds) {
  Row m = rounds.front();
  auto median = [&](auto field) {
    std::vector<double> v;
    for (const Row& r : rounds) v.push_back(double(r.*field));
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  };
  m.open_ms = median(&Row::open_ms);
  m.first_ms = median(&Row::first_ms);
  m.first_points = uint64_t(median(&Row::first_points));
  m.settle_ms = median(&Row::settle_ms);
  m.frame_ms = median(&Row::frame_ms);
  m.budget_frame_ms = median(&Row::budget_frame_ms);
  m.lasso_ms = median(&Row::lasso_ms);
  m.measure_ms = median(&Row::measure_ms);
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "scale: open, first picture, settled view, frames, lasso and a full-resolution "
      "measurement on stores of growing size (bench/scale.sh runs it)"};
  std::vector<std::string> stores;
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  int rounds = 5;
  bool drop = false;
  app.add_option("stores", stores, "LABEL=PATH.tlod, one per store")->required();
  app.add_option("--out", out, "Folder for scale_store.csv and the pictures")
      ->capture_default_str();
  app.add_option("--rounds", rounds, "Rounds over every store (each figure's median is kept)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_flag("--drop-caches", drop,
               "Drop the OS page cache before the view, the lasso and the measurement (root): "
               "cold from the disk, not only from a fresh store");
  CLI11_PARSE(app, argc, argv);
  try {
    std::vector<std::pair<std::string, fs::path>> specs;
    for (const std::string& spec : stores) {
      const size_t eq = spec.find('=');
      if (eq == std::string::npos || eq == 0 || eq + 1 == spec.size())
        throw std::runtime_error("a store is LABEL=PATH, got '" + spec + "'");
      specs.emplace_back(spec.substr(0, eq), spec.substr(eq + 1));
    }
    fs::create_directories(out);
    auto ctx = render::GlContext::createHeadless();
    const std::string header =
        "label,points,file_bytes,open_ms,first_ms,first_points,settle_ms,settle_frames,"
        "settled_points,frame_ms,budget_frame_ms,budget_points,lasso_ms,lasso_tested,"
        "lasso_selected,measure_ms,distance_m,uncertainty_m";
    std::ofstream every(fs::path(out) / "scale_store_rounds.csv");
    every << "round," << header << "\n";
    std::map<std::string, std::vector<Row>> rows;
    for (int round = 1; round <= rounds; ++round) {
      for (const auto& [label, path] : specs) {
        const Row r = measureStore(label, path, out, drop);
        every << round << "," << csvLine(r) << "\n";
        every.flush();
        std::fprintf(stderr, "scale: round %d of %d, %s: %s\n", round, rounds, label.c_str(),
                     csvLine(r).c_str());
        rows[label].push_back(r);
      }
    }
    std::ofstream csv(fs::path(out) / "scale_store.csv");
    csv << header << "\n";
    std::cout << header << std::endl;
    for (const auto& [label, path] : specs) {
      const std::string line = csvLine(medianRow(rows[label]));
      csv << line << "\n";
      std::cout << line << std::endl;
    }
  } catch (const std::exception& e) {
    std::cerr << "scale: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
