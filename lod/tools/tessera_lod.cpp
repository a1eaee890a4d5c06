// tessera-lod: inspect scanned data and make test scans. `tessera-lod --help` lists subcommands.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>

#include <tessera/core/check.h>
#include <tessera/lod/mesh.h>
#include <tessera/lod/source_summary.h>
#include <tessera/lod/virtual_scanner.h>

namespace {

using namespace tessera::lod;

// Exit codes: 0 success, 1 bad input data, 2 bad command line (CLI11), 3 I/O failure writing.
constexpr int kExitBadInput = 1;
constexpr int kExitWriteFailed = 3;

int runInfo(const std::vector<std::string>& files, bool json, bool quiet) {
  int rc = 0;
  if (json && files.size() > 1) std::cout << "[\n";
  for (size_t i = 0; i < files.size(); ++i) {
    SourceSummary s = summarizeSource(files[i], quiet);
    if (json) {
      std::cout << (files.size() > 1 ? "  " : "") << summaryJson(s) << (i + 1 < files.size() ? "," : "") << "\n";
    } else {
      std::cout << summaryText(s);
    }
    if (!s.error.empty()) {
      std::cerr << "tessera-lod info: " << s.error << "\n";
      rc = kExitBadInput;
    }
  }
  if (json && files.size() > 1) std::cout << "]\n";
  return rc;
}

int runScan(const std::string& mesh_path, const std::string& out, const std::string& resolution,
            ScanOptions o) {
  unsigned w = 0, h = 0;
  char extra;
  if (std::sscanf(resolution.c_str(), "%ux%u%c", &w, &h, &extra) != 2 || w == 0 || h == 0 || w > 65535 ||
      h > 65535) {
    std::cerr << "tessera-lod scan: --resolution " << resolution << ": expected WxH, e.g. 512x400\n";
    return 2;
  }
  o.columns = w;
  o.rows = h;
  Mesh mesh;
  try {
    mesh = readMesh(mesh_path);
  } catch (const ReadError& e) {
    std::cerr << "tessera-lod scan: " << e.what() << "\n";
    return kExitBadInput;
  }
  try {
    ScanResult r = scanMesh(mesh, out, o);
    std::cout << "scanned " << mesh_path << " (" << mesh.triangles.size() << " triangles) from " << r.scans.size()
              << (o.panoramic ? " panoramic" : "") << " scanners: " << r.points << " points of " << r.rays
              << " rays\nwrote " << r.conf.string() << "\n";
  } catch (const tessera::PreconditionError& e) {
    std::cerr << "tessera-lod scan: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "tessera-lod scan: " << e.what() << "\n";
    return kExitWriteFailed;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"tessera-lod: read, inspect and generate scanned 3D data for Tessera"};
  app.require_subcommand(1);
  app.set_config("--config", "", "Read options from a TOML file ([scan] section for scan options)");

  std::vector<std::string> info_files;
  bool info_json = false, info_quiet = false;
  auto* info = app.add_subcommand("info", "Describe scan files: format, points, triangles, bounds, attributes, skips, scans");
  info->add_option("FILE", info_files, "PLY, LAS, Stanford .conf, XYZ/PTS/TXT or OBJ files")->required();
  info->add_flag("--json", info_json, "Print JSON (one object per file; an array for several)");
  info->add_flag("--quiet", info_quiet, "No progress bar");

  std::string scan_mesh, scan_out, scan_res = "512x400";
  ScanOptions so;
  auto* scan = app.add_subcommand("scan", "Virtual laser scanner: ray-cast a mesh into Stanford-format range scans + .conf");
  scan->add_option("MESH", scan_mesh, "Mesh to scan (PLY or OBJ with faces)")->required();
  scan->add_option("-o,--output", scan_out, "Output folder (scan_NNN.ply and scans.conf)")->required();
  scan->add_option("--scanners", so.scanners, "Number of scanner poses")->check(CLI::Range(1, 10000))->capture_default_str();
  scan->add_option("--resolution", scan_res, "Range grid WxH per scanner")->capture_default_str();
  scan->add_flag("--panoramic", so.panoramic, "Scanners inside the model, 360-degree panoramas");
  scan->add_option("--noise-mm", so.noise_mm, "Gaussian range noise (standard deviation, mm)")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  scan->add_option("--units-per-mm", so.units_per_mm, "Model units per millimetre (metres: 0.001)")
      ->check(CLI::PositiveNumber)->capture_default_str();
  scan->add_option("--seed", so.seed, "Noise seed (same seed, same scans)")->capture_default_str();
  scan->add_option("--max-incidence", so.max_incidence_deg, "Drop hits more oblique than this (degrees)")
      ->check(CLI::Range(0.0, 90.0))->capture_default_str();
  scan->add_flag("--binary", so.binary, "Write binary little-endian PLY (for large scans)");
  scan->add_option("--threads", so.threads, "Threads (0: every core)")->capture_default_str();
  scan->add_flag("--quiet", so.quiet, "No progress output");

  CLI11_PARSE(app, argc, argv);
  if (*info) return runInfo(info_files, info_json, info_quiet);
  if (*scan) return runScan(scan_mesh, scan_out, scan_res, so);
  return 2;
}
