// mvao: multi-view ambient occlusion (lod/ambient_occlusion.h) on the ten Stanford bunny scans.
// Times the pipeline end to end (load, SSAO, integration) and each method's error against two
// Embree references, the reconstruction mesh and the scans' discs (mean |AO - reference| on
// every --stride-th point, on all points and the grazing, border and thin subsets, the signed
// mean and the 95th percentile), with eq. 5 as written and with the angle bias 0.1; writes
// OUT/mvao.csv, OUT/mvao_error.png (error against SSAO samples per subset) and pictures: per
// scan SSAO | MVAO | disc reference | mesh reference in the range map's image space (gamma 4,
// as the paper's figures), and the whole bunny in the same order. With --virtual-scanners it
// also times SSAO and the integration on a virtual scan of the mesh (points per second). The
// methods run in one process, each the best of --rounds.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>

#include <tessera/lod/ambient_occlusion.h>
#include <tessera/lod/mesh.h>
#include <tessera/lod/virtual_scanner.h>
#include <tessera/render/image.h>

#include "bench_stats.h"

namespace {

using namespace tessera;
using namespace tessera::lod;
using Clock = std::chrono::steady_clock;

double since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

uint8_t grey(float v) {
  return uint8_t(std::lround(std::pow(std::clamp(v, 0.0f, 1.0f), 4.0f) * 255.0f));
}

/// The point subsets accuracy is reported on (ambient_occlusion.h's grazingPoint(),
/// borderPoint(); thin: the mesh is less than t_max / 2 thick behind the point).
const char* const kSubsets[] = {"all", "grazing", "border", "thin"};
constexpr int kSubsetCount = 4;
const char* const kRefs[] = {"discs", "mesh"};

struct Row {
  std::string method;
  int samples = 0;
  double seconds = 0;
  double mean[2][kSubsetCount] = {};  ///< [reference][subset] mean |AO - reference|
  double p95[2] = {};                 ///< over all points, per reference
  double bias[2] = {};                ///< mean AO - reference over all points
};

struct Sample {
  std::vector<uint32_t> points;
  std::vector<float> ref[2];
  std::vector<uint8_t> in[kSubsetCount];
};

void errorsOf(Row& r, const std::vector<float>& ao, const Sample& s) {
  for (int f = 0; f < 2; ++f) {
    std::vector<double> all;
    for (int c = 0; c < kSubsetCount; ++c) {
      double sum = 0;
      size_t n = 0;
      for (size_t k = 0; k < s.points.size(); ++k) {
        if (!s.in[c][k]) continue;
        const double d = std::abs(double(ao[s.points[k]]) - s.ref[f][k]);
        sum += d;
        ++n;
        if (c == 0) all.push_back(d), r.bias[f] += double(ao[s.points[k]]) - s.ref[f][k];
      }
      r.mean[f][c] = sum / double(std::max<size_t>(1, n));
    }
    r.p95[f] = bench::percentile(all, 0.95);
    r.bias[f] /= double(std::max<size_t>(1, all.size()));
  }
}

/// One scan's panels side by side in its grid (rows top first), each value per point (negative:
/// not drawn).
void rangeMapPicture(const ScanSet& set, uint16_t scan,
                     const std::vector<const std::vector<float>*>& panels,
                     const std::string& path) {
  const RangeMap& m = set.maps[scan];
  const uint32_t count = uint32_t(panels.size());
  render::Image img;
  img.width = count * (m.columns + 4);
  img.height = m.rows;
  img.rgba.assign(size_t(img.width) * img.height * 4, 0);
  for (size_t i = 0; i < img.rgba.size(); i += 4) {
    img.rgba[i] = 30, img.rgba[i + 1] = 34, img.rgba[i + 2] = 48, img.rgba[i + 3] = 255;
  }
  for (size_t i = 0; i < set.size(); ++i) {
    if (set.scan_of_point[i] != scan) continue;
    const size_t px = set.pixel_of_point[i];
    for (uint32_t panel = 0; panel < count; ++panel) {
      const float v = (*panels[panel])[i];
      if (v < 0) continue;
      const size_t x = px % m.columns + panel * (m.columns + 4), y = px / m.columns;
      uint8_t* o = &img.rgba[(y * img.width + x) * 4];
      o[0] = o[1] = o[2] = grey(v);
    }
  }
  render::writePng(path, img);
}

/// The whole bunny seen from +z (orthographic, nearest point per pixel, 2x2 splats), one panel
/// per value (negative: not drawn).
void bunnyPicture(const ScanSet& set, const std::vector<const std::vector<float>*>& panels,
                  const std::string& path) {
  glm::dvec3 lo(1e300), hi(-1e300);
  for (auto& p : set.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
  const uint32_t S = 560;
  const int count = int(panels.size());
  const double scale = (S - 20) / std::max(hi.x - lo.x, hi.y - lo.y);
  render::Image img;
  img.width = uint32_t(count) * S;
  img.height = S;
  img.rgba.assign(size_t(img.width) * img.height * 4, 255);
  std::vector<double> depth(size_t(img.width) * img.height, -1e300);
  for (size_t i = 0; i < set.size(); ++i) {
    if ((*panels[0])[i] < 0) continue;
    const glm::dvec3& p = set.positions[i];
    int x = int((p.x - lo.x) * scale) + 10, y = int(S - 10 - (p.y - lo.y) * scale);
    for (int panel = 0; panel < count; ++panel)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          int px = x + dx + panel * int(S), py = y + dy;
          if (px < 0 || py < 0 || px >= int(img.width) || py >= int(S)) continue;
          size_t k = size_t(py) * img.width + size_t(px);
          if (p.z <= depth[k]) continue;
          depth[k] = p.z;
          uint8_t g = grey((*panels[panel])[i]);
          img.rgba[k * 4] = img.rgba[k * 4 + 1] = img.rgba[k * 4 + 2] = g;
        }
  }
  render::writePng(path, img);
}

/// Section 4 and 5 on a virtual scan of `mesh` with `scanners` x `per_scan` points: points per
/// second of SSAO and of the integration (borders + eq. 6-12, 1x1).
void virtualThroughput(const std::string& mesh_path, int scanners, uint32_t per_scan,
                       const std::string& dir, int samples) {
  Mesh mesh = readMesh(mesh_path);
  ScanOptions so;
  so.scanners = scanners;
  so.binary = true;
  so.quiet = true;
  so.units_per_mm = 0.001;
  // A pilot scan at 200 x 160 measures how much of each view the model fills; the grid is then
  // sized for `per_scan` points a scanner (5:4).
  so.columns = 200;
  so.rows = 160;
  const ScanResult pilot = scanMesh(mesh, dir + "/pilot", so);
  std::filesystem::remove_all(dir + "/pilot");
  const double fill = double(pilot.points) / double(pilot.rays);
  const double rays = double(per_scan) / std::max(fill, 1e-3);
  so.columns = uint32_t(std::min(65000.0, std::ceil(std::sqrt(rays * 1.25))));
  so.rows = uint32_t(std::min(65000.0, std::ceil(rays / so.columns)));
  auto t = Clock::now();
  ScanResult scan = scanMesh(mesh, dir, so);
  const double seconds_scan = since(t);
  t = Clock::now();
  ScanSet set = loadScans(scan.conf);
  const double seconds_load = since(t);
  AoOptions o;
  o.samples = samples;
  o = resolveAoOptions(set, o);
  t = Clock::now();
  for (size_t j = 0; j < set.maps.size(); ++j) computeSsao(set.maps[j], uint32_t(j), o);
  const double seconds_ssao = since(t);
  t = Clock::now();
  for (auto& m : set.maps) computeBorders(m, o.threads);
  std::vector<float> mv = integrateMvao(set, o);
  const double seconds_int = since(t);
  std::printf(
      "virtual scan: %d scanners x %ux%u grid, %zu points (scan %.1f s, load %.1f s); "
      "ssao %d samples %.2f s = %.2f Mpoints/s; borders + mvao 1x1 %.2f s = %.2f "
      "Mpoints/s\n",
      scanners, so.columns, so.rows, set.size(), seconds_scan, seconds_load, samples, seconds_ssao,
      double(set.size()) / seconds_ssao * 1e-6, seconds_int,
      double(set.size()) / seconds_int * 1e-6);
  std::filesystem::remove_all(dir);  // hundreds of megabytes of scans at full size
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"mvao: multi-view ambient occlusion of the bunny scans, time and error"};
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  std::string conf = std::string(TESSERA_DATA_DIR) + "/stanford-bunny/scans/bun.conf";
  std::string mesh_path =
      std::string(TESSERA_DATA_DIR) + "/stanford-bunny/reconstruction/bun_zipper.ply";
  int rounds = 3, rays = 256, picture_stride = 3, stride = 8;
  int virtual_scanners = 0;
  uint32_t virtual_per_scan = 400000;
  bool pictures = true;
  app.add_option("--out", out, "Folder for CSV, charts and pictures")->capture_default_str();
  app.add_option("--scans", conf, "Registered range scans (.conf)")->capture_default_str();
  app.add_option("--mesh", mesh_path, "Their surface reconstruction (second reference)")
      ->capture_default_str();
  app.add_option("--rounds", rounds, "Rounds per method (best kept)")->capture_default_str();
  app.add_option("--rays", rays, "Reference rays per point")->capture_default_str();
  app.add_option("--stride", stride, "Reference on every Nth point")->capture_default_str();
  app.add_option("--picture-stride", picture_stride,
                 "Reference for every Nth point of the whole-bunny picture")
      ->capture_default_str();
  app.add_flag("!--no-pictures", pictures, "Skip the pictures");
  app.add_option("--virtual-scanners", virtual_scanners,
                 "Also time a virtual scan of the mesh with this many scanners (0: none)")
      ->capture_default_str();
  app.add_option("--virtual-points", virtual_per_scan, "Points per virtual scanner")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  std::filesystem::create_directories(out);

