// spbr: see-through rendering (stochastic point-based rendering, Tanaka et al. 2016) measured,
// all in one run on one context:
//  figure5   the paper's Figure 5: a white plane of n_raw uniformly random points parallel to the
//            image, black background, 512x512, alpha 0.05..0.95: mean intensity and its standard
//            deviation against 255 alpha, for n_raw = 10^6 and 4 x 10^6 (L = 64);
//  opacity   the opacity drawn against the opacity set, with the default method on the Figure 5
//            plane at 10^6 points: alpha 0.1..0.9 at L = 16, 64 and 256, slant shading on and
//            off: mean against 255 alpha, std against the binomial, a half-plane's edge width;
//            crops of the plane beside the flat 255 alpha it must average to;
//  accuracy  image error (RMSE to an exact CPU compositor, reference_compositor.h) against frame
//            time for SPBR at L = 4, 16, 64, 256, the weighted average and weighted blended OIT,
//            on the bunny's scans fused at two opacities and on Autzen;
//  speed     1024x1024, L = 64, a ~10^7-point view of the 10^8-point store: the SPBR frame
//            against one opaque pass over the same adjusted points (goal: at most 2x);
//  sparse    see-through on sparse scans (2 points a pixel; the paper assumes ~38): the default
//            (copies stratified over surface cells), the paper's copies, the Gaussian jitter over
//            cells (the earlier sparse method), independent ensembles (k <= 1) and Gaussian jitter
//            alone, on the Figure 5 plane at 10^6 points: std over pixels against the binomial
//            255 sqrt(a (1 - a) / L), mean error, the 10-90% width of a half-plane's edge, ms per
//            frame, crops of the edge at alpha 0.5; and each method's RMSE on the fused bunny;
//  breaks    where the method's uniform-density assumption fails: a plane whose density jumps
//            4x (per-node estimates against the paper's single global one), and alpha near 1
//            (k with the paper's fixed cross-section, the copies and bytes it would take).
// Prints CSV; writes OUT/spbr_*.csv and OUT/spbr_*.png.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/reference_compositor.h>
#include <tessera/render/view_renderer.h>

#include <tessera/core/stopwatch.h>
#include "bench_inputs.h"

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

void gnuplot(const fs::path& script) {
  const std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + script.string() + "'";
  if (std::system(cmd.c_str()) != 0)
    std::fprintf(stderr, "spbr: gnuplot failed on %s; the CSV is complete\n", script.c_str());
}

/// A store of `n` white points uniformly random on [0, 1] x [0, 1] at z = 0, the right half
/// (x > 1 / 2) `right_density` times denser (0: empty, a half-plane). Cached in `dir`.
fs::path planeStore(const fs::path& dir, size_t n, double right_density = 1.0) {
  char name[96];
  std::snprintf(name, sizeof name, "plane-%zu-%g.tlod", n, right_density);
  const fs::path path = dir / name;
  if (fs::exists(path)) return path;
  fs::create_directories(dir);
  lod::PointBatch b;
  b.reset(lod::kColor);
  std::mt19937_64 rng(n);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  // Left half: n / (1 + r) points, right half r times as many on the same area.
  const size_t left = right_density > 0 ? size_t(double(n) / (1.0 + right_density)) : n;
  for (size_t i = 0; i < n; ++i) {
    const double x = i < left ? 0.5 * u(rng) : 0.5 + 0.5 * u(rng);
    b.positions.push_back({x, u(rng), 0.0});
    b.colors.push_back({255, 255, 255, 255});
  }
  const fs::path ply = dir / (std::string(name) + ".ply");
  lod::writePly(ply, b, glm::dvec3(0.0));
  lod::BuildOptions o;
  o.quiet = true;
  lod::buildStore({ply}, path, o);
  fs::remove(ply);
  return path;
}

render::ViewSetup lookAt(glm::dvec3 eye, glm::dvec3 target, glm::dvec3 up, uint32_t w, uint32_t h,
                         double fovy, double near, double far) {
  config::Camera c;
  auto set = [](config::Vec3* d, glm::dvec3 v) {
    d->set_x(v.x);
    d->set_y(v.y);
    d->set_z(v.z);
  };
  set(c.mutable_eye(), eye);
  set(c.mutable_target(), target);
  set(c.mutable_up(), up);
  render::ViewSetup v;
  v.view = render::cameraView(c);
  v.projection = glm::perspective(glm::radians(fovy), double(w) / h, near, far);
  v.width = w;
  v.height = h;
  v.eye_world = eye;
  return v;
}

double meanOf(const render::Image& img, uint32_t x0, uint32_t x1, double* sd = nullptr) {
  double s = 0, s2 = 0;
  size_t n = 0;
  for (uint32_t y = 0; y < img.height; ++y)
    for (uint32_t x = x0; x < x1; ++x) {
      const double v = img.rgba[(size_t(y) * img.width + x) * 4];
      s += v;
      s2 += v * v;
      ++n;
    }
  const double m = s / double(n);
  if (sd) *sd = std::sqrt(std::max(0.0, s2 / double(n) - m * m));
  return m;
}

double rmse(const render::Image& a, const render::Image& b) {
  double se = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4)
    for (int c = 0; c < 3; ++c) {
      const double d = double(a.rgba[i + c]) - double(b.rgba[i + c]);
      se += d * d;
    }
  return std::sqrt(se / double(a.rgba.size() / 4 * 3));
}

