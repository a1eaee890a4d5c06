// analysis: the relative depth filter and contour lines (screen_passes.h AnalysisPass) beside
// eye-dome lighting, in one run on one context, at 1920x1080 on real scans: the Autzen LiDAR
// (seen from above at 40 degrees) and the bunny's ten registered range scans (from the front).
// Each scan's frame is rendered once (lod-px 1, settled) and its depth plane copied; then on
// that plane, round by round (interleaved, the best kept): EDL (robust, the default), relative
// depth at several radii, contour lines of the view depth and of the height, and EDL followed
// by both (a frame with everything on). Prints CSV; writes OUT/analysis.csv, OUT/analysis.png
// (ms per pass, EDL's beside), the pictures OUT/analysis-<scan>-<pass>.png and
// OUT/analysis_pictures.png (per scan: its colours, relative depth, EDL with height contours;
// the middle 960x540 of each frame, at half size).
// Goal: the default relative depth (radius 24) and contour lines each cost at most half an EDL
// pass, so a frame with EDL and one of them stays within 1.5x of the frame with EDL alone.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/view_renderer.h>

#include "bench_images.h"

namespace {

namespace fs = std::filesystem;
using namespace tessera;

struct Scan {
  std::string name;
  fs::path input;
  glm::dvec3 direction;  ///< from the model's centre to the eye
  glm::dvec3 up;
  double contour_interval = 1.0;  ///< units of the scan (Autzen: feet; the bunny: metres)
  glm::dvec3 height_axis;
};

/// A camera on `direction` from the store's centre, its bounding sphere filling the view.
render::ViewSetup viewOf(const lod::PointStore& store, const Scan& s, uint32_t w, uint32_t h) {
  const lod::StoreSummary& sum = store.summary();
  const glm::dvec3 centre = 0.5 * (sum.bbox_min + sum.bbox_max);
  const double radius = 0.5 * glm::length(sum.bbox_max - sum.bbox_min);
  const double fovy = glm::radians(40.0);
  const double distance = radius / std::sin(fovy / 2) * 0.8;
  const glm::dvec3 eye = centre + glm::normalize(s.direction) * distance;
  render::ViewSetup v;
  // Local frame of the store: the store's origin is added by the renderer's model matrix.
  v.view = glm::lookAt(eye + sum.origin, centre + sum.origin, s.up);
  v.projection = glm::perspective(fovy, double(w) / h, distance * 0.05, distance * 4);
  v.width = w;
  v.height = h;
  v.eye_world = eye + sum.origin;
  return v;
}

/// Half the size, each pixel the mean of a 2x2 block (the figure for the docs).
render::Image halve(const render::Image& img) {
  render::Image h;
  h.width = img.width / 2;
  h.height = img.height / 2;
  h.rgba.resize(size_t(h.width) * h.height * 4);
  for (uint32_t y = 0; y < h.height; ++y)
    for (uint32_t x = 0; x < h.width; ++x)
      for (int c = 0; c < 4; ++c) {
        int sum = 0;
        for (uint32_t k = 0; k < 4; ++k)
          sum += img.rgba[(size_t(2 * y + k / 2) * img.width + 2 * x + k % 2) * 4 + c];
        h.rgba[(size_t(y) * h.width + x) * 4 + c] = uint8_t((sum + 2) / 4);
      }
  return h;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"analysis: relative depth and contour lines against eye-dome lighting, ms at "
               "1920x1080 on real scans. Prints CSV; writes analysis.csv, analysis.png and the "
               "pictures into --out."};
  std::string out = std::string(TESSERA_BENCH_RESULTS_DIR) + "/analysis";
  int repeats = 3;
  app.add_option("--out", out, "Results folder (inputs built there once)")->capture_default_str();
  app.add_option("--repeats", repeats, "Timed rounds (best kept)")
      ->check(CLI::Range(1, 50))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  render::timePasses(true);  // the passes' milliseconds
  try {
    fs::create_directories(fs::path(out) / "inputs");
    const std::string data = TESSERA_DATA_DIR;
    const std::vector<Scan> scans = {
        {"autzen", data + "/lidar/autzen_trim.las", {0.0, -0.8, 0.75}, {0, 0, 1}, 5.0, {0, 0, 1}},
        {"bunny-scans", data + "/stanford-bunny/scans/bun.conf", {0.0, 0.1, 1.0}, {0, 1, 0}, 0.005,
         {0, 1, 0}}};
    auto ctx = render::GlContext::createHeadless();
    const uint32_t W = 1920, H = 1080;
    render::ViewRenderer renderer(W, H);
    std::ofstream csv(fs::path(out) / "analysis.csv");
    std::vector<render::Image> pictures;
    const std::string header = "scan,pass,ms,frame_ms";
    csv << header << "\n";
    std::cout << header << "\n";
    for (const Scan& s : scans) {
      const fs::path store_path = fs::path(out) / "inputs" / (s.name + ".tlod");
      if (!fs::exists(store_path)) {
        lod::BuildOptions b;
        b.quiet = true;
        lod::buildStore({s.input}, store_path, b);
      }
      auto store = lod::PointStore::open(store_path);
      render::ModelInstance inst{store.get(), render::storeModel(*store)};
      const render::ViewSetup view = viewOf(*store, s, W, H);
      render::RenderOptions o;
      // Every level the pixels ask for: the method measured alone, without the pixel budget.
      o.budget_per_covered_pixel = 0.0;
      render::RenderStats st;
      renderer.renderSettled({&inst, 1}, view, o, &st);
      const double frame_ms = st.totalMs();
      // The frame's depth and image, copied into a target of our own before every pass.
      render::FrameTarget target(W, H);
      render::GlBuffer depth(target.pixels() * 4, nullptr), image(target.pixels() * 4, nullptr);
      glCopyNamedBufferSubData(renderer.target().depth().name(), depth.name(), 0, 0,
                               GLsizeiptr(depth.bytes()));
      glCopyNamedBufferSubData(renderer.target().image().name(), image.name(), 0, 0,
                               GLsizeiptr(image.bytes()));
      auto restore = [&] {
        glCopyNamedBufferSubData(depth.name(), target.depth().name(), 0, 0, GLsizeiptr(depth.bytes()));
        glCopyNamedBufferSubData(image.name(), target.image().name(), 0, 0, GLsizeiptr(image.bytes()));
      };
      render::EdlPass edl;
      render::AnalysisPass analysis;
      struct Pass {
        std::string name;
        std::function<double()> run;
        double best = 1e300;
      };
      auto rel = [&](int radius) {
        render::RelativeDepthOptions r;
        r.enabled = true;
        r.radius = radius;
        return r;
      };
      render::ContourOptions depth_lines, height_lines;
      depth_lines.enabled = height_lines.enabled = true;
      depth_lines.interval = height_lines.interval = s.contour_interval;
      height_lines.height = true;
      height_lines.axis = s.height_axis;
      std::vector<Pass> passes = {
          {"edl", [&] { return edl.run(target, render::EdlOptions{}, view.projection); }},
          {"relative-depth-r12", [&] { return analysis.relativeDepth(target, rel(12), view.projection); }},
          {"relative-depth-r24", [&] { return analysis.relativeDepth(target, rel(24), view.projection); }},
          {"relative-depth-r48", [&] { return analysis.relativeDepth(target, rel(48), view.projection); }},
          {"contours-depth", [&] { return analysis.contours(target, depth_lines, view.projection, view.view); }},
          {"contours-height", [&] { return analysis.contours(target, height_lines, view.projection, view.view); }},
          {"edl+contours-height", [&] {
             return edl.run(target, render::EdlOptions{}, view.projection) +
                    analysis.contours(target, height_lines, view.projection, view.view);
           }},
      };
      for (int round = 0; round < repeats; ++round) {
        for (Pass& p : passes) {
          restore();
          p.best = std::min(p.best, p.run());
          if (round == 0) {
            const render::Image img = target.readImage();
            render::writePng((fs::path(out) / ("analysis-" + s.name + "-" + p.name + ".png")).string(),
                             img);
            if (p.name == "relative-depth-r24" || p.name == "edl+contours-height")
              pictures.push_back(bench::crop(img, W / 4, H / 4, W / 2, H / 2, 1));
          }
        }
      }
      restore();
      const render::Image colour = target.readImage();
      render::writePng((fs::path(out) / ("analysis-" + s.name + "-colour.png")).string(), colour);
      pictures.insert(pictures.end() - 2, bench::crop(colour, W / 4, H / 4, W / 2, H / 2, 1));
      for (const Pass& p : passes) {
        char line[256];
        std::snprintf(line, sizeof line, "%s,%s,%.1f,%.1f", s.name.c_str(), p.name.c_str(), p.best,
                      frame_ms);
        csv << line << "\n";
        std::cout << line << std::endl;
      }
    }
    csv.close();
    render::writePng((fs::path(out) / "analysis_pictures.png").string(),
                     halve(bench::grid(pictures, 3)));
    const fs::path gp = fs::path(out) / "analysis.gp";
    std::ofstream g(gp);
    g << "set terminal pngcairo size 1100,500 font 'sans,10' noenhanced\n"
      << "set output '" << (fs::path(out) / "analysis.png").string() << "'\n"
      << "set datafile separator ','\nset style data histogram\nset style histogram clustered\n"
      << "set style fill solid 0.85 border -1\nset grid ytics\nset yrange [0:*]\n"
         "set ylabel 'ms at 1920x1080 "
         "(llvmpipe, 2 cores)'\nset xtics rotate by -20\nset key top left\n"
      << "set title 'Analysis passes beside eye-dome lighting (best of " << repeats << ")'\n"
      << "plot '< grep ^autzen " << (fs::path(out) / "analysis.csv").string()
      << "' using 3:xtic(2) title 'Autzen (LiDAR)' lc rgb '#1f77b4', "
      << "'< grep ^bunny " << (fs::path(out) / "analysis.csv").string()
      << "' using 3 title 'bunny range scans' lc rgb '#ff7f0e'\n";
    g.close();
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + gp.string() + "'").c_str()) != 0)
      std::cerr << "analysis: gnuplot failed; the CSV is there\n";
  } catch (const std::exception& e) {
    std::cerr << "analysis: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
