// bench/cluster_frames: the wall cluster's frame time split into sync (master: take the frame,
// serialize, broadcast), render (the slowest node: apply, select, stream, draw) and barrier (the
// rest of the master's frame: the swap barrier and the stats gather past the slowest node), so the
// three add up to the frame; also the mean node wait at the barrier (load imbalance between
// tiles, overlapping the slowest node's render), for 1, 2, 4 and 8
// nodes sharing one wall of the same total pixels (1x1, 2x1, 2x2, 4x2 tiles without bezels), and
// each node's resident bytes against the whole store: each tile should hold only what its frustum
// needs.
//
// Every run is `mpirun --oversubscribe` master + K tessera-nodes on THIS machine: with 2 cores,
// 2 or more nodes share them, so render time grows with K instead of shrinking; the figures show
// the protocol's overhead and the per-tile streaming, not a real cluster's speed-up.
//
//   cluster_frames [--store S.tlod] [--frames N] [--nodes 1,2,4,8] [--size 1920x1080] [--out DIR]
//
// Prints CSV on stdout; writes DIR/cluster_frames.csv, DIR/cluster_resident.csv and
// DIR/cluster_frames.png (gnuplot).
#include <CLI/CLI.hpp>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <tessera/lod/store_builder.h>

#include "bench_walls.h"

namespace {

namespace fs = std::filesystem;

struct Row {  // one CSV row of tessera-master --stats
  uint64_t frame = 0;
  int rank = 0;
  std::string tile;
  double sync_ms = 0, render_ms = 0, barrier_ms = 0, frame_ms = 0;
  uint64_t points = 0, resident_disk = 0, store_bytes = 0;
};

std::vector<Row> readStats(const fs::path& csv) {
  std::vector<Row> rows;
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    if (f.size() < 17) continue;
    Row r;
    r.frame = std::stoull(f[0]);
    r.rank = std::stoi(f[2]);
    r.tile = f[3];
    r.sync_ms = std::stod(f[5]);
    r.render_ms = std::stod(f[6]);
    r.barrier_ms = std::stod(f[7]);
    r.frame_ms = std::stod(f[9]);
    r.points = std::stoull(f[11]);
    r.resident_disk = std::stoull(f[14]);
    r.store_bytes = std::stoull(f[15]);
    rows.push_back(r);
  }
  return rows;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cluster_frames: wall frame time split into sync, render and barrier"};
  std::string store, out = TESSERA_BENCH_RESULTS_DIR, nodes_list = "1,2,4,8", size = "1920x1080";
  int frames = 30;
  app.add_option("--store", store, "A .tlod store (default: the registered bunny scans, built)");
  app.add_option("--frames", frames, "Frames per run, along configs/paths/bunny-orbit.json")
      ->check(CLI::Range(6, 100000));
  app.add_option("--nodes", nodes_list, "Node counts (1, 2, 4, 8)")->capture_default_str();
  app.add_option("--size", size, "Whole wall pixels WxH")->capture_default_str();
  app.add_option("--out", out, "Results folder")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  unsigned width = 0, height = 0;
  if (std::sscanf(size.c_str(), "%ux%u", &width, &height) != 2 || width < 64 || height < 64) {
    std::cerr << "cluster_frames: --size " << size << ": expected WxH\n";
    return 2;
  }
  const fs::path dir = fs::path(out) / "cluster_frames";
  fs::create_directories(dir);
  if (store.empty()) {
    store = (dir / "bunny.tlod").string();
    if (!fs::exists(store)) {
      tessera::lod::BuildOptions o;
      o.quiet = true;
      tessera::lod::buildStore({fs::path(TESSERA_DATA_DIR) / "stanford-bunny/scans/bun.conf"},
                               store, o);
    }
  }
  store = fs::absolute(store).string();
  {
    std::ifstream scene_in(std::string(TESSERA_CONFIG_DIR) + "/scenes/bunny.json");
    std::string scene((std::istreambuf_iterator<char>(scene_in)), {});
    const std::string from = "../../out/demo/stores/bunny.tlod";
    scene.replace(scene.find(from), from.size(), store);
    std::ofstream(dir / "scene.json") << scene;
  }
  const std::string bin = fs::canonical("/proc/self/exe").parent_path().parent_path().string();
  const std::string mpirun =
      std::string("mpirun --oversubscribe") + (getuid() == 0 ? " --allow-run-as-root" : "");

