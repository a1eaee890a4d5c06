// stereo_wall: what a passive stereo wall and a moved viewer's head (sync/viewer_head.h) cost
// against the mono wall seen from its eye, on one context (llvmpipe): a 1x2 wall of 960x540
// tiles (0.96 x 0.54 m, a 2 cm bezel) with the bunny's ten range scans filling its height. Per round
// (interleaved, the median kept): every slot's frame (settled, chunks resident: draw and
// read-back) of the mono wall from its eye (the baseline), of the mono wall from a head moved
// and turned, and of the stereo wall (a slot per eye and tile); the master's screenshot of the
// mono wall (assembleWallMosaic()) and of the stereo one (the left eye and each eye's picture,
// assembleWallEye()); and the views themselves (slotView() of every slot, with and without a
// head, 10000 times). Beside the times, how far the eyes' pictures are apart (pixels that differ,
// mean level difference). Prints CSV; writes OUT/stereo_wall.csv, OUT/stereo_wall.png (ms per
// step) and OUT/stereo_wall-left.png, -right.png (the eyes' walls).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/inset.h>
#include <tessera/render/view_renderer.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/sync/config.h>
#include <tessera/sync/vec3.h>
#include <tessera/sync/viewer_head.h>

namespace {

namespace fs = std::filesystem;
using namespace tessera;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

/// The frames of every slot of `wall` seen from `head` (null: the wall's eye).
struct WallFrames {
  config::WallConfig wall;
  std::vector<render::WallSlot> slots;
  std::vector<render::ViewSetup> views;
  std::vector<std::unique_ptr<render::ViewRenderer>> renderers;
  std::vector<render::Image> pictures;