/// A frame drawn from scratch once every chunk is resident: settles through `streamer`, then a
/// fresh renderer (nothing accumulated) draws one frame; best of `repeats`.
double timedFrame(std::span<const render::ModelInstance> models, const render::ViewSetup& v,
                  const render::RenderOptions& o, std::shared_ptr<render::ChunkStreamer> streamer,
                  int repeats, render::Image* image, render::RenderStats* stats) {
  {
    render::ViewRenderer settle(v.width, v.height, streamer);
    settle.renderSettled(models, v, o);
  }
  double best = 1e300;
  for (int i = 0; i < repeats; ++i) {
    render::ViewRenderer r(v.width, v.height, streamer);
    render::RenderStats st;
    const auto t = Clock::now();
    r.draw(models, v, o, &st);
    best = std::min(best, msSince(t));
    if (i == 0) {
      if (image) *image = r.render(models, v, o);  // same accumulation: no new ensembles
      if (stats) *stats = st;
    }
  }
  return best;
}

void figure5(const fs::path& out, const std::vector<size_t>& sizes) {
  std::ofstream csv(out / "spbr_figure5.csv");
  csv << "n_raw,alpha,mean,stddev,theory,error_pct,ensembles,mode\n";
  std::cout
      << "\n== figure 5: white plane, 512x512, L = 64\nn_raw,alpha,mean,stddev,theory,error_pct\n";
  const render::ViewSetup v =
      lookAt({0.5, 0.5, 1.0}, {0.5, 0.5, 0.0}, {0, 1, 0}, 512, 512, 40.0, 0.1, 10.0);
  for (size_t n : sizes) {
    auto store = lod::PointStore::open(planeStore(out / "inputs", n));
    for (int a = 1; a <= 38; ++a) {
      // The paper's copies, then independent ensembles (k <= 1).
      const bool independent = a > 19;
      const float alpha = float(independent ? a - 19 : a) * 0.05f;
      render::ModelInstance inst{store.get(), render::storeModel(*store), alpha};
      render::RenderOptions o;
      // Every level the pixels ask for: the method measured alone, without the pixel budget.
      o.budget_per_covered_pixel = 0.0;
      o.spbr = render::SpbrOptions::papersCopies();
      o.spbr.ensembles = 64;
      if (independent) o.spbr.max_k = 1.0;
      render::ViewRenderer r(512, 512);
      render::RenderStats st;
      const render::Image img = r.renderSettled({&inst, 1}, v, o, &st);
      double sd = 0;
      const double mean = meanOf(img, 0, 512, &sd);
      char line[256];
      std::snprintf(line, sizeof line, "%zu,%.2f,%.2f,%.2f,%.2f,%.2f,%u,%s", n, alpha, mean, sd,
                    255.0 * alpha, 100.0 * (mean / (255.0 * alpha) - 1.0), st.ensembles,
                    independent ? "independent" : "copies");
      csv << line << "\n";
      std::cout << line << std::endl;
    }
  }
  csv.close();
  std::ofstream g(out / "spbr_figure5.gp");
  g << "set terminal pngcairo size 1100,430 font 'sans,10' noenhanced\nset output '"
    << (out / "spbr_figure5.png").string() << "'\nset datafile separator ','\n"
    << "set multiplot layout 1,2 title 'White plane, black background, 512x512, L = 64 (the "
       "paper s Figure 5; error bars: standard deviation over pixels)'\n"
    << "set xlabel 'alpha'\nset ylabel 'mean pixel intensity'\nset grid\nset key top left\n"
    << "set xrange [0:1]\nset yrange [0:260]\n";
  for (size_t n : sizes) {
    const std::string f = (out / "spbr_figure5.csv").string();
    g << "set title 'n_raw = " << n << "'\nplot '" << f << "' using ($1==" << n
      << " && stringcolumn(8) eq 'copies' ? $2 - 0.006 : 1/0):3:4 with yerrorbars pt 7 ps 0.6 "
         "title 'the paper s copies (--spbr-copies paper)', '"
      << f << "' using ($1==" << n
      << " && stringcolumn(8) eq 'independent' ? $2 + 0.006 : 1/0):3:4 with yerrorbars pt 6 ps "
         "0.6 title 'independent ensembles (k <= 1)', 255*x with lines lw 2 title '255 alpha'\n";
  }
  g << "unset multiplot\n";
  g.close();
  gnuplot(out / "spbr_figure5.gp");
}

struct Scene {
  std::string name;
  std::vector<std::unique_ptr<lod::PointStore>> stores;
  std::vector<render::ModelInstance> models;
  render::ViewSetup view;
};

/// The bunny's ten scans in two groups, fused at two opacities (orange 0.3, blue 0.7), 640x480.
Scene bunnyScene(const fs::path& dir) {
  const std::string data = TESSERA_DATA_DIR;
  Scene s;
  s.name = "bunny";
  const char* groups[2][5] = {{"bun000", "bun045", "bun315", "chin", "top2"},
                              {"bun090", "bun180", "bun270", "top3", "ear_back"}};
  std::ifstream conf_in(data + "/stanford-bunny/scans/bun.conf");
  std::vector<std::string> lines;
  for (std::string l; std::getline(conf_in, l);) lines.push_back(l);
  const float opacity[2] = {0.3f, 0.7f};
  const glm::u8vec3 color[2] = {{255, 170, 60}, {80, 160, 255}};
  for (int gi = 0; gi < 2; ++gi) {
    const fs::path conf = dir / "inputs" / ("bunny-group" + std::to_string(gi) + ".conf");
    const fs::path store = dir / "inputs" / ("bunny-group" + std::to_string(gi) + ".tlod");
    if (!fs::exists(store)) {
      std::ofstream c(conf);
      for (const std::string& l : lines)
        for (const char* name : groups[gi])
          if (l.rfind(std::string("bmesh ") + name + ".ply", 0) == 0)
            c << "bmesh " << data << "/stanford-bunny/scans/" << l.substr(6) << "\n";
      c.close();
      lod::BuildOptions o;
      o.quiet = true;
      lod::buildStore({conf}, store, o);
    }
    s.stores.push_back(lod::PointStore::open(store));
    s.models.push_back(
        {s.stores.back().get(), render::storeModel(*s.stores.back()), opacity[gi], color[gi]});
  }
  s.view = lookAt({-0.02, 0.11, 0.3}, {-0.02, 0.1, 0.0}, {0, 1, 0}, 640, 480, 40.0, 0.01, 2.0);
  return s;
}

