// lasso: lasso selection time against store size (10^6 to 10^8 points, goal at most
// 2 s at 10^8 on this machine), the hierarchy's pruning (annotate/lasso_selection.h) against the
// baseline that reads every leaf and tests every point with the same point test, in one process.
//
// Input: a scan-like surface, points on a wavy height field over a square (what terrain LiDAR
// and facade scans look like to the hierarchy), built into stores of each --sizes count under
// --cache (reused when there; never in the repo). One oblique view (1920x1080) and a freehand-
// like lasso (240 vertices, concave) selecting about a quarter of the surface; THROUGH mode.
// Times (ms, best of --repeats): the lasso on a freshly opened store (chunks decoded from the
// file, the OS page cache warm) on one thread and on a thread per core, and again with the
// store's chunk cache warm; the baseline (one thread) once, on a fresh store. speedup = baseline
// / lasso on one thread (like for like). Both must select the same points (column `equal`).
// The same surface as regular-grid meshes (--mesh-sizes triangles, .tmesh stores), the lasso
// testing leaf triangles' centroids against every leaf triangle tested.
// Prints CSV; writes OUT/lasso.csv, OUT/lasso_mesh.csv and OUT/lasso.png.
//
// Measured here (dev preset, an otherwise idle machine; docs/figures/lasso.png; `build/dev/bench/
// lasso --sizes 1000000,10000000,100000000`): at 10^8 points the lasso reads 1,812 of the leaves
// (8.7 M points tested, 26 M selected) and takes 0.38 s cold on one thread (0.18 s on two)
// against 3.3 s for the baseline; 0.11 s against 0.32 s at 10^7. The mesh of 10^7 triangles:
// 521 leaf patches read, 0.11 s against 0.43 s. Store builds on two threads: points 2 s, 7 s,
// 58 s; meshes 1 s, 13 s.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/cli.h>
#include <tessera/core/stopwatch.h>
#include <tessera/lod/mesh_builder.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/annotate/lasso_selection.h>

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr uint64_t kBatch = 10'000'000;  ///< points per generated input file

/// The surface's height at (x, y), metres: gentle waves and a finer ripple.
double height(double x, double y) {
  return 4.0 * std::sin(x * 0.13) * std::cos(y * 0.09) + 0.5 * std::sin(x * 1.7 + y);
}

/// The store of `n` surface points in `cache`, built on first use. Returns it and the build
/// seconds (0 when reused).
std::pair<fs::path, double> surfaceStore(const fs::path& cache, uint64_t n, int threads) {
  const fs::path store = cache / ("surface-" + std::to_string(n) + ".tlod");
  if (fs::exists(store)) return {store, 0.0};
  const auto t0 = Clock::now();
  std::vector<fs::path> inputs;
  std::mt19937_64 rng(n);
  std::uniform_real_distribution<double> u(0.0, 100.0);  // metres
  for (uint64_t done = 0; done < n; done += kBatch) {
    lod::PointBatch b;
    b.reset(0);
    const uint64_t m = std::min(kBatch, n - done);
    b.positions.reserve(m);
    for (uint64_t i = 0; i < m; ++i) {
      const double x = u(rng), y = u(rng);
      b.positions.push_back({x, y, height(x, y)});
    }
    inputs.push_back(
        cache / ("surface-" + std::to_string(n) + "-" + std::to_string(inputs.size()) + ".ply"));
    lod::writePly(inputs.back(), b, glm::dvec3(0.0));
  }
  lod::BuildOptions o;
  o.quiet = true;
  o.temp_dir = cache;
  o.threads = threads;
  lod::buildStore(inputs, store, o);
  for (const fs::path& p : inputs) fs::remove(p);
  return {store, msSince(t0) / 1e3};
}

