// paraview_peer: Tessera against the peer a user would pick instead: ParaView 5.11's
// pvbatch drawing 1 px OpenGL points, on the same points from the same camera (ParaView's reset
// camera: the bounding sphere fills the 30 degree view, looking along (1, -0.8, 0.6)),
// 1920x1080, on this machine, runs interleaved (ParaView, then each Tessera variant, round after
// round) so load from other work hits both. Two inputs at each size N (--inputs):
//   cube    N points uniformly random in the unit cube (a volume of points)
//   autzen  the Autzen LiDAR (autzen_trim.las, RGB) tiled side by side into one LAS of N points
//           by bench/tile_las.py (as bench/potree_peer.sh), built into a store from that LAS;
//           ParaView reads the same points, positions relative to the LAS's box corner.
//
// Tessera variants, each on a fresh store and renderer every round:
//   full      every leaf (lod-px 1e-9, coverage stop off, no budget, discs): the reference
//   defaults  RenderOptions{} as a user gets them: a budget of 2 points a covered pixel (at
//             least 5x10^5 points), the coverage stop, the fill chosen for the frame
//             (SurfaceFill::kAuto)
//   nobudget  the defaults without the budget (--points-per-pixel 0)
//   coverage  the coverage stop alone, no budget, discs
//   budget    the coverage stop and a point budget (--budget, as Potree users set one), discs
//   ppp-F     the defaults with F points a covered pixel and no floor, for each F of --sweep:
//             frame time against accuracy (OUT/paraview_peer_sweep.png)
// For each: the first picture (store opened cold, every chunk of the cut resident), then the
// frame time (best and median of --frames frames: cut selection, raster, readback), the points
// drawn, the fill drawn, the pixel IoU of the covered pixels against the full render, the
// silhouette IoU of 8-pixel blocks against it (the outline) and the PSNR of the picture's
// colours against it. The summary's speed-up is the median over rounds of each round's
// ParaView frame over the variant's (best frames).
// ParaView: load (reader), first render, frame time (a camera nudge and Render() with glFinish,
// best and median). ParaView runs only when pvbatch is on PATH (Debian `paraview`; under
// xvfb-run without a display); otherwise its rows are left out with a message.
//
// Prints CSV; writes OUT/paraview_peer.csv (every run), OUT/paraview_peer_summary.csv (medians
// over rounds) and OUT/paraview_peer.png (gnuplot). Inputs are generated once into OUT/inputs:
// the store (cube: from a binary PLY, then removed; autzen: from the tiled LAS, then removed)
// and legacy VTK for ParaView.
#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <numbers>
#include <random>
#include <sstream>

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/core/stopwatch.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/view_renderer.h>

#include "bench_views.h"

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// `n` points uniformly random in [0, 1]^3, the same for a given n every run.
lod::PointBatch cubePoints(uint64_t n) {
  lod::PointBatch b;
  b.reset(0);
  b.positions.resize(n);
  std::mt19937_64 rng(n);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (glm::dvec3& p : b.positions) p = {u(rng), u(rng), u(rng)};
  return b;
}

/// Legacy VTK polydata (binary, big-endian), streamed: the points as float relative to
/// `origin`, one poly-vertex cell, and their RGB as colour scalars "rgb" when `colors` is not
/// empty.
class VtkWriter {
 public:
  VtkWriter(const fs::path& path, uint64_t n) : mPath(path), mN(n), mFile(path, std::ios::binary) {
    mFile << "# vtk DataFile Version 3.0\ntessera paraview_peer\nBINARY\nDATASET POLYDATA\nPOINTS "
          << n << " float\n";
  }
  void add(const glm::dvec3& p, const glm::dvec3& origin) {
    for (int c = 0; c < 3; ++c) put(std::bit_cast<uint32_t>(float(p[c] - origin[c])));
    ++mWritten;
  }
  /// Ends the file with the cell and, when given (one per point), the colours.
  void finish(const std::vector<glm::u8vec3>& colors) {
    if (mWritten != mN || (!colors.empty() && colors.size() != mN))
      throw std::runtime_error("paraview_peer: " + mPath.string() + ": point count mismatch");
    mFile << "\nVERTICES 1 " << mN + 1 << "\n";
    put(uint32_t(mN));
    for (uint64_t i = 0; i < mN; ++i) put(uint32_t(i));
    if (!colors.empty()) {
      mFile << "\nPOINT_DATA " << mN << "\nCOLOR_SCALARS rgb 3\n";
      mFile.write(reinterpret_cast<const char*>(colors.data()), std::streamsize(colors.size() * 3));
    }
    mFile << "\n";
    mFile.close();
    if (!mFile) throw std::runtime_error("paraview_peer: cannot write " + mPath.string());
  }