  // End to end: load, SSAO (32 samples), borders + MVAO (1 sample per scan).
  double best_load = 1e30, best_ssao = 1e30, best_int = 1e30;
  ScanSet set;
  AoOptions o;
  for (int r = 0; r < rounds; ++r) {
    auto t = Clock::now();
    set = loadScans(conf);
    best_load = std::min(best_load, since(t));
    o = resolveAoOptions(set, {});
    t = Clock::now();
    for (size_t j = 0; j < set.maps.size(); ++j) computeSsao(set.maps[j], uint32_t(j), o);
    best_ssao = std::min(best_ssao, since(t));
    t = Clock::now();
    for (auto& m : set.maps) computeBorders(m, o.threads);
    integrateMvao(set, o);
    best_int = std::min(best_int, since(t));
  }
  std::printf(
      "bunny: %zu scans, %zu points; load %.2f s, ssao %.2f s, integration %.2f s, "
      "end to end %.2f s (best of %d); t_max %.5f, r_s %.5f\n",
      set.maps.size(), set.size(), best_load, best_ssao, best_int, best_load + best_ssao + best_int,
      rounds, o.t_max, o.radius);
  if (virtual_scanners > 0)
    virtualThroughput(mesh_path, virtual_scanners, virtual_per_scan, out + "/virtual_scan", 32);

