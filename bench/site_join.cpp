// bench/site_join: how long a remote site takes to join and see the scene ("chunks on
// demand"): the snapshot's bytes, the time to its first image and to a settled view (the whole
// cut of its view resident), with the stores on the site's host against chunks fetched from the
// master's chunk server into an empty cache over a link throttled by the server to 100, 20 and
// 5 Mbit/s (tessera-master --chunk-rate), and from a warm cache at the slowest rate; and a site
// whose view moves on before its chunks came, its requests withdrawn (the default) against kept
// until answered (--withdraw-after 0), at 1 Mbit/s: the second view's settling and the bytes.
//
// The scene is the autzen lidar tile (its store built once into the results folder), the site a
// real tessera-site process rendering headless 640x480 from the scene's camera, taking one
// settled screenshot and leaving; the wall one tessera-node tile. Times are from the site's
// start (process start to the line it prints), so they include connecting, the CURVE
// handshake, the snapshot and opening the store. Each case runs --runs times; the medians are
// printed and charted.
//
//   site_join [--runs 3] [--rates 100,20,5] [--out DIR] [--store S.tlod] [--join-only]
//
// Writes DIR/site_join.csv (every run), DIR/site_join_summary.csv (medians) and
// DIR/site_join.png (gnuplot). Every process runs on THIS machine (2 cores, loopback).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <tessera/collab/curve.h>
#include <tessera/core/cli.h>
#include <tessera/lod/store_builder.h>

#include "../tests/support/process.h"
#include "../tests/support/site_scripts.h"
#include "bench_walls.h"

namespace {

namespace fs = std::filesystem;
using tessera::test::Process;

/// What one site run said.
struct Join {
  double snapshot_bytes = 0, joined_s = 0, first_s = 0, settled_s = 0, fetched = 0;
  double withdrawn = 0;  ///< chunk requests withdrawn because the view moved on
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::optional<Join> parseJoin(const std::string& log) {
  Join j;
  std::smatch m;
  if (!std::regex_search(log, m, std::regex("snapshot (\\d+) bytes, ([0-9.]+) s\\)"))) return {};
  j.snapshot_bytes = std::stod(m[1]);
  j.joined_s = std::stod(m[2]);
  if (!std::regex_search(log, m, std::regex("first image at ([0-9.]+) s"))) return {};
  j.first_s = std::stod(m[1]);
  if (!std::regex_search(log, m, std::regex("view settled at ([0-9.]+) s"))) return {};
  j.settled_s = std::stod(m[1]);
  if (std::regex_search(log, m, std::regex("chunks: fetched (\\d+) bytes")))
    j.fetched = std::stod(m[1]);
  if (std::regex_search(log, m, std::regex("(\\d+) requests withdrawn")))
    j.withdrawn = std::stod(m[1]);
  return j;
}

struct Bench {
  fs::path dir, store;
  std::string master_bin, node_bin, site_bin, master_public;
  fs::path site_key;

  /// A master serving chunks at `mbit` with its node; killed when the returned pair goes.
  std::pair<std::unique_ptr<Process>, std::unique_ptr<Process>> wall(double mbit,
                                                                     std::string& sites) {
    const fs::path run = dir / ("wall-" + std::to_string(int(mbit)));
    fs::create_directories(run);
    // The scene's camera held for longer than the runs take (the master is killed after them).
    std::smatch cam;
    const std::string scene = slurp(dir / "scene.json");
    if (!std::regex_search(scene, cam,
                           std::regex("\"camera\"\\s*:\\s*(\\{[^}]*\\}[^}]*\\}[^}]*\\}[^}]*\\})")))
      throw std::runtime_error("site_join: no camera in " + (dir / "scene.json").string());
    auto master = std::make_unique<Process>(
        tessera::test::masterWithSites(master_bin, dir, run, 3600, cam[1].str(),
                                       {"--chunks", "tcp://127.0.0.1:*", "--chunk-rate",
                                        std::to_string(mbit), "--site-timeout", "60"}),
        run / "master.log");
    if (!master->waitFor("chunks served on tcp://", 30))
      throw std::runtime_error("the master did not start: " + master->output());
    const std::string out = master->output();
    std::smatch m;
    std::regex_search(out, m, std::regex("listening on (tcp://\\S+)"));
    const std::string wall_endpoint = m[1].str();
    std::regex_search(out, m, std::regex("remote sites join on tcp://[^:]+:(\\d+)"));
    sites = "tcp://127.0.0.1:" + m[1].str();
    auto node = std::make_unique<Process>(
        std::vector<std::string>{node_bin, "--master", wall_endpoint, "--headless"},
        run / "node.log");
    if (!master->waitFor("1 of 1 tiles have a node", 60))
      throw std::runtime_error("the node did not join: " + master->output());
    return {std::move(master), std::move(node)};
  }