  std::ofstream frames_csv(dir.parent_path() / "cluster_frames.csv");
  std::ofstream resident_csv(dir.parent_path() / "cluster_resident.csv");
  const std::string head = "nodes,sync_ms,render_ms,barrier_ms,frame_ms,node_wait_ms,points";
  frames_csv << head << "\n";
  resident_csv << "nodes,rank,tile,points,resident_disk_bytes,store_bytes,share\n";
  std::cout << head << "\n";
  std::stringstream ks(nodes_list);
  for (std::string k_text; std::getline(ks, k_text, ',');) {
    const int k = std::stoi(k_text);
    if (k != 1 && k != 2 && k != 4 && k != 8) {
      std::cerr << "cluster_frames: --nodes: " << k << " is not 1, 2, 4 or 8\n";
      return 2;
    }
    const fs::path wall = dir / ("wall-" + std::to_string(k) + ".json");
    std::ofstream(wall) << tessera::bench::gridWallJson(k, width, height);
    const fs::path stats = dir / ("stats-" + std::to_string(k) + ".csv");
    const std::string cmd = mpirun + " -np 1 " + bin + "/master/tessera-master --wall " +
                            wall.string() + " --scene " + (dir / "scene.json").string() +
                            " --script " + TESSERA_CONFIG_DIR + "/paths/bunny-orbit.json" +
                            " --frames " + std::to_string(frames) + " --stats " + stats.string() +
                            " : -np " + std::to_string(k) + " " + bin +
                            "/render_node/tessera-node --headless > " +
                            (dir / ("log-" + std::to_string(k) + ".txt")).string() + " 2>&1";
    std::cerr << "cluster_frames: " << k << " nodes ...\n";
    if (std::system(cmd.c_str()) != 0) {
      std::cerr << "cluster_frames: the run failed: " << cmd << "\n";
      return 1;
    }
    // Per frame: sync from the master, render of the slowest node, barrier averaged over nodes.
    // The first 5 frames load the store and are left out.
    std::map<uint64_t, Row> per_frame;  // accumulated
    std::map<uint64_t, int> node_rows;
    std::map<int, Row> last_of_rank;
    for (const Row& r : readStats(stats)) {
      Row& f = per_frame[r.frame];
      if (r.rank == 0) {
        f.sync_ms = r.sync_ms;
        f.frame_ms = r.frame_ms;
      } else {
        f.render_ms = std::max(f.render_ms, r.render_ms);
        f.barrier_ms += r.barrier_ms;
        f.points += r.points;
        ++node_rows[r.frame];
        last_of_rank[r.rank] = r;
      }
    }
    double sum_sync = 0, sum_render = 0, sum_barrier = 0, sum_frame = 0, sum_wait = 0,
           sum_points = 0;
    int n = 0;
    for (const auto& [frame, f] : per_frame) {
      if (frame <= 5 || node_rows[frame] == 0) continue;
      sum_sync += f.sync_ms;
      sum_render += f.render_ms;
      sum_barrier += std::max(0.0, f.frame_ms - f.sync_ms - f.render_ms);
      sum_wait += f.barrier_ms / node_rows[frame];
      sum_frame += f.frame_ms;
      sum_points += double(f.points);
      ++n;
    }
    char line[256];
    std::snprintf(line, sizeof line, "%d,%.3f,%.1f,%.1f,%.1f,%.1f,%.0f", k, sum_sync / n,
                  sum_render / n, sum_barrier / n, sum_frame / n, sum_wait / n, sum_points / n);
    frames_csv << line << "\n";
    std::cout << line << std::endl;
    for (const auto& [rank, r] : last_of_rank) {
      std::snprintf(line, sizeof line, "%d,%d,%s,%llu,%llu,%llu,%.4f", k, rank, r.tile.c_str(),
                    (unsigned long long)r.points, (unsigned long long)r.resident_disk,
                    (unsigned long long)r.store_bytes,
                    r.store_bytes ? double(r.resident_disk) / double(r.store_bytes) : 0.0);
      resident_csv << line << "\n";
    }
  }
  frames_csv.close();
  resident_csv.close();

  const fs::path res = dir.parent_path();
  std::ofstream gp(res / "cluster_frames.gp");
  gp << "set terminal pngcairo noenhanced size 1200,520 font ',10'\n"
     << "set output '" << (res / "cluster_frames.png").string() << "'\n"
     << "set datafile separator ','\n"
     << "set multiplot layout 1,2\n"
     << "set title 'Frame time by part, " << width << "x" << height
     << " wall (mpirun --oversubscribe on 2 cores)'\n"
     << "set style data histogram\nset style histogram rowstacked\n"
     << "set style fill solid 0.85 border -1\nset boxwidth 0.6\n"
     << "set ylabel 'ms per frame (mean)'\nset xlabel 'render nodes'\nset grid ytics\n"
     << "set key below\n"
     << "plot '" << (res / "cluster_frames.csv").string()
     << "' skip 1 using 2:xtic(1) lc rgb '#9467bd' title 'sync (master: frame + broadcast)', \\\n"
     << "  '' skip 1 using 3 lc rgb '#1f77b4' title 'render (slowest node)', \\\n"
     << "  '' skip 1 using 4 lc rgb '#ff7f0e' title 'barrier + stats gather', \\\n"
     << "  '' skip 1 using 0:6 with linespoints lw 2 pt 7 lc rgb '#d62728' "
     << "title 'mean node wait at the barrier (imbalance)'\n"
     << "set title 'Each node: on-disk bytes resident / whole store'\n"
     << "unset style\nset style data points\nset ylabel 'share of the store'\n"
     << "set format y '%.0f%%'\nset xrange [0.5:9]\nset logscale x 2\nset xtics (1,2,4,8)\n"
     << "plot '" << (res / "cluster_resident.csv").string()
     << "' skip 1 using 1:($7*100) with points pt 7 ps 1.2 lc rgb '#2ca02c' title 'one node'\n"
     << "unset multiplot\n";
  gp.close();
  std::string gnuplot = TESSERA_GNUPLOT;
  if (gnuplot.empty()) gnuplot = "gnuplot";
  if (std::system(("'" + gnuplot + "' '" + (res / "cluster_frames.gp").string() + "'").c_str()))
    std::cerr << "cluster_frames: gnuplot failed; the CSVs are still there\n";
  else
    std::cerr << "chart: " << (res / "cluster_frames.png").string() << "\n";
  return 0;
}