void accuracy(const fs::path& out, std::vector<Scene>& scenes) {
  std::ofstream csv(out / "spbr_accuracy.csv");
  csv << "scene,method,L,frame_ms,rmse,points\n";
  std::cout << "\n== accuracy against the exact CPU compositor\nscene,method,L,frame_ms,rmse\n";
  for (Scene& s : scenes) {
    auto t = Clock::now();
    render::ReferenceOptions ro;
    const render::Image ref = render::referenceSeeThrough(s.models, s.view, ro);
    std::fprintf(stderr, "spbr: reference for %s in %.1f s\n", s.name.c_str(), msSince(t) / 1e3);
    render::writePng((out / ("spbr-" + s.name + "-reference.png")).string(), ref);
    auto streamer = std::make_shared<render::ChunkStreamer>();
    auto row = [&](const std::string& method, uint32_t L, const render::RenderOptions& o) {
      render::Image img;
      render::RenderStats st;
      const double ms = timedFrame(s.models, s.view, o, streamer, 2, &img, &st);
      char line[256];
      std::snprintf(line, sizeof line, "%s,%s,%u,%.1f,%.2f,%llu", s.name.c_str(), method.c_str(), L,
                    ms, rmse(img, ref), (unsigned long long)st.points);
      csv << line << "\n";
      std::cout << line << std::endl;
      render::writePng(
          (out / ("spbr-" + s.name + "-" + method + (L ? "-" + std::to_string(L) : "") + ".png"))
              .string(),
          img);
    };
    for (uint32_t L : {4u, 16u, 64u, 256u}) {
      render::RenderOptions o;
      o.budget_per_covered_pixel = 0.0;
      o.spbr = render::SpbrOptions::papersCopies();
      o.spbr.ensembles = L;
      row("spbr", L, o);
      render::RenderOptions cell;  // the default: copies in surface cells
      cell.budget_per_covered_pixel = 0.0;
      cell.spbr.ensembles = L;
      row("spbr-cell", L, cell);
      // Independent ensembles (k <= 1): discs grow with L instead of points being copied.
      o.spbr.max_k = 1.0;
      row("spbr-independent", L, o);
    }
    render::RenderOptions avg;
    avg.budget_per_covered_pixel = 0.0;
    avg.transparency = render::Transparency::kWeightedAverage;
    row("average", 0, avg);
    render::RenderOptions wb;
    wb.budget_per_covered_pixel = 0.0;
    wb.transparency = render::Transparency::kWeightedBlended;
    row("wboit", 0, wb);
  }
  csv.close();
  std::ofstream g(out / "spbr_accuracy.gp");
  g << "set terminal pngcairo size 1100,430 font 'sans,10' noenhanced\nset output '"
    << (out / "spbr_accuracy.png").string() << "'\nset datafile separator ','\n"
    << "set multiplot layout 1," << scenes.size()
    << " title 'See-through: error to the exact compositor against frame time'\n"
    << "set xlabel 'frame time, ms (llvmpipe, 2 cores)'\nset ylabel 'RMSE (0..255)'\nset grid\n"
       "set logscale x\nset key bottom left\nset yrange [0:*]\n";
  for (const Scene& s : scenes) {
    const std::string f = (out / "spbr_accuracy.csv").string();
    g << "set title '" << s.name << "'\nplot '" << f << "' using (stringcolumn(1) eq '" << s.name
      << "' && stringcolumn(2) eq 'spbr' ? $4 : 1/0):5 with points pt 7 ps 1.2 title "
         "'SPBR (copies), L = 4..256', '' using (stringcolumn(1) eq '"
      << s.name
      << "' && stringcolumn(2) eq 'spbr' ? $4 : 1/0):5:(sprintf('L=%d', $3)) with "
         "labels offset 0,1 notitle, '' using (stringcolumn(1) eq '"
      << s.name
      << "' && stringcolumn(2) eq 'average' ? $4 : 1/0):5 with points pt 5 ps 1.5 "
         "title 'weighted average', '' using (stringcolumn(1) eq '"
      << s.name
      << "' && stringcolumn(2) eq 'wboit' ? $4 : 1/0):5 with points pt 9 ps 1.5 "
         "title 'weighted blended OIT', '' using (stringcolumn(1) eq '"
      << s.name
      << "' && stringcolumn(2) eq 'spbr-independent' ? $4 : 1/0):5 with points pt 6 ps 1.2 "
         "title 'SPBR, independent ensembles (k <= 1)'\n";
  }
  g << "unset multiplot\n";
  g.close();
  gnuplot(out / "spbr_accuracy.gp");
}

/// A see-through method as options; the first is the default (copies in surface cells), then
/// the paper's copies and the earlier sparse method (Gaussian jitter over cells).
struct SparseMethod {
  std::string name;
  render::SpbrOptions spbr;
};

std::vector<SparseMethod> sparseMethods(const std::vector<double>& jitters,
                                        const std::vector<double>& shares) {
  std::vector<SparseMethod> m;
  const render::SpbrOptions cell;
  const render::SpbrOptions paper = render::SpbrOptions::papersCopies();
  const render::SpbrOptions gaussian = render::SpbrOptions::gaussianJitter();
  m.push_back({"default: copies in cells", cell});
  m.push_back({"paper: copies at the point", paper});
  m.push_back({"gaussian: jitter 1.5 over cells", gaussian});
  SparseMethod independent{"independent (k <= 1)", paper};
  independent.spbr.max_k = 1.0;
  m.push_back(independent);
  SparseMethod jitter_only{"gaussian without cells", gaussian};
  jitter_only.spbr.cell_weights = false;
  m.push_back(jitter_only);
  for (double j : jitters) {  // a sweep of the Gaussian method's jitter
    SparseMethod sweep{"gaussian, jitter " + std::to_string(j).substr(0, 4), gaussian};
    sweep.spbr.copy_jitter = j;
    m.push_back(sweep);
  }
  for (double share : shares) {  // a sweep of the default's max_share
    SparseMethod sweep{"cells, max_share " + std::to_string(share).substr(0, 4), cell};
    sweep.spbr.max_share = share;
    m.push_back(sweep);
  }
  return m;
}