 private:
  void put(uint32_t v) {
    v = __builtin_bswap32(v);
    mFile.write(reinterpret_cast<const char*>(&v), 4);
  }
  fs::path mPath;
  uint64_t mN, mWritten = 0;
  std::ofstream mFile;
};

/// One input at one size: the store, the VTK ParaView reads (positions minus vtk_origin) and
/// the points' world box.
struct Inputs {
  std::string name;  ///< "cube" or "autzen"
  fs::path store, vtk;
  glm::dvec3 lo{0.0}, hi{1.0}, vtk_origin{0.0};
};

Inputs cubeInputs(const fs::path& dir, uint64_t n) {
  fs::create_directories(dir);
  const std::string tag = "cube-" + std::to_string(n);
  Inputs in{"cube", dir / (tag + ".tlod"), dir / (tag + ".vtk")};
  if (fs::exists(in.store) && fs::exists(in.vtk)) return in;
  std::fprintf(stderr, "paraview_peer: generating %llu points...\n", (unsigned long long)n);
  const lod::PointBatch b = cubePoints(n);
  VtkWriter vtk(in.vtk, n);
  for (const glm::dvec3& p : b.positions) vtk.add(p, in.vtk_origin);
  vtk.finish({});
  const fs::path ply = dir / (tag + ".ply");
  lod::writePly(ply, b, glm::dvec3(0.0));
  lod::BuildOptions o;
  o.quiet = true;
  const auto t = Clock::now();
  lod::buildStore({ply}, in.store, o);
  std::fprintf(stderr, "paraview_peer: built %s in %.1f s\n", in.store.c_str(),
               msSince(t) / 1000.0);
  fs::remove(ply);
  return in;
}

/// Autzen tiled to `n` points by bench/tile_las.py; the store is built from that LAS and the
/// VTK written from it (positions relative to the LAS box's lower corner, so floats keep cm).
Inputs autzenInputs(const fs::path& dir, uint64_t n) {
  fs::create_directories(dir);
  const std::string tag = "autzen-" + std::to_string(n);
  Inputs in{"autzen", dir / (tag + ".tlod"), dir / (tag + ".vtk")};
  const fs::path las = dir / (tag + ".las");
  const fs::path box = dir / (tag + ".box");  // lo, hi: the LAS header's box
  if (!(fs::exists(in.store) && fs::exists(in.vtk) && fs::exists(box))) {
    // The script beside this file's sources (TESSERA_CONFIG_DIR is the repository's configs/).
    const fs::path script = fs::path(TESSERA_CONFIG_DIR).parent_path() / "bench" / "tile_las.py";
    const std::string cmd = "python3 '" + script.string() + "' '" + TESSERA_DATA_DIR +
                            "/lidar/autzen_trim.las' -o '" + las.string() + "' -n " +
                            std::to_string(n) + " >&2";
    if (std::system(cmd.c_str()) != 0)
      throw std::runtime_error("paraview_peer: tiling Autzen failed: " + cmd);
    auto reader = lod::openPointReader(las);
    const auto bbox = reader->info().header_bbox;
    if (!bbox) throw std::runtime_error("paraview_peer: " + las.string() + " has no box");
    VtkWriter vtk(in.vtk, reader->info().declared_points);
    std::vector<glm::u8vec3> colors;
    lod::PointBatch b;
    while (reader->next(b)) {
      for (size_t i = 0; i < b.size(); ++i) {
        vtk.add(reader->info().origin + b.positions[i], bbox->first);  // world, then local
        colors.push_back(b.colors.empty() ? glm::u8vec3(200) : glm::u8vec3(b.colors[i]));
      }
    }
    vtk.finish(colors);
    lod::BuildOptions o;
    o.quiet = true;
    const auto t = Clock::now();
    lod::buildStore({las}, in.store, o);
    std::fprintf(stderr, "paraview_peer: built %s in %.1f s\n", in.store.c_str(),
                 msSince(t) / 1000.0);
    std::ofstream(box) << std::setprecision(17) << bbox->first.x << " " << bbox->first.y << " "
                       << bbox->first.z << " " << bbox->second.x << " " << bbox->second.y << " "
                       << bbox->second.z << "\n";
    fs::remove(las);
  }
  std::ifstream f(box);
  f >> in.lo.x >> in.lo.y >> in.lo.z >> in.hi.x >> in.hi.y >> in.hi.z;
  if (!f) throw std::runtime_error("paraview_peer: cannot read " + box.string());
  in.vtk_origin = in.lo;
  return in;
}