  /// A site run: `actions` its script's actions (default: one settled screenshot of the scene's
  /// camera, then goodbye).
  Join site(const std::string& sites, const std::string& name, std::vector<std::string> extra,
            const std::string& actions = R"([{"frame": 1, "screenshot": "view.png"},
              {"frame": 2, "bye": true}])") {
    const fs::path out = dir / name;
    fs::remove_all(out);
    fs::create_directories(out);
    std::ofstream(out / "script.json")
        << R"({"width": 640, "height": 480, "actions": )" << actions << "}";
    std::vector<std::string> argv = {site_bin,
                                     "--master",
                                     sites,
                                     "--master-key",
                                     master_public,
                                     "--name",
                                     name,
                                     "--key",
                                     site_key.string(),
                                     "--headless",
                                     "-o",
                                     out.string(),
                                     "--script",
                                     (out / "script.json").string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    Process p(argv, out / "site.log");
    const auto code = p.wait(300);
    const auto j = parseJoin(p.output());
    if (code != std::optional<int>(0) || !j)
      throw std::runtime_error("site " + name + " failed: " + p.output());
    return *j;
  }
};

}  // namespace

int main(int argc, char** argv) {
  return tessera::cli::runMain("site_join", [&]() -> int {
    CLI::App app{
        "bench/site_join: a remote site's join time with local stores and with chunks "
        "over throttled links"};
    int runs = 3;
    std::vector<double> rates = {100, 20, 5};
    std::string out = std::string(TESSERA_BENCH_RESULTS_DIR);
    app.add_option("--runs", runs, "Runs per case (medians)")
        ->check(tessera::cli::integerRange<int>(1, 50))
        ->capture_default_str();
    app.add_option("--rates", rates, "Chunk server rates, Mbit/s per site (comma-separated)")
        ->delimiter(',')
        ->check(tessera::cli::finiteRange(0.01, 1e5))
        ->capture_default_str();
    app.add_option("--out", out, "Output folder")->capture_default_str();
    std::string store;
    app.add_option("--store", store,
                   "A store built elsewhere holding Autzen where the scene looks (bench/scale.sh's "
                   "tiled Autzen: its first copy is unshifted); default: Autzen built here")
        ->check(CLI::ExistingFile);
    bool join_only = false;
    app.add_flag("--join-only", join_only, "Only the joins (not the view that moves on)");
    if (const auto code = tessera::cli::parse(app, argc, argv, "site_join")) return *code;
    if (rates.empty()) throw tessera::cli::UsageError("--rates: needs at least one rate");

    Bench b;
    b.dir = fs::path(out) / "site-join-work";
    fs::remove_all(b.dir);
    fs::create_directories(b.dir);
    const std::string bin = fs::canonical("/proc/self/exe").parent_path().parent_path().string();
    b.master_bin = bin + "/master/tessera-master";
    b.node_bin = bin + "/render_node/tessera-node";
    b.site_bin = bin + "/collab/tessera-site";
    b.store = store.empty() ? fs::absolute(fs::path(out) / "inputs" / "autzen.tlod")
                            : fs::absolute(store);
    if (!fs::exists(b.store)) {
      fs::create_directories(b.store.parent_path());
      tessera::lod::BuildOptions o;
      o.quiet = true;
      tessera::lod::buildStore({std::string(TESSERA_DATA_DIR) + "/lidar/autzen_trim.las"},
                               b.store.string(), o);
    }
    std::ifstream scene_in(std::string(TESSERA_CONFIG_DIR) + "/scenes/autzen.json");
    std::stringstream scene_text;
    scene_text << scene_in.rdbuf();
    // The scene file as shipped, with the store built here.
    std::ofstream(b.dir / "scene.json")
        << std::regex_replace(scene_text.str(), std::regex("\"store\"\\s*:\\s*\"[^\"]*\""),
                              "\"store\": \"" + b.store.string() + "\"");
    std::ofstream(b.dir / "wall.json") << tessera::bench::gridWallJson(1, 640, 360);
    const tessera::collab::KeyPair master_keys = tessera::collab::generateKeyPair();
    tessera::collab::writeKeyFile(b.dir / "master.key", master_keys);
    b.master_public = master_keys.public_key;
    const tessera::collab::KeyPair site_keys = tessera::collab::generateKeyPair();
    b.site_key = b.dir / "site.key";
    tessera::collab::writeKeyFile(b.site_key, site_keys);
    std::ofstream(b.dir / "allow.txt") << site_keys.public_key << " bench site\n";
    fs::permissions(b.dir / "allow.txt", fs::perms::owner_read | fs::perms::owner_write);

    std::ofstream csv(fs::path(out) / "site_join.csv");
    csv << "case,rate_mbit,run,snapshot_bytes,joined_s,first_image_s,settled_s,fetched_bytes,"
           "withdrawn_requests\n";
    struct Case {
      std::string name;
      double rate;
      std::vector<Join> joins;
    };
    std::vector<Case> cases;
    const double slowest = *std::min_element(rates.begin(), rates.end());
    for (const double rate : rates) {
      std::string sites;
      auto w = b.wall(rate, sites);
      std::vector<std::pair<std::string, std::vector<std::string>>> kinds;
      if (rate == rates.front()) kinds.push_back({"local stores", {}});
      char name[64];
      std::snprintf(name, sizeof name, "chunks %g Mbit/s", rate);
      kinds.push_back({name, {"--remote-stores", "--cache"}});
      if (rate == slowest) {
        std::snprintf(name, sizeof name, "warm cache %g Mbit/s", rate);
        kinds.push_back({name, {"--remote-stores", "--cache"}});
      }
      for (const auto& [kind, flags] : kinds) {
        Case c{kind, kind == "local stores" ? 0.0 : rate, {}};
        const bool warm = kind.starts_with("warm");
        for (int r = 0; r < runs; ++r) {
          std::vector<std::string> extra = flags;
          const fs::path cache =
              b.dir / ("cache-" + std::to_string(int(rate)) + "-" + std::to_string(r));
          if (!extra.empty()) {
            if (!warm) fs::remove_all(cache);  // cold: an empty cache; warm: the cold run's
            extra.push_back(cache.string());
          }
          const Join j =
              b.site(sites, "site-" + std::to_string(int(rate)) + "-" + std::to_string(r), extra);
          c.joins.push_back(j);
          csv << '"' << kind << "\"," << c.rate << "," << r << "," << j.snapshot_bytes << ","
              << j.joined_s << "," << j.first_s << "," << j.settled_s << "," << j.fetched << ","
              << j.withdrawn << "\n";
          csv.flush();
        }
        cases.push_back(std::move(c));
      }
    }
    // A view that moves on before its chunks came: close over the tile's west end, then after
    // 0.2 s over its east end, settled there. Requests withdrawn (the default) against kept
    // until answered (--withdraw-after 0), at a rate where the first view's chunks still wait.
    if (!join_only) {
      constexpr double kMovedRate = 1.0;
      std::string sites;
      auto w = b.wall(kMovedRate, sites);
      const glm::dvec3 origin(636590.49, 849216.55, 463.39);  // the store's, as the scene's
      const glm::dvec3 west = origin + glm::dvec3(-520.0, -150.0, -40.0),
                       east = origin + glm::dvec3(520.0, 150.0, -40.0);
      const std::string actions =
          R"([{"frame": 0, "camera": )" +
          tessera::test::cameraJson(west + glm::dvec3(0.0, -60.0, 60.0), west) +
          R"(}, {"frame": 6, "camera": )" +
          tessera::test::cameraJson(east + glm::dvec3(0.0, -60.0, 60.0), east) +
          R"(}, {"frame": 8, "screenshot": "view.png"}, {"frame": 9, "bye": true}])";
      for (const auto& [kind, after] :
           {std::pair<std::string, std::string>{"moved on, withdrawn", "2"},
            {"moved on, kept", "0"}}) {
        Case c{kind + " 1 Mbit/s", kMovedRate, {}};
        for (int r = 0; r < runs; ++r) {
          const Join j = b.site(sites, "site-moved-" + after + "-" + std::to_string(r),
                                {"--remote-stores", "--withdraw-after", after}, actions);
          c.joins.push_back(j);
          csv << '"' << c.name << "\"," << c.rate << "," << r << "," << j.snapshot_bytes << ","
              << j.joined_s << "," << j.first_s << "," << j.settled_s << "," << j.fetched << ","
              << j.withdrawn << "\n";
          csv.flush();
        }
        cases.push_back(std::move(c));
      }
    }
    csv.close();

    std::ofstream sum(fs::path(out) / "site_join_summary.csv");
    sum << "case,snapshot_bytes,joined_s,first_image_s,settled_s,fetched_bytes,withdrawn\n";
    std::printf(
        "remote site join (autzen store %.1f MB, view 640x480, %d runs, medians; times "
        "from the site's start):\n",
        double(fs::file_size(b.store)) / 1e6, runs);
    for (const Case& c : cases) {
      auto pick = [&](double Join::*f) {
        std::vector<double> v;
        for (const Join& j : c.joins) v.push_back(j.*f);
        return median(v);
      };
      sum << '"' << c.name << "\"," << pick(&Join::snapshot_bytes) << "," << pick(&Join::joined_s)
          << "," << pick(&Join::first_s) << "," << pick(&Join::settled_s) << ","
          << pick(&Join::fetched) << "," << pick(&Join::withdrawn) << "\n";
      std::printf(
          "  %-30s snapshot %6.0f B, joined %.3f s, first image %.3f s, settled %.3f s, "
          "fetched %.0f bytes, %.0f requests withdrawn\n",
          c.name.c_str(), pick(&Join::snapshot_bytes), pick(&Join::joined_s), pick(&Join::first_s),
          pick(&Join::settled_s), pick(&Join::fetched), pick(&Join::withdrawn));
    }
    sum.close();

    const fs::path res = fs::path(out);
    std::ofstream gp(res / "site_join.gp");
    gp << "set terminal pngcairo noenhanced size 900,480 font ',10'\n"
       << "set output '" << (res / "site_join.png").string() << "'\n"
       << "set datafile separator ','\nset grid ytics\n"
       << "set title 'A remote site joins: autzen, 640x480, chunks throttled by the master "
          "(medians)'\n"
       << "set ylabel 'seconds from the site start'\nset yrange [0:*]\n"
       << "set style data histograms\nset style histogram clustered gap 1\n"
       << "set style fill solid 0.7\nset boxwidth 0.9\nset key top left\nset xtics rotate by -20\n"
       << "plot '" << (res / "site_join_summary.csv").string()
       << "' skip 1 using 3:xtic(1) title 'joined (snapshot)', '' skip 1 using 4 title 'first "
          "image', '' skip 1 using 5 title 'settled view'\n";
    gp.close();
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + (res / "site_join.gp").string() + "'").c_str()))
      std::cerr << "site_join: gnuplot failed; the CSVs are still there\n";
    else
      std::cerr << "chart: " << (res / "site_join.png").string() << "\n";
    return 0;
  });
}
