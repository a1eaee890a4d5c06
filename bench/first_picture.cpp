// first_picture: how soon a raw scan shows. tessera-render --model SCAN --preview (a preview
// store from an even sample of the scan, lod/scan_preview.h, drawn first; the whole store built
// and drawn after it) against building the whole store first and drawing it (what --model does
// without --preview), and against ParaView 5.11's first picture of the same points (pvbatch:
// the reader, then the first render) when pvbatch is on PATH (xvfb-run without a display).
//
// Inputs, at each size N (--points), generated once into OUT/inputs:
//   autzen  autzen_trim.las tiled side by side into one LAS of N points by bench/tile_las.py
//   cube    N points uniformly random in the unit cube as a binary PLY (the points of
//           bench/paraview_peer and tests/support/random_cube.h)
// ParaView reads the same points as binary PLY (Autzen: positions relative to the box's lower
// corner, colours kept). The view: 1280x720 (tessera-render's default), Tessera's defaults; the
// cube from ParaView's reset camera (bench_views.h cubeCamera()), Autzen from the south and above
// as tessera-render fits flat scans. Each Tessera run starts from an empty store cache and the
// input in the page cache; the GL context is made once (both methods pay it alike in
// tessera-render). Methods alternate in each round (--rounds); medians are kept.
//
// Per run: the time to the first picture and to the final picture, and for the preview its
// likeness to the final picture (render/image.h comparePictures(): the IoU of the covered
// pixels, brighter than 16 in any channel; the silhouette IoU of 8-pixel blocks; the mean
// absolute difference of its RGB over the pixels either picture covers).
//
// Prints CSV; writes OUT/first_picture.csv (every run), OUT/first_picture_summary.csv
// (medians), OUT/first_picture.png (gnuplot) and each input's preview and final pictures as
// OUT/first_picture-INPUT-N-{preview,final}.png.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/stopwatch.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/scan_preview.h>
#include <tessera/lod/store_cache.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/image.h>
#include <tessera/render/view_renderer.h>

#include "../tests/support/random_cube.h"
#include "bench_views.h"

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr uint32_t kWidth = 1280, kHeight = 720;

struct Input {
  std::string name;  ///< "autzen" or "cube"
  uint64_t points = 0;
  fs::path scan;                    ///< what Tessera opens
  fs::path paraview;                ///< the same points as binary PLY for ParaView (made on demand)
  bench::CubeCamera camera;         ///< world frame
  glm::dvec3 paraview_origin{0.0};  ///< ParaView's positions are world minus this
};

/// Autzen tiled to `n` points (bench/tile_las.py), kept between runs.
Input autzenInput(const fs::path& dir, uint64_t n) {
  Input in;
  in.name = "autzen";
  in.points = n;
  in.scan = dir / ("autzen-" + std::to_string(n) + ".las");
  in.paraview = dir / ("autzen-" + std::to_string(n) + ".ply");
  if (!fs::exists(in.scan)) {
    const fs::path script = fs::path(TESSERA_CONFIG_DIR).parent_path() / "bench" / "tile_las.py";
    const std::string cmd = "python3 '" + script.string() + "' '" + TESSERA_DATA_DIR +
                            "/lidar/autzen_trim.las' -o '" + in.scan.string() + "' -n " +
                            std::to_string(n) + " >&2";
    if (std::system(cmd.c_str()) != 0)
      throw std::runtime_error("first_picture: tiling Autzen failed: " + cmd);
  }
  const auto box = lod::openPointReader(in.scan)->info().header_bbox;
  if (!box) throw std::runtime_error("first_picture: " + in.scan.string() + " has no box");
  // From the south and above, z up, as tessera-render fits flat scans.
  const glm::dvec3 c = 0.5 * (box->first + box->second);
  const double r = 0.5 * glm::length(box->second - box->first);
  in.camera = {c + glm::dvec3(0.0, -1.6 * r, 1.2 * r), c, glm::dvec3(0, 0, 1), 45.0};
  in.paraview_origin = box->first;
  return in;
}

Input cubeInput(const fs::path& dir, uint64_t n) {
  Input in;
  in.name = "cube";
  in.points = n;
  in.scan = in.paraview = dir / ("cube-" + std::to_string(n) + ".ply");
  if (!fs::exists(in.scan)) test::randomCubePly(in.scan, n);
  in.camera = bench::cubeCamera();
  return in;
}

