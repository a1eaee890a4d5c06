// sync_bytes: bytes on the wire per serialized frame (scene::Frame, what the master broadcasts
// each frame) and per snapshot (what a late joiner receives), for scenes of 10 to 10^4 nodes.
// Cases per scene: nothing changed; a camera-only change, eye, target and roll all moving (goal
// goal: <= 64 bytes); the camera plus one opacity change (goal: adds <= 32 bytes); a few
// changes (camera, 3 opacities, a visibility, a georeferenced transform); the whole scene as a
// snapshot. Frames are numbered as an hour into a 60 Hz session (frame 216000), so the varint
// headers are not flattered by small numbers. Sizes are deterministic: no timing here. Prints CSV
// on stdout, writes OUT/sync_bytes.csv and draws OUT/sync_bytes.png with gnuplot.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include <tessera/sync/scene_graph.h>
#include <tessera/sync/wire.h>

namespace {

namespace fs = std::filesystem;
using tessera::scene::SceneNode;
using tessera::sync::SceneGraph;

constexpr const char* kCsvName = "sync_bytes.csv";
constexpr size_t kCameraGoal = 64;    // a camera-only frame
constexpr size_t kOpacityGoal = 32;   // what one opacity change may add
constexpr uint64_t kFrame = 216'000;  // one hour at 60 Hz
constexpr uint64_t kFrameUs = 16'667;

struct Row {
  size_t nodes = 0;
  size_t unchanged = 0, camera = 0, camera_opacity = 0, few = 0, snapshot = 0;
};

/// A camera at (x, y, z) looking at the survey, rolled by `tilt` (so every part of it changes).
tessera::config::Camera camera(double x, double y, double z, double tilt) {
  tessera::config::Camera c;
  c.mutable_eye()->set_x(x);
  c.mutable_eye()->set_y(y);
  c.mutable_eye()->set_z(z);
  c.mutable_target()->set_x(636590.0);
  c.mutable_target()->set_y(849216.0);
  c.mutable_target()->set_z(463.0);
  c.mutable_up()->set_x(tilt);
  c.mutable_up()->set_z(1.0);
  return c;
}

/// A scene like a wall session's: every tenth node a group with a georeferenced transform, the
/// others models (with a store path) and annotations (with a text and an anchor) in the groups.
SceneGraph makeScene(size_t nodes) {
  SceneGraph g;
  SceneGraph::NodeId group = SceneGraph::kRoot;
  for (size_t i = 0; i < nodes; ++i) {
    if (i % 10 == 0) {
      group = g.add(SceneNode::GROUP, SceneGraph::kRoot, "survey " + std::to_string(i / 10));
      std::vector<double> m(16, 0.0);
      m[0] = m[5] = m[10] = m[15] = 1.0;
      m[12] = 636000.0 + double(i);
      m[13] = 848900.0;
      m[14] = 400.0;
      g.setTransform(group, m);
    } else if (i % 3 == 0) {
      const auto id = g.add(SceneNode::ANNOTATION, group, "note " + std::to_string(i));
      tessera::scene::AnnotationPayload note;
      note.set_text("crack, measured 2024-05-" + std::to_string(1 + i % 28));
      note.mutable_anchor()->set_x(double(i % 100));
      g.setPayload(id, note);
    } else {
      const auto id = g.add(SceneNode::MODEL, group, "scan " + std::to_string(i));
      tessera::scene::ModelPayload model;
      model.set_store("/srv/tessera/stores/scan-" + std::to_string(i) + ".tlod");
      g.setPayload(id, model);
    }
  }
  g.setCamera(camera(636590.0, 847900.0, 1400.0, 0.0));
  g.takeFrame(kFrame - 10, (kFrame - 10) * kFrameUs);
  return g;
}

size_t frameBytes(SceneGraph& g, uint64_t number) {
  return tessera::sync::serializeFrame(g.takeFrame(number, number * kFrameUs)).size();
}

Row measure(size_t nodes) {
  SceneGraph g = makeScene(nodes);
  const std::vector<SceneGraph::NodeId> ids = g.ids();
  auto model = [&](size_t k) {  // the k-th model, from the end (the largest ids)
    for (auto it = ids.rbegin(); it != ids.rend(); ++it) {
      if (g.node(*it).kind() == SceneNode::MODEL && k-- == 0) return *it;
    }
    throw std::logic_error("sync_bytes: too few models");
  };
  Row r;
  r.nodes = nodes;
  uint64_t number = kFrame;
  r.unchanged = frameBytes(g, number++);
  g.setCamera(camera(636591.5, 847901.25, 1399.0, 0.01));
  r.camera = frameBytes(g, number++);
  g.setCamera(camera(636593.0, 847902.5, 1398.0, 0.02));
  g.setOpacity(model(0), 0.5f);
  r.camera_opacity = frameBytes(g, number++);
  g.setCamera(camera(636594.5, 847903.75, 1397.0, 0.03));
  g.setOpacity(model(0), 0.25f);
  g.setOpacity(model(1), 0.5f);
  g.setOpacity(model(2), 0.75f);
  g.setVisible(model(3), false);
  std::vector<double> m(16, 0.0);
  m[0] = m[5] = m[10] = m[15] = 1.0;
  m[12] = 636001.5;
  m[13] = 848901.5;
  g.setTransform(ids.front(), m);
  r.few = frameBytes(g, number++);
  r.snapshot = tessera::sync::serializeSnapshot(g.snapshot()).size();
  return r;
}

std::string csvLine(const Row& r) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%zu,%zu,%zu,%zu,%zu,%zu,%.1f", r.nodes, r.unchanged, r.camera,
                r.camera_opacity, r.few, r.snapshot, double(r.snapshot) / double(r.few));
  return buf;
}

