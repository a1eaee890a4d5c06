// wall_movie: what a filmed frame costs the master (tessera-master --path --movie, master.cpp
// Master::film()) beside its baseline, a screenshot frame (the wall assembled and written as a
// PNG), in one process on the configs/walls/2x2.json wall (four 960x540 tiles, a 1940x1100
// picture): the wall assembled and encoded into the MP4 (media/movie_writer.h), the same scaled
// to 1280x726 first (render::resizeImage()), and written as a PNG of a frame sequence. Also, for
// two overlapping 1920x1080 projectors, the screen recomposed (render::recomposeScreen(), a
// projector wall's screenshot) and the projectors' pictures side by side
// (render::assembleProjectorFrames()). The tiles are a moving pattern of gradients and noise, so
// the encoder works as on a real picture. Rounds interleave the steps; the median of each is
// kept, and for the movies the mean with the encoder's flush at the end shared out over the
// frames (it holds frames back). Prints CSV; writes OUT/wall_movie.csv and OUT/wall_movie.png
// (ms per frame). Pixels:
// what is timed makes the pictures the tests check (tests/cluster/cluster_test.cpp).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include <tessera/core/stopwatch.h>
#include <tessera/media/movie_writer.h>
#include <tessera/render/image.h>
#include <tessera/render/projector_pass.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/config.h>

#include "bench_stats.h"