/// ParaView's copy of an input that is not a PLY: positions relative to paraview_origin (float
/// keeps centimetres), colours kept.
void writeParaViewPly(const Input& in) {
  if (fs::exists(in.paraview)) return;
  auto reader = lod::openPointReader(in.scan);
  lod::PointBatch all, b;
  all.reset(reader->info().attributes & lod::kColor);
  while (reader->next(b)) all.appendRange(b, 0, b.size());
  lod::writePly(in.paraview, all, reader->info().origin - in.paraview_origin);
}

render::ViewSetup viewOf(const bench::CubeCamera& c) {
  render::ViewSetup v;
  v.view = glm::lookAt(c.eye, c.target, c.up);
  const double d = glm::length(c.eye - c.target);
  v.projection = glm::perspective(glm::radians(c.fovy), double(kWidth) / kHeight, 0.02 * d, 4 * d);
  v.width = kWidth;
  v.height = kHeight;
  v.eye_world = c.eye;
  return v;
}

struct Run {
  double first_s = 0, final_s = 0, iou = 1, silhouette_iou = 1, mean_diff = 0;
  double sample_s = 0, preview_build_s = 0;  ///< preview: its parts of first_s
  uint64_t preview_points = 0;
  render::Image first, final;
};

/// `preview`: as tessera-render --preview draws a preview (no per-point splat sizes).
render::Image draw(const fs::path& store_path, const render::ViewSetup& view,
                   bool preview = false) {
  auto store = lod::PointStore::open(store_path);
  render::ModelInstance inst{store.get(), render::storeModel(*store)};
  render::StreamerOptions stream;
  stream.point_splat_sizes = !preview;
  render::ViewRenderer r(view.width, view.height, nullptr, stream);
  return r.renderSettled({&inst, 1}, view, render::RenderOptions{});
}

/// An empty store cache for one run, removed after it.
struct FreshCache {
  explicit FreshCache(const fs::path& dir) : path(dir) {
    fs::remove_all(path);
    fs::create_directories(path);
    setenv("XDG_CACHE_HOME", path.c_str(), 1);
  }
  ~FreshCache() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  fs::path path;
};

Run buildThenDraw(const Input& in, const fs::path& cache) {
  FreshCache fresh(cache);
  Run run;
  const auto t = Clock::now();
  run.final = draw(lod::cachedStoreFor(in.scan, "first_picture", true), viewOf(in.camera));
  run.first_s = run.final_s = msSince(t) / 1000.0;
  run.first = run.final;
  return run;
}

Run previewFirst(const Input& in, const fs::path& cache, uint64_t sample) {
  FreshCache fresh(cache);
  Run run;
  const auto t = Clock::now();
  lod::ScanPreview preview(in.scan, "first_picture", {sample}, true);
  if (!preview.hasPreview())
    throw std::runtime_error("first_picture: " + in.scan.string() +
                             ": no preview: " + preview.whyNot());
  run.first = draw(preview.previewPath(), viewOf(in.camera), true);
  run.first_s = msSince(t) / 1000.0;
  run.final = draw(preview.finalStore(), viewOf(in.camera));
  run.final_s = msSince(t) / 1000.0;
  run.preview_points = preview.previewPoints();
  run.sample_s = preview.sampleSeconds();
  run.preview_build_s = preview.previewBuildSeconds();
  const render::PictureLikeness like = render::comparePictures(run.first, run.final);
  run.iou = like.pixel_iou;
  run.silhouette_iou = like.silhouette_iou;
  run.mean_diff = like.mean_difference;
  return run;
}

constexpr const char* kPvScript = R"(# bench/first_picture: ParaView's first picture of a PLY
# prints PVFIRST,seconds from the script's start to the first frame finished
import sys, time
t0 = time.time()
import paraview.simple as pv
ply, png = sys.argv[1], sys.argv[2]
cam = [float(x) for x in sys.argv[3:13]]
w, h = int(sys.argv[13]), int(sys.argv[14])
source = pv.PLYReader(FileNames=[ply])
view = pv.CreateView('RenderView', ViewSize=[w, h], OrientationAxesVisibility=0)
try:
    view.UseColorPaletteForBackground = 0
except AttributeError:
    pass
view.Background = [0, 0, 0]
shown = pv.Show(source, view, Representation='Points', PointSize=1)
arrays = [a.Name for a in source.PointData]
colour = next((a for a in ('RGB', 'rgb', 'RGBA') if a in arrays), None)
shown.ColorArrayName = ['POINTS', colour or '']
shown.MapScalars = 0
view.CameraPosition, view.CameraFocalPoint, view.CameraViewUp = cam[0:3], cam[3:6], cam[6:9]
view.CameraViewAngle = cam[9]
pv.Render(view)
view.GetRenderWindow().WaitForCompletion()
print('PVFIRST,%.3f' % (time.time() - t0), flush=True)
pv.SaveScreenshot(png, view, ImageResolution=[w, h])
)";