/// The mesh store of the same surface as a regular grid of about `n` triangles in `cache`, built
/// on first use. Returns it and the build seconds (0 when reused).
std::pair<fs::path, double> surfaceMesh(const fs::path& cache, uint64_t n, int threads) {
  const fs::path store = cache / ("surface-" + std::to_string(n) + ".tmesh");
  if (fs::exists(store)) return {store, 0.0};
  const auto t0 = Clock::now();
  const uint32_t k = uint32_t(std::ceil(std::sqrt(double(n) / 2.0)));  // cells a side
  lod::Mesh mesh;
  mesh.positions.reserve(size_t(k + 1) * (k + 1));
  for (uint32_t j = 0; j <= k; ++j)
    for (uint32_t i = 0; i <= k; ++i) {
      const double x = 100.0 * i / k, y = 100.0 * j / k;
      mesh.positions.push_back({x, y, height(x, y)});
    }
  mesh.triangles.reserve(size_t(2) * k * k);
  for (uint32_t j = 0; j < k; ++j)
    for (uint32_t i = 0; i < k; ++i) {
      const uint32_t a = j * (k + 1) + i, b = a + 1, c = a + k + 1, d = c + 1;
      mesh.triangles.push_back({a, b, d});
      mesh.triangles.push_back({a, d, c});
    }
  lod::MeshBuildOptions o;
  o.quiet = true;
  o.threads = uint32_t(threads);
  lod::buildMeshStore(mesh, store, o);
  return {store, msSince(t0) / 1e3};
}

/// The mesh baseline: every leaf patch read, every triangle's centroid tested (the lasso's test).
uint64_t bruteForce(lod::MeshStore& store, const annotate::LassoProjector& proj,
                    const annotate::LassoPolygon& poly, glm::uvec2 viewport) {
  uint64_t selected = 0;
  for (lod::NodeId id = 0; id < store.nodeCount(); ++id) {
    if (store.record(id).child_count != 0) continue;
    const lod::MeshPatch p = store.readPatch(id);
    for (size_t t = 0; t < p.triangles(); ++t) {
      glm::dvec3 sum(0.0);
      for (int c = 0; c < 3; ++c) sum += p.offset + glm::dvec3(p.positions[p.indices[3 * t + c]]);
      const auto q = proj.project(sum / 3.0);
      selected += q.in_front && q.pixel.x >= 0 && q.pixel.y >= 0 && q.pixel.x < viewport.x &&
                  q.pixel.y < viewport.y && poly.contains(q.pixel);
    }
  }
  return selected;
}