  const Mesh mesh = readMesh(mesh_path);
  Sample sample;
  for (uint32_t i = 0; i < set.size(); i += uint32_t(stride)) sample.points.push_back(i);
  auto t = Clock::now();
  sample.ref[0] = referenceAo(set, sample.points, rays, o);
  const double disc_seconds = since(t);
  t = Clock::now();
  MeshAoReference mref = meshReferenceAo(set, mesh, sample.points, rays, o);
  sample.ref[1] = mref.ao;
  const double mesh_seconds = since(t);
  for (uint32_t i : sample.points) {
    sample.in[0].push_back(1);
    sample.in[1].push_back(grazingPoint(set, i));
    sample.in[2].push_back(borderPoint(set, i));
  }
  std::vector<double> dist;
  for (size_t k = 0; k < sample.points.size(); ++k) {
    sample.in[3].push_back(mref.thickness[k] < 0.5 * o.t_max);
    dist.push_back(mref.distance[k]);
  }
  // Residual of each reference: the same points at 4x the rays.
  std::vector<uint32_t> few;
  for (size_t k = 0; k < sample.points.size() && few.size() < 4000; k += 4)
    few.push_back(sample.points[k]);
  std::vector<float> fine[2] = {referenceAo(set, few, 4 * rays, o),
                                meshReferenceAo(set, mesh, few, 4 * rays, o).ao};
  for (int f = 0; f < 2; ++f) {
    std::vector<double> resid;
    for (size_t k = 0; k < few.size(); ++k)
      resid.push_back(std::abs(fine[f][k] - sample.ref[f][4 * k]));
    double m = 0;
    for (double x : resid) m += x;
    std::printf("%s reference: against %d rays: mean %.4f, p95 %.4f\n", kRefs[f], 4 * rays,
                m / double(resid.size()), bench::percentile(resid, 0.95));
  }
  std::printf(
      "references: %zu points x %d rays, discs %.1f s, mesh %.1f s; points to mesh: "
      "median %.5f, p95 %.5f (median edge %.5f)\n",
      sample.points.size(), rays, disc_seconds, mesh_seconds, bench::percentile(dist, 0.5),
      bench::percentile(dist, 0.95), mref.edge);
  {
    Row rr;
    rr.method = "discs-vs-mesh";
    std::vector<float> disc_all(set.size(), 0.0f);
    for (size_t k = 0; k < sample.points.size(); ++k) disc_all[sample.points[k]] = sample.ref[0][k];
    errorsOf(rr, disc_all, sample);
    std::printf("discs against mesh: all %.4f grazing %.4f border %.4f thin %.4f; subset sizes",
                rr.mean[1][0], rr.mean[1][1], rr.mean[1][2], rr.mean[1][3]);
    for (int c = 0; c < kSubsetCount; ++c) {
      size_t n = 0;
      for (uint8_t x : sample.in[c]) n += x;
      std::printf(" %s %zu", kSubsets[c], n);
    }
    double mean[2] = {};
    for (int f = 0; f < 2; ++f) {
      for (float x : sample.ref[f]) mean[f] += x;
      mean[f] /= double(sample.points.size());
    }
    std::printf("; mean reference discs %.4f mesh %.4f\n", mean[0], mean[1]);
    // Where the discs read darker than the mesh by more than 0.3: how far the point's own
    // normal (the scan's, which the disc reference starts its rays around) is from the mesh's.
    std::vector<double> angle_all, angle_dark;
    for (size_t k = 0; k < sample.points.size(); ++k) {
      const double c = glm::dot(set.normal(sample.points[k]), glm::dvec3(mref.normal[k]));
      const double deg = std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / 3.141592653589793;
      angle_all.push_back(deg);
      if (sample.ref[0][k] < sample.ref[1][k] - 0.3f) angle_dark.push_back(deg);
    }
    std::printf(
        "scan normal against mesh normal: median %.1f deg (p95 %.1f) on all points, "
        "%.1f (p95 %.1f) on the %zu points the discs read 0.3 darker\n",
        bench::percentile(angle_all, 0.5), bench::percentile(angle_all, 0.95),
        angle_dark.empty() ? 0.0 : bench::percentile(angle_dark, 0.5),
        angle_dark.empty() ? 0.0 : bench::percentile(angle_dark, 0.95), angle_dark.size());
  }

