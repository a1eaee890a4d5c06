// lazy_snapping: 3D lazy snapping's time and accuracy (IoU against known labels) against the
// number of strokes and against the model's size, with the baseline of a per-sample graph cut
// (no over-segmentation) in the same run (thesis 4.2).
//   strokes  the Stanford bunny's ear (tests/support/snapping_models.h): one stroke on the ear
//            and one on the head, then a simulated user adds one corrective dab at a time on
//            the largest visible error (the visible sample with the most wrong samples within
//            two rings), labelled by the truth; each method gets its own corrective strokes.
//   size     a UV sphere with a red cap in blue (10^3.7 .. 10^6 vertices), one stroke per side.
//   lasso    the robust lasso (4.3.1) on the bunny's ear: a heavy stroke along the ear's outline
//            on the screen (the convex hull of its projected vertices), 16 pixels wide.
//   tool     the snap tool end to end (interact/snap_tool.h: gather the leaves the view shows,
//            cut, map back to leaf elements, region mask) on stores of two sizes each, the
//            bunny's reconstruction at 1/16 and full resolution as mesh stores and one scan and
//            all ten as point stores, against the lasso (interact/select_tool.h lassoSelection(),
//            one thread) drawn around the ear's outline in the same view; IoU of the elements
//            against the ear (tests/support/ear_labels.h).
// Prints CSV; writes OUT/lazy_snapping.csv, OUT/lazy_snapping.png (chart),
// OUT/lazy_snapping_bunny.png (the selections on the bunny, front view), OUT/snap_tool.csv and
// OUT/snap_tool.png with gnuplot.
#include <algorithm>
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

#include <tessera/lod/mesh.h>
#include <tessera/lod/mesh_builder.h>
#include <tessera/lod/store_builder.h>
#include <tessera/annotate/lazy_snapping.h>
#include <tessera/interact/snap_tool.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/view_renderer.h>

#include "../tests/support/ear_labels.h"
#include "../tests/support/snapping_models.h"
#include "bench_stats.h"

namespace fs = std::filesystem;
using namespace tessera;
using annotate::LazySnapping;
using annotate::ScreenView;
using annotate::SnapOptions;
using annotate::SnapResult;
using annotate::Strokes;
using annotate::SurfaceSamples;

namespace {

struct Row {
  std::string series, model;
  size_t samples = 0, strokes = 0;
  std::string method;
  uint32_t graph_nodes = 0;
  double prepare_ms = 0, cut_ms = 0, iou = 0;
};

std::string csvLine(const Row& r) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "%s,%s,%zu,%zu,%s,%u,%.3f,%.3f,%.4f", r.series.c_str(),
                r.model.c_str(), r.samples, r.strokes, r.method.c_str(), r.graph_nodes,
                r.prepare_ms, r.cut_ms, r.iou);
  return buf;
}

/// Median CPU milliseconds of `repeat` runs of `f` on this thread (the library is single
/// threaded; CPU time keeps the figures apart from other work on a shared machine).
double medianMs(int repeat, const std::function<void()>& f) {
  std::vector<double> ms;
  for (int k = 0; k < repeat; ++k) {
    const double t0 = bench::threadCpuSeconds();
    f();
    ms.push_back(1e3 * (bench::threadCpuSeconds() - t0));
  }
  return bench::percentile(ms, 0.5);
}

/// LazySnapping on `s` with or without over-segmentation; `ms`: the median time to build it
/// (over-segmentation and node graph, done once per view).
std::unique_ptr<LazySnapping> prepareSnapping(const SurfaceSamples& s, bool over_segment,
                                              int repeat, double& ms) {
  SnapOptions options;
  options.over_segment = over_segment;
  std::unique_ptr<LazySnapping> snapping;
  ms = medianMs(repeat, [&] { snapping = std::make_unique<LazySnapping>(s, options); });
  return snapping;
}

const char* methodName(bool over_segment) {
  return over_segment ? "segments" : "per_sample";
}

