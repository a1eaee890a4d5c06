// bench/annotation_db: the annotation database on this machine's disk.
//
//  1. Writes per second with durability on: one item added and committed per acknowledged edit
//     with synchronous=FULL in WAL mode (what AnnotationDb does; each commit waits for fsync of
//     the WAL), against the baselines synchronous=NORMAL (no fsync per commit; a power cut may
//     lose the last commits) and batched transactions of 100 edits with FULL (one fsync per
//     batch). Each item is a text item of ~200 bytes attached to a point, as `tessera-annotate
//     add --at` writes.
//  2. Full-text search time against item count (10^3, 10^4, 10^5 items of synthetic words with
//     a Zipf-like frequency): a rare word, a common word, a prefix, a two-word phrase and an OR,
//     median and p90 over repeated queries, with the number of hits.
//
//   annotation_db [--edits N] [--max-items N] [--out DIR]
//
// Writes DIR/annotation_writes.csv, DIR/annotation_search.csv and DIR/annotation_db.png.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include <tessera/core/cli.h>
#include <tessera/annotate/annotation_db.h>

#include "bench_stats.h"

namespace {

namespace fs = std::filesystem;
using namespace tessera::annotate;
using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

/// Word k of a synthetic vocabulary: "w" + base-26 letters, all distinct, 3..6 letters.
std::string word(size_t k) {
  std::string w = "w";
  do {
    w += char('a' + k % 26);
    k /= 26;
  } while (k);
  return w;
}

/// A sentence of `n` words drawn with probability ~ 1/rank (Zipf), from `vocabulary` words.
std::string sentence(std::mt19937_64& rng, size_t n, size_t vocabulary) {
  // Inverse CDF of a continuous 1/x law on [1, V]: rank = V^u.
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::string s;
  for (size_t i = 0; i < n; ++i) {
    const size_t rank = size_t(std::pow(double(vocabulary), u(rng))) - 1;
    s += (i ? " " : "") + word(std::min(rank, vocabulary - 1));
  }
  return s;
}

Item benchItem(std::mt19937_64& rng, size_t i) {
  Item it;
  it.layer = "bench/layer" + std::to_string(i % 16);
  it.title = sentence(rng, 4, 5000);
  it.text = sentence(rng, 28, 5000);  // ~200 bytes
  return it;
}

Place benchPlace(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-50.0, 50.0);
  Place p;
  p.kind = PlaceKind::kPoint;
  p.model = "bench";
  p.position = {u(rng), u(rng), u(rng)};
  return p;
}

void removeDb(const fs::path& file) {
  for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(file.string() + suffix);
}

}  // namespace

