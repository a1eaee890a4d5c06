// Inputs the benchmarks share, generated into their results folder (never into the repo) and
// cached between runs.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include <tessera/lod/mesh.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/store_builder.h>
#include <tessera/lod/virtual_scanner.h>

namespace tessera::bench {

/// A virtual scan of the Stanford bunny reconstruction with about `points` points from 40
/// scanners with 0.2 mm noise, as Stanford range scans with a .conf, in `dir` (reused when
/// `dir`/scans.conf exists). Returns the .conf path.
inline std::filesystem::path bigBunnyScan(const std::filesystem::path& dir, uint64_t points,
                                          const std::string& data) {
  namespace fs = std::filesystem;
  using namespace tessera::lod;
  fs::path conf = dir / "scans.conf";
  if (fs::exists(conf)) return conf;
  Mesh mesh = readMesh(data + "/stanford-bunny/reconstruction/bun_zipper.ply");
  // Pilot scan for the hit ratio, then a resolution that gives the requested count.
  ScanOptions o;
  o.scanners = 40;
  o.columns = 200;
  o.rows = 160;
  o.quiet = true;
  o.binary = true;
  ScanResult pilot = scanMesh(mesh, dir / "pilot", o);
  fs::remove_all(dir / "pilot");
  double ratio = double(pilot.points) / double(pilot.rays);
  double rays_per_scanner = double(points) / ratio / o.scanners;
  double scale = std::sqrt(rays_per_scanner / (200.0 * 160.0));
  o.columns = uint32_t(std::ceil(200 * scale));
  o.rows = uint32_t(std::ceil(160 * scale));
  o.noise_mm = 0.2;
  o.quiet = false;
  std::fprintf(stderr, "bench: scanning %u x %u from %d scanners for ~%.0f M points\n", o.columns,
               o.rows, o.scanners, double(points) / 1e6);
  auto t = std::chrono::steady_clock::now();
  ScanResult r = scanMesh(mesh, dir, o);
  std::fprintf(stderr, "bench: %llu points scanned in %.1f s\n", (unsigned long long)r.points,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count());
  return conf;
}

/// The point store of bigBunnyScan(`points`), built once into `out`/inputs and reused.
inline std::filesystem::path bigBunnyStore(const std::filesystem::path& out, uint64_t points,
                                           const std::string& data) {
  const std::string tag = "bunny-scan-" + std::to_string(points);
  const std::filesystem::path conf = bigBunnyScan(out / "inputs" / tag, points, data);
  const std::filesystem::path store = out / "inputs" / (tag + ".tlod");
  if (!std::filesystem::exists(store)) {
    tessera::lod::BuildOptions o;
    o.memory_mb = 2048;
    tessera::lod::buildStore({conf}, store, o);
  }
  return store;
}

/// The inputs of a benchmark on one store: --out (results and generated inputs), --store (a
/// .tlod of the user's), --points (of the virtual bunny scan, when no store is named).
struct StoreInputs {
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  std::string store;
  uint64_t points = 100'000'000;

  void addOptions(CLI::App& app) {
    app.add_option("--out", out, "Folder for inputs, CSV and chart")->capture_default_str();
    app.add_option("--store", store, "A .tlod to use (default: the virtual bunny scan)");
    app.add_option("--points", points, "Points of the virtual bunny scan")->capture_default_str();
  }
  /// Creates `out`; the store named, or bigBunnyStore(`points`) (built on first use).
  std::string storePath() const {
    std::filesystem::create_directories(out);
    return store.empty() ? bigBunnyStore(out, points, TESSERA_DATA_DIR).string() : store;
  }
};

}  // namespace tessera::bench