/// The visible surface sample with the most wrongly labelled samples within two rings, or -1.
int64_t largestError(const SurfaceSamples& s, const std::vector<uint8_t>& selected,
                     const std::vector<uint8_t>& truth, const std::vector<uint8_t>& visible) {
  std::vector<uint8_t> wrong(s.size());
  for (uint32_t i = 0; i < s.size(); ++i)
    wrong[i] = selected[i] != truth[i] && !s.neighboursOf(i).empty();
  int64_t best = -1;
  size_t best_score = 0;
  std::vector<uint32_t> ring;
  for (uint32_t i = 0; i < s.size(); ++i) {
    if (!wrong[i] || !visible[i]) continue;
    ring.assign(1, i);
    for (uint32_t j : s.neighboursOf(i)) {
      ring.push_back(j);
      for (uint32_t k : s.neighboursOf(j)) ring.push_back(k);
    }
    std::sort(ring.begin(), ring.end());
    ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
    size_t score = 0;
    for (uint32_t j : ring) score += wrong[j];
    if (score > best_score) {
      best_score = score;
      best = i;
    }
  }
  return best;
}

struct BunnyPicture {
  std::vector<uint8_t> strokes_selected, lasso_selected;
  Strokes strokes, lasso_seeds;
  std::vector<glm::dvec2> lasso;
};

/// The bunny series (strokes and lasso). Fills `rows` and the picture's data.
void bunnySeries(const fs::path& data_dir, int repeat, size_t max_strokes, std::vector<Row>& rows,
                 BunnyPicture& pic, SurfaceSamples& s, std::vector<uint8_t>& ear,
                 std::vector<uint8_t>& visible) {
  const lod::Mesh mesh = lod::readMesh(test::bunnyMeshPath(data_dir));
  s = annotate::surfaceFromMesh(mesh);
  ear = test::bunnyEar(s);
  const ScreenView view = test::bunnyView();
  visible = annotate::visibleSamples(s, view, 3.0, 0.003);
  const Strokes first{annotate::pickStroke(s, view, test::bunnyEarStroke(), 4.0, visible),
                      annotate::pickStroke(s, view, test::bunnyHeadStroke(), 4.0, visible)};
  for (bool over : {true, false}) {
    double prepare = 0;
    const auto snapping = prepareSnapping(s, over, repeat, prepare);
    Strokes strokes = first;
    for (size_t count = 2; count <= max_strokes; ++count) {
      SnapResult r;
      const double cut = medianMs(repeat, [&] { r = snapping->cut(strokes, &view); });
      rows.push_back({"strokes", "bunny_ear", s.size(), count, methodName(over), r.graph_nodes,
                      prepare, cut, annotate::intersectionOverUnion(r.selected, ear)});
      if (over && count == 2) {
        pic.strokes_selected = r.selected;
        pic.strokes = strokes;
      }
      // The next stroke: a dab of 6 pixels on the largest visible error, kept on its side.
      const int64_t at = largestError(s, r.selected, ear, visible);
      if (at < 0) break;
      const annotate::ScreenPoint sp = annotate::project(view, s.positions[size_t(at)]);
      const glm::dvec2 dab[] = {sp.pixel};
      auto& list = ear[size_t(at)] ? strokes.foreground : strokes.background;
      for (uint32_t i : annotate::pickStroke(s, view, dab, 6.0, visible))
        if (ear[i] == ear[size_t(at)]) list.push_back(i);
    }
  }
  // The robust lasso: a heavy stroke along the ear's outline as seen from the view.
  annotate::HeavyStroke heavy;
  heavy.polyline = test::earOutline(s, ear, visible, view);
  heavy.width_px = 16;
  heavy.seed_band_px = 16;
  pic.lasso = heavy.polyline;
  pic.lasso_seeds = annotate::robustLassoSeeds(s, view, heavy, visible);
  const LazySnapping snapping(s);
  SnapResult r;
  const double cut = medianMs(repeat, [&] { r = snapping.cut(pic.lasso_seeds, &view); });
  pic.lasso_selected = r.selected;
  rows.push_back({"lasso", "bunny_ear", s.size(), 1, "robust_lasso", r.graph_nodes, 0.0, cut,
                  annotate::intersectionOverUnion(r.selected, ear)});
}