  {
    // Where MVAO takes its values from: the own scan's share of eq. 8's weight, per subset.
    std::vector<float> share;
    integrateMvao(set, o, &share);
    std::printf("own scan's share of the weight:");
    for (int c = 0; c < kSubsetCount; ++c) {
      double sum = 0;
      size_t n = 0, alone = 0;
      for (size_t k = 0; k < sample.points.size(); ++k)
        if (sample.in[c][k])
          sum += share[sample.points[k]], ++n, alone += share[sample.points[k]] > 0.999f;
      std::printf(" %s %.3f (alone %.3f)", kSubsets[c], sum / double(std::max<size_t>(1, n)),
                  double(alone) / double(std::max<size_t>(1, n)));
    }
    std::printf("\n");
    // The estimator's bias where the mesh says the surface is open: no view can remove it.
    const std::vector<float> ssao = ownSsao(set), mv = integrateMvao(set, o);
    double sum_s = 0, sum_m = 0;
    size_t open = 0;
    for (size_t k = 0; k < sample.points.size(); ++k)
      if (sample.ref[1][k] > 0.999f)
        sum_s += ssao[sample.points[k]], sum_m += mv[sample.points[k]], ++open;
    std::printf(
        "points the mesh reference finds open (> 0.999): %zu of %zu, ssao mean %.4f, "
        "mvao 1x1 mean %.4f\n",
        open, sample.points.size(), sum_s / double(std::max<size_t>(1, open)),
        sum_m / double(std::max<size_t>(1, open)));
  }