namespace {

namespace fs = std::filesystem;
using namespace tessera;

/// A tile's picture at frame `f`: gradients with hashed noise, moved by `f` pixels a frame.
render::Image tilePicture(uint32_t w, uint32_t h, uint32_t tile, uint32_t f) {
  render::Image img;
  img.width = w;
  img.height = h;
  img.rgba.resize(size_t(w) * h * 4);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const uint32_t n = (x + 3 * f) * 2654435761u ^ (y + 977 * tile) * 40503u;
      uint8_t* p = &img.rgba[(size_t(y) * w + x) * 4];
      p[0] = uint8_t((x + 2 * f) * 255 / w / 2 + (n >> 28));
      p[1] = uint8_t(y * 255 / h / 2 + 60 + (n >> 27 & 15));
      p[2] = uint8_t(80 + 40 * tile + (n >> 26 & 31));
      p[3] = 255;
    }
  return img;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"wall_movie: a filmed frame's cost to the master beside a screenshot frame's. "
               "Prints CSV; writes wall_movie.csv and wall_movie.png into --out."};
  std::string out = std::string(TESSERA_BENCH_RESULTS_DIR) + "/wall_movie";
  int rounds = 9;
  app.add_option("--out", out, "Results folder")->capture_default_str();
  app.add_option("--rounds", rounds, "Timed rounds (the median kept)")
      ->check(CLI::Range(1, 200))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    fs::create_directories(out);
    const config::WallConfig wall =
        sync::loadWallConfig(std::string(TESSERA_CONFIG_DIR) + "/walls/2x2.json");
    const config::WallConfig projectors = sync::parseWallConfig(
        R"({"eye": {"x": 1.7, "y": 0.54, "z": 3}, "tiles": [
          {"name": "a", "x": 0, "y": 0, "width": 1.92, "height": 1.08, "pixelWidth": 1920,
           "pixelHeight": 1080, "blend": "auto"},
          {"name": "b", "x": 1.536, "y": 0, "width": 1.92, "height": 1.08, "pixelWidth": 1920,
           "pixelHeight": 1080, "blend": "auto"}]})",
        "bench");
    const std::vector<render::ProjectorMap> maps = render::loadProjectorMaps(projectors, false);
    const glm::uvec2 size = render::wallPictureSize(wall);
    const uint32_t small_w = 1280, small_h = uint32_t(size.y * 1280 / size.x) & ~1u;
    std::vector<std::vector<render::Image>> tiles(uint32_t(rounds) + 1),
        shown(uint32_t(rounds) + 1);
    for (uint32_t f = 0; f <= uint32_t(rounds); ++f) {
      for (int t = 0; t < wall.tiles_size(); ++t)
        tiles[f].push_back(tilePicture(wall.tiles(t).pixel_width(), wall.tiles(t).pixel_height(),
                                       uint32_t(t), f));
      for (uint32_t t = 0; t < 2; ++t) shown[f].push_back(tilePicture(1920, 1080, t, f));
    }
    media::MovieSettings ms;
    ms.width = int(size.x);
    ms.height = int(size.y);
    ms.fps = 30;
    media::MovieWriter movie((fs::path(out) / "wall.mp4").string(), ms);
    ms.width = int(small_w);
    ms.height = int(small_h);
    media::MovieWriter small((fs::path(out) / "wall-small.mp4").string(), ms);
    const fs::path png = fs::path(out) / "frame.png";
    uint32_t frame = 0;
    const std::vector<std::pair<std::string, std::function<void()>>> steps = {
        {"screenshot (assemble + PNG)",
         [&] { render::writePng(png.string(), render::assembleWallMosaic(wall, tiles[frame])); }},
        {"movie frame (assemble + encode)",
         [&] {
           const render::Image w = render::assembleWallMosaic(wall, tiles[frame]);
           movie.write(w.rgba, int(w.width), int(w.height));
         }},
        {"movie frame at 1280 wide (+ resize)",
         [&] {
           const render::Image w = render::resizeImage(
               render::assembleWallMosaic(wall, tiles[frame]), small_w, small_h);
           small.write(w.rgba, int(w.width), int(w.height));
         }},
        {"assemble + resize to 1280 wide", [&] {
           (void)render::resizeImage(render::assembleWallMosaic(wall, tiles[frame]), small_w,
                                     small_h);
         }},
        {"projectors recomposed (2 x 1920x1080)",
         [&] { (void)render::recomposeScreen(projectors, shown[frame], maps); }},
        {"projectors side by side",
         [&] { (void)render::assembleProjectorFrames(projectors, shown[frame]); }},
    };
    std::vector<std::vector<double>> times(steps.size());
    for (int r = -1; r < rounds; ++r) {  // round -1 warms up
      frame = uint32_t(r + 1);
      for (size_t k = 0; k < steps.size(); ++k) {
        const auto start = std::chrono::steady_clock::now();
        steps[k].second();
        if (r >= 0) times[k].push_back(msSince(start));
      }
    }
    // The encoder holds frames back (its lookahead) and drains them at the end: its last frames'
    // cost is in finish(), shared out over the frames written.
    std::vector<double> flush_ms(steps.size(), 0.0);
    for (auto [k, writer] : {std::pair<size_t, media::MovieWriter*>{1, &movie}, {2, &small}}) {
      const auto start = std::chrono::steady_clock::now();
      writer->finish();
      flush_ms[k] = msSince(start) / double(writer->frames());
    }
    std::ofstream csv(fs::path(out) / "wall_movie.csv");
    const std::string header =
        "step,width,height,median_ms,p90_ms,mean_ms_with_flush,ratio_to_screenshot";
    std::cout << header << "\n";
    csv << header << "\n";
    const double base = bench::percentile(times[0], 0.5);
    auto mean = [](const std::vector<double>& v) {
      double sum = 0;
      for (const double x : v) sum += x;
      return v.empty() ? 0.0 : sum / double(v.size());
    };
    for (size_t k = 0; k < steps.size(); ++k) {
      const bool proj = k >= 4;
      char line[256];
      std::snprintf(line, sizeof line, "\"%s\",%u,%u,%.2f,%.2f,%.2f,%.2f",
                    steps[k].first.c_str(), proj ? 3456u : k == 2 || k == 3 ? small_w : size.x,
                    proj ? 1080u : k == 2 || k == 3 ? small_h : size.y,
                    bench::percentile(times[k], 0.5), bench::percentile(times[k], 0.9),
                    mean(times[k]) + flush_ms[k], bench::percentile(times[k], 0.5) / base);
      std::cout << line << "\n";
      csv << line << "\n";
    }
    csv.close();
    std::printf("# encoder: %s\n", movie.encoder().c_str());
    const fs::path gp = fs::path(out) / "wall_movie.gp";
    std::ofstream(gp)
        << "set terminal pngcairo size 1000,560\nset output '"
        << (fs::path(out) / "wall_movie.png").string()
        << "'\nset datafile separator ','\nset style data histograms\nset style fill solid 0.8\n"
           "set ylabel 'ms per frame on the master (log scale)'\nset title 'A filmed frame of "
           "the 2x2 wall (1940x1100) beside a screenshot frame; a projector wall'\nset logscale "
           "y\nset yrange [10:*]\nset key top left\nset xtics rotate by -25 font ',9'\nset "
           "bmargin 9\nset rmargin 8\nplot '"
        << (fs::path(out) / "wall_movie.csv").string()
        << "' every ::1 using 4:xtic(1) title 'median ms', '' every ::1 using 6 title 'mean ms "
           "with the encoder flush'\n";
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + gp.string() + "'").c_str()) != 0)
      std::cerr << "wall_movie: gnuplot failed; the CSV is there\n";
    std::printf("# reproduce: build/dev/bench/wall_movie --rounds %d --out %s\n", rounds,
                out.c_str());
  } catch (const std::exception& e) {
    std::cerr << "wall_movie: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