int main(int argc, char** argv) {
  return tessera::cli::runMain("annotation_db", [&]() -> int {
    CLI::App app{"bench/annotation_db: durable writes per second and FTS5 search time"};
    int edits = 400;
    int max_items = 100000;
    std::string out = std::string(TESSERA_BENCH_RESULTS_DIR);
    app.add_option("--edits", edits, "Acknowledged edits timed per write mode")
        ->check(tessera::cli::integerRange(10, 1000000))
        ->capture_default_str();
    app.add_option("--max-items", max_items, "Largest database for the search (10^3 up to it)")
        ->check(tessera::cli::integerRange(1000, 10000000))
        ->capture_default_str();
    app.add_option("--out", out, "Output folder (the databases are made there too)")
        ->capture_default_str();
    if (const auto code = tessera::cli::parse(app, argc, argv, "annotation_db")) return *code;
    const fs::path res(out);
    fs::create_directories(res);

    // 1. Writes per second.
    std::ofstream writes(res / "annotation_writes.csv");
    writes << "mode,edits,seconds,edits_per_s\n";
    std::printf("mode,edits,seconds,edits_per_s\n");
    struct Mode {
      const char* name;
      bool full_sync;
      int batch;
    };
    for (const Mode mode : {Mode{"FULL, 1 edit per commit (acknowledged)", true, 1},
                            Mode{"NORMAL, 1 edit per commit (baseline)", false, 1},
                            Mode{"FULL, 100 edits per commit", true, 100}}) {
      const fs::path file = res / "annotation_bench_writes.tadb";
      removeDb(file);
      AnnotationDb db(file, {.read_only = false, .full_sync = mode.full_sync});
      std::mt19937_64 rng(7);
      // Batches write 10x more edits so the timing covers as many commits.
      const int n = edits * (mode.batch > 1 ? 10 : 1);
      const auto start = Clock::now();
      for (int i = 0; i < n; i += mode.batch) {
        db.transaction([&] {
          for (int k = i; k < std::min(n, i + mode.batch); ++k) {
            const int64_t id = db.addItem(benchItem(rng, size_t(k)), "bench");
            db.attach(id, db.addPlace(benchPlace(rng)));
          }
        });
      }
      const double s = seconds(start);
      writes << '"' << mode.name << "\"," << n << ',' << s << ',' << n / s << '\n';
      std::printf("\"%s\",%d,%.3f,%.1f\n", mode.name, n, s, n / s);
      std::fflush(stdout);
    }
    writes.close();

    // 2. Search time against item count: one database grown to each size in turn.
    std::ofstream search(res / "annotation_search.csv");
    search << "items,query,hits,median_ms,p90_ms\n";
    std::printf("items,query,hits,median_ms,p90_ms\n");
    const fs::path file = res / "annotation_bench_search.tadb";
    removeDb(file);
    AnnotationDb db(file, {.read_only = false, .full_sync = false});
    std::mt19937_64 rng(11);
    size_t count = 0;
    const std::vector<std::pair<std::string, std::string>> queries = {
        {"rare-word", word(4000)},
        {"common-word", word(3)},
        {"prefix", word(30).substr(0, 3) + "*"},
        {"phrase", "\"" + word(0) + " " + word(1) + "\""},
        {"OR", word(2000) + " OR " + word(3000)},
    };
    // The chart's table: one row per size, one median column per query (lines through points).
    std::ofstream wide(res / "annotation_search_wide.csv");
    wide << "items";
    for (const auto& q : queries) wide << ',' << q.first;
    wide << '\n';
    for (size_t target = 1000; target <= size_t(max_items); target *= 10) {
      wide << target;
      while (count < target) {
        db.transaction([&] {
          for (size_t k = 0; k < 1000 && count < target; ++k, ++count)
            db.addItem(benchItem(rng, count), "bench");
        });
      }
      for (const auto& [name, query] : queries) {
        std::vector<double> ms;
        size_t hits = 0;
        for (int r = 0; r < 30; ++r) {
          const auto start = Clock::now();
          hits = db.search(query, 50).size();
          ms.push_back(1000.0 * seconds(start));
        }
        const double median = tessera::bench::percentile(ms, 0.5);
        const double p90 = tessera::bench::percentile(ms, 0.9);
        search << target << ",\"" << name << "\"," << hits << ',' << median << ',' << p90 << '\n';
        std::printf("%zu,\"%s\",%zu,%.3f,%.3f\n", target, name.c_str(), hits, median, p90);
        std::fflush(stdout);
        wide << ',' << median;
      }
      wide << '\n';
    }
    wide.close();
    search.close();
    removeDb(res / "annotation_bench_writes.tadb");
    removeDb(file);

    // The chart.
    const std::string w = (res / "annotation_writes.csv").string();
    const std::string q = (res / "annotation_search_wide.csv").string();
    std::ofstream gp(res / "annotation_db.gp");
    gp << "set terminal pngcairo noenhanced size 1400,500 font ',10'\n"
       << "set output '" << (res / "annotation_db.png").string() << "'\n"
       << "set datafile separator ','\nset multiplot layout 1,2\nset grid\n"
       << "set title 'Annotation writes per second (WAL; an item + its point per edit)'\n"
       << "set style fill solid 0.7\nset boxwidth 0.6\nset logscale y\nset yrange [1:*]\n"
       << "set ylabel 'edits per second (log)'\nset xtics rotate by -12\nunset key\n"
       << "plot '" << w << "' skip 1 using 0:4:xtic(1) with boxes lc rgb '#1f77b4', \\\n"
       << "  '' skip 1 using 0:4:(sprintf('%.0f', $4)) with labels offset 0,1\n"
       << "unset logscale y\nset yrange [*:*]\nset xtics norotate\n"
       << "set title 'Full-text search (FTS5, bm25, 50 best) against item count'\n"
       << "set logscale xy\nset xrange [700:150000]\nset xlabel 'items (log)'\n"
       << "set ylabel 'median query time (ms, log)'\nset key top left\n"
       << "plot for [c=2:6] '" << q << "' using 1:c w lp pt 7 lw 2 title columnhead(c)\n"
       << "unset multiplot\n";
    gp.close();
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + (res / "annotation_db.gp").string() + "'").c_str()))
      std::cerr << "annotation_db: gnuplot failed; the CSVs are still there\n";
    else
      std::cerr << "chart: " << (res / "annotation_db.png").string() << "\n";
    return 0;
  });
}
