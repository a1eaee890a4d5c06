// inset: what a foveal inset (render/inset.h) costs against the context it sits in, per frame,
// on one context (llvmpipe): a 1920x1080 context tile of 0.96 x 0.54 m and a 1920x1080 inset over
// a fifth of its area (0.429 x 0.241 m, 2.24 times the density each way), the bunny's ten range
// scans filling the tile. Per round (interleaved, the median kept): the context's frame (settled,
// chunks resident: draw and read-back), its weights (blacking it out under the inset: the CPU
// reference and the GPU pass nodes run, with its read-back), the inset's frame, its weights, and
// the wall picture (the screenshot's composite:
// assembleInsetWall()) and the inset's own picture (insetDetail()). Prints CSV; writes
// OUT/inset.csv, OUT/inset.png (ms per step) and OUT/inset_wall.png (the composite).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
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
#include <tessera/sync/config.h>

namespace {

namespace fs = std::filesystem;
using namespace tessera;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "inset: a foveal inset's cost against its 1920x1080 context tile, ms per frame. "
      "Prints CSV; writes inset.csv, inset.png and inset_wall.png into --out."};
  std::string out = std::string(TESSERA_BENCH_RESULTS_DIR) + "/inset";
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
    // One tile and an inset of a fifth of its area, centred on it.
    const double side = 1.0 / std::sqrt(5.0), w = 0.96 * side, h = 0.54 * side;
    char json[1024];
    std::snprintf(json, sizeof json,
                  R"({"name": "bench", "tiles": [{"name": "context", "x": 0, "y": 0, "width": 0.96,
                  "height": 0.54, "pixelWidth": 1920, "pixelHeight": 1080}], "insets": [{"name":
                  "fovea", "x": %.9f, "y": %.9f, "width": %.9f, "height": %.9f, "pixelWidth": 1920,
                  "pixelHeight": 1080}], "eye": {"x": 0.48, "y": 0.27, "z": 1.0}})",
                  0.48 - w / 2, 0.27 - h / 2, w, h);
    const config::WallConfig wall = sync::parseWallConfig(json, "bench wall", "");
    auto ctx = render::GlContext::createHeadless();
    auto store = lod::PointStore::open(store_path);
    render::ModelInstance inst{store.get(), render::storeModel(*store)};
    // The camera: the bunny's bounding sphere filling the tile's height, from the front.
    const lod::StoreSummary& sum = store->summary();
    const glm::dvec3 c = sum.origin + 0.5 * (sum.bbox_min + sum.bbox_max);
    const double radius = 0.5 * glm::length(sum.bbox_max - sum.bbox_min);
    config::Camera cam;
    cam.mutable_eye()->set_x(c.x);
    cam.mutable_eye()->set_y(c.y);
    cam.mutable_eye()->set_z(c.z + radius * 1.0 / 0.27 * 0.9);
    cam.mutable_target()->set_x(c.x);
    cam.mutable_target()->set_y(c.y);
    cam.mutable_target()->set_z(c.z);
    cam.mutable_up()->set_y(1.0);
    const std::vector<render::WallSlot> slots = render::wallSlots(wall);
    const scene::InsetPlacement placement;
    std::vector<render::ViewSetup> views;
    std::vector<std::unique_ptr<render::ViewRenderer>> renderers;
    for (const render::WallSlot& s : slots) {
      views.push_back(render::slotView(wall, s, placement, cam));
      renderers.push_back(
          std::make_unique<render::ViewRenderer>(views.back().width, views.back().height));
    }
    std::vector<render::Image> pictures(slots.size()), weighted(slots.size());
    render::RenderOptions options;
    options.edl.strength = 1.0f;  // the wall's default shading
    struct Step {
      std::string name;
      std::function<void()> run;
      std::vector<double> ms;
    };
    auto frame = [&](size_t i) {
      return [&, i] { pictures[i] = renderers[i]->renderSettled({&inst, 1}, views[i], options); };
    };
    auto weigh = [&](size_t i) {
      return [&, i] {
        weighted[i] = pictures[i];
        render::applySlotWeights(wall, slots[i], placement, weighted[i]);
      };
    };
    render::InsetPass pass;
    auto weighGpu = [&](size_t i) {
      return [&, i] {
        pass.run(renderers[i]->imageBuffer(), wall, slots[i], placement);
        weighted[i] = pass.read();
      };
    };
    render::Image composite, detail;
    std::vector<Step> steps = {
        {"context frame", frame(0), {}},
        {"context weights (CPU)", weigh(0), {}},
        {"context weights (GPU)", weighGpu(0), {}},
        {"inset frame", frame(1), {}},
        {"inset weights (CPU)", weigh(1), {}},
        {"inset weights (GPU)", weighGpu(1), {}},
        {"wall composite (screenshot)",
         [&] { composite = render::assembleInsetWall(wall, weighted, placement); },
         {}},
        {"inset picture (screenshot)",
         [&] { detail = render::insetDetail(wall, weighted, placement, 0, 0); },
         {}},
    };
    for (Step& s : steps) s.run();  // settles both views: every chunk of the cut resident
    for (int round = 0; round < repeats; ++round)
      for (Step& s : steps) {
        const auto t0 = std::chrono::steady_clock::now();
        s.run();
        s.ms.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
      }
    std::ofstream csv(fs::path(out) / "inset.csv");
    const std::string header = "step,ms_median,ms_best,pixels";
    csv << header << "\n";
    std::cout << header << "\n";
    for (const Step& s : steps) {
      char line[256];
      std::snprintf(line, sizeof line, "%s,%.2f,%.2f,%u", s.name.c_str(), median(s.ms),
                    *std::min_element(s.ms.begin(), s.ms.end()), 1920u * 1080u);
      csv << line << "\n";
      std::cout << line << std::endl;
    }
    csv.close();
    render::writePng((fs::path(out) / "inset_wall.png").string(), composite);
    render::writePng((fs::path(out) / "inset_detail.png").string(), detail);
    const fs::path gp = fs::path(out) / "inset.gp";
    std::ofstream g(gp);
    g << "set terminal pngcairo size 900,450 font 'sans,10' noenhanced\n"
      << "set output '" << (fs::path(out) / "inset.png").string() << "'\n"
      << "set datafile separator ','\nset style data histogram\n"
      << "set style fill solid 0.85 border -1\nset grid ytics\nset yrange [0:*]\n"
      << "set ylabel 'ms per frame (llvmpipe, 2 cores)'\nset xtics rotate by -20\n"
      << "set title 'A 1920x1080 foveal inset over a fifth of a 1920x1080 context tile (median of "
      << repeats << ")'\n"
      << "plot '" << (fs::path(out) / "inset.csv").string()
      << "' every ::1 using 2:xtic(1) notitle lc rgb '#1f77b4'\n";
    g.close();
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + gp.string() + "'").c_str()) != 0)
      std::cerr << "inset: gnuplot failed; the CSV is there\n";
  } catch (const std::exception& e) {
    std::cerr << "inset: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