/// The size series on capped spheres.
void sizeSeries(const std::vector<uint32_t>& rings, int repeat, std::vector<Row>& rows,
                bool quiet) {
  std::vector<Row> per_sample;  // after the segments' rows, so each method's line is unbroken
  for (uint32_t ring_count : rings) {
    std::vector<uint8_t> cap;
    const lod::Mesh mesh = test::cappedSphere(ring_count, &cap);
    const SurfaceSamples s = annotate::surfaceFromMesh(mesh);
    const Strokes strokes{test::samplesNear(s, {{-0.5, 0, 0.87}, {0.5, 0, 0.87}}, 0.03),
                          test::samplesNear(s, {{1, 0, 0}, {0, 1, 0}, {-1, 0, 0}}, 0.03)};
    for (bool over : {true, false}) {
      double prepare = 0;
      const auto snapping = prepareSnapping(s, over, repeat, prepare);
      SnapResult r;
      const double cut = medianMs(repeat, [&] { r = snapping->cut(strokes); });
      auto& into = over ? rows : per_sample;
      into.push_back({"size", "capped_sphere", s.size(), 2, methodName(over), r.graph_nodes,
                      prepare, cut, annotate::intersectionOverUnion(r.selected, cap)});
      if (!quiet) std::cerr << "lazy_snapping: " << csvLine(into.back()) << "\n";
    }
  }
  rows.insert(rows.end(), per_sample.begin(), per_sample.end());
}

/// One end-to-end run of the tool or the lasso on a store.
struct ToolRow {
  std::string model, kind, method;
  uint64_t samples = 0, elements = 0, selected = 0;
  double gather_ms = 0, cut_ms = 0, map_ms = 0, mask_ms = 0, total_ms = 0, iou = 0;
};

std::string csvLine(const ToolRow& r) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "%s,%s,%s,%llu,%llu,%llu,%.2f,%.2f,%.2f,%.2f,%.2f,%.4f",
                r.model.c_str(), r.kind.c_str(), r.method.c_str(), (unsigned long long)r.samples,
                (unsigned long long)r.elements, (unsigned long long)r.selected, r.gather_ms,
                r.cut_ms, r.map_ms, r.mask_ms, r.total_ms, r.iou);
  return buf;
}