/// Pixels covered, top row first: Tessera's from its depth plane (what a point was drawn on, dark
/// colours included), ParaView's from its picture (anything but the black background).
using Mask = std::vector<uint8_t>;

Mask imageMask(const render::Image& img) {
  Mask m(size_t(img.width) * img.height, 0);
  for (size_t i = 0; i < m.size() && 4 * i + 3 < img.rgba.size(); ++i)
    m[i] = (img.rgba[4 * i] | img.rgba[4 * i + 1] | img.rgba[4 * i + 2]) != 0;
  return m;
}

Mask depthMask(const render::ViewRenderer& r, uint32_t width, uint32_t height) {
  const std::vector<uint32_t> depth = r.readDepth();  // row 0 at the bottom
  Mask m(size_t(width) * height, 0);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x)
      m[size_t(height - 1 - y) * width + x] = depth[size_t(y) * width + x] != render::kEmptyDepth;
  return m;
}

double silhouetteIou(const Mask& a, const Mask& b) {
  size_t both = 0, either = 0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i) {
    both += a[i] && b[i];
    either += a[i] || b[i];
  }
  return either ? double(both) / double(either) : 1.0;
}

/// The silhouette IoU of `block` x `block` pixel blocks holding a covered pixel: the outline,
/// as render::comparePictures() measures it (the pixel IoU also counts every open pixel
/// between scan lines, where one picture shows the background and the other a point).
double blockIou(const Mask& a, const Mask& b, uint32_t width, uint32_t height, uint32_t block = 8) {
  const uint32_t bw = (width + block - 1) / block, bh = (height + block - 1) / block;
  Mask ba(size_t(bw) * bh, 0), bb(size_t(bw) * bh, 0);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x) {
      const size_t i = size_t(y) * width + x, j = size_t(y / block) * bw + x / block;
      if (i < a.size() && a[i]) ba[j] = 1;
      if (i < b.size() && b[i]) bb[j] = 1;
    }
  return silhouetteIou(ba, bb);
}

/// PSNR of the RGB of every pixel of `a` against `b` (background included), dB; 99 when equal.
double psnr(const render::Image& a, const render::Image& b) {
  double se = 0.0;
  size_t n = 0;
  for (size_t i = 0; i + 3 < a.rgba.size() && i + 3 < b.rgba.size(); i += 4)
    for (size_t c = 0; c < 3; ++c, ++n) {
      const double d = double(a.rgba[i + c]) - double(b.rgba[i + c]);
      se += d * d;
    }
  const double mse = n ? se / double(n) : 0.0;
  return mse > 0.0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 99.0;
}