  WallFrames(const config::WallConfig& w, const config::Camera& cam, const sync::ViewerHead* head)
      : wall(w), slots(render::wallSlots(w)) {
    for (const render::WallSlot& s : slots) {
      views.push_back(render::slotView(wall, s, {}, cam, head));
      renderers.push_back(
          std::make_unique<render::ViewRenderer>(views.back().width, views.back().height));
    }
    pictures.resize(slots.size());
  }
  void draw(const render::ModelInstance& inst, const render::RenderOptions& options) {
    for (size_t i = 0; i < slots.size(); ++i)
      pictures[i] = renderers[i]->renderSettled({&inst, 1}, views[i], options);
  }
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "stereo_wall: a passive stereo wall's and a moved head's cost against the mono 1x2 wall "
      "of 960x540 tiles seen from its eye, ms per step. Prints CSV; writes stereo_wall.csv and "
      "stereo_wall.png into --out."};
  std::string out = std::string(TESSERA_BENCH_RESULTS_DIR) + "/stereo_wall";
  int repeats = 5;
  app.add_option("--out", out, "Results folder (inputs built there once)")->capture_default_str();
  app.add_option("--repeats", repeats, "Timed rounds (the median kept)")
      ->check(CLI::Range(1, 50))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    fs::create_directories(fs::path(out) / "inputs");
    const fs::path store_path = fs::path(out) / "inputs" / "bunny-scans.tlod";
    if (!fs::exists(store_path)) {
      lod::BuildOptions b;
      b.quiet = true;
      lod::buildStore({std::string(TESSERA_DATA_DIR) + "/stanford-bunny/scans/bun.conf"},
                      store_path, b);
    }
    const std::string tiles = R"("tiles": [
        {"name": "left", "x": 0, "y": 0, "width": 0.96, "height": 0.54, "pixelWidth": 960,
         "pixelHeight": 540},
        {"name": "right", "x": 0.98, "y": 0, "width": 0.96, "height": 0.54, "pixelWidth": 960,
         "pixelHeight": 540}], "eye": {"x": 0.97, "y": 0.27, "z": 1.0})";
    const config::WallConfig mono = sync::parseWallConfig("{" + tiles + "}", "mono wall", "");
    const config::WallConfig stereo = sync::parseWallConfig(
        R"({"stereo": true, "eyeSeparation": 0.065, )" + tiles + "}", "stereo wall", "");
    auto ctx = render::GlContext::createHeadless();
    auto store = lod::PointStore::open(store_path);
    render::ModelInstance inst{store.get(), render::storeModel(*store)};
    // The camera: the bunny's bounding sphere across the wall's height, from the front (it
    // stands in front of the wall plane, as near the eyes as the camera is to it).
    const lod::StoreSummary& sum = store->summary();
    const glm::dvec3 c = sum.origin + 0.5 * (sum.bbox_min + sum.bbox_max);
    const double radius = 0.5 * glm::length(sum.bbox_max - sum.bbox_min);
    config::Camera cam;
    sync::set(cam.mutable_eye(), c + glm::dvec3(0.0, 0.0, radius / 0.27 * 0.9));
    sync::set(cam.mutable_target(), c);
    cam.mutable_up()->set_y(1.0);
    // A head 10 cm left, 5 cm up and 10 cm nearer, turned 20 degrees.
    scene::Settings moved;
    sync::set(moved.mutable_head()->mutable_eye(), glm::dvec3(0.87, 0.32, 0.9));
    sync::set(moved.mutable_head()->mutable_right(),
              glm::dvec3(std::cos(glm::radians(20.0)), 0.0, std::sin(glm::radians(20.0))));
    if (const auto why = sync::headProblem(mono, moved.head()))
      throw std::runtime_error("the bench's head: " + *why);
    const sync::ViewerHead head = sync::viewerHead(mono, moved);

    WallFrames from_eye(mono, cam, nullptr), from_head(mono, cam, &head),
        eyes(stereo, cam, nullptr);
    render::RenderOptions options;
    options.edl.strength = 1.0f;  // the wall's default shading
    render::Image mono_shot, left, right, stereo_shot;
    const std::vector<render::WallSlot> stereo_slots = render::wallSlots(stereo);
    size_t views_made = 0;
    auto makeViews = [&](const sync::ViewerHead* h) {
      return [&, h] {
        for (int k = 0; k < 10000; ++k)
          for (const render::WallSlot& s : stereo_slots)
            views_made += render::slotView(stereo, s, {}, cam, h).width > 0;
      };
    };
    struct Step {
      std::string name;
      std::function<void()> run;
      std::vector<double> ms;
    };
    std::vector<Step> steps = {
        {"mono wall frames from its eye (2 slots)", [&] { from_eye.draw(inst, options); }, {}},
        {"mono wall frames from a moved head (2 slots)",
         [&] { from_head.draw(inst, options); },
         {}},
        {"stereo wall frames (4 slots)", [&] { eyes.draw(inst, options); }, {}},
        {"mono screenshot",
         [&] { mono_shot = render::assembleWallMosaic(mono, from_eye.pictures); },
         {}},
        {"stereo screenshot and both eyes",
         [&] {
           stereo_shot = render::assembleInsetWall(stereo, eyes.pictures, {});
           left = render::assembleWallEye(stereo, eyes.pictures, {}, -1);
           right = render::assembleWallEye(stereo, eyes.pictures, {}, 1);
         },
         {}},
        {"10000 x 4 slot views from the wall's eye", makeViews(nullptr), {}},
        {"10000 x 4 slot views from a head", makeViews(&head), {}},
    };
    for (Step& s : steps) s.run();  // settles every view: every chunk of the cuts resident
    for (int round = 0; round < repeats; ++round)
      for (Step& s : steps) {
        const auto t0 = std::chrono::steady_clock::now();
        s.run();
        s.ms.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
      }
    // How far the eyes are apart: the pixels that differ and their mean level difference.
    size_t differ = 0;
    double level = 0.0;
    for (size_t i = 0; i < left.rgba.size(); i += 4) {
      int d = 0;
      for (int k = 0; k < 3; ++k)
        d = std::max(d, std::abs(int(left.rgba[i + k]) - right.rgba[i + k]));
      differ += d > 0;
      level += d;
    }
    const size_t pixels = left.rgba.size() / 4;
    std::ofstream csv(fs::path(out) / "stereo_wall.csv");
    const std::string header = "step,ms_median,ms_best";
    csv << header << "\n";
    std::cout << header << "\n";
    for (const Step& s : steps) {
      char line[256];
      std::snprintf(line, sizeof line, "%s,%.2f,%.2f", s.name.c_str(), median(s.ms),
                    *std::min_element(s.ms.begin(), s.ms.end()));
      csv << line << "\n";
      std::cout << line << std::endl;
    }
    csv.close();
    std::printf(
        "eyes apart: %zu of %zu pixels differ (%.1f%%), mean level difference %.2f; "
        "the screenshot is the left eye: %s\n",
        differ, pixels, 100.0 * double(differ) / double(pixels), level / double(pixels),
        stereo_shot.rgba == left.rgba ? "yes" : "NO");
    render::writePng((fs::path(out) / "stereo_wall-left.png").string(), left);
    render::writePng((fs::path(out) / "stereo_wall-right.png").string(), right);
    const fs::path gp = fs::path(out) / "stereo_wall.gp";
    std::ofstream g(gp);
    g << "set terminal pngcairo size 900,450 font 'sans,10' noenhanced\n"
      << "set output '" << (fs::path(out) / "stereo_wall.png").string() << "'\n"
      << "set datafile separator ','\nset style data histogram\n"
      << "set style fill solid 0.85 border -1\nset grid ytics\nset yrange [0:*]\n"
      << "set ylabel 'ms (llvmpipe, 2 cores)'\nset xtics rotate by -20 font ',8'\n"
      << "set bmargin 8\nset title 'A 1x2 wall of 960x540 tiles: mono from its eye, from a "
         "moved head, and passive stereo (median of "
      << repeats << ")'\n"
      << "plot '" << (fs::path(out) / "stereo_wall.csv").string()
      << "' every ::1 using 2:xtic(1) notitle lc rgb '#1f77b4'\n";
    g.close();
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + gp.string() + "'").c_str()) != 0)
      std::cerr << "stereo_wall: gnuplot failed; the CSV is there\n";
    std::cerr << "stereo_wall: " << views_made << " views made\n"
              << "reproduce: " << argv[0] << " --repeats " << repeats << " --out " << out << "\n";
  } catch (const std::exception& e) {
    std::cerr << "stereo_wall: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
