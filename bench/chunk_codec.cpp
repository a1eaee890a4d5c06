// chunk_codec: bytes per point by stream and encode / decode rates of the point chunk codec
// (lod/src/chunk_codec.h) against its baseline, format 1 (Morton deltas as LEB128 varints,
// zstd; what stores of version 1-3 hold), on the nodes of a store: every node's points are
// re-encoded by both at the step the store used, alternating the two in rounds on one thread,
// best round kept. Position bytes are a chunk encoded without attributes (header included),
// colour what adding colour costs, attributes the rest. Prints CSV on stdout, writes
// OUT/chunk_codec.csv and draws OUT/chunk_codec.png with gnuplot.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include <tessera/core/stopwatch.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/store_builder.h>

#include "../lod/src/chunk_codec.h"

namespace {

namespace fs = std::filesystem;
using namespace tessera::lod;
using Clock = std::chrono::steady_clock;

double since(Clock::time_point t) {
  return tessera::msSince(t) / 1000.0;
}

struct Node {
  std::vector<BuildPoint> points;
  glm::dvec3 box_min{0.0};
  double extent = 0.0, step = 0.0;
  bool leaf = false, lattice = false;
};

struct Result {
  std::string codec;
  double position = 0, color = 0, attributes = 0;  // bytes over input points
  double encode_mpts = 0, decode_mpts = 0;         // best round, one thread
};

/// Every node of the store, decoded: the points as the builder held them.
std::vector<Node> loadNodes(PointStore& s) {
  std::vector<Node> nodes;
  std::vector<NodeId> todo{s.root()};
  const bool exact = s.summary().exact_leaves;
  while (!todo.empty()) {
    const NodeId id = todo.back();
    todo.pop_back();
    for (NodeId c : s.children(id)) todo.push_back(c);
    const NodeInfo info = s.node(id);
    if (info.points == 0) continue;
    auto c = s.decodeChunk(id, {}, true);
    Node n;
    n.box_min = info.box_min;
    n.extent = info.box_max.x - info.box_min.x;
    n.step = c->step;
    n.leaf = info.leaf();
    n.lattice = exact && n.leaf;
    n.points.resize(c->size());
    for (size_t i = 0; i < c->size(); ++i) {
      BuildPoint& p = n.points[i];
      p.position = glm::clamp(c->offset + c->grid + glm::dvec3(c->cells[i]) * c->step, info.box_min,
                              info.box_max);
      if (c->attributes & kColor) p.rgb = glm::u8vec3(c->colors[i]);
      if (c->attributes & kIntensity) p.intensity = c->intensities[i];
      if (c->attributes & kScanIndex) p.source = c->sources[i];
      if (c->attributes & kClassification) p.classification = c->classifications[i];
      p.ao = c->attributes & kAmbientOcclusion ? c->ambient_occlusion[i] : 255;
    }
    nodes.push_back(std::move(n));
  }
  return nodes;
}

EncodedChunk encode(bool format2, Node& n, AttributeMask a) {
  return format2 ? encodeChunk(n.points, n.box_min, n.extent, n.step, a, 5, n.lattice)
                 : encodeChunkFormat1(n.points, n.box_min, n.extent, n.step, a, 5);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"chunk_codec: the point chunk codec against format 1, bytes by stream and rates"};
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  std::string input = std::string(TESSERA_DATA_DIR) + "/lidar/autzen_trim.las";
  std::string store_path;
  int rounds = 3;
  bool lossy = false;
  app.add_option("--input", input, "Scan to build the store from (any format tessera-lod reads)");
  app.add_option("--store", store_path, "Use this store instead of building one from --input");
  app.add_flag("--lossy", lossy, "Build the store with lossy leaves");
  app.add_option("--rounds", rounds, "Rounds (best kept)")->check(CLI::Range(1, 100));
  app.add_option("--out", out, "Folder for the CSV and the chart");
  CLI11_PARSE(app, argc, argv);
  fs::create_directories(out);

  if (store_path.empty()) {
    store_path = (fs::path(out) / "chunk_codec.tlod").string();
    BuildOptions o;
    o.quiet = true;
    o.exact_leaves = !lossy;
    buildStore({input}, store_path, o);
  }
  auto store = PointStore::open(store_path);
  const StoreSummary& sum = store->summary();
  std::vector<Node> nodes = loadNodes(*store);
  const AttributeMask all = sum.attributes;
  const double n_in = double(sum.points);
  uint64_t stored = 0;
  for (const Node& n : nodes) stored += n.points.size();