/// Images side by side on white, `gap` pixels apart.
render::Image sideBySide(const std::vector<const render::Image*>& images, uint32_t gap) {
  uint32_t w = 0, h = 0;
  for (const render::Image* i : images) w += i->width, h = std::max(h, i->height);
  w += gap * uint32_t(images.size() - 1);
  render::Image out{w, h, std::vector<uint8_t>(size_t(w) * h * 4, 255)};
  uint32_t x0 = 0;
  for (const render::Image* i : images) {
    for (uint32_t y = 0; y < i->height; ++y)
      std::copy_n(&i->rgba[size_t(y) * i->width * 4], size_t(i->width) * 4,
                  &out.rgba[(size_t(y) * w + x0) * 4]);
    x0 += i->width + gap;
  }
  return out;
}

/// The opacity drawn is the opacity set: the default method on the Figure 5 plane (10^6 points,
/// 512x512) at alpha 0.1 .. 0.9, L = 16, 64 and 256, slant shading on and off (the plane faces
/// the image, so both must give 255 alpha; off, each point's disc follows its estimated normal).
void opacity(const fs::path& out) {
  std::ofstream csv(out / "spbr_opacity.csv");
  csv << "slant,L,alpha,mean,theory,error_pct,error_grey,stddev,std_over_binomial,edge_10_90_px,"
         "frame_ms\n";
  std::cout << "\n== opacity drawn against opacity set: Figure 5 plane, 10^6 points, 512x512\n"
               "slant,L,alpha,mean,theory,error_pct,error_grey,stddev,std_over_binomial,"
               "edge_10_90_px,frame_ms\n";
  auto plane = lod::PointStore::open(planeStore(out / "inputs", 1'000'000));
  auto half = lod::PointStore::open(planeStore(out / "inputs", 500'000, 0.0));
  const render::ViewSetup v =
      lookAt({0.5, 0.5, 1.0}, {0.5, 0.5, 0.0}, {0, 1, 0}, 512, 512, 40.0, 0.1, 10.0);
  render::StreamerOptions with_normals;
  with_normals.normals = true;  // for slant shading off; the default ignores them
  auto streamer = std::make_shared<render::ChunkStreamer>(with_normals);
  // Crops at L = 64, slant shading on: 96x96 of the plane's centre over a flat 255 alpha.
  std::vector<render::Image> crops;
  for (bool slant : {true, false})
    for (uint32_t L : {16u, 64u, 256u})
      for (int a = 1; a <= 9; ++a) {
        const float alpha = float(a) * 0.1f;
        render::RenderOptions o;
        o.budget_per_covered_pixel = 0.0;
        o.spbr.ensembles = L;
        o.spbr.slant_shading = slant;
        render::ModelInstance inst{plane.get(), render::storeModel(*plane), alpha};
        render::Image img;
        const double ms = timedFrame({&inst, 1}, v, o, streamer, 1, &img, nullptr);
        double sd = 0;
        const double mean = meanOf(img, 0, img.width, &sd);
        render::ModelInstance edge_inst{half.get(), render::storeModel(*half), alpha};
        render::ViewRenderer re(v.width, v.height, streamer);
        const double edge = render::edgeWidth(re.renderSettled({&edge_inst, 1}, v, o), 256);
        const double theory = 255.0 * alpha;
        const double binomial = 255.0 * std::sqrt(alpha * (1.0 - alpha) / L);
        char line[256];
        std::snprintf(line, sizeof line, "%s,%u,%.1f,%.2f,%.2f,%.2f,%.2f,%.2f,%.3f,%.2f,%.1f",
                      slant ? "on" : "off", L, alpha, mean, theory, 100.0 * (mean / theory - 1.0),
                      mean - theory, sd, sd / binomial, edge, ms);
        csv << line << "\n";
        std::cout << line << std::endl;
        if (slant && L == 64 && a % 2 == 1) {
          render::Image c{96, 192, std::vector<uint8_t>(96 * 192 * 4, 255)};
          const uint8_t flat = uint8_t(std::lround(theory));
          for (uint32_t y = 0; y < 96; ++y)
            for (uint32_t x = 0; x < 96; ++x)
              for (int ch = 0; ch < 3; ++ch) {
                c.rgba[(y * 96 + x) * 4 + ch] = img.rgba[((208 + y) * 512 + 208 + x) * 4 + ch];
                c.rgba[((96 + y) * 96 + x) * 4 + ch] = flat;
              }
          crops.push_back(std::move(c));
        }
      }
  std::vector<const render::Image*> row;
  for (const render::Image& c : crops) row.push_back(&c);
  render::writePng((out / "spbr_opacity_crops.png").string(), sideBySide(row, 8));
  csv.close();
  const std::string f = (out / "spbr_opacity.csv").string();
  std::ofstream g(out / "spbr_opacity.gp");
  g << "set terminal pngcairo size 1200,520 font 'sans,10' noenhanced\nset output '"
    << (out / "spbr_opacity.png").string() << "'\nset datafile separator ','\n"
    << "set multiplot layout 1,3 title 'Opacity drawn against opacity set: the Figure 5 plane, "
       "10^6 points, 512x512, the default method (copies in cells)'\n"
    << "set grid\nset xlabel 'alpha'\nset xrange [0:1]\nset key below font ',9'\n";
  auto plot = [&](const char* title, const char* ylabel, int column, const char* goal) {
    g << "set title '" << title << "'\nset ylabel '" << ylabel << "'\nplot ";
    int k = 0;
    for (const char* slant : {"on", "off"})
      for (int L : {16, 64, 256})
        g << "'" << f << "' using (stringcolumn(1) eq '" << slant << "' && $2 == " << L
          << " ? $3 : 1/0):" << column << " with linespoints pt " << (slant[1] == 'n' ? 7 : 6)
          << " lc " << ++k % 3 + 1 << " title 'L = " << L << ", slant " << slant << "', ";
    g << goal << "\n";
  };
  plot("mean - 255 alpha", "grey levels", 7,
       "(2.55*x > 1 ? 2.55*x : 1) with lines dt 2 lc rgb 'black' title 'goal: 1% or 1 grey', "
       "(2.55*x > 1 ? -2.55*x : -1) with lines dt 2 lc rgb 'black' notitle");
  plot("standard deviation / binomial", "std / binomial", 9,
       "1.5 with lines dt 2 lc rgb 'black' title 'goal 1.5'");
  plot("edge of a half-plane, 10-90%", "px", 10,
       "2 with lines dt 2 lc rgb 'black' title 'goal 2 px'");
  g << "unset multiplot\n";
  g.close();
  gnuplot(out / "spbr_opacity.gp");
}

void sparse(const fs::path& out, const std::vector<double>& jitters,
            const std::vector<double>& shares, const std::vector<std::string>& only,
            bool with_bunny) {
  const uint32_t L = 64;
  const size_t n = 1'000'000;
  std::ofstream csv(out / "spbr_sparse.csv");
  csv << "method,alpha,mean,stddev,binomial,std_over_binomial,mean_error_pct,edge_10_90_px,"
         "frame_ms\n";
  std::cout << "\n== sparse scans: Figure 5 plane, 10^6 points (2 a pixel), 512x512, L = 64\n"
               "method,alpha,mean,stddev,binomial,std_over_binomial,mean_error_pct,"
               "edge_10_90_px,frame_ms\n";
  auto plane = lod::PointStore::open(planeStore(out / "inputs", n));
  auto half = lod::PointStore::open(planeStore(out / "inputs", n / 2, 0.0));  // same density
  const render::ViewSetup v =
      lookAt({0.5, 0.5, 1.0}, {0.5, 0.5, 0.0}, {0, 1, 0}, 512, 512, 40.0, 0.1, 10.0);
  render::StreamerOptions with_cells;  // for the sparse method; the others ignore them
  with_cells.surface_cells = true;
  auto streamer = std::make_shared<render::ChunkStreamer>(with_cells);
  std::vector<SparseMethod> methods = sparseMethods(jitters, shares);
  if (!only.empty())  // methods whose names start with one of `only`
    std::erase_if(methods, [&](const SparseMethod& m) {
      return std::none_of(only.begin(), only.end(),
                          [&](const std::string& o) { return m.name.rfind(o, 0) == 0; });
    });
  std::vector<render::Image> crops(methods.size());
  for (const SparseMethod& m : methods) {
    for (float alpha : {0.05f, 0.2f, 0.35f, 0.5f, 0.65f, 0.8f, 0.95f}) {
      render::RenderOptions o;
      o.budget_per_covered_pixel = 0.0;
      o.spbr = m.spbr;
      o.spbr.ensembles = L;
      render::ModelInstance inst{plane.get(), render::storeModel(*plane), alpha};
      render::Image img;
      const double ms = timedFrame({&inst, 1}, v, o, streamer, 1, &img, nullptr);
      double sd = 0;
      const double mean = meanOf(img, 0, img.width, &sd);
      if (&m == &methods.front() && (alpha == 0.5f || alpha == 0.8f))
        render::writePng(
            (out / ("spbr-sparse-plane-" + std::to_string(int(alpha * 100)) + ".png")).string(),
            img);
      render::ModelInstance edge_inst{half.get(), render::storeModel(*half), alpha};
      render::ViewRenderer re(v.width, v.height, streamer);
      const render::Image edge_img = re.renderSettled({&edge_inst, 1}, v, o);
      const double binomial = 255.0 * std::sqrt(alpha * (1.0 - alpha) / L);
      char line[256];
      std::snprintf(line, sizeof line, "%s,%.2f,%.2f,%.2f,%.2f,%.3f,%.2f,%.2f,%.1f", m.name.c_str(),
                    alpha, mean, sd, binomial, sd / binomial,
                    100.0 * (mean / (255.0 * alpha) - 1.0), render::edgeWidth(edge_img, 256), ms);
      csv << line << "\n";
      std::cout << line << std::endl;
      if (alpha == 0.5f) {
        // 128x128 around the edge, at 2x: the plateau's grain on the left, the edge, background.
        render::Image c{256, 256, std::vector<uint8_t>(256 * 256 * 4)};
        for (uint32_t y = 0; y < 256; ++y)
          for (uint32_t x = 0; x < 256; ++x)
            for (int ch = 0; ch < 4; ++ch)
              c.rgba[(y * 256 + x) * 4 + ch] =
                  edge_img.rgba[((192 + y / 2) * 512 + 160 + x / 2) * 4 + ch];
        crops[size_t(&m - methods.data())] = std::move(c);
      }
    }
  }
  // The paper's copies, independent ensembles, the Gaussian method and the default (copies in
  // cells), side by side.
  if (only.empty()) {
    render::writePng((out / "spbr_sparse_crops.png").string(),
                     sideBySide({&crops[1], &crops[3], &crops[2], &crops[0]}, 8));
  } else {
    std::vector<const render::Image*> all;
    for (const render::Image& c : crops) all.push_back(&c);
    render::writePng((out / "spbr_sparse_crops.png").string(), sideBySide(all, 8));
  }

  if (with_bunny) {
    csv << "\nmethod,L,bunny_rmse,bunny_frame_ms\n";
    std::cout << "method,L,bunny_rmse,bunny_frame_ms\n";
    Scene bunny = bunnyScene(out);
    const render::Image ref = render::referenceSeeThrough(bunny.models, bunny.view, {});
    auto bunny_streamer = std::make_shared<render::ChunkStreamer>(with_cells);
    render::writePng((out / "spbr-bunny-reference.png").string(), ref);
    std::vector<render::Image> bunny64(methods.size());
    for (const SparseMethod& m : methods) {
      for (uint32_t l : {16u, 64u}) {
        render::RenderOptions o;
        o.budget_per_covered_pixel = 0.0;
        o.spbr = m.spbr;
        o.spbr.ensembles = l;
        render::Image img;
        const double ms = timedFrame(bunny.models, bunny.view, o, bunny_streamer, 2, &img, nullptr);
        char line[256];
        std::snprintf(line, sizeof line, "%s,%u,%.2f,%.1f", m.name.c_str(), l, rmse(img, ref), ms);
        csv << line << "\n";
        std::cout << line << std::endl;
        if (l == 64) bunny64[size_t(&m - methods.data())] = std::move(img);
      }
    }
    // The reference beside each method at L = 64 (default, paper, Gaussian first).
    std::vector<const render::Image*> row{&ref};
    for (const render::Image& i : bunny64) row.push_back(&i);
    if (row.size() > 4) row.resize(4);
    render::writePng((out / "spbr_sparse_bunny.png").string(), sideBySide(row, 8));
  }
  csv.close();
  const std::string f = (out / "spbr_sparse.csv").string();
  std::ofstream g(out / "spbr_sparse.gp");
  g << "set terminal pngcairo size 1200,820 font 'sans,10' noenhanced\nset output '"
    << (out / "spbr_sparse.png").string() << "'\nset datafile separator ','\n"
    << "set multiplot layout 2,2 title 'See-through on a sparse scan: the paper s Figure 5 "
       "plane at 10^6 points (2 a pixel), 512x512, L = 64'\n"
    << "set grid\nset xlabel 'alpha'\nset xrange [0:1]\nset key top left\n";
  auto plot = [&](const char* title, const char* ylabel, int column, const char* goal) {
    g << "set title '" << title << "'\nset ylabel '" << ylabel << "'\nplot ";
    for (size_t k = 0; k < methods.size(); ++k)
      g << "'" << f << "' using (stringcolumn(1) eq '" << methods[k].name
        << "' ? $2 : 1/0):" << column << " with linespoints pt " << (k == 0 ? 7 : int(k) + 3)
        << " lw " << (k == 0 ? 2 : 1) << " title '" << methods[k].name << "', ";
    g << goal << "\n";
  };
  g << "set logscale y\n";
  plot("standard deviation over pixels / binomial", "std / binomial", 6,
       "1.5 with lines dt 2 lc rgb 'black' title 'goal 1.5'");
  g << "unset logscale y\nset yrange [-5:5]\n";
  plot("mean error", "% of 255 alpha", 7,
       "2.5 with lines dt 2 lc rgb 'black' title 'goal +-2.5%', -2.5 with lines dt 2 lc rgb "
       "'black' notitle");
  g << "set yrange [0:8]\n";
  plot("half-plane edge, 10-90% width (off the chart: noise, no edge)", "pixels", 8,
       "2 with lines dt 2 lc rgb 'black' title 'goal 2 px'");
  g << "set yrange [*:*]\n";
  plot("frame time (llvmpipe, 2 cores)", "ms", 9, "1/0 notitle");
  g << "unset multiplot\n";
  g.close();
  gnuplot(out / "spbr_sparse.gp");
}

void speed(const fs::path& out, const fs::path& store_path, double lod_px) {
  auto store = lod::PointStore::open(store_path);
  render::ModelInstance inst{store.get(), render::storeModel(*store), 0.5f};
  const render::ViewSetup v =
      lookAt({-0.02, 0.13, 0.26}, {-0.02, 0.1, 0.0}, {0, 1, 0}, 1024, 1024, 45.0, 0.01, 2.0);
  auto streamer = std::make_shared<render::ChunkStreamer>(render::StreamerOptions{8ull << 30});
  render::RenderOptions o;
  o.budget_per_covered_pixel = 0.0;
  o.spbr = render::SpbrOptions::papersCopies();  // as the README's speed figures
  o.lod_pixels = lod_px;
  o.spbr.ensembles = 64;
  render::RenderStats st;
  const double spbr_ms = timedFrame({&inst, 1}, v, o, streamer, 3, nullptr, &st);
  render::RenderOptions one = o;
  one.spbr.single_layer_baseline = true;
  render::RenderStats st1;
  const double opaque_ms = timedFrame({&inst, 1}, v, one, streamer, 3, nullptr, &st1);
  std::ofstream csv(out / "spbr_speed.csv");
  const std::string header =
      "width,height,L,alpha,points,copies,spbr_ms,opaque_same_copies_ms,ratio,spbr_fps";
  csv << header << "\n";
  char line[256];
  std::snprintf(line, sizeof line, "1024,1024,64,0.5,%llu,%llu,%.1f,%.1f,%.2f,%.2f",
                (unsigned long long)st.points, (unsigned long long)st.copies, spbr_ms, opaque_ms,
                spbr_ms / opaque_ms, 1000.0 / spbr_ms);
  csv << line << "\n";
  std::cout << "\n== speed: SPBR frame against one opaque pass over the same adjusted points\n"
            << header << "\n"
            << line << std::endl;
}

/// The registered bunny's ten scans overlap: where k scans cover a surface it holds about k times
/// the points of a single scan, while the density each node measures is its average. Per pixel,
/// the number of scans on the nearest surface against SPBR's and the reference's intensity.
void bunnyOverlap(const fs::path& out, std::ofstream& csv) {
  const std::string data = TESSERA_DATA_DIR;
  const fs::path path = out / "inputs" / "bunny-all.tlod";
  if (!fs::exists(path)) {
    lod::BuildOptions o;
    o.quiet = true;
    lod::buildStore({data + "/stanford-bunny/scans/bun.conf"}, path, o);
  }
  auto store = lod::PointStore::open(path);
  const float alpha = 0.3f;
  render::ModelInstance inst{store.get(), render::storeModel(*store), alpha, {255, 255, 255}};
  const render::ViewSetup v =
      lookAt({-0.02, 0.11, 0.3}, {-0.02, 0.1, 0.0}, {0, 1, 0}, 640, 480, 40.0, 0.01, 2.0);
  render::RenderOptions o;
  o.budget_per_covered_pixel = 0.0;
  o.spbr = render::SpbrOptions::papersCopies();  // as the README's overlap figures
  o.spbr.ensembles = 64;
  render::ViewRenderer r(v.width, v.height);
  const render::Image spbr = r.renderSettled({&inst, 1}, v, o);
  render::StreamerOptions with_ratios;
  with_ratios.density_ratios = true;
  render::ViewRenderer rr(v.width, v.height, nullptr, with_ratios);
  const render::Image spbr_local = rr.renderSettled({&inst, 1}, v, o);
  const render::Image ref = render::referenceSeeThrough({&inst, 1}, v);
  // Scans on the nearest surface of each pixel: the sources of points within three leaf
  // spacings of the nearest point's depth.
  const size_t W = v.width, H = v.height;
  std::vector<float> nearest(W * H, 1e30f);
  std::vector<uint32_t> mask(W * H, 0);
  struct P {
    size_t pixel;
    float depth, gap;
    uint16_t source;
  };
  std::vector<P> pts;
  std::vector<lod::NodeId> stack{store->root()};
  while (!stack.empty()) {
    const lod::NodeId id = stack.back();
    stack.pop_back();
    const lod::NodeInfo n = store->node(id);
    if (!n.leaf()) {
      for (lod::NodeId c : store->children(id)) stack.push_back(c);
      continue;
    }
    const auto chunk = store->decodeChunk(id);
    const glm::dmat4 to_view = v.view * inst.model * glm::translate(glm::dmat4(1.0), chunk->offset);
    for (size_t i = 0; i < chunk->size(); ++i) {
      const glm::dvec4 pv = to_view * glm::dvec4(glm::dvec3(chunk->positions[i]), 1.0);
      const glm::dvec4 c = v.projection * pv;
      if (c.w <= 0) continue;
      const double x = (c.x / c.w * 0.5 + 0.5) * W, y = (0.5 - c.y / c.w * 0.5) * H;
      if (x < 0 || y < 0 || x >= W || y >= H) continue;
      const size_t pixel = size_t(y) * W + size_t(x);
      const float depth = float(-pv.z);
      pts.push_back({pixel, depth, 3.0f * n.spacing,
                     chunk->sources.empty() ? uint16_t(0) : chunk->sources[i]});
      nearest[pixel] = std::min(nearest[pixel], depth);
    }
  }
  for (const P& p : pts)
    if (p.depth - nearest[p.pixel] < p.gap) mask[p.pixel] |= 1u << (p.source & 31u);
  struct Bucket {
    size_t pixels = 0;
    double spbr = 0, local = 0, ref = 0;
  };
  std::vector<Bucket> buckets(6);
  for (size_t px = 0; px < W * H; ++px) {
    if (!mask[px]) continue;
    const size_t k = std::min<size_t>(size_t(__builtin_popcount(mask[px])), 5);
    buckets[k].pixels++;
    buckets[k].spbr += spbr.rgba[px * 4];
    buckets[k].local += spbr_local.rgba[px * 4];
    buckets[k].ref += ref.rgba[px * 4];
  }
  csv << "\ncase,scans_on_surface,pixels,spbr_mean,spbr_point_density_mean,reference_mean,"
         "spbr_over_reference,point_density_over_reference\n";
  std::cout << "bunny, alpha 0.3: scans on the nearest surface against mean intensity\n";
  for (size_t k = 1; k < buckets.size(); ++k) {
    const Bucket& b = buckets[k];
    if (!b.pixels) continue;
    char line[256];
    std::snprintf(line, sizeof line, "bunny scans overlap,%zu%s,%zu,%.1f,%.1f,%.1f,%.3f,%.3f", k,
                  k == 5 ? "+" : "", b.pixels, b.spbr / b.pixels, b.local / b.pixels,
                  b.ref / b.pixels, b.spbr / std::max(b.ref, 1.0), b.local / std::max(b.ref, 1.0));
    csv << line << "\n";
    std::cout << line << std::endl;
  }
  render::writePng((out / "spbr-bunny-overlap.png").string(), spbr);
  render::writePng((out / "spbr-bunny-overlap-point-density.png").string(), spbr_local);
  render::writePng((out / "spbr-bunny-overlap-reference.png").string(), ref);
}

void breaks(const fs::path& out) {
  // (1) A density jump: the right half 4x denser. Per-node densities keep each side right except
  // in nodes that straddle the jump; the paper's one global estimate gets both sides wrong.
  std::ofstream csv(out / "spbr_breaks.csv");
  csv << "case,alpha,left_mean,right_mean,theory,global_estimate_left,global_estimate_right\n";
  std::cout << "\n== where it breaks: a 4x density jump; alpha near 1\n";
  auto store = lod::PointStore::open(planeStore(out / "inputs", 2'000'000, 4.0));
  const render::ViewSetup v =
      lookAt({0.5, 0.5, 1.0}, {0.5, 0.5, 0.0}, {0, 1, 0}, 512, 512, 40.0, 0.1, 10.0);
  for (float alpha : {0.2f, 0.5f, 0.8f}) {
    render::ModelInstance inst{store.get(), render::storeModel(*store), alpha};
    render::RenderOptions o;
    o.budget_per_covered_pixel = 0.0;
    o.spbr = render::SpbrOptions::papersCopies();  // as the README's density-jump figures
    render::ViewRenderer r(512, 512);
    const render::Image img = r.renderSettled({&inst, 1}, v, o);
    // Columns away from the jump (x = 256) by 32 pixels.
    const double left = meanOf(img, 0, 224), right = meanOf(img, 288, 512);
    // One global density (the mean, 2.5x the left's) for both halves: alpha_side =
    // 1 - (1 - alpha)^(density_side / density_mean).
    const double gl = 255.0 * (1.0 - std::pow(1.0 - alpha, 1.0 / 2.5));
    const double gr = 255.0 * (1.0 - std::pow(1.0 - alpha, 4.0 / 2.5));
    char line[256];
    std::snprintf(line, sizeof line, "density jump 4x,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f", alpha, left,
                  right, 255.0 * alpha, gl, gr);
    csv << line << "\n";
    std::cout << line << std::endl;
    if (alpha == 0.5f) render::writePng((out / "spbr-density-jump.png").string(), img);
  }
  bunnyOverlap(out, csv);
  // (2) Alpha near 1 with the paper's fixed cross-section (k grows as -ln(1 - alpha)) against
  // ours (k <= 1, cross-sections grow instead): k, copies per frame for a 10^7-point view at
  // L = 64 and the bytes they would take materialised (16 bytes a point).
  csv << "\ncase,alpha,k_fixed_cross_section,copies_per_frame,bytes_materialised,"
         "disc_growth_ours\n";
  const double spacing = 1.0, density = 1.0 / (spacing * spacing);  // grid-like sampling
  for (double alpha : {0.5, 0.9, 0.95, 0.99, 0.999}) {
    const render::SpbrNodeParams fixed = render::spbrNodeParams(alpha, density, spacing, 64, 1e9);
    const render::SpbrNodeParams ours = render::spbrNodeParams(alpha, density, spacing, 64, 1.0);
    const double copies = 1e7 * std::min(fixed.k, 64.0);
    char line[256];
    std::snprintf(line, sizeof line, "alpha near 1,%.3f,%.2f,%.3g,%.3g,%.2f", alpha, fixed.k,
                  copies, copies * 16.0, std::sqrt(ours.cross_section / fixed.cross_section));
    csv << line << "\n";
    std::cout << line << std::endl;
  }
}

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  CLI::App app{
      "spbr: see-through rendering: Figure 5, accuracy against an exact compositor, "
      "speed, and where it breaks"};
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  std::vector<std::string> parts{"figure5", "opacity", "sparse", "accuracy", "speed", "breaks"};
  double speed_lod = 1.5;
  std::vector<double> jitters, shares;
  std::vector<std::string> only;
  bool sparse_bunny = true;
  app.add_option("--out", out, "Folder for inputs, CSV and charts")->capture_default_str();
  app.add_option("--parts", parts, "Which parts: figure5 opacity sparse accuracy speed breaks")
      ->capture_default_str();
  app.add_option("--speed-lod", speed_lod, "LOD threshold of the speed view")
      ->capture_default_str();
  app.add_option("--sparse-jitter", jitters,
                 "sparse: also the sparse method with these copy jitters (node spacings)");
  app.add_option("--sparse-share", shares,
                 "sparse: also the default method with these max_share values");
  app.add_option("--sparse-only", only, "sparse: only the methods whose names start so");
  app.add_option("--sparse-bunny", sparse_bunny, "sparse: each method's RMSE on the bunny")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  auto has = [&](const char* p) { return std::find(parts.begin(), parts.end(), p) != parts.end(); };
  try {
    const fs::path dir(out);
    fs::create_directories(dir / "inputs");
    auto ctx = render::GlContext::createHeadless();
    if (has("figure5")) figure5(dir, {1'000'000, 4'000'000});
    if (has("opacity")) opacity(dir);
    if (has("sparse")) sparse(dir, jitters, shares, only, sparse_bunny);
    if (has("accuracy")) {
      std::vector<Scene> scenes;
      const std::string data = TESSERA_DATA_DIR;
      scenes.push_back(bunnyScene(dir));
      {
        Scene s;
        s.name = "autzen";
        const fs::path store = dir / "inputs" / "autzen.tlod";
        if (!fs::exists(store)) {
          lod::BuildOptions o;
          o.quiet = true;
          lod::buildStore({data + "/lidar/autzen_trim.las"}, store, o);
        }
        s.stores.push_back(lod::PointStore::open(store));
        s.models.push_back({s.stores.back().get(), render::storeModel(*s.stores.back()), 0.5f});
        const auto& sum = s.stores.back()->summary();
        const glm::dvec3 c = sum.origin + 0.5 * (sum.bbox_min + sum.bbox_max);
        const double r = 0.5 * glm::length(sum.bbox_max - sum.bbox_min);
        s.view = lookAt(c + glm::dvec3(0, -1.0 * r, 0.8 * r), c, {0, 0, 1}, 640, 480, 45.0,
                        0.05 * r, 6.0 * r);
        scenes.push_back(std::move(s));
      }
      accuracy(dir, scenes);
    }
    if (has("speed"))
      speed(dir, bench::bigBunnyStore(dir, 100'000'000, TESSERA_DATA_DIR), speed_lod);
    if (has("breaks")) breaks(dir);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "spbr: %s\n", e.what());
    return 1;
  }
}