  std::vector<Row> rows;
  auto timed = [&](const std::function<std::vector<float>()>& f, double& best) {
    std::vector<float> v;
    best = 1e30;
    for (int r = 0; r < rounds; ++r) {
      auto t0 = Clock::now();
      v = f();
      best = std::min(best, since(t0));
    }
    return v;
  };
  // Eq. 5 as written (angle bias 0), then with the angle bias 0.1 (methods suffixed "-b").
  for (int variant = 0; variant < 2; ++variant)
    for (int samples : {8, 16, 32, 64}) {
      AoOptions os = o;
      os.samples = samples;
      os.angle_bias = variant ? 0.1 : 0.0;
      const std::string suffix = variant ? "-b" : "";
      Row r;
      r.method = "ssao" + suffix;
      r.samples = samples;
      auto v = timed(
          [&] {
            for (size_t j = 0; j < set.maps.size(); ++j) computeSsao(set.maps[j], uint32_t(j), os);
            return ownSsao(set);
          },
          r.seconds);
      errorsOf(r, v, sample);
      rows.push_back(r);
      for (int nb : {1, 3, 5}) {
        AoOptions om = os;
        om.neighbours = nb;
        Row m;
        m.method = "mvao" + std::to_string(nb) + "x" + std::to_string(nb) + suffix;
        m.samples = samples;
        double secs;
        auto mv = timed(
            [&] {
              for (auto& mp : set.maps) computeBorders(mp, om.threads);
              return integrateMvao(set, om);
            },
            secs);
        m.seconds = r.seconds + secs;
        errorsOf(m, mv, sample);
        rows.push_back(m);
      }
      Row g;
      g.method = "grid" + suffix;
      g.samples = samples;
      double secs;
      auto gv = timed([&] { return gridMvao(set, os); }, secs);
      g.seconds = r.seconds + secs;
      errorsOf(g, gv, sample);
      rows.push_back(g);
    }
  const std::string csv = out + "/mvao.csv";
  {
    std::ofstream f(csv);
    std::string head = "method,samples,seconds";
    for (int rf = 0; rf < 2; ++rf) {
      head += std::string(",") + kRefs[rf] + "_bias," + kRefs[rf] + "_p95";
      for (int c = 0; c < kSubsetCount; ++c)
        head += std::string(",") + kRefs[rf] + "_" + kSubsets[c];
    }
    f << head << "\n";
    std::printf("%s\n", head.c_str());
    for (auto& r : rows) {
      char line[512];
      int n =
          std::snprintf(line, sizeof line, "%s,%d,%.3f", r.method.c_str(), r.samples, r.seconds);
      for (int rf = 0; rf < 2; ++rf) {
        n += std::snprintf(line + n, sizeof line - size_t(n), ",%.4f,%.4f", r.bias[rf], r.p95[rf]);
        for (int c = 0; c < kSubsetCount; ++c)
          n += std::snprintf(line + n, sizeof line - size_t(n), ",%.4f", r.mean[rf][c]);
      }
      f << line << "\n";
      std::printf("%s\n", line);
    }
  }
  if (pictures) {
    // Pictures: SSAO and MVAO 5x5 at 32 samples, the two references.
    AoOptions op = o;
    op.neighbours = 5;
    for (size_t j = 0; j < set.maps.size(); ++j) computeSsao(set.maps[j], uint32_t(j), op);
    for (auto& m : set.maps) computeBorders(m, op.threads);
    std::vector<float> mvao = integrateMvao(set, op), ssao = ownSsao(set);
    std::vector<float> ref_all[2] = {std::vector<float>(set.size(), -1.0f),
                                     std::vector<float>(set.size(), -1.0f)};
    auto fill = [&](const std::vector<uint32_t>& pts) {
      std::vector<float> r = referenceAo(set, pts, rays, o);
      std::vector<float> mr = meshReferenceAo(set, mesh, pts, rays, o).ao;
      for (size_t k = 0; k < pts.size(); ++k) {
        ref_all[0][pts[k]] = r[k];
        ref_all[1][pts[k]] = mr[k];
      }
    };
    for (uint16_t scan : {uint16_t(0), uint16_t(5)}) {
      std::vector<uint32_t> mine;
      for (uint32_t i = 0; i < set.size(); ++i)
        if (set.scan_of_point[i] == scan) mine.push_back(i);
      fill(mine);
      rangeMapPicture(set, scan, {&ssao, &mvao, &ref_all[0], &ref_all[1]},
                      out + "/mvao_scan_" +
                          std::filesystem::path(set.maps[scan].name).stem().string() + ".png");
    }
    std::vector<uint32_t> some;
    for (uint32_t i = 0; i < set.size(); i += uint32_t(picture_stride))
      if (ref_all[0][i] < 0) some.push_back(i);
    fill(some);
    std::vector<float> mvao_shown(set.size(), -1.0f), ssao_shown(set.size(), -1.0f);
    for (uint32_t i = 0; i < set.size(); ++i)
      if (ref_all[0][i] >= 0) mvao_shown[i] = mvao[i], ssao_shown[i] = ssao[i];
    bunnyPicture(set, {&ssao_shown, &mvao_shown, &ref_all[0], &ref_all[1]},
                 out + "/mvao_bunny.png");
  }

