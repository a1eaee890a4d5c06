// mvao: multi-view ambient occlusion (lod/ambient_occlusion.h) on the ten Stanford bunny scans.
// Times the pipeline end to end (load, SSAO, integration) and each method's error against the
// Embree reference (mean and 95th percentile of |AO - reference| per point, on every 8th point,
// also on the grazing and border subsets); writes OUT/mvao.csv, OUT/mvao_error.png (error
// against time per method) and pictures: per scan SSAO | MVAO | reference in the range map's
// image space (gamma 4, as the paper's figures), and the whole bunny with MVAO beside the
// reference. The methods run in one process, each the best of --rounds.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>

#include <tessera/lod/ambient_occlusion.h>
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

struct Row {
  std::string method;
  double seconds = 0;
  double mean = 0, p95 = 0, grazing = 0, border = 0;
};

void errorsOf(Row& r, const std::vector<float>& ao, const std::vector<float>& ref,
              const std::vector<uint32_t>& pts, const std::vector<bool>& graz,
              const std::vector<bool>& bord) {
  std::vector<double> e;
  double g = 0, b = 0;
  size_t ng = 0, nb = 0;
  for (size_t k = 0; k < pts.size(); ++k) {
    double d = std::abs(double(ao[pts[k]]) - ref[k]);
    e.push_back(d);
    if (graz[k]) g += d, ++ng;
    if (bord[k]) b += d, ++nb;
  }
  for (double x : e) r.mean += x;
  r.mean /= double(e.size());
  r.p95 = bench::percentile(e, 0.95);
  r.grazing = g / double(std::max<size_t>(1, ng));
  r.border = b / double(std::max<size_t>(1, nb));
}

/// One scan's SSAO | MVAO | reference side by side in its grid (rows top first).
void rangeMapPicture(const ScanSet& set, uint16_t scan, const std::vector<float>& mvao,
                     const std::vector<float>& ref_all, const std::string& path) {
  const RangeMap& m = set.maps[scan];
  render::Image img;
  img.width = 3 * m.columns + 8;
  img.height = m.rows;
  img.rgba.assign(size_t(img.width) * img.height * 4, 0);
  for (size_t i = 0; i < img.rgba.size(); i += 4) {
    img.rgba[i] = 30, img.rgba[i + 1] = 34, img.rgba[i + 2] = 48, img.rgba[i + 3] = 255;
  }
  auto put = [&](uint32_t panel, size_t px, float v) {
    size_t x = px % m.columns + panel * (m.columns + 4), y = px / m.columns;
    uint8_t g = grey(v);
    uint8_t* o = &img.rgba[(y * img.width + x) * 4];
    o[0] = o[1] = o[2] = g;
  };
  for (size_t i = 0; i < set.size(); ++i) {
    if (set.scan_of_point[i] != scan) continue;
    size_t px = set.pixel_of_point[i];
    put(0, px, m.ssao[px]);
    put(1, px, mvao[i]);
    if (ref_all[i] >= 0) put(2, px, ref_all[i]);
  }
  render::writePng(path, img);
}