size_t coveredPixels(const Mask& a) {
  return size_t(std::count(a.begin(), a.end(), uint8_t(1)));
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  if (v.empty()) return 0.0;
  const size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

struct Run {
  uint64_t points = 0;            ///< drawn
  uint64_t budget = 0;            ///< Tessera: the point budget of the cut
  std::string fill = "-";         ///< Tessera: how the frame closed surfaces
  render::FillEstimate estimate;  ///< Tessera: what the fill was chosen by
  double first_s = 0, load_s = 0, best_ms = 0, median_ms = 0;
  double iou = 1.0;        ///< pixel IoU against the every-leaf render
  double psnr = 99.0;      ///< dB, the RGB of every pixel against the every-leaf render
  double block_iou = 1.0;  ///< silhouette IoU of 8-pixel blocks against it
  render::Image image;
  Mask mask;  ///< covered pixels
};

Run runTessera(const fs::path& store_path, const render::ViewSetup& view,
               const render::RenderOptions& options, int frames) {
  Run run;
  const auto t = Clock::now();
  auto store = lod::PointStore::open(store_path, 2ull << 30);
  render::ModelInstance inst{store.get(), render::storeModel(*store)};
  render::StreamerOptions so;
  so.budget_bytes = 16ull << 30;
  render::ViewRenderer r(view.width, view.height, nullptr, so);
  render::RenderStats st;
  run.image = r.renderSettled({&inst, 1}, view, options, &st);
  run.first_s = msSince(t) / 1000.0;
  std::vector<double> ms;
  for (int i = 0; i < frames; ++i) {
    const auto f = Clock::now();
    run.image = r.render({&inst, 1}, view, options, &st);
    ms.push_back(msSince(f));
  }
  run.mask = depthMask(r, view.width, view.height);
  run.points = st.points;
  run.budget = st.point_budget;
  run.estimate = st.fill_estimate;
  run.fill = st.fill == render::SurfaceFill::kPullPush ? "pullpush"
             : st.fill == render::SurfaceFill::kNone   ? "none"
                                                       : "discs";
  run.best_ms = *std::min_element(ms.begin(), ms.end());
  run.median_ms = median(ms);
  return run;
}

constexpr const char* kPvScript =
    R"(# pvbatch script written by bench/paraview_peer: 1 px points of a
# legacy VTK file, one camera; prints PVRESULT,load_s,first_s,best_ms,median_ms,points
import sys, time
t0 = time.time()
from paraview.simple import *
vtk, png = sys.argv[1], sys.argv[2]
e, t, u = [float(x) for x in sys.argv[3:6]], [float(x) for x in sys.argv[6:9]], [float(x) for x in sys.argv[9:12]]
fovy, w, h, frames = float(sys.argv[12]), int(sys.argv[13]), int(sys.argv[14]), int(sys.argv[15])
reader = LegacyVTKReader(FileNames=[vtk])
reader.UpdatePipeline()
t_load = time.time()
view = CreateView('RenderView')
view.ViewSize = [w, h]
view.OrientationAxesVisibility = 0
try:
    view.UseColorPaletteForBackground = 0
except AttributeError:
    pass
view.Background = [0, 0, 0]
d = Show(reader, view)
d.SetRepresentationType('Points')
d.ColorArrayName = ['POINTS', '']
d.PointSize = 1
d.AmbientColor = [200 / 255.0] * 3
d.DiffuseColor = [200 / 255.0] * 3
d.Ambient = 1.0
d.Diffuse = 0.0
if reader.PointData.GetArray('rgb') is not None:
    d.ColorArrayName = ['POINTS', 'rgb']
    d.MapScalars = 0
view.CameraPosition, view.CameraFocalPoint, view.CameraViewUp = e, t, u
view.CameraViewAngle = fovy
rw = view.GetRenderWindow()
Render(view)
rw.WaitForCompletion()
t_first = time.time()
ms = []
cam = GetActiveCamera()
for i in range(frames):
    f = time.time()
    cam.Azimuth(1e-3 if i % 2 == 0 else -1e-3)
    Render(view)
    rw.WaitForCompletion()
    ms.append((time.time() - f) * 1000.0)
view.CameraPosition, view.CameraFocalPoint, view.CameraViewUp = e, t, u
SaveScreenshot(png, view, ImageResolution=[w, h])
ms.sort()
n = reader.GetDataInformation().GetNumberOfPoints()
print('PVRESULT,%.3f,%.3f,%.1f,%.1f,%d' % (t_load - t0, t_first - t0, ms[0], ms[len(ms) // 2], n))
)";

bool onPath(const std::string& tool) {
  return std::system(("command -v " + tool + " > /dev/null 2>&1").c_str()) == 0;
}

/// One pvbatch process; false (with a message) if it failed.
bool runParaView(const fs::path& out, const fs::path& vtk, const bench::CubeCamera& c, uint32_t w,
                 uint32_t h, int frames, Run& run) {
  const fs::path script = out / "paraview_peer.py";
  std::ofstream(script) << kPvScript;
  const fs::path png = out / "paraview_peer-paraview.png";
  const fs::path log = out / "paraview_peer-pvbatch.log";
  std::ostringstream cmd;
  if (!std::getenv("DISPLAY")) cmd << "xvfb-run -a -s '-screen 0 " << w << "x" << h << "x24' ";
  cmd << "pvbatch '" << script.string() << "' '" << vtk.string() << "' '" << png.string() << "'";
  for (const glm::dvec3& v : {c.eye, c.target, c.up}) cmd << " " << v.x << " " << v.y << " " << v.z;
  cmd << " " << c.fovy << " " << w << " " << h << " " << frames << " > '" << log.string()
      << "' 2>&1";
  // xvfb-run sometimes hands over its display before the server accepts connections: retry.
  int rc = 0;
  for (int attempt = 1; attempt <= 3; ++attempt) {
    const auto t = Clock::now();
    rc = std::system(cmd.str().c_str());
    const double wall = msSince(t) / 1000.0;
    std::ifstream in(log);
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("PVRESULT,", 0) != 0) continue;
      unsigned long long n = 0;
      if (std::sscanf(line.c_str(), "PVRESULT,%lf,%lf,%lf,%lf,%llu", &run.load_s, &run.first_s,
                      &run.best_ms, &run.median_ms, &n) == 5) {
        run.points = n;
        run.image = render::readPng(png.string());
        run.mask = imageMask(run.image);
        std::fprintf(stderr, "paraview_peer: pvbatch took %.1f s in all\n", wall);
        return true;
      }
    }
  }
  std::fprintf(stderr, "paraview_peer: pvbatch failed (exit %d); see %s\n", rc, log.c_str());
  return false;
}

/// The variants after ParaView, in the CSV's and the chart's order, with the chart's titles.
constexpr std::array<std::pair<const char*, const char*>, 5> kVariants{{
    {"full", "Tessera, every leaf"},
    {"defaults", "Tessera, defaults (2 points/covered pixel, coverage stop, fill chosen)"},
    {"nobudget", "Tessera, defaults without the budget"},
    {"coverage", "Tessera, coverage stop alone, discs"},
    {"budget", "Tessera, coverage stop + budget 10^6, discs"},
}};

/// 10000000 as "10^7", 50000000 as "5x10^7"; other counts as they are.
std::string powerOfTen(uint64_t n) {
  int e = 0;
  uint64_t m = n;
  while (m >= 10 && m % 10 == 0) m /= 10, ++e;
  if (e < 3 || m >= 10) return std::to_string(n);
  return (m == 1 ? std::string() : std::to_string(m) + "x") + "10^" + std::to_string(e);
}

std::string sweepName(double f) {
  char s[32];
  std::snprintf(s, sizeof s, "ppp-%g", f);
  return s;
}

/// OUT/paraview_peer_sweep.csv holds one block per input (two blank lines between): points a
/// covered pixel (1e9: no budget; 0: ParaView, after a blank line), frame ms, PSNR, label; the
/// chart puts frame time against accuracy.
void sweepChart(const fs::path& out, const std::vector<std::string>& titles) {
  const fs::path gp = out / "paraview_peer_sweep.gp";
  const std::string data = (out / "paraview_peer_sweep.csv").string();
  std::ofstream g(gp);
  g << "set terminal pngcairo size 900,560 font 'sans,10' noenhanced\n"
    << "set output '" << (out / "paraview_peer_sweep.png").string() << "'\n"
    << "set datafile separator ','\n"
    << "set title 'Points a covered pixel: frame time against accuracy (1920x1080, llvmpipe)'\n"
    << "set xlabel 'ms per frame (log)'\nset ylabel 'PSNR against every leaf, dB'\n"
    << "set logscale x\nset grid\nset key top left font ',9'\n"
    << "set offsets graph 0.05, graph 0.12, 1, 1\n"
    << "plot ";
  for (size_t i = 0; i < titles.size(); ++i)
    g << (i ? ", " : "") << "'" << data << "' index " << i
      << " using 2:3 with linespoints lw 2 pt 7 lt " << i + 1 << " title '" << titles[i]
      << "', '' index " << i << " using 2:3:4 with labels offset 1.2,0.6 font ',8' notitle";
  g << "\n";
  g.close();
  const std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp.string() + "'";
  if (std::system(cmd.c_str()) != 0)
    std::fprintf(stderr, "paraview_peer: gnuplot failed on the sweep; its CSV is complete\n");
}

/// OUT/paraview_peer_chart.csv holds per input: label, ParaView's ms, each variant's ms, then
/// each variant's speed-up.
void chart(const fs::path& out) {
  const fs::path gp = out / "paraview_peer.gp";
  const std::string data = (out / "paraview_peer_chart.csv").string();
  std::ofstream g(gp);
  g << "set terminal pngcairo size 1400,520 font 'sans,10' noenhanced\n"
    << "set output '" << (out / "paraview_peer.png").string() << "'\n"
    << "set datafile separator ','\nset multiplot layout 1,2\n"
    << "set title 'Frame time, 1920x1080 (llvmpipe, 2 cores)'\n"
    << "set style data histograms\nset style histogram clustered gap 1\n"
    << "set style fill solid 0.85 border -1\nset logscale y\nset ylabel 'ms per frame (log)'\n"
    << "set grid ytics\nset key top left font ',8'\nset yrange [10:1e6]\nset xtics rotate by -20\n"
    << "plot '" << data << "' using 2:xtic(1) title 'ParaView 5.11, 1 px points' lt 1";
  // Each variant keeps its colour in both panels (ParaView's is the first).
  for (size_t i = 0; i < kVariants.size(); ++i)
    g << ", '' using " << 3 + i << " title '" << kVariants[i].second << "' lt " << i + 2;
  g << "\nset title 'Speed-up over ParaView per frame (median of rounds)'\n"
    << "set ylabel 'ParaView ms / Tessera ms (log)'\nset yrange [0.5:2000]\n"
    << "set arrow 1 from graph 0, first 20 to graph 1, first 20 nohead dt 2 lw 2 lc rgb 'red'\n"
    << "set label 1 'goal: 20x' at graph 0.01, first 24 tc rgb 'red'\n"
    << "plot '" << data << "' using " << 3 + kVariants.size() << ":xtic(1) title '"
    << kVariants[0].second << "' lt 2";
  for (size_t i = 1; i < kVariants.size(); ++i)
    g << ", '' using " << 3 + kVariants.size() + i << " title '" << kVariants[i].second << "' lt "
      << i + 2;
  g << "\nunset multiplot\n";
  g.close();
  const std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp.string() + "'";
  if (std::system(cmd.c_str()) != 0)
    std::fprintf(stderr, "paraview_peer: gnuplot failed; the CSV is complete\n");
}

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  CLI::App app{
      "paraview_peer: Tessera against ParaView pvbatch on random points in a cube and "
      "on tiled Autzen LiDAR"};
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  std::vector<uint64_t> sizes{10'000'000, 50'000'000};
  std::vector<std::string> inputs{"cube", "autzen"};
  int rounds = 3, frames = 3;
  uint64_t budget = 1'000'000;
  std::vector<double> sweep{1.0, 1.5, 3.0, 4.0};
  bool no_paraview = false;
  app.add_option("--out", out, "Folder for inputs, CSV and chart")->capture_default_str();
  app.add_option("--points", sizes, "Input sizes (points)")->capture_default_str();
  app.add_option("--inputs", inputs, "Inputs: cube (random points), autzen (tiled LiDAR)")
      ->check(CLI::IsMember({"cube", "autzen"}))
      ->capture_default_str();
  app.add_option("--rounds", rounds, "Interleaved rounds (medians kept)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--frames", frames, "Timed frames per run")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--budget", budget, "Point budget of the budget variant")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--sweep", sweep,
                 "Points a covered pixel of the ppp-F variants (the defaults' 2 and no budget "
                 "are charted beside them; none: --sweep with no value)")
      ->check(CLI::PositiveNumber)
      ->expected(0, -1)
      ->capture_default_str();
  app.add_flag("--no-paraview", no_paraview, "Leave ParaView out even when pvbatch is on PATH");
  CLI11_PARSE(app, argc, argv);
  try {
    const fs::path dir(out);
    fs::create_directories(dir);
    const bool paraview =
        !no_paraview && onPath("pvbatch") && (std::getenv("DISPLAY") || onPath("xvfb-run"));
    if (!paraview)
      std::fprintf(stderr,
                   "paraview_peer: pvbatch (Debian package paraview; xvfb-run without a display) "
                   "not found or --no-paraview: measuring Tessera alone\n");
    const uint32_t w = 1920, h = 1080;
    auto ctx = render::GlContext::createHeadless();
    render::RenderOptions full;
    full.lod_pixels = 1e-9;
    full.coverage_stop = false;
    full.fill = render::SurfaceFill::kDiscs;  // the reference picture
    full.budget_per_covered_pixel = 0.0;
    const render::RenderOptions defaults;
    render::RenderOptions nobudget;
    nobudget.budget_per_covered_pixel = 0.0;
    render::RenderOptions coverage = nobudget;
    coverage.fill = render::SurfaceFill::kDiscs;
    render::RenderOptions budgeted = coverage;
    budgeted.point_budget = budget;
    std::vector<std::pair<std::string, render::RenderOptions>> options{
        {kVariants[0].first, full},
        {kVariants[1].first, defaults},
        {kVariants[2].first, nobudget},
        {kVariants[3].first, coverage},
        {kVariants[4].first, budgeted}};
    std::sort(sweep.begin(), sweep.end());
    for (double f : sweep) {
      render::RenderOptions o;
      o.budget_per_covered_pixel = f;
      o.budget_floor = 0;
      options.emplace_back(sweepName(f), o);
    }

    std::ofstream csv(dir / "paraview_peer.csv");
    const std::string header =
        "input,points,round,renderer,variant,points_drawn,point_budget,fill,disc_layers,"
        "max_disc_radius_px,wide_disc_share,covered_px,load_s,first_picture_s,frame_best_ms,"
        "frame_median_ms,iou_vs_full,silhouette_iou_vs_full,psnr_vs_full_db";
    csv << header << "\n";
    std::cout << header << "\n";
    // (input, points, variant) -> per-round best frame ms, points drawn, IoU, block IoU, PSNR.
    std::map<std::tuple<std::string, uint64_t, std::string>, std::vector<std::array<double, 5>>>
        all;
    auto row = [&](const Inputs& in, uint64_t n, int round, const char* who,
                   const std::string& variant, const Run& r) {
      const render::FillEstimate& e = r.estimate;
      char line[640];
      std::snprintf(
          line, sizeof line,
          "%s,%llu,%d,%s,%s,%llu,%llu,%s,%.1f,%.1f,%.4f,%zu,%.3f,%.3f,%.1f,%.1f,%.4f,%.4f,%.2f",
          in.name.c_str(), (unsigned long long)n, round, who, variant.c_str(),
          (unsigned long long)r.points, (unsigned long long)r.budget, r.fill.c_str(),
          e.covered_px > 0 ? e.disc_px / e.covered_px : 0.0, e.max_radius_px,
          e.points > 0 ? e.wide_points / e.points : 0.0, coveredPixels(r.mask), r.load_s, r.first_s,
          r.best_ms, r.median_ms, r.iou, r.block_iou, r.psnr);
      csv << line << "\n";
      std::cout << line << std::endl;
      all[{in.name, n, variant}].push_back(
          {r.best_ms, double(r.points), r.iou, r.block_iou, r.psnr});
    };
    std::vector<std::pair<std::string, uint64_t>> measured;
    for (const std::string& input : inputs) {
      for (uint64_t n : sizes) {
        const Inputs in =
            input == "cube" ? cubeInputs(dir / "inputs", n) : autzenInputs(dir / "inputs", n);
        measured.emplace_back(input, n);
        const bench::CubeCamera cam = bench::boxCamera(in.lo, in.hi);
        const render::ViewSetup view = bench::cubeView(cam, w, h);
        bench::CubeCamera pv_cam = cam;  // ParaView's points are relative to vtk_origin
        pv_cam.eye -= in.vtk_origin;
        pv_cam.target -= in.vtk_origin;
        const std::string tag = input + "-" + std::to_string(n);
        for (int round = 1; round <= rounds; ++round) {
          Run pv;
          const bool pv_ok = paraview && runParaView(dir, in.vtk, pv_cam, w, h, frames, pv);
          Run reference;
          for (size_t v = 0; v < options.size(); ++v) {
            Run r = runTessera(in.store, view, options[v].second, frames);
            if (v == 0) reference = r;
            r.iou = silhouetteIou(r.mask, reference.mask);
            r.block_iou = blockIou(r.mask, reference.mask, w, h);
            r.psnr = psnr(r.image, reference.image);
            row(in, n, round, "tessera", options[v].first, r);
            if (round == 1)
              render::writePng(
                  (dir / ("paraview_peer-" + tag + "-" + options[v].first + ".png")).string(),
                  r.image);
          }
          if (pv_ok) {
            pv.iou = silhouetteIou(pv.mask, reference.mask);
            pv.block_iou = blockIou(pv.mask, reference.mask, w, h);
            pv.psnr = psnr(pv.image, reference.image);
            row(in, n, round, "paraview", "paraview", pv);
            if (round == 1)
              fs::copy_file(dir / "paraview_peer-paraview.png",
                            dir / ("paraview_peer-" + tag + "-paraview.png"),
                            fs::copy_options::overwrite_existing);
          }
        }
      }
    }
    csv.close();

    // Medians over rounds, the speed-ups against ParaView, and the chart's table.
    std::ofstream sum(dir / "paraview_peer_summary.csv");
    std::ofstream tab(dir / "paraview_peer_chart.csv");
    std::ofstream swp(dir / "paraview_peer_sweep.csv");
    std::vector<std::string> sweep_titles;
    const char* sum_header =
        "input,points,variant,points_drawn,frame_ms,iou_vs_full,silhouette_iou_vs_full,"
        "psnr_vs_full_db,speedup_vs_paraview\n";
    sum << sum_header;
    std::cout << "\n" << sum_header;
    for (const auto& [input, n] : measured) {
      auto med = [&](const std::string& v, int i) {
        std::vector<double> x;
        for (const auto& r : all[{input, n, v}]) x.push_back(r[size_t(i)]);
        return median(x);
      };
      // The speed-up of each round's interleaved pair, then their median: the machine's load
      // changes between rounds, less within one.
      auto speedup = [&](const std::string& v) {
        const auto& pv = all[{input, n, "paraview"}];
        const auto& t = all[{input, n, v}];
        std::vector<double> x;
        for (size_t i = 0; i < pv.size() && i < t.size(); ++i) x.push_back(pv[i][0] / t[i][0]);
        return median(x);
      };
      std::vector<std::string> names{"paraview"};
      for (const auto& v : options) names.push_back(v.first);
      for (const std::string& v : names) {
        if (all[{input, n, v}].empty()) continue;
        char line[256];
        std::snprintf(line, sizeof line, "%s,%llu,%s,%.0f,%.1f,%.4f,%.4f,%.2f,%.2f", input.c_str(),
                      (unsigned long long)n, v.c_str(), med(v, 1), med(v, 0), med(v, 2), med(v, 3),
                      med(v, 4), speedup(v));
        sum << line << "\n";
        std::cout << line << "\n";
      }
      const double pv_ms = med("paraview", 0);
      tab << (input == "cube" ? "cube " : "Autzen ") << double(n) / 1e6 << "M,"
          << (pv_ms > 0 ? pv_ms : 1e-9);
      for (const auto& v : kVariants) tab << "," << med(v.first, 0);
      for (const auto& v : kVariants) tab << "," << std::max(speedup(v.first), 1e-9);
      tab << "\n";
      // The sweep, by points a covered pixel: the ppp-F variants, the defaults (2, with the
      // floor) and no budget (charted as 'none').
      std::vector<std::tuple<double, std::string, std::string>> points;
      for (double f : sweep) points.emplace_back(f, sweepName(f), sweepName(f).substr(4));
      points.emplace_back(render::RenderOptions{}.budget_per_covered_pixel, "defaults", "defaults");
      std::stable_sort(points.begin(), points.end());
      points.emplace_back(1e9, "nobudget", "none");
      if (!sweep_titles.empty()) swp << "\n\n";
      for (const auto& [f, v, label] : points)
        if (!all[{input, n, v}].empty())
          swp << f << "," << med(v, 0) << "," << med(v, 4) << "," << label << "\n";
      if (!all[{input, n, "paraview"}].empty())  // its own point, not joined to the line
        swp << "\n0," << med("paraview", 0) << "," << med("paraview", 4) << ",ParaView\n";
      sweep_titles.push_back((input == "cube" ? "random cube, " : "Autzen tiled, ") +
                             powerOfTen(n) + " points");
    }
    sum.close();
    tab.close();
    swp.close();
    chart(dir);
    sweepChart(dir, sweep_titles);
    std::fprintf(stderr, "paraview_peer: wrote %s/paraview_peer.csv, _summary.csv, .png\n",
                 out.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "paraview_peer: %s\n", e.what());
    return 1;
  }
}