/// Clustered bars per scene size (bytes, log scale) with the two goals as lines.
bool drawChart(const fs::path& out, size_t rows, bool quiet) {
  const fs::path script = out / "sync_bytes.gp";
  std::ofstream gp(script);
  gp << "set terminal pngcairo noenhanced size 1100,600 font ',10'\n"
     << "set output '" << (out / "sync_bytes.png").string() << "'\n"
     << "set datafile separator ','\n"
     << "set title 'Bytes on the wire per frame and per snapshot (frame " << kFrame
     << ", an hour into a 60 Hz session)'\n"
     << "set style data histogram\n"
     << "set style histogram clustered gap 1\n"
     << "set style fill solid 0.85 border -1\n"
     << "set boxwidth 0.9\n"
     << "set logscale y\n"
     << "set yrange [5:*]\n"
     << "set ylabel 'bytes (log scale)'\n"
     << "set xlabel 'nodes in the scene'\n"
     << "set grid ytics\n"
     << "set key top left\n"
     << "set xrange [-0.6:" << double(rows) - 0.4 << "]\n"
     << "plot '" << (out / kCsvName).string() << "' skip 1 using 2:xtic(1) lc rgb '#9e9e9e' "
     << "title 'nothing changed', \\\n"
     << "  '' skip 1 using 3 lc rgb '#1f77b4' title 'camera only', \\\n"
     << "  '' skip 1 using 4 lc rgb '#ff7f0e' title 'camera + 1 opacity', \\\n"
     << "  '' skip 1 using 5 lc rgb '#2ca02c' title 'camera + 5 node changes', \\\n"
     << "  '' skip 1 using 6 lc rgb '#9467bd' title 'snapshot (whole scene)', \\\n"
     << "  '' skip 1 using ($0-1.0/6):3:(sprintf('%d', $3)) with labels offset 0,0.7 notitle, \\\n"
     << "  '' skip 1 using ($0+2.0/6):6:(sprintf('%d', $6)) with labels offset 0,0.7 notitle, \\\n"
     << "  " << kCameraGoal
     << " with lines dt 2 lw 2 lc rgb '#d62728' title 'goal: camera only <= " << kCameraGoal
     << " B'\n";
  gp.close();
  std::string gnuplot = TESSERA_GNUPLOT;
  if (gnuplot.empty()) gnuplot = "gnuplot";
  const std::string cmd = "'" + gnuplot + "' '" + script.string() + "'";
  if (std::system(cmd.c_str()) != 0) {
    std::cerr << "sync_bytes: gnuplot failed (" << cmd << "); the CSV is still there\n";
    return false;
  }
  if (!quiet) std::cerr << "chart: " << (out / "sync_bytes.png").string() << "\n";
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "sync_bytes: serialized frame and snapshot sizes of the scene sync for scenes of 10 to "
      "10^4 nodes. Prints CSV; writes sync_bytes.csv and .png into --out."};
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  bool quiet = false;
  app.add_option("--out", out, "Results folder")->capture_default_str();
  app.add_flag("--quiet", quiet, "No chart message on stderr");
  CLI11_PARSE(app, argc, argv);

  try {
    const fs::path out_dir = fs::absolute(out);
    fs::create_directories(out_dir);
    std::vector<Row> rows;
    for (size_t nodes : {10, 100, 1000, 10000}) rows.push_back(measure(nodes));
    const std::string header =
        "nodes,unchanged_bytes,camera_only_bytes,camera_opacity_bytes,few_changes_bytes,"
        "snapshot_bytes,snapshot_over_few_changes";
    std::ofstream csv(out_dir / kCsvName);
    std::cout << header << "\n";
    csv << header << "\n";
    bool goals = true;
    for (const Row& r : rows) {
      std::cout << csvLine(r) << "\n";
      csv << csvLine(r) << "\n";
      goals = goals && r.camera <= kCameraGoal && r.camera_opacity <= r.camera + kOpacityGoal;
    }
    csv.close();
    if (!csv) throw std::runtime_error("cannot write " + (out_dir / kCsvName).string());
    std::cerr << "goals (camera only <= " << kCameraGoal
              << " B, one opacity adds <= " << kOpacityGoal << " B): " << (goals ? "met" : "MISSED")
              << "\n";
    drawChart(out_dir, rows.size(), quiet);
    return goals ? 0 : 2;
  } catch (const std::exception& e) {
    std::cerr << "sync_bytes: " << e.what() << "\n";
    return 1;
  }
}