/// The baseline: every leaf read, every point tested (the same test as the lasso's leaves).
uint64_t bruteForce(lod::PointStore& store, const annotate::LassoProjector& proj,
                    const annotate::LassoPolygon& poly, glm::uvec2 viewport) {
  uint64_t selected = 0;
  std::vector<lod::NodeId> open = {store.root()};
  while (!open.empty()) {
    const lod::NodeId id = open.back();
    open.pop_back();
    if (!store.node(id).leaf()) {
      for (lod::NodeId c : store.children(id)) open.push_back(c);
      continue;
    }
    const auto chunk = store.decodeChunk(id);
    for (const glm::vec3& p : chunk->positions) {
      const auto q = proj.project(chunk->offset + glm::dvec3(p));
      selected += q.in_front && q.pixel.x >= 0 && q.pixel.y >= 0 && q.pixel.x < viewport.x &&
                  q.pixel.y < viewport.y && poly.contains(q.pixel);
    }
  }
  return selected;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runMain("lasso", [&]() -> int {
    CLI::App app{"lasso: lasso selection time against store size"};
    std::string out = TESSERA_BENCH_RESULTS_DIR;
    std::string cache;
    std::vector<uint64_t> sizes = {1'000'000, 10'000'000};
    app.add_option("--out", out, "Folder for the CSV and the chart")->capture_default_str();
    app.add_option("--cache", cache, "Folder for the generated stores (default: OUT/lasso-cache)");
    app.add_option("--sizes", sizes, "Store sizes in points")
        ->delimiter(',')
        ->capture_default_str();
    std::vector<uint64_t> mesh_sizes = {1'000'000, 10'000'000};
    app.add_option("--mesh-sizes", mesh_sizes, "Mesh store sizes in triangles (none: \"\")")
        ->delimiter(',')
        ->capture_default_str();
    bool skip_baseline = false;
    int repeats = 3;
    app.add_option("--repeats", repeats, "Lasso runs per size (the best counts)")
        ->check(cli::integerRange(1, 100))
        ->capture_default_str();
    app.add_flag("--skip-baseline", skip_baseline, "Only the lasso (profiling)");
    int build_threads = 1;
    app.add_option("--build-threads", build_threads,
                   "Threads building the stores (0: every core; 1 leaves the machine to others)")
        ->check(cli::integerRange(0, lod::kMaxThreads))
        ->capture_default_str();
    if (const auto code = cli::parse(app, argc, argv, "lasso")) return *code;
    fs::create_directories(out);
    const fs::path cache_dir = cache.empty() ? fs::path(out) / "lasso-cache" : fs::path(cache);
    fs::create_directories(cache_dir);

    const glm::uvec2 viewport(1920, 1080);
    annotate::LassoView view;
    const glm::dvec3 target(50.0, 50.0, 0.0), eye(5.0, -15.0, 45.0);
    view.view = glm::lookAt(eye, target, glm::dvec3(0, 0, 1));
    view.projection =
        glm::perspective(glm::radians(50.0), double(viewport.x) / viewport.y, 0.1, 1000.0);
    view.viewport = viewport;
    std::vector<glm::dvec2> vertices;
    for (int i = 0; i < 240; ++i) {
      const double t = 2 * M_PI * i / 240;
      const double r = 190.0 * (1.0 + 0.3 * std::sin(7 * t));
      vertices.push_back(glm::dvec2(1000, 520) + r * glm::dvec2(1.3 * std::cos(t), std::sin(t)));
    }
    const annotate::LassoPolygon poly(vertices);

    // One size of one kind: the baseline first, then the lasso on fresh stores (the chunk cache
    // empty; the OS page cache warm for both), best of --repeats against the other builds on
    // this machine.
    const char* head =
        "%s,build_s,nodes_visited,nodes_whole,leaves_read,%s_tested,selected,lasso_1t_ms,"
        "lasso_ms,lasso_warm_ms,brute_ms,speedup,equal\n";
    auto measure = [&](std::ofstream& csv, uint64_t n, double build_s, auto open, auto lasso,
                       auto origin) {
      uint64_t brute = 0;
      double brute_ms = 0.0;
      if (!skip_baseline) {
        auto fresh = open();
        const glm::dmat4 model = glm::translate(glm::dmat4(1.0), origin(*fresh));
        const auto t0 = Clock::now();
        brute = bruteForce(*fresh, annotate::LassoProjector(view, model), poly, viewport);
        brute_ms = msSince(t0);
      }
      annotate::LassoResult r, warm, single;
      double cold = 1e300, warm_ms = 1e300, single_ms = 1e300;
      for (int k = 0; k < repeats; ++k) {
        annotate::LassoOptions one;
        one.threads = 1;
        auto t0 = Clock::now();
        single = lasso(*open(), one);
        single_ms = std::min(single_ms, msSince(t0));
        auto store = open();
        t0 = Clock::now();
        r = lasso(*store, annotate::LassoOptions{});
        cold = std::min(cold, msSince(t0));
        t0 = Clock::now();
        warm = lasso(*store, annotate::LassoOptions{});
        warm_ms = std::min(warm_ms, msSince(t0));
      }
      if (skip_baseline) brute = r.selection.count();
      char line[512];
      std::snprintf(
          line, sizeof line, "%llu,%.1f,%llu,%llu,%llu,%llu,%llu,%.1f,%.1f,%.1f,%.1f,%.1f,%d\n",
          (unsigned long long)n, build_s, (unsigned long long)r.stats.nodes_visited,
          (unsigned long long)r.stats.nodes_whole, (unsigned long long)r.stats.leaves_read,
          (unsigned long long)r.stats.elements_tested, (unsigned long long)r.selection.count(),
          single_ms, cold, warm_ms, brute_ms, brute_ms / single_ms,
          int(brute == r.selection.count() && warm.selection == r.selection &&
              single.selection == r.selection));
      csv << line;
      csv.flush();
      std::printf("%s", line);
      std::fflush(stdout);
    };

    const fs::path csv_path = fs::path(out) / "lasso.csv";
    std::ofstream csv(csv_path);
    char header[256];
    std::snprintf(header, sizeof header, head, "points", "points");
    csv << header;
    std::printf("%s", header);
    for (uint64_t n : sizes) {
      const auto [path, build_s] = surfaceStore(cache_dir, n, build_threads);
      measure(
          csv, n, build_s, [&, p = path] { return lod::PointStore::open(p, 64ull << 20); },
          [&](lod::PointStore& st, const annotate::LassoOptions& o) {
            return annotate::lassoPoints(st, view, poly, o);
          },
          [](const lod::PointStore& st) { return st.summary().origin; });
    }
    csv.close();
    // The same surface as meshes of 10^6 and 10^7 triangles (selection on models of
    // 10^7 triangles), the lasso testing the leaf triangles' centroids.
    const fs::path mesh_csv_path = fs::path(out) / "lasso_mesh.csv";
    std::ofstream mesh_csv(mesh_csv_path);
    std::snprintf(header, sizeof header, head, "triangles", "triangles");
    mesh_csv << header;
    std::printf("%s", header);
    for (uint64_t n : mesh_sizes) {
      const auto [path, build_s] = surfaceMesh(cache_dir, n, build_threads);
      measure(
          mesh_csv, n, build_s, [&, p = path] { return lod::MeshStore::open(p); },
          [&](lod::MeshStore& st, const annotate::LassoOptions& o) {
            return annotate::lassoTriangles(st, view, poly, o);
          },
          [](const lod::MeshStore& st) { return st.summary().origin; });
    }
    mesh_csv.close();

    const fs::path gp = fs::path(out) / "lasso.gp";
    std::ofstream g(gp);
    g << "set terminal pngcairo size 900,520 font 'DejaVu Sans,10'\n"
      << "set output '" << (fs::path(out) / "lasso.png").string() << "'\n"
      << "set datafile separator ','\nset key bottom right\nset grid\n"
      << "set title 'Lasso selection (THROUGH, 1920x1080, a quarter of a surface scan inside; 2 "
         "shared cores)'\n"
      << "set xlabel 'store size (points, or triangles for the meshes)'\nset ylabel 'time (ms)'\n"
      << "set logscale xy\nset format x '10^{%L}'\nset xrange [5e5:2e8]\n"
      << "set arrow from 1e8, graph 0 to 1e8, first 2000 nohead dt 2 lc rgb 'red'\n"
      << "set arrow from 5e5, first 2000 to 1e8, first 2000 nohead dt 2 lc rgb 'red'\n"
      << "set label 'goal: 2 s at 10^8' at 1.2e6, first 2600 tc rgb 'red'\n"
      << "plot '" << csv_path.string()
      << "' using 1:11 with linespoints pt 7 title 'baseline: every leaf point tested (1 thread)', "
      << "'' using 1:8 with linespoints pt 7 title 'lasso, store opened cold, 1 thread', "
      << "'' using 1:9 with linespoints pt 7 title 'lasso, store opened cold, 2 threads', "
      << "'' using 1:10 with linespoints pt 5 title 'lasso, chunk cache warm, 2 threads', '"
      << mesh_csv_path.string()
      << "' using 1:11 with linespoints pt 6 dt 2 lc rgb '#b03060' title 'mesh baseline: every "
         "leaf triangle tested (1 thread)', "
      << "'' using 1:8 with linespoints pt 6 dt 2 lc rgb '#2060b0' title 'mesh lasso, store "
         "opened cold, 1 thread'\n";
    g.close();
    const std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp.string() + "'";
    if (std::system(cmd.c_str()) != 0)
      std::fprintf(stderr, "lasso: gnuplot failed; the CSV is complete\n");
    return 0;
  });
}