bool onPath(const std::string& tool) {
  return std::system(("command -v " + tool + " > /dev/null 2>&1").c_str()) == 0;
}

/// ParaView's first picture of `in` (seconds from pvbatch's start, and the process's wall
/// time); nothing when pvbatch fails.
std::optional<std::pair<double, double>> paraviewFirst(const fs::path& out, const Input& in) {
  writeParaViewPly(in);
  const fs::path script = out / "first_picture.py", log = out / "first_picture-pvbatch.log";
  const fs::path png =
      out / ("first_picture-" + in.name + "-" + std::to_string(in.points) + "-paraview.png");
  std::ofstream(script) << kPvScript;
  std::ostringstream cmd;
  cmd.precision(17);
  if (!std::getenv("DISPLAY"))
    cmd << "xvfb-run -a -s '-screen 0 " << kWidth << "x" << kHeight << "x24' ";
  cmd << "pvbatch '" << script.string() << "' '" << in.paraview.string() << "' '" << png.string()
      << "'";
  for (const glm::dvec3& v :
       {in.camera.eye - in.paraview_origin, in.camera.target - in.paraview_origin, in.camera.up})
    cmd << " " << v.x << " " << v.y << " " << v.z;
  cmd << " " << in.camera.fovy << " " << kWidth << " " << kHeight << " > '" << log.string()
      << "' 2>&1";
  for (int attempt = 0; attempt < 3; ++attempt) {  // xvfb-run's display is sometimes late
    const auto t = Clock::now();
    const int rc = std::system(cmd.str().c_str());
    const double wall = msSince(t) / 1000.0;
    std::ifstream f(log);
    for (std::string line; std::getline(f, line);) {
      double s = 0;
      if (std::sscanf(line.c_str(), "PVFIRST,%lf", &s) == 1) return std::make_pair(s, wall);
    }
    std::fprintf(stderr, "first_picture: pvbatch failed (exit %d); see %s\n", rc, log.c_str());
  }
  return std::nullopt;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

void chart(const fs::path& out) {
  const fs::path gp = out / "first_picture.gp";
  const std::string data = (out / "first_picture_summary.csv").string();
  std::ofstream g(gp);
  g << "set terminal pngcairo size 1100,520 font 'sans,10' noenhanced\n"
    << "set output '" << (out / "first_picture.png").string() << "'\n"
    << "set datafile separator ','\nset key autotitle columnhead\n"
    << "set title 'Time to the first picture of a raw scan, 1280x720 (llvmpipe, 2 shared cores)'\n"
    << "set style data histograms\nset style histogram clustered gap 1\n"
    << "set style fill solid 0.85 border -1\nset logscale y\nset yrange [0.1:*]\n"
    << "set ylabel 'seconds (log)'\nset grid ytics\nset key top left\nset xtics rotate by -20\n"
    << "plot '" << data << "' using 3:xtic(1) title 'ParaView 5.11, first picture', "
    << "'' using 4 title 'build, then draw (first = final)', "
    << "'' using 5 title 'preview: first picture', '' using 6 title 'preview: final picture', "
    << "'' using 0:($5*1.15):(sprintf('IoU %.3f outline, %.3f pixels', $8, $7)) with labels offset "
       "4,0 font ',8' "
       "notitle\n";
  g.close();
  if (std::system((std::string(TESSERA_GNUPLOT) + " '" + gp.string() + "'").c_str()) != 0)
    std::fprintf(stderr, "first_picture: gnuplot failed; the CSV is complete\n");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "first_picture: a raw scan's first picture, previewed, against build-then-draw "
      "and ParaView"};
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  std::vector<std::string> inputs{"autzen:1.1e7", "cube:1e7"};
  int rounds = 2;
  uint64_t sample = lod::SampleOptions{}.points;
  bool no_paraview = false;
  app.add_option("--out", out, "Folder for inputs, CSV and chart")->capture_default_str();
  app.add_option("--inputs", inputs, "Inputs as NAME:POINTS, NAME autzen or cube")
      ->capture_default_str();
  app.add_option("--rounds", rounds, "Rounds, methods alternating")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--preview-points", sample, "Points in the preview's sample")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_flag("--no-paraview", no_paraview, "Leave ParaView out even when pvbatch is on PATH");
  CLI11_PARSE(app, argc, argv);
  try {
    const fs::path dir(out), input_dir = dir / "inputs";
    fs::create_directories(input_dir);
    const bool paraview =
        !no_paraview && onPath("pvbatch") && (std::getenv("DISPLAY") || onPath("xvfb-run"));
    if (!paraview)
      std::fprintf(stderr, "first_picture: pvbatch not found or --no-paraview: Tessera alone\n");
    auto ctx = render::GlContext::createHeadless();
    std::ofstream csv(dir / "first_picture.csv"), summary(dir / "first_picture_summary.csv");
    const std::string header =
        "input,points,method,round,first_s,final_s,pixel_iou,silhouette_iou,mean_diff,"
        "preview_points,sample_s,preview_build_s\n";
    csv << header;
    std::fputs(header.c_str(), stdout);
    summary << "input,points,paraview_first_s,build_then_draw_s,preview_first_s,preview_final_s,"
               "preview_pixel_iou,preview_silhouette_iou,preview_mean_diff,preview_points,"
               "paraview_wall_s\n";
    for (const std::string& spec : inputs) {
      const size_t colon = spec.find(':');
      const std::string name = spec.substr(0, colon);
      char* end = nullptr;
      const double size =
          colon == std::string::npos ? 0.0 : std::strtod(spec.c_str() + colon + 1, &end);
      if ((name != "autzen" && name != "cube") || !(size >= 1.0 && size <= 1e10) || *end)
        throw std::runtime_error("--inputs " + spec + ": give autzen:N or cube:N");
      const uint64_t n = uint64_t(std::llround(size));
      const Input in = name == "cube" ? cubeInput(input_dir, n) : autzenInput(input_dir, n);
      std::map<std::string, std::vector<Run>> runs;
      auto row = [&](const std::string& method, int round, const Run& r) {
        std::ostringstream s;
        s << name << "," << n << "," << method << "," << round << "," << r.first_s << ","
          << r.final_s << "," << r.iou << "," << r.silhouette_iou << "," << r.mean_diff << ","
          << r.preview_points << "," << r.sample_s << "," << r.preview_build_s << "\n";
        csv << s.str();
        csv.flush();
        std::fputs(s.str().c_str(), stdout);
        std::fflush(stdout);
      };
      const fs::path cache = dir / "first_picture-cache";
      for (int round = 1; round <= rounds; ++round) {
        // Alternate which goes first, so neither always follows the other's page cache.
        for (int k = 0; k < 2; ++k) {
          const bool preview = (k + round) % 2 == 0;
          Run r = preview ? previewFirst(in, cache, sample) : buildThenDraw(in, cache);
          row(preview ? "preview" : "build_then_draw", round, r);
          runs[preview ? "preview" : "build_then_draw"].push_back(std::move(r));
        }
      }
      std::optional<std::pair<double, double>> pv;
      if (paraview) {
        pv = paraviewFirst(dir, in);
        if (pv) {
          Run r;
          r.first_s = r.final_s = pv->first;
          row("paraview", 1, r);
        }
      }
      const std::string tag = "first_picture-" + name + "-" + std::to_string(n);
      render::writePng((dir / (tag + "-preview.png")).string(), runs["preview"].back().first);
      render::writePng((dir / (tag + "-final.png")).string(), runs["preview"].back().final);
      auto med = [&](const std::string& m, double Run::*field) {
        std::vector<double> v;
        for (const Run& r : runs[m]) v.push_back(r.*field);
        return median(v);
      };
      summary << name << " " << n << "," << n << "," << (pv ? pv->first : 0.0) << ","
              << med("build_then_draw", &Run::final_s) << "," << med("preview", &Run::first_s)
              << "," << med("preview", &Run::final_s) << "," << med("preview", &Run::iou) << ","
              << med("preview", &Run::silhouette_iou) << "," << med("preview", &Run::mean_diff)
              << "," << runs["preview"].front().preview_points << "," << (pv ? pv->second : 0.0)
              << "\n";
      summary.flush();
    }
    summary.close();
    chart(dir);
    std::fprintf(stderr,
                 "first_picture: wrote %s/first_picture{.csv,_summary.csv,.png}\n"
                 "reproduce: ./build/dev/bench/first_picture --inputs",
                 dir.c_str());
    for (const std::string& s : inputs) std::fprintf(stderr, " %s", s.c_str());
    std::fprintf(stderr, " --rounds %d --preview-points %llu\n", rounds,
                 (unsigned long long)sample);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "first_picture: %s\n", e.what());
    return 1;
  }
  return 0;
}
