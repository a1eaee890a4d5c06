// projector: the cost of the projector pass (render/projector_pass.h) per tile at 1920x1080,
// beside a plain frame's hand-over (the same pass with neither blend nor warp: one read and one
// write a pixel), in one run on one context: blend only (the automatic blend of a projector
// overlapping its neighbour by a fifth), warp only (a 33 x 19 grid: keystone and a wave), and
// both. Rounds interleave the four; the median of each is kept. Also the CPU time of computing
// the automatic blend (once per session on a node). Prints CSV; writes OUT/projector.csv and
// OUT/projector.png (ms per pass). The pass changes pixels: that is its purpose (tests check
// what it makes: tests/render/projector_test.cpp).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/core/stopwatch.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/image.h>
#include <tessera/render/projector_pass.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/config.h>

#include "bench_stats.h"

namespace {

namespace fs = std::filesystem;
using namespace tessera;

constexpr uint32_t kW = 1920, kH = 1080;

/// A keystone with a wave: the projector's top edge lands narrower, the picture bends a little.
std::vector<glm::vec2> warpGrid(uint32_t gw, uint32_t gh) {
  std::vector<glm::vec2> g;
  for (uint32_t j = 0; j < gh; ++j)
    for (uint32_t i = 0; i < gw; ++i) {
      const double s = double(i) / (gw - 1), t = double(j) / (gh - 1);
      const double inset = 0.08 * (1 - t);
      g.emplace_back(float(inset + (1 - 2 * inset) * s + 0.01 * std::sin(6 * t)),
                     float(0.02 + 0.96 * t + 0.008 * std::sin(5 * s)));
    }
  return g;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"projector: the blend and warp pass per 1920x1080 tile beside a plain frame's "
               "hand-over. Prints CSV; writes projector.csv and projector.png into --out."};
  std::string out = std::string(TESSERA_BENCH_RESULTS_DIR) + "/projector";
  int rounds = 15;
  app.add_option("--out", out, "Results folder")->capture_default_str();
  app.add_option("--rounds", rounds, "Timed rounds (the median kept)")
      ->check(CLI::Range(1, 200))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    fs::create_directories(out);
    // Two 1920x1080 projectors of 1.92 x 1.08 m overlapping by 0.384 m (a fifth).
    const config::WallConfig wall = sync::parseWallConfig(
        R"({"eye": {"x": 1.7, "y": 0.54, "z": 3}, "tiles": [
          {"name": "a", "x": 0, "y": 0, "width": 1.92, "height": 1.08, "pixelWidth": 1920,
           "pixelHeight": 1080, "blend": "auto"},
          {"name": "b", "x": 1.536, "y": 0, "width": 1.92, "height": 1.08, "pixelWidth": 1920,
           "pixelHeight": 1080, "blend": "auto"}]})",
        "bench");
    auto ctx = render::GlContext::createHeadless();
    const auto blend_start = std::chrono::steady_clock::now();
    const std::vector<render::ProjectorMap> maps = render::loadProjectorMaps(wall, true, 0);
    const double blend_setup_ms = msSince(blend_start);

    render::ProjectorMap plain, blend = maps[0], warp, both = maps[0];
    plain.width = warp.width = kW;
    plain.height = warp.height = kH;
    blend.warp.clear();
    warp.grid_width = both.grid_width = 33;
    warp.grid_height = both.grid_height = 19;
    warp.warp = both.warp = warpGrid(33, 19);
    const std::vector<std::pair<std::string, const render::ProjectorMap*>> modes = {
        {"plain", &plain}, {"blend", &blend}, {"warp", &warp}, {"blend+warp", &both}};

    std::vector<uint32_t> pixels(size_t(kW) * kH);
    for (size_t i = 0; i < pixels.size(); ++i) pixels[i] = uint32_t(i * 2654435761u) | 0xFF000000u;
    render::GlBuffer image(pixels.size() * 4, pixels.data());
    std::vector<render::ProjectorPass> passes;
    for (const auto& m : modes) passes.emplace_back(*m.second);
    std::vector<std::vector<double>> ms(modes.size());
    for (int r = -1; r < rounds; ++r) {  // round -1 warms up
      for (size_t k = 0; k < modes.size(); ++k) {
        glFinish();
        const auto start = std::chrono::steady_clock::now();
        passes[k].run(image.name());
        glFinish();
        if (r >= 0) ms[k].push_back(msSince(start));
      }
    }
    std::ofstream csv(fs::path(out) / "projector.csv");
    const std::string header = "pass,width,height,median_ms,p90_ms,ratio_to_plain";
    std::cout << header << "\n";
    csv << header << "\n";
    const double plain_ms = bench::percentile(ms[0], 0.5);
    for (size_t k = 0; k < modes.size(); ++k) {
      char line[256];
      std::snprintf(line, sizeof line, "%s,%u,%u,%.3f,%.3f,%.2f", modes[k].first.c_str(), kW, kH,
                    bench::percentile(ms[k], 0.5), bench::percentile(ms[k], 0.9),
                    bench::percentile(ms[k], 0.5) / plain_ms);
      std::cout << line << "\n";
      csv << line << "\n";
    }
    csv.close();
    std::printf("# the automatic blend of one 1920x1080 projector (CPU, once a session): %.1f ms\n",
                blend_setup_ms);
    const fs::path gp = fs::path(out) / "projector.gp";
    std::ofstream(gp)
        << "set terminal pngcairo size 800,450\nset output '"
        << (fs::path(out) / "projector.png").string()
        << "'\nset datafile separator ','\nset style data histograms\nset style fill solid 0.8\n"
           "set ylabel 'ms per 1920x1080 tile (median)'\nset title 'Projector pass on "
           "llvmpipe: blend and warp beside a plain hand-over'\nset yrange [0:*]\nplot '"
        << (fs::path(out) / "projector.csv").string()
        << "' every ::1 using 4:xtic(1) title 'median ms'\n";
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + gp.string() + "'").c_str()) != 0)
      std::cerr << "projector: gnuplot failed; the CSV is there\n";
    {
      // The overlap as the room sees it, without and with the blend (the two projectors'
      // pictures recomposed on the screen): a grid of lines over a colour ramp.
      std::vector<render::Image> shown(2);
      for (int t = 0; t < 2; ++t) {
        render::Image img;
        img.width = kW;
        img.height = kH;
        const double x0 = wall.tiles(t).x();
        for (uint32_t y = 0; y < kH; ++y)
          for (uint32_t x = 0; x < kW; ++x) {
            const double wx = x0 + (x + 0.5) / 1000.0, wy = (y + 0.5) / 1000.0;
            const bool line = std::fmod(wx, 0.2) < 0.006 || std::fmod(wy, 0.2) < 0.006;
            const uint8_t r = uint8_t(60 + 140 * wx / 3.456), g = uint8_t(90 + 80 * wy / 1.08);
            img.rgba.insert(img.rgba.end(), {line ? uint8_t(230) : r, line ? uint8_t(230) : g,
                                             line ? uint8_t(230) : uint8_t(110), 255});
          }
        shown[size_t(t)] = std::move(img);
      }
      config::WallConfig unblended = wall;
      for (auto& t : *unblended.mutable_tiles()) t.clear_blend();
      std::vector<render::ProjectorMap> none = render::loadProjectorMaps(unblended);
      std::vector<render::ProjectorMap> all = render::loadProjectorMaps(wall);
      const render::Image before = render::recomposeScreen(unblended, shown, none);
      std::vector<render::Image> blended = {render::applyProjector(all[0], shown[0]),
                                            render::applyProjector(all[1], shown[1])};
      const render::Image after = render::recomposeScreen(wall, blended, all);
      // The overlap and its surroundings, 1000 x 540 pixels of each, one above the other.
      render::Image pair;
      pair.width = 1000;
      pair.height = 1080 + 8;
      pair.rgba.assign(size_t(pair.width) * pair.height * 4, 255);
      for (int k = 0; k < 2; ++k) {
        const render::Image& src = k == 0 ? before : after;
        for (uint32_t y = 0; y < 540; ++y)
          std::copy_n(&src.rgba[((y + 270) * size_t(src.width) + 1228) * 4], 1000 * 4,
                      &pair.rgba[((y + k * 548) * size_t(pair.width)) * 4]);
      }
      render::writePng((fs::path(out) / "projector_overlap.png").string(), pair);
    }
    std::printf("# reproduce: build/dev/bench/projector --rounds %d --out %s\n", rounds,
                out.c_str());
  } catch (const std::exception& e) {
    std::cerr << "projector: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