/// Wall-clock milliseconds (the tool's stages report wall time too; the median of `repeat`
/// runs keeps other work on the machine out of the figures).
double wallMs(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// The tool and the lasso on the bunny's ear, per store (built into `work` once).
void toolSeries(const fs::path& data_dir, const fs::path& work, int repeat,
                std::vector<ToolRow>& rows, bool quiet) {
  const test::EarLabels ear(data_dir);
  const ScreenView sv = test::bunnyView();
  render::ViewSetup view;
  view.view = sv.view;
  view.projection = sv.projection;
  view.width = sv.viewport.x;
  view.height = sv.viewport.y;
  auto yDown = [&](std::vector<glm::dvec2> px) {
    for (glm::dvec2& p : px) p.y = double(view.height) - p.y;
    return px;
  };
  const auto fg = yDown(test::bunnyEarStroke()), bg = yDown(test::bunnyHeadStroke());
  const std::vector<uint8_t> visible = annotate::visibleSamples(ear.samples(), sv, 3.0, 0.003);
  const auto outline =
      yDown(test::earOutline(ear.samples(), test::bunnyEar(ear.samples()), visible, sv));
  const fs::path bunny = data_dir / "stanford-bunny";
  struct Model {
    std::string name, kind;
    std::vector<fs::path> inputs;
  };
  const std::vector<Model> models = {
      {"reconstruction_res2", "mesh", {bunny / "reconstruction/bun_zipper_res2.ply"}},
      {"reconstruction", "mesh", {bunny / "reconstruction/bun_zipper.ply"}},
      {"scan_bun000", "points", {bunny / "scans/bun000.ply"}},
      {"scans_all", "points", {bunny / "scans/bun.conf"}}};
  fs::create_directories(work);
  for (const Model& m : models) {
    const bool mesh = m.kind == "mesh";
    const fs::path store = work / (m.name + (mesh ? ".tmesh" : ".tlod"));
    if (!fs::exists(store)) {
      if (mesh) {
        lod::MeshBuildOptions o;
        o.patch_triangles = 1024;
        o.quiet = true;
        lod::buildMeshStore(m.inputs, store, o);
      } else {
        lod::BuildOptions o;
        o.quiet = true;
        lod::buildStore(m.inputs, store, o);
      }
    }
    std::unique_ptr<lod::MeshStore> ms;
    std::unique_ptr<lod::PointStore> ps;
    render::ModelInstance inst;
    if (mesh) {
      ms = lod::MeshStore::open(store);
      inst.mesh = ms.get();
      inst.model = render::storeModel(*ms);
    } else {
      ps = lod::PointStore::open(store);
      inst.store = ps.get();
      inst.model = render::storeModel(*ps);
    }
    const uint64_t elements = mesh ? ms->summary().input_triangles : ps->summary().points;
    auto iouOf = [&](const std::string& bytes) {
      const annotate::Selection sel = test::selectionOf(bytes);
      return mesh ? test::earIoU(*ms, sel, ear) : test::earIoU(*ps, sel, ear);
    };
    // The tool: the run of median total time.
    std::vector<interact::SnapSelection> runs;
    for (int k = 0; k < repeat; ++k) runs.push_back(interact::snapSelection(inst, 1, view, fg, bg));
    std::sort(runs.begin(), runs.end(), [](const auto& a, const auto& b) {
      const auto t = [](const interact::SnapToolStats& s) {
        return s.gather_ms + s.cut_ms + s.map_ms + s.mask_ms;
      };
      return t(a.stats) < t(b.stats);
    });
    const interact::SnapSelection& s = runs[runs.size() / 2];
    ToolRow t{m.name,
              m.kind,
              "snap_tool",
              s.stats.samples,
              elements,
              s.count,
              s.stats.gather_ms,
              s.stats.cut_ms,
              s.stats.map_ms,
              s.stats.mask_ms,
              0.0,
              iouOf(s.payload.elements())};
    t.total_ms = t.gather_ms + t.cut_ms + t.map_ms + t.mask_ms;
    rows.push_back(t);
    if (!quiet) std::cerr << "lazy_snapping: " << csvLine(rows.back()) << "\n";
    // The lasso around the ear's outline, the same view, one thread.
    std::vector<double> ms_runs;
    interact::LassoSelection l;
    for (int k = 0; k < repeat; ++k)
      ms_runs.push_back(wallMs([&] { l = interact::lassoSelection(inst, 1, view, outline, 1); }));
    std::sort(ms_runs.begin(), ms_runs.end());
    ToolRow lr{m.name,
               m.kind,
               "lasso",
               0,
               elements,
               l.count,
               0,
               0,
               0,
               0,
               ms_runs[ms_runs.size() / 2],
               iouOf(l.payload.elements())};
    rows.push_back(lr);
    if (!quiet) std::cerr << "lazy_snapping: " << csvLine(rows.back()) << "\n";
  }
}

bool runGnuplot(const fs::path& script) {
  std::string gnuplot = TESSERA_GNUPLOT;
  if (gnuplot.empty()) gnuplot = "gnuplot";
  const std::string cmd = "'" + gnuplot + "' '" + script.string() + "'";
  if (std::system(cmd.c_str()) != 0) {
    std::cerr << "lazy_snapping: gnuplot failed (" << cmd << "); the CSV is still there\n";
    return false;
  }
  return true;
}

void drawChart(const fs::path& out, const std::vector<Row>& rows) {
  double min_iou = 1;
  for (const Row& r : rows)
    if (r.series == "size") min_iou = std::min(min_iou, r.iou);
  const fs::path script = out / "lazy_snapping.gp";
  const std::string csv = (out / "lazy_snapping.csv").string();
  std::ofstream gp(script);
  auto sel = [&](const char* series, const char* method, int col) {
    return "'" + csv + "' skip 1 using (strcol(1) eq '" + series + "' && strcol(5) eq '" + method +
           "' ? $4 : 1/0):" + std::to_string(col);
  };
  gp << "set terminal pngcairo noenhanced size 1300,900 font ',10'\n"
     << "set output '" << (out / "lazy_snapping.png").string() << "'\n"
     << "set datafile separator ','\n"
     << "set multiplot layout 2,2 title '3D lazy snapping: watershed segments against one node "
        "per sample (same energy, same strokes)'\n"
     << "set grid\nset key bottom right\n"
     << "set title \"Bunny's ear: accuracy against strokes\"\n"
     << "set xlabel 'strokes (1 on the ear + 1 on the head, then corrective dabs)'\n"
     << "set ylabel 'IoU against the known ear'\nset yrange [0.8:1]\n"
     << "plot " << sel("strokes", "segments", 9) << " with linespoints lw 2 title 'segments', \\\n"
     << "     " << sel("strokes", "per_sample", 9) << " with linespoints lw 2 title 'per sample'\n"
     << "set title \"Bunny's ear (35947 vertices): time of a cut against strokes\"\n"
     << "set ylabel 'CPU ms per cut (median)'\nset yrange [0:*]\nset key top left\n"
     << "plot " << sel("strokes", "segments", 8) << " with linespoints lw 2 title 'segments', \\\n"
     << "     " << sel("strokes", "per_sample", 8) << " with linespoints lw 2 title 'per sample'\n";
  // Size panels: x is the sample count (column 3).
  auto size = [&](const char* method, const std::string& expr) {
    return "'" + csv + "' skip 1 using (strcol(1) eq 'size' && strcol(5) eq '" + method +
           "' ? $3 : 1/0):(" + expr + ")";
  };
  gp << "set title 'Capped sphere, one stroke per side: time against size'\n"
     << "set xlabel 'samples (vertices)'\nset ylabel 'CPU ms (median)'\nset logscale xy\nset "
        "yrange [*:*]\n"
     << "set key top left\n"
     << "plot " << size("segments", "$8") << " with linespoints lw 2 title 'cut, segments', \\\n"
     << "     " << size("per_sample", "$8")
     << " with linespoints lw 2 title 'cut, per sample', \\\n"
     << "     " << size("segments", "$7")
     << " with linespoints dt 2 title 'once per view: watershed + segment graph', \\\n"
     << "     " << size("per_sample", "$7")
     << " with linespoints dt 2 title 'once per view: sample graph'\n"
     << "set title sprintf('Capped sphere: graph nodes against size (IoU >= %.3f for both "
        "at every size)', "
     << min_iou << ")\n"
     << "set ylabel 'nodes of the cut graph'\nset key top left\n"
     << "plot " << size("segments", "$6") << " with linespoints lw 2 title 'segments', \\\n"
     << "     " << size("per_sample", "$6") << " with linespoints lw 2 title 'per sample'\n"
     << "unset multiplot\n";
  gp.close();
  runGnuplot(script);
}

/// The tool's stages per store, against the lasso's time, and both IoUs: a wide table (one line
/// per store: its snap_tool row then its lasso row) for gnuplot's histograms.
void drawToolChart(const fs::path& out, const std::vector<ToolRow>& rows) {
  const fs::path table = out / "snap_tool_wide.dat";
  {
    std::ofstream t(table);
    for (size_t i = 0; i + 1 < rows.size(); i += 2) {
      const ToolRow &s = rows[i], &l = rows[i + 1];
      char buf[512];
      std::snprintf(buf, sizeof buf, "\"%s %s\" %.3f %.3f %.3f %.3f %.3f %.3f %.3f %.3f\n",
                    s.model.c_str(), (std::to_string(s.samples) + " samples").c_str(), s.gather_ms,
                    s.cut_ms, s.map_ms, s.mask_ms, s.total_ms, l.total_ms, s.iou, l.iou);
      t << buf;
    }
  }
  const fs::path script = out / "snap_tool.gp";
  std::ofstream gp(script);
  const std::string dat = "'" + table.string() + "'";
  gp << "set terminal pngcairo noenhanced size 1300,560 font ',10'\n"
     << "set output '" << (out / "snap_tool.png").string() << "'\n"
     << "set multiplot layout 1,2 title \"The snap tool end to end on the bunny's ear (a stroke "
        "on the ear, one on the head) against the lasso along the ear's outline, same view "
        "(dev build, wall ms, median of 3)\"\n"
     << "set style data histograms\nset style histogram clustered gap 1\n"
     << "set style fill solid 0.8 border -1\nset grid y\nset key top left\n"
     << "set logscale y\nset yrange [0.01:20000]\nset ylabel 'ms'\nset xtics rotate by -15\n"
     << "set title 'snap tool: its stages'\n"
     << "plot " << dat << " using 2:xtic(1) title 'gather leaves (k-NN + normals / weld)', \\\n"
     << "     '' using 3 title 'over-segment + cut', '' using 4 title 'map back to leaf elements', "
        "\\\n"
     << "     '' using 5 title 'region mask'\n"
     << "set title 'total time; labels: IoU of the elements against the ear'\n"
     << "plot " << dat
     << " using 6:xtic(1) title 'snap tool', '' using 7 title 'lasso (1 thread)', "
        "\\\n"
     << "     '' using ($0 - 0.17):($6 * 1.6):(sprintf('%.3f', $8)) with labels notitle, \\\n"
     << "     '' using ($0 + 0.17):($7 * 1.6):(sprintf('%.3f', $9)) with labels notitle\n"
     << "unset multiplot\n";
  gp.close();
  runGnuplot(script);
}

/// The bunny seen from the stroke view: visible vertices by outcome, strokes on top.
void drawBunny(const fs::path& out, const SurfaceSamples& s, const std::vector<uint8_t>& ear,
               const std::vector<uint8_t>& visible, const BunnyPicture& pic,
               const std::vector<Row>& rows) {
  const ScreenView view = test::bunnyView();
  auto write = [&](const std::string& name, const std::vector<uint8_t>& selected,
                   const Strokes& strokes) {
    std::ofstream f(out / name);
    std::vector<uint8_t> mark(s.size(), 0);
    for (uint32_t i : strokes.foreground) mark[i] = 1;
    for (uint32_t i : strokes.background) mark[i] = 2;
    for (uint32_t i = 0; i < s.size(); ++i) {
      if (!visible[i] || s.neighboursOf(i).empty()) continue;
      const glm::dvec2 p = annotate::project(view, s.positions[i]).pixel;
      // 0 neither, 1 selected and ear, 2 selected only, 3 missed; 4/5 stroke fg/bg
      const int kind = mark[i] ? 3 + mark[i]
                               : (selected[i] && ear[i] ? 1
                                  : selected[i]         ? 2
                                  : ear[i]              ? 3
                                                        : 0);
      f << p.x << ' ' << p.y << ' ' << kind << '\n';
    }
  };
  write("lazy_snapping_bunny_strokes.dat", pic.strokes_selected, pic.strokes);
  write("lazy_snapping_bunny_lasso.dat", pic.lasso_selected, pic.lasso_seeds);
  {
    std::ofstream f(out / "lazy_snapping_bunny_heavy.dat");
    for (const glm::dvec2& p : pic.lasso) f << p.x << ' ' << p.y << '\n';
    if (!pic.lasso.empty()) f << pic.lasso[0].x << ' ' << pic.lasso[0].y << '\n';
  }
  double iou_strokes = 0, iou_lasso = 0;
  for (const Row& r : rows) {
    if (r.series == "strokes" && r.method == "segments" && r.strokes == 2) iou_strokes = r.iou;
    if (r.series == "lasso") iou_lasso = r.iou;
  }
  const fs::path script = out / "lazy_snapping_bunny.gp";
  std::ofstream gp(script);
  auto layer = [&](const std::string& file, int kind, const char* colour, double size,
                   const char* title) {
    return "'" + (out / file).string() + "' using 1:($3 == " + std::to_string(kind) +
           " ? $2 : 1/0) with points pt 7 ps " + std::to_string(size) + " lc rgb '" + colour +
           "' title '" + title + "'";
  };
  auto panel = [&](const std::string& file, bool heavy) {
    std::string p = "plot " + layer(file, 0, "#c8c8c8", 0.15, "not selected") + ", \\\n  " +
                    layer(file, 1, "#1f77b4", 0.2, "selected, ear") + ", \\\n  " +
                    layer(file, 2, "#d62728", 0.35, "selected, not ear") + ", \\\n  " +
                    layer(file, 3, "#2ca02c", 0.35, "ear, missed");
    if (heavy)
      p += ", \\\n  '" + (out / "lazy_snapping_bunny_heavy.dat").string() +
           "' with lines lw 12 lc rgb '#80808080' title 'heavy stroke'";
    p += ", \\\n  " + layer(file, 4, "#ffbf00", 0.5, "foreground seeds") + ", \\\n  " +
         layer(file, 5, "#00bfff", 0.5, "background seeds") + "\n";
    return p;
  };
  char t1[160], t2[160];
  std::snprintf(t1, sizeof t1, "Lazy snapping: one stroke on the ear, one on the head (IoU %.3f)",
                iou_strokes);
  std::snprintf(t2, sizeof t2, "Robust lasso: one heavy stroke around the ear (IoU %.3f)",
                iou_lasso);
  gp << "set terminal pngcairo noenhanced size 1400,560 font ',10'\n"
     << "set output '" << (out / "lazy_snapping_bunny.png").string() << "'\n"
     << "set multiplot layout 1,2\nset size ratio -1\nunset xtics\nunset ytics\n"
     << "set xrange [0:540]\nset yrange [230:530]\nset key bottom right\n"
     << "set title '" << t1 << "'\n"
     << panel("lazy_snapping_bunny_strokes.dat", false) << "set title '" << t2 << "'\n"
     << panel("lazy_snapping_bunny_lasso.dat", true) << "unset multiplot\n";
  gp.close();
  runGnuplot(script);
}

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  CLI::App app{
      "lazy_snapping: time and IoU of 3D lazy snapping against strokes (the bunny's ear) and "
      "model size (capped spheres), segments against one node per sample. Prints CSV; writes "
      "lazy_snapping.csv, lazy_snapping.png and lazy_snapping_bunny.png into --out."};
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  std::string data = TESSERA_DATA_DIR;
  int repeat = 3;
  size_t max_strokes = 12;
  std::vector<uint32_t> rings{50, 100, 200, 400, 700};
  bool quiet = false, tool_only = false;
  app.add_flag("--tool-only", tool_only, "Only the snap tool against the lasso (snap_tool.*)");
  app.add_option("--out", out, "Results folder")->capture_default_str();
  app.add_option("--data", data, "Shared data folder (stanford-bunny/...)")->capture_default_str();
  app.add_option("--repeat", repeat, "Timed runs per measurement; the median is kept")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--max-strokes", max_strokes, "Strokes on the bunny, 2 and up")
      ->check(CLI::Range(size_t(2), size_t(200)))
      ->capture_default_str();
  app.add_option("--rings", rings, "Latitude rings of the capped spheres (2 r^2 vertices)")
      ->delimiter(',')
      ->check(CLI::Range(uint32_t(4), uint32_t(4000)));
  app.add_flag("--quiet", quiet, "No progress output on stderr");
  CLI11_PARSE(app, argc, argv);

  try {
    const fs::path out_dir = fs::absolute(out);
    fs::create_directories(out_dir);
    {
      std::vector<ToolRow> tool;
      toolSeries(data, out_dir / "snap_tool_stores", repeat, tool, quiet);
      const std::string header =
          "model,kind,method,samples,elements,selected,gather_ms,cut_ms,"
          "map_ms,mask_ms,total_ms,iou";
      std::ofstream csv(out_dir / "snap_tool.csv");
      std::cout << header << "\n";
      csv << header << "\n";
      for (const ToolRow& r : tool) {
        std::cout << csvLine(r) << "\n";
        csv << csvLine(r) << "\n";
      }
      csv.close();
      if (!csv) throw std::runtime_error("cannot write " + (out_dir / "snap_tool.csv").string());
      drawToolChart(out_dir, tool);
      if (tool_only) return 0;
    }
    std::vector<Row> rows;
    BunnyPicture pic;
    SurfaceSamples bunny;
    std::vector<uint8_t> ear, visible;
    bunnySeries(data, repeat, max_strokes, rows, pic, bunny, ear, visible);
    sizeSeries(rings, repeat, rows, quiet);
    const std::string header =
        "series,model,samples,strokes,method,graph_nodes,prepare_ms,cut_ms,iou";
    std::ofstream csv(out_dir / "lazy_snapping.csv");
    std::cout << header << "\n";
    csv << header << "\n";
    for (const Row& r : rows) {
      std::cout << csvLine(r) << "\n";
      csv << csvLine(r) << "\n";
    }
    csv.close();
    if (!csv) throw std::runtime_error("cannot write " + (out_dir / "lazy_snapping.csv").string());
    drawChart(out_dir, rows);
    drawBunny(out_dir, bunny, ear, visible, pic, rows);
    if (!quiet)
      std::cerr << "charts: " << (out_dir / "lazy_snapping.png").string() << ", "
                << (out_dir / "lazy_snapping_bunny.png").string() << "\n";
  } catch (const std::exception& e) {
    std::cerr << "lazy_snapping: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