  const std::string gp = out + "/mvao.gp";
  {
    std::ofstream f(gp);
    // Columns: 1 method, 2 samples, 3 seconds, 4 discs bias, 5 discs p95, 6-9 discs
    // all/grazing/border/thin, 10 mesh bias, 11 mesh p95, 12-15 mesh all/grazing/border/thin.
    f << "set terminal pngcairo size 1200,800\nset output '" << out << "/mvao_error.png'\n"
      << "set datafile separator ','\nset key top right font ',8'\nset multiplot layout 2,2\n"
      << "set xlabel 'SSAO samples'\nset logscale x 2\nset xrange [6:85]\nset xtics (8,16,32,64)\n"
      << "set ylabel 'mean |AO - reference|'\n";
    const char* panels[4][2] = {{"12", "mesh reference, all points"},
                                {"13", "mesh reference, grazing"},
                                {"14", "mesh reference, border"},
                                {"15", "mesh reference, thin"}};
    for (auto& p : panels) {
      f << "set title '" << p[1] << "'\nplot ";
      const char* methods[] = {"ssao", "mvao1x1", "mvao5x5", "ssao-b", "mvao1x1-b", "mvao5x5-b"};
      for (int k = 0; k < 6; ++k)
        f << (k ? ", " : "") << "'" << csv << "' using 2:(stringcolumn(1) eq '" << methods[k]
          << "' ? $" << p[0] << " : 1/0) smooth unique with linespoints title '" << methods[k]
          << "'";
      f << "\n";
    }
    f << "unset multiplot\n";
  }
  std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp + "'";
  if (std::system(cmd.c_str()) != 0)
    std::fprintf(stderr, "mvao: gnuplot failed; the CSV is complete\n");
  std::printf(
      "wrote %s, %s/mvao_error.png, pictures in %s\nreproduce: %s --out %s --rounds %d "
      "--stride %d --virtual-scanners %d --virtual-points %u\n",
      csv.c_str(), out.c_str(), out.c_str(), argv[0], out.c_str(), rounds, stride, virtual_scanners,
      virtual_per_scan);
  return 0;
}
