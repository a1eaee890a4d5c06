// tessera-lod: inspect scanned data and make test scans. `tessera-lod --help` lists subcommands.
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <tuple>

#include <tessera/annotate/annotation_db.h>
#include <tessera/annotate/selection.h>
#include <tessera/core/check.h>
#include <tessera/scene.pb.h>
#include <tessera/core/cli.h>
#include <tessera/core/file_checks.h>
#include <tessera/lod/ambient_occlusion.h>
#include <tessera/lod/mesh.h>
#include <tessera/lod/mesh_builder.h>
#include <tessera/lod/photo_points.h>
#include <tessera/lod/point_export.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/source_summary.h>
#include <tessera/lod/store_builder.h>
#include <tessera/lod/virtual_scanner.h>

namespace {

using namespace tessera::lod;
namespace cli = tessera::cli;

// Exit codes (README, "Exit codes"): 0 success, 1 bad input data, 2 bad command line (also an
// output that is an input), 3 I/O failure writing, 4 verification failed.
constexpr int kExitBadInput = cli::kExitBadInput;
constexpr int kExitBadCommandLine = cli::kExitBadCommandLine;
constexpr int kExitWriteFailed = cli::kExitWriteFailed;

/// Every file reading `inputs` opens (a .conf's scans too); ReadError propagates (exit 1).
std::vector<std::filesystem::path> filesReadBy(const std::vector<std::filesystem::path>& inputs) {
  std::vector<std::filesystem::path> files;
  for (const auto& in : inputs) {
    for (auto& f : filesRead(in)) files.push_back(std::move(f));
  }
  return files;
}

/// Runs a subcommand's body and maps its errors to the exit codes (README, "Exit codes"): a bad
/// command line 2, bad input 1, a store error `store_error_code` (3 writing, 1 reading).
template <class Body>
int guarded(const char* command, int store_error_code, Body body) {
  try {
    return body();
  } catch (const cli::UsageError& e) {
    std::fprintf(stderr, "tessera-lod %s: %s\n", command, e.what());
    return kExitBadCommandLine;
  } catch (const ReadError& e) {
    std::fprintf(stderr, "tessera-lod %s: %s\n", command, e.what());
    return kExitBadInput;
  } catch (const StoreError& e) {
    std::fprintf(stderr, "tessera-lod %s: %s\n", command, e.what());
    return store_error_code;
  }
}

/// Describes every file, scan or store alike (summarizeSource() tells them apart).
int runInfo(const std::vector<std::string>& files, bool json, bool quiet) {
  int rc = 0;
  if (json && files.size() > 1) std::cout << "[\n";
  for (size_t i = 0; i < files.size(); ++i) {
    SourceSummary s = summarizeSource(files[i], quiet);
    if (json) {
      std::cout << (files.size() > 1 ? "  " : "") << summaryJson(s)
                << (i + 1 < files.size() ? "," : "") << "\n";
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
  const cli::Size size = cli::parseSize(resolution, "--resolution", 65535);
  o.columns = size.width;
  o.rows = size.height;
  // The scans and the .conf the scan writes must not be the mesh it reads.
  const std::filesystem::path dir(out);
  const std::vector<std::filesystem::path> mesh_files{mesh_path};
  cli::refuseOverwrite(dir / "scans.conf", mesh_files, "-o");
  for (int i = 0; i < o.scanners; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "scan_%03d.ply", i);
    cli::refuseOverwrite(dir / name, mesh_files, "-o");
  }
  Mesh mesh;
  try {
    mesh = readMesh(mesh_path);
  } catch (const ReadError& e) {
    std::cerr << "tessera-lod scan: " << e.what() << "\n";
    return kExitBadInput;
  }
  try {
    ScanResult r = scanMesh(mesh, out, o);
    std::cout << "scanned " << mesh_path << " (" << mesh.triangles.size() << " triangles) from "
              << r.scans.size() << (o.panoramic ? " panoramic" : "") << " scanners: " << r.points
              << " points of " << r.rays << " rays\nwrote " << r.conf.string() << "\n";
  } catch (const tessera::PreconditionError& e) {
    std::cerr << "tessera-lod scan: " << e.what() << "\n";
    return kExitBadCommandLine;
  } catch (const std::exception& e) {
    std::cerr << "tessera-lod scan: " << e.what() << "\n";
    return kExitWriteFailed;
  }
  return 0;
}

// Exit codes for build/verify: 0 ok, 1 bad input, 3 failed writing, 4 verification failed.
constexpr int kExitVerifyFailed = 4;

int runMeshBuild(const std::vector<std::filesystem::path>& paths, const std::string& out,
                 const MeshBuildOptions& o) {
  return guarded("build", kExitWriteFailed, [&] {
    cli::refuseOverwrite(out, filesReadBy(paths), "-o");
    const MeshBuildReport r = buildMeshStore(paths, out, o);
    std::printf("built %s: %llu triangles (%llu dropped), %llu vertices, %llu patches (%llu "
                "leaves), depth %u, %.2fx stored\n",
                out.c_str(), (unsigned long long)r.triangles,
                (unsigned long long)r.dropped_triangles, (unsigned long long)r.vertices,
                (unsigned long long)r.nodes, (unsigned long long)r.leaves, r.depth,
                double(r.stored_triangles) / double(r.triangles));
    if (r.blocks > 0)
      std::printf("  built in %llu blocks (estimated peak %.0f MB)\n",
                  (unsigned long long)r.blocks, double(r.peak_bytes) / double(1 << 20));
    std::printf("  %.2f bytes/triangle, grid step %.3g (quantisation error %.3g), root error %.3g\n",
                double(r.file_bytes) / double(r.triangles), r.step, r.quant_error, r.root_error);
    std::printf("  %.2f s (read %.2f, partition %.2f, simplify %.2f, write %.2f): %.2f M "
                "triangles/s\n",
                r.seconds, r.seconds_read, r.seconds_partition, r.seconds_simplify,
                r.seconds_write, double(r.triangles) / r.seconds / 1e6);
    return 0;
  });
}

int runMeshVerify(const std::string& store, const std::vector<std::filesystem::path>& paths,
                  bool quiet) {
  return guarded("verify", kExitBadInput, [&] {
    const MeshVerifyReport r = verifyMeshStore(store, paths, quiet);
    std::printf("%s: %llu input triangles, %llu at the leaves, %llu matched, %llu missing, %llu "
                "extra, %llu corrupt patches, %llu errors below a child's\n",
                store.c_str(), (unsigned long long)r.input_triangles,
                (unsigned long long)r.leaf_triangles, (unsigned long long)r.matched,
                (unsigned long long)r.missing, (unsigned long long)r.extra,
                (unsigned long long)r.corrupt_patches,
                (unsigned long long)r.error_order_violations);
    std::printf("depth  triangles  stated-error  max-to-input  max-from-input  mean-to-input\n");
    for (const MeshLevelError& e : r.levels)
      std::printf("%5u  %9llu  %12.4g  %12.4g  %14.4g  %13.4g\n", e.depth,
                  (unsigned long long)e.triangles, e.stated, e.max_to_input, e.max_from_input,
                  e.mean_to_input);
    std::printf("%s\n", r.ok() ? "OK: every input triangle is stored once at the leaves"
                               : "FAILED");
    return r.ok() ? 0 : kExitVerifyFailed;
  });
}

int runBuild(const std::vector<std::string>& inputs, const std::string& out,
             const BuildOptions& o, const MeshBuildOptions& mo, bool ao) {
  std::vector<std::filesystem::path> paths(inputs.begin(), inputs.end());
  if (std::filesystem::path(out).extension() == ".tmesh") {
    if (ao) {
      std::cerr << "tessera-lod build: --ao: ambient occlusion is a point attribute; a .tmesh "
                   "store cannot carry it (write a .tlod)\n";
      return kExitBadCommandLine;
    }
    return runMeshBuild(paths, out, mo);
  }
  return guarded("build", kExitWriteFailed, [&] {
    cli::refuseOverwrite(out, filesReadBy(paths), "-o");
    BuildReport r;
    if (ao) {
      // --ao: MVAO (section 5) of each input's scans with the defaults of `tessera-lod ao`.
      AoStoreReport a;
      try {
        AoOptions ao_options;
        ao_options.threads = o.threads;
        a = buildStoreWithAo(paths, out, AoMethod::kMvao, ao_options, o);
      } catch (const AoError& e) {
        throw ReadError(std::string(e.what()) + " (build --ao needs registered range scans)");
      }
      std::printf("ambient occlusion: %zu scans, %llu points; %.2f s load, %.2f s ssao, %.2f s "
                  "integration\n",
                  a.scans, (unsigned long long)a.points, a.seconds_load, a.seconds_ssao,
                  a.seconds_integrate);
      r = a.build;
    } else {
      r = buildStore(paths, out, o);
    }
    std::printf(
        "built %s: %llu points (%llu skipped), %llu nodes, depth %u, %llu chunks, overhead %.3fx\n",
        out.c_str(), (unsigned long long)r.points, (unsigned long long)r.skipped,
        (unsigned long long)r.nodes, r.depth, (unsigned long long)r.chunks,
        double(r.stored_points) / double(r.points));
    std::printf(
        "  %.2f bytes/point in all, %.2f bytes/point position + colour, max quantisation error "
        "%.3g\n",
        double(r.file_bytes) / double(r.points), double(r.position_color_bytes) / double(r.points),
        r.max_error);
    std::printf("  %.2f s (read %.2f, process %.2f, write %.2f): %.2f M points/s\n", r.seconds,
                r.seconds_read, r.seconds_process, r.seconds_write,
                double(r.points) / r.seconds / 1e6);
    return 0;
  });
}

int runVerify(const std::string& store, const std::vector<std::string>& inputs,
              const BuildOptions& o) {
  std::vector<std::filesystem::path> paths(inputs.begin(), inputs.end());
  if (isMeshStore(store)) return runMeshVerify(store, paths, o.quiet);
  return guarded("verify", kExitBadInput, [&] {
    VerifyReport r = verifyStore(store, paths, o);
    std::printf(
        "%s: %llu input points, %llu stored, %llu matched, %llu unmatched, %llu corrupt chunks\n",
        store.c_str(), (unsigned long long)r.input_points, (unsigned long long)r.store_points,
        (unsigned long long)r.matched, (unsigned long long)r.unmatched,
        (unsigned long long)r.corrupt_chunks);
    std::printf("max error %.6g (%.3f of the stated bound)\n", r.max_error, r.max_error_ratio);
    if (r.exact_store)
      std::printf("exact leaves: %llu of %llu input points at their own integer coordinates\n",
                  (unsigned long long)r.exact, (unsigned long long)r.input_points);
    const char* verdict = !r.ok()          ? "FAILED"
                          : r.exact_store ? "OK: every input point is stored once, exactly"
                                          : "OK: every input point is stored once within its "
                                            "error bound";
    std::printf("%s\n", verdict);
    return r.ok() ? 0 : kExitVerifyFailed;
  });
}

int runPhoto(const PhotoOptions& o, const std::string& out, const BuildOptions& bo) {
  try {
    glm::dvec3 origin;
    PhotoReport r;
    const std::filesystem::path target(out);
    std::vector<std::filesystem::path> read{o.image};
    if (!o.height.empty()) read.push_back(o.height);
    cli::refuseOverwrite(target, read, "-o");
    if (target.extension() != ".ply")
      cli::refuseOverwrite(target.string() + ".points.ply", read, "-o (its temporary points)");
    const PointBatch points = photoPoints(o, origin, &r);
    std::printf("photo %s: %ux%u pixels -> %llu points (1/cos(phi) up to %.2f)\n", o.image.c_str(),
                r.width, r.height, (unsigned long long)r.points, r.max_copies);
    if (target.extension() == ".ply") {
      writePly(target, points, origin);
    } else {
      const std::filesystem::path ply = target.string() + ".points.ply";
      writePly(ply, points, origin);
      BuildOptions b = bo;
      try {
        buildStore({ply}, target, b);
      } catch (...) {
        std::filesystem::remove(ply);
        throw;
      }
      std::filesystem::remove(ply);
    }
    std::printf("wrote %s\n", out.c_str());
    return 0;
  } catch (const ReadError& e) {
    std::fprintf(stderr, "tessera-lod photo: %s\n", e.what());
    return kExitBadInput;
  } catch (const cli::UsageError& e) {
    std::fprintf(stderr, "tessera-lod photo: %s\n", e.what());
    return kExitBadCommandLine;
  } catch (const tessera::PreconditionError& e) {
    std::fprintf(stderr, "tessera-lod photo: %s\n", e.what());
    return kExitBadCommandLine;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tessera-lod photo: %s\n", e.what());
    return kExitWriteFailed;
  }
}

/// "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX" or "A,B,C,D": `n` finite numbers.
std::vector<double> parseNumbers(const std::string& text, size_t n, const char* option) {
  std::vector<double> v;
  size_t at = 0;
  while (at <= text.size()) {
    const size_t comma = std::min(text.find(',', at), text.size());
    const std::string part = text.substr(at, comma - at);
    char* end = nullptr;
    const double x = std::strtod(part.c_str(), &end);
    if (part.empty() || end != part.c_str() + part.size() || !std::isfinite(x)) {
      throw cli::UsageError(std::string(option) + " " + text + ": '" + part +
                            "' is not a finite number");
    }
    v.push_back(x);
    at = comma + 1;
  }
  if (v.size() != n) {
    throw cli::UsageError(std::string(option) + " " + text + ": expected " + std::to_string(n) +
                          " numbers separated by commas, got " + std::to_string(v.size()));
  }
  return v;
}

/// The region selected at place ID of the annotation database DB ("DB:ID"), as the lasso or the
/// lazy snapping stored it: per store leaf, the indices of its points.
tessera::annotate::Selection storedSelection(const std::string& spec) {
  namespace annotate = tessera::annotate;
  const size_t colon = spec.rfind(':');
  char* end = nullptr;
  const long long id = colon == std::string::npos ? 0 : std::strtoll(spec.c_str() + colon + 1, &end, 10);
  if (colon == std::string::npos || colon == 0 || id <= 0 || *end != '\0') {
    throw cli::UsageError("--selection " + spec +
                          ": expected DB:ID (an annotation database and a place id, as "
                          "`tessera-annotate place` lists them)");
  }
  const std::string db_path = spec.substr(0, colon);
  const std::string where = "--selection " + spec + ": ";
  try {
    annotate::AnnotationDbOptions options;
    options.read_only = true;
    annotate::AnnotationDb db(db_path, options);
    const std::optional<annotate::Place> place = db.place(id);
    if (!place) throw ReadError(where + db_path + " has no place " + std::to_string(id));
    if (place->kind != annotate::PlaceKind::kSelection ||
        place->selection_id != annotate::kSelectionBlob) {
      throw ReadError(where + "place " + std::to_string(id) +
                      " is not a selected region (a point, a hot spot or a measurement)");
    }
    tessera::scene::SelectionPayload payload;
    if (!payload.ParseFromString(std::string(place->selection.begin(), place->selection.end()))) {
      throw ReadError(where + "place " + std::to_string(id) + ": its selection does not parse");
    }
    const auto& e = payload.elements();
    annotate::Selection selection = annotate::Selection::deserialize(
        std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(e.data()), e.size()));
    if (selection.elements() != annotate::SelectionElements::kPoints) {
      throw ReadError(where + "place " + std::to_string(id) +
                      " selects triangles of a mesh; export writes the points of a .tlod store");
    }
    return selection;
  } catch (const annotate::AnnotationError& e) {
    throw ReadError(where + e.what());
  } catch (const annotate::SelectionError& e) {
    throw ReadError(where + e.what());
  }
}

int runExport(const std::string& in, const std::string& out, const std::string& box,
              const std::vector<std::string>& planes, const std::string& selection_spec,
              ExportOptions o) {
  return guarded("export", kExitBadInput, [&] {
    tessera::annotate::Selection selection;
    if (!selection_spec.empty()) {
      selection = storedSelection(selection_spec);
      std::vector<NodeId> leaves;
      for (const auto& [node, sel] : selection.nodes()) leaves.push_back(node);
      o.leaves = std::move(leaves);
      o.keep_element = [&](NodeId node, uint32_t index) {
        return selection.contains(node, index);
      };
      o.leaf_size = [&](NodeId node) { return selection.node(node)->size(); };
    }
    if (!box.empty()) {
      const auto v = parseNumbers(box, 6, "--box");
      const glm::dvec3 lo(v[0], v[1], v[2]), hi(v[3], v[4], v[5]);
      if (glm::any(glm::greaterThan(lo, hi))) {
        throw cli::UsageError("--box " + box + ": a minimum is above its maximum");
      }
      o.box = std::make_pair(lo, hi);
    }
    for (const std::string& p : planes) {
      const auto v = parseNumbers(p, 4, "--plane");
      if (v[0] == 0 && v[1] == 0 && v[2] == 0) {
        throw cli::UsageError("--plane " + p + ": the normal (A,B,C) is zero");
      }
      o.planes.emplace_back(v[0], v[1], v[2], v[3]);
    }
    cli::refuseOverwrite(out, filesReadBy({in}), "-o");
    try {
      const ExportReport r = exportPoints(in, out, o);
      std::printf("exported %s: %llu of %llu points, %s\n", out.c_str(),
                  (unsigned long long)r.written, (unsigned long long)r.read, r.method.c_str());
    } catch (const WriteError& e) {
      std::fprintf(stderr, "tessera-lod export: %s\n", e.what());
      return kExitWriteFailed;
    }
    return 0;
  });
}

/// `ao`: multi-view ambient occlusion of range scans into a store (lod/ambient_occlusion.h).
int runAo(const std::string& in, const std::string& out, const std::string& method,
          const AoOptions& ao, const BuildOptions& bo) {
  return guarded("ao", kExitWriteFailed, [&] {
    const AoMethod m = method == "ssao" ? AoMethod::kSsao
                       : method == "grid" ? AoMethod::kGrid
                                          : AoMethod::kMvao;
    cli::refuseOverwrite(out, filesReadBy({in}), "-o");
    AoStoreReport r;
    try {
      r = buildStoreWithAo(in, out, m, ao, bo);
    } catch (const AoError& e) {
      throw ReadError(e.what());
    }
    std::printf("ao %s: %zu scans, %llu points, method %s, t_max %.4g, radius %.4g, %d samples, "
                "%dx%d neighbours\n",
                out.c_str(), r.scans, (unsigned long long)r.points, method.c_str(),
                r.resolved.t_max, r.resolved.radius, r.resolved.samples, r.resolved.neighbours,
                r.resolved.neighbours);
    std::printf("  %.2f s load, %.2f s ssao, %.2f s integration, %.2f s store build\n",
                r.seconds_load, r.seconds_ssao, r.seconds_integrate, r.build.seconds);
    return 0;
  });
}

int run(int argc, char** argv) {
  CLI::App app{"tessera-lod: read, inspect and generate scanned 3D data for Tessera"};
  app.require_subcommand(1);
  app.set_config("--config", "", "Read options from a TOML file ([scan] section for scan options)");

  std::vector<std::string> info_files;
  bool info_json = false, info_quiet = false;
  auto* info = app.add_subcommand(
      "info", "Describe scan files: format, points, triangles, bounds, attributes, skips, scans");
  info->add_option("FILE", info_files,
                   "PLY, LAS, LAZ, E57, Stanford .conf, XYZ/PTS/TXT or OBJ files, .tlod point stores "
                   "or .tmesh mesh stores")
      ->required();
  info->add_flag("--json", info_json, "Print JSON (one object per file; an array for several)");
  info->add_flag("--quiet", info_quiet, "No progress bar");

  std::string scan_mesh, scan_out, scan_res = "512x400";
  ScanOptions so;
  auto* scan = app.add_subcommand(
      "scan", "Virtual laser scanner: ray-cast a mesh into Stanford-format range scans + .conf");
  scan->add_option("MESH", scan_mesh, "Mesh to scan (PLY or OBJ with faces)")->required();
  scan->add_option("-o,--output", scan_out, "Output folder (scan_NNN.ply and scans.conf)")
      ->required();
  scan->add_option("--scanners", so.scanners, "Number of scanner poses")
      ->check(cli::integerRange(1, 10000))
      ->capture_default_str();
  scan->add_option("--resolution", scan_res, "Range grid WxH per scanner")->capture_default_str();
  scan->add_flag("--panoramic", so.panoramic, "Scanners inside the model, 360-degree panoramas");
  scan->add_option("--noise-mm", so.noise_mm, "Gaussian range noise (standard deviation, mm)")
      ->check(cli::finiteRange(0.0, 1e6))
      ->capture_default_str();
  scan->add_option("--units-per-mm", so.units_per_mm, "Model units per millimetre (metres: 0.001)")
      ->check(cli::positiveFinite(1e12))
      ->capture_default_str();
  scan->add_option("--seed", so.seed, "Noise seed (same seed, same scans)")
      ->check(cli::anyInteger<uint64_t>())
      ->capture_default_str();
  scan->add_option("--max-incidence", so.max_incidence_deg,
                   "Drop hits more oblique than this (degrees)")
      ->check(cli::finiteRange(0.0, 90.0))
      ->capture_default_str();
  scan->add_flag("--binary", so.binary, "Write binary little-endian PLY (for large scans)");
  scan->add_option("--threads", so.threads, "Threads (0: every core)")
      ->check(cli::integerRange(0, kMaxScanThreads))
      ->capture_default_str();
  scan->add_flag("--quiet", so.quiet, "No progress output");

  std::vector<std::string> build_in;
  std::string build_out;
  BuildOptions bo;
  auto* build = app.add_subcommand(
      "build",
      "Build an out-of-core multiresolution point store (.tlod) from inputs, or a mesh patch "
      "hierarchy (.tmesh) from PLY/OBJ meshes when the output ends in .tmesh");
  build
      ->add_option(
          "IN", build_in,
          "Input files (any readable format); several are fused, each point keeps its source")
      ->required();
  build->add_option("-o,--output", build_out, "Output store (.tlod, or .tmesh for meshes)")
      ->required();
  build
      ->add_option("--memory-mb", bo.memory_mb,
                   "Memory budget in MB (peak stays within it plus a small constant)")
      ->check(cli::integerRange<uint64_t>(64, 1 << 20))
      ->capture_default_str();
  build->add_option("--threads", bo.threads, "Threads (0: every core)")
      ->check(cli::integerRange(0, kMaxThreads))
      ->capture_default_str();
  build->add_option("--temp-dir", bo.temp_dir,
                    "Folder for temporary files (default: beside the output)");
  bool lossy = false, exact_alias = false;
  build->add_flag("--lossy", lossy,
                  "Leaves keep positions within a quarter of their spacing (Euclidean) instead of "
                  "the input's own coordinates (a LAS scale factor; a 1024th of the leaf spacing "
                  "for inputs that declare none): a smaller store, not for measuring");
  build->add_flag("--exact-leaves", exact_alias,
                  "The default: leaves keep the input's own coordinates (accepted for scripts)");
  build->add_flag("--quiet", bo.quiet, "No progress output");
  bool build_ao = false;
  build->add_flag("--ao", build_ao,
                  "Points carry multi-view ambient occlusion of their scans (as `tessera-lod "
                  "ao --method mvao` with its defaults); every input must be registered range "
                  "scans with poses (a Stanford .conf, a range-grid PLY, an E57)");
  MeshBuildOptions mbo;
  build
      ->add_option("--patch-triangles", mbo.patch_triangles,
                   ".tmesh: triangles per patch (leaves, and inner nodes' target)")
      ->check(cli::integerRange<uint32_t>(64, 1u << 20))
      ->capture_default_str();
  build->add_option("--arity", mbo.arity, ".tmesh: children per inner patch")
      ->check(cli::integerRange<uint32_t>(2, 8))
      ->capture_default_str();
  build
      ->add_option("--block-triangles", mbo.block_triangles,
                   ".tmesh: build in blocks of at most this many triangles (default: in blocks "
                   "only when the whole build would not fit --memory-mb, as large as it allows)")
      ->check(cli::integerRange<uint64_t>(64, uint64_t(1) << 40));

  std::string ao_in, ao_out, ao_method = "mvao";
  AoOptions aoo;
  BuildOptions abo;
  auto* ao = app.add_subcommand(
      "ao",
      "Ambient occlusion of range scans (Sabbadin et al. 2016: per-scan SSAO, multi-view "
      "integration) into a point store whose points carry it");
  ao->add_option("SCANS", ao_in, "Registered range scans: a Stanford .conf, a range-grid PLY or "
                                 "an E57 (scans without a grid are projected orthographically)")
      ->required();
  ao->add_option("-o,--output", ao_out, "Output store (.tlod, format version 3)")->required();
  ao->add_option("--tmax", aoo.t_max,
                 "Falloff distance t_max of the occlusion, scan units (0: 5% of the diagonal)")
      ->check(cli::finiteRange(0.0, 1e12))
      ->capture_default_str();
  ao->add_option("--radius", aoo.radius, "Screen-space disk radius r_s, scan units (0: t_max / 2)")
      ->check(cli::finiteRange(0.0, 1e12))
      ->capture_default_str();
  ao->add_option("--samples", aoo.samples, "SSAO samples per point")
      ->check(cli::integerRange(1, 4096))
      ->capture_default_str();
  ao->add_option("--neighbours", aoo.neighbours,
                 "Samples per scan in the integration: 1, 3 (3x3) or 5 (5x5)")
      ->check(CLI::IsMember({1, 3, 5}))
      ->capture_default_str();
  ao->add_option("--method", ao_method,
                 "ssao: each point's own scan; mvao: multi-view integration; grid: the real-time "
                 "voxel grid")
      ->check(CLI::IsMember({"ssao", "mvao", "grid"}))
      ->capture_default_str();
  ao->add_option("--angle-bias", aoo.angle_bias,
                 "SSAO angle bias: samples less than asin(B) above the tangent plane do not "
                 "occlude (0: eq. 5 as written; 0.1 removes most of the darkening of open "
                 "surfaces by normal error and noise)")
      ->check(cli::finiteRange(0.0, 0.49))
      ->capture_default_str();
  ao->add_option("--seed", aoo.seed, "Sample seed (same seed, same store)")
      ->check(cli::anyInteger<uint64_t>())
      ->capture_default_str();
  ao->add_option("--threads", aoo.threads, "Threads (0: every core)")
      ->check(cli::integerRange(0, kMaxThreads))
      ->capture_default_str();
  ao->add_flag("--quiet", abo.quiet, "No progress output");

  std::string verify_store;
  std::vector<std::string> verify_in;
  BuildOptions vo;
  auto* verify = app.add_subcommand(
      "verify", "Check that every input point is in a store within its error bound");
  verify->add_option("STORE", verify_store, "The .tlod or .tmesh store")->required();
  verify->add_option("IN", verify_in, "The inputs it was built from")->required();
  verify->add_option("--memory-mb", vo.memory_mb, "Memory budget in MB")
      ->check(cli::integerRange<uint64_t>(64, 1 << 20))
      ->capture_default_str();
  verify->add_flag("--quiet", vo.quiet, "No progress output");

  PhotoOptions po;
  std::string photo_image, photo_height, photo_corner, photo_u, photo_v, photo_out;
  BuildOptions pbo;
  auto* photo = app.add_subcommand(
      "photo",
      "Turn a photo into points on a rectangle in 3D (displaced by a height map, 1/cos(phi) "
      "copies), to fuse with scans in see-through views");
  photo->add_option("IMAGE", photo_image, "The photo (PNG)")->required();
  photo->add_option("--height", photo_height, "Height map (PNG, grey levels)");
  photo->add_option("--height-scale", po.height_scale, "Metres at full grey level")
      ->check(cli::finiteRange(0.0, 1e9))
      ->capture_default_str();
  photo->add_option("--corner", photo_corner, "X,Y,Z of the picture's lower-left corner")
      ->required();
  photo->add_option("--u", photo_u, "X,Y,Z: the picture's width, lower-left to lower-right")
      ->required();
  photo->add_option("--v", photo_v, "X,Y,Z: the picture's height, lower-left to upper-left")
      ->required();
  photo->add_option("--seed", po.seed, "Seed of the fractional copies")
      ->check(cli::anyInteger<decltype(po.seed)>())
      ->capture_default_str();
  photo->add_option("-o,--output", photo_out, "Output store (.tlod) or points (.ply)")->required();
  photo->add_flag("--quiet", pbo.quiet, "No progress output");

  std::string export_in, export_out, export_box, export_selection;
  std::vector<std::string> export_planes;
  ExportOptions eo;
  auto* exp = app.add_subcommand(
      "export",
      "Write the points of a scan or a store, or the part inside a box or planes, as LAS, LAZ or "
      "PLY for another program. LAS or LAZ in and out: the records are copied with every "
      "attribute, scale, offset and VLR. Other scans and .tlod stores (their leaves: every input "
      "point once, at the positions the store keeps) become LAS 1.4 point format 7 (6 without "
      "colour) with intensity and classification; PLY out is binary with double positions. "
      "Waveform packets (LAS formats 4, 5, 9, 10) are not exported");
  exp->add_option("IN", export_in,
                  "A scan (PLY, LAS, LAZ, E57, .conf, XYZ/PTS/TXT, OBJ) or a .tlod store")
      ->required();
  exp->add_option("-o,--output", export_out, "OUT.las, OUT.laz or OUT.ply (never an input)")
      ->required();
  exp->add_option("--box", export_box,
                  "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX: keep the points inside (world coordinates)");
  exp->add_option("--plane", export_planes,
                  "A,B,C,D: keep the points with A*x + B*y + C*z + D >= 0 (repeat for several)");
  exp->add_option("--selection", export_selection,
                  "DB:ID: only the points of the region selected at place ID of the annotation "
                  "database DB (a lasso or lazy snapping on the .tlod store IN)");
  exp->add_option("--scale", eo.scale,
                  "Coordinate resolution of converted points (default: the input's own, else "
                  "0.0001); copied LAS records keep theirs")
      ->check(cli::positiveFinite(1e6));
  exp->add_option("--threads", eo.threads, "Threads for LAZ chunks (0: every core)")
      ->check(cli::integerRange(0u, 64u))
      ->capture_default_str();
  bool export_quiet = false;
  exp->add_flag("--quiet", export_quiet, "No progress bar");

  // CLI11 reads the --config file before any validator runs: a FIFO there would block it.
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::string(argv[i]) != "--config") continue;
    if (const auto why = tessera::notRegularFile(argv[i + 1]);
        why && std::filesystem::exists(argv[i + 1]))
      throw cli::UsageError(std::string("--config ") + argv[i + 1] + ": " + *why);
  }
  if (const auto code = cli::parse(app, argc, argv, "tessera-lod")) return *code;
  if (*photo) {
    po.image = photo_image;
    po.height = photo_height;
    po.corner = cli::parseVec3(photo_corner, "--corner");
    po.u = cli::parseVec3(photo_u, "--u");
    po.v = cli::parseVec3(photo_v, "--v");
    if (!photo_height.empty() && !(po.height_scale > 0))
      throw cli::UsageError("--height needs a positive --height-scale");
    return runPhoto(po, photo_out, pbo);
  }
  if (*build) {
    mbo.threads = bo.threads;
    mbo.quiet = bo.quiet;
    mbo.temp_dir = bo.temp_dir;
    if (bo.memory_mb != BuildOptions{}.memory_mb) mbo.memory_mb = bo.memory_mb;
    if (lossy && exact_alias)
      throw cli::UsageError("--lossy and --exact-leaves contradict each other");
    bo.exact_leaves = !lossy;
    return runBuild(build_in, build_out, bo, mbo, build_ao);
  }
  if (*verify) return runVerify(verify_store, verify_in, vo);
  if (*ao) {
    abo.threads = aoo.threads;
    return runAo(ao_in, ao_out, ao_method, aoo, abo);
  }
  if (*exp) {
    eo.quiet = export_quiet;
    return runExport(export_in, export_out, export_box, export_planes, export_selection, eo);
  }
  if (*info) return runInfo(info_files, info_json, info_quiet);
  if (*scan) return runScan(scan_mesh, scan_out, scan_res, so);
  return kExitBadCommandLine;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runMain("tessera-lod", [&] { return run(argc, argv); });
}