/// The whole bunny seen from +z (orthographic, nearest point per pixel, 2x2 splats): MVAO on the
/// left, the reference on the right; only points with a reference are drawn.
void bunnyPicture(const ScanSet& set, const std::vector<float>& mvao,
                  const std::vector<float>& ref_all, const std::string& path) {
  glm::dvec3 lo(1e300), hi(-1e300);
  for (auto& p : set.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
  const uint32_t S = 640;
  const double scale = (S - 20) / std::max(hi.x - lo.x, hi.y - lo.y);
  render::Image img;
  img.width = 2 * S;
  img.height = S;
  img.rgba.assign(size_t(img.width) * img.height * 4, 255);
  std::vector<double> depth(size_t(img.width) * img.height, -1e300);
  for (size_t i = 0; i < set.size(); ++i) {
    if (ref_all[i] < 0) continue;
    const glm::dvec3& p = set.positions[i];
    int x = int((p.x - lo.x) * scale) + 10, y = int(S - 10 - (p.y - lo.y) * scale);
    for (int panel = 0; panel < 2; ++panel)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          int px = x + dx + panel * int(S), py = y + dy;
          if (px < 0 || py < 0 || px >= int(img.width) || py >= int(S)) continue;
          size_t k = size_t(py) * img.width + size_t(px);
          if (p.z <= depth[k]) continue;
          depth[k] = p.z;
          uint8_t g = grey(panel == 0 ? mvao[i] : ref_all[i]);
          img.rgba[k * 4] = img.rgba[k * 4 + 1] = img.rgba[k * 4 + 2] = g;
        }
  }
  render::writePng(path, img);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"mvao: multi-view ambient occlusion of the bunny scans, time and error"};
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  std::string conf = std::string(TESSERA_DATA_DIR) + "/stanford-bunny/scans/bun.conf";
  int rounds = 3, rays = 256, picture_stride = 3;
  app.add_option("--out", out, "Folder for CSV, charts and pictures")->capture_default_str();
  app.add_option("--scans", conf, "Registered range scans (.conf)")->capture_default_str();
  app.add_option("--rounds", rounds, "Rounds per method (best kept)")->capture_default_str();
  app.add_option("--rays", rays, "Reference rays per point")->capture_default_str();
  app.add_option("--picture-stride", picture_stride,
                 "Reference for every Nth point of the whole-bunny picture")
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
  std::printf("bunny: %zu scans, %zu points; load %.2f s, ssao %.2f s, integration %.2f s, "
              "end to end %.2f s (best of %d)\n",
              set.maps.size(), set.size(), best_load, best_ssao, best_int,
              best_load + best_ssao + best_int, rounds);

  std::vector<uint32_t> pts;
  for (uint32_t i = 0; i < set.size(); i += 8) pts.push_back(i);
  auto t = Clock::now();
  std::vector<float> ref = referenceAo(set, pts, rays, o);
  const double ref_seconds = since(t);
  // Residual of the reference: the same points at 4x the rays.
  std::vector<uint32_t> few(pts.begin(), pts.begin() + std::min<size_t>(pts.size(), 4000));
  std::vector<float> fine = referenceAo(set, few, 4 * rays, o);
  std::vector<double> resid;
  for (size_t k = 0; k < few.size(); ++k) resid.push_back(std::abs(fine[k] - ref[k]));
  double resid_mean = 0;
  for (double x : resid) resid_mean += x;
  resid_mean /= double(resid.size());
  std::printf("reference: %zu points x %d rays in %.1f s; against %d rays: mean %.4f, p95 %.4f\n",
              pts.size(), rays, ref_seconds, 4 * rays, resid_mean,
              bench::percentile(resid, 0.95));

  std::vector<bool> graz, bord;
  for (uint32_t i : pts) graz.push_back(grazingPoint(set, i)), bord.push_back(borderPoint(set, i));

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
  for (int samples : {8, 16, 32, 64}) {
    AoOptions os = o;
    os.samples = samples;
    Row r;
    r.method = "ssao-" + std::to_string(samples);
    auto v = timed(
        [&] {
          for (size_t j = 0; j < set.maps.size(); ++j) computeSsao(set.maps[j], uint32_t(j), os);
          return ownSsao(set);
        },
        r.seconds);
    errorsOf(r, v, ref, pts, graz, bord);
    rows.push_back(r);
    for (int nb : {1, 3, 5}) {
      AoOptions om = os;
      om.neighbours = nb;
      Row m;
      m.method = "mvao" + std::to_string(nb) + "x" + std::to_string(nb) + "-" +
                 std::to_string(samples);
      double secs;
      auto mv = timed(
          [&] {
            for (auto& mp : set.maps) computeBorders(mp, om.threads);
            return integrateMvao(set, om);
          },
          secs);
      m.seconds = r.seconds + secs;
      errorsOf(m, mv, ref, pts, graz, bord);
      rows.push_back(m);
    }
    Row g;
    g.method = "grid-" + std::to_string(samples);
    double secs;
    auto gv = timed([&] { return gridMvao(set, os); }, secs);
    g.seconds = r.seconds + secs;
    errorsOf(g, gv, ref, pts, graz, bord);
    rows.push_back(g);
  }
  const std::string csv = out + "/mvao.csv";
  {
    std::ofstream f(csv);
    f << "method,seconds,mean_abs_error,p95_abs_error,grazing_mean,border_mean\n";
    std::printf("method,seconds,mean_abs_error,p95_abs_error,grazing_mean,border_mean\n");
    for (auto& r : rows) {
      char line[256];
      std::snprintf(line, sizeof line, "%s,%.3f,%.4f,%.4f,%.4f,%.4f\n", r.method.c_str(),
                    r.seconds, r.mean, r.p95, r.grazing, r.border);
      f << line;
      std::fputs(line, stdout);
    }
  }

  // Pictures: MVAO at 32 samples, 5x5.
  AoOptions op = o;
  op.neighbours = 5;
  for (size_t j = 0; j < set.maps.size(); ++j) computeSsao(set.maps[j], uint32_t(j), op);
  for (auto& m : set.maps) computeBorders(m, op.threads);
  std::vector<float> mvao = integrateMvao(set, op);
  std::vector<float> ref_all(set.size(), -1.0f);
  for (uint16_t scan : {uint16_t(0), uint16_t(5)}) {
    std::vector<uint32_t> mine;
    for (uint32_t i = 0; i < set.size(); ++i)
      if (set.scan_of_point[i] == scan) mine.push_back(i);
    std::vector<float> r = referenceAo(set, mine, rays, o);
    for (size_t k = 0; k < mine.size(); ++k) ref_all[mine[k]] = r[k];
    rangeMapPicture(set, scan, mvao, ref_all,
                    out + "/mvao_scan_" + std::filesystem::path(set.maps[scan].name).stem().string() +
                        ".png");
  }
  {
    std::vector<uint32_t> some;
    for (uint32_t i = 0; i < set.size(); i += uint32_t(picture_stride))
      if (ref_all[i] < 0) some.push_back(i);
    std::vector<float> r = referenceAo(set, some, rays, o);
    for (size_t k = 0; k < some.size(); ++k) ref_all[some[k]] = r[k];
    bunnyPicture(set, mvao, ref_all, out + "/mvao_bunny.png");
  }

  const std::string gp = out + "/mvao.gp";
  {
    std::ofstream f(gp);
    f << "set terminal pngcairo size 1100,450\nset output '" << out << "/mvao_error.png'\n"
      << "set datafile separator ','\nset key outside right\nset multiplot layout 1,2\n"
      << "set xlabel 'seconds (10 bunny scans, 2 cores)'\nset ylabel 'mean |AO - reference|'\n"
      << "set title 'mean absolute error'\n"
      << "plot '" << csv << "' every ::1 using 2:3:1 with labels point pt 7 offset 0.5,0.5 font ',7' notitle\n"
      << "set ylabel 'p95 |AO - reference|'\nset title '95th percentile'\n"
      << "plot '" << csv << "' every ::1 using 2:4:1 with labels point pt 7 offset 0.5,0.5 font ',7' notitle\n"
      << "unset multiplot\n";
  }
  std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp + "'";
  if (std::system(cmd.c_str()) != 0)
    std::fprintf(stderr, "mvao: gnuplot failed; the CSV is complete\n");
  std::printf("wrote %s, %s/mvao_error.png, pictures in %s\nreproduce: %s --out %s\n", csv.c_str(),
              out.c_str(), out.c_str(), argv[0], out.c_str());
  return 0;
}