  std::vector<Result> results(2);
  results[0].codec = "format 1 (varint Morton deltas, zstd)";
  results[1].codec = "format 2 (2D Morton + heights, rANS)";
  for (int f = 0; f < 2; ++f) {
    Result& r = results[size_t(f)];
    for (Node& n : nodes) {
      const double pos = double(encode(f == 1, n, 0).bytes.size());
      const double pc = double(encode(f == 1, n, all & kColor).bytes.size());
      const double whole = double(encode(f == 1, n, all).bytes.size());
      r.position += pos / n_in;
      r.color += (pc - pos) / n_in;
      r.attributes += (whole - pc) / n_in;
    }
  }
  // Rates: the formats alternate within each round.
  std::vector<std::vector<uint8_t>> encoded(nodes.size());
  for (int round = 0; round < rounds; ++round) {
    for (int f = 0; f < 2; ++f) {
      auto t = Clock::now();
      for (size_t i = 0; i < nodes.size(); ++i) encoded[i] = encode(f == 1, nodes[i], all).bytes;
      const double enc_s = since(t);
      ChunkPoints cp;
      t = Clock::now();
      for (size_t i = 0; i < nodes.size(); ++i)
        decodeChunk(encoded[i], nodes[i].box_min, cp, "bench");
      const double dec_s = since(t);
      Result& r = results[size_t(f)];
      r.encode_mpts = std::max(r.encode_mpts, double(stored) / enc_s / 1e6);
      r.decode_mpts = std::max(r.decode_mpts, double(stored) / dec_s / 1e6);
    }
  }

  std::ofstream csv(fs::path(out) / "chunk_codec.csv");
  const std::string head =
      "codec,input,points,stored_points,position_bpp,color_bpp,attributes_bpp,total_bpp,"
      "encode_mpts_1thread,decode_mpts_1thread\n";
  csv << head;
  std::cout << head;
  for (const Result& r : results) {
    char line[512];
    std::snprintf(line, sizeof line, "\"%s\",\"%s\",%llu,%llu,%.4f,%.4f,%.4f,%.4f,%.2f,%.2f\n",
                  r.codec.c_str(), fs::path(store_path).filename().c_str(),
                  (unsigned long long)sum.points, (unsigned long long)stored, r.position, r.color,
                  r.attributes, r.position + r.color + r.attributes, r.encode_mpts, r.decode_mpts);
    csv << line;
    std::cout << line;
  }
  csv.close();

  const fs::path dat = fs::path(out) / "chunk_codec.dat", gp = fs::path(out) / "chunk_codec.gp";
  std::ofstream d(dat);
  for (const Result& r : results)
    d << '"' << r.codec << "\" " << r.position << " " << r.color << " " << r.attributes << " "
      << r.encode_mpts << " " << r.decode_mpts << "\n";
  d.close();
  std::ofstream g(gp);
  g << "set terminal pngcairo size 1200,460 font 'sans,10' noenhanced\nset output '"
    << (fs::path(out) / "chunk_codec.png").string() << "'\n"
    << "set multiplot layout 1,2 title 'Point chunk codec on "
    << fs::path(input).filename().string() << " (" << sum.points << " points, "
    << (sum.exact_leaves ? "exact" : "lossy") << " leaves; one thread)'\n"
    << "set style fill solid 0.8 border -1\nset grid ytics\nset key below\nset yrange [0:*]\n"
    << "set xtics rotate by -10\n"
    << "set title 'Bytes per input point (inner copies included)'\n"
    << "set style data histograms\nset style histogram rowstacked\nset boxwidth 0.5\n"
    << "plot '" << dat.string()
    << "' using 2:xtic(1) title 'position', '' using 3 title "
       "'colour', '' using 4 title 'intensity, source, class'\n"
    << "set title 'M points/s, one thread'\nset style histogram clustered gap 1\n"
    << "plot '" << dat.string() << "' using 5:xtic(1) title 'encode', '' using 6 title 'decode'\n"
    << "unset multiplot\n";
  g.close();
  const std::string cmd = std::string(TESSERA_GNUPLOT) + " '" + gp.string() + "'";
  if (std::system(cmd.c_str()) != 0)
    std::fprintf(stderr, "chunk_codec: gnuplot failed; the CSV is complete\n");
  std::fprintf(stderr, "chunk_codec: wrote %s/chunk_codec.csv and chunk_codec.png\n", out.c_str());
  std::fprintf(stderr, "reproduce: %s --input %s --rounds %d%s\n", argv[0], input.c_str(), rounds,
               lossy ? " --lossy" : "");
  return 0;
}
