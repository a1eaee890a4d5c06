// bench/annotation_db: the annotation database on this machine's disk.
//
//  1. Writes per second with durability on: one item added and committed per acknowledged edit
//     with synchronous=FULL in WAL mode (what AnnotationDb does; each commit waits for fsync of
//     the WAL), against the baselines synchronous=NORMAL (no fsync per commit; a power cut may
//     lose the last commits) and batched transactions of 100 edits with FULL (one fsync per
//     batch). Each item is a text item of ~200 bytes attached to a point, as `tessera-annotate
//     add --at` writes.
//  2. Full-text search time against item count (10^3, 10^4, 10^5 items of synthetic words with
//     a Zipf-like frequency, one in ten also with a Japanese sentence, written without spaces):
//     a rare word, a common word, a prefix, a two-word phrase, an OR, a Japanese word and a
//     Japanese phrase, median and p90 over repeated queries, with the number of hits; the index
//     in any script (schema v3, "after") against an index of words between spaces only
//     (schema v2, unicode61, "before", queried with the same SQL through the bare C API), the
//     same items in both.
//  3. Opening a database of the largest size: with the page check (quick_check) and without.
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
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <sqlite3.h>

#include <tessera/annotate/annotation_db.h>
#include <tessera/core/cli.h>

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

/// Japanese word k: two ideographs of a pool of 64 (4096 words).
std::string japaneseWord(size_t k) {
  static const char* kPool[64] = {"亀", "裂", "東", "京", "調", "査", "石", "柱", "壁", "画", "修",
                                  "復", "寺", "院", "塔", "門", "屋", "根", "瓦", "木", "材", "彫",
                                  "刻", "仏", "像", "金", "箔", "漆", "塗", "彩", "色", "剥", "落",
                                  "風", "化", "苔", "水", "害", "虫", "損", "傷", "記", "録", "測",
                                  "量", "写", "真", "図", "面", "床", "梁", "柱", "礎", "土", "台",
                                  "階", "段", "庭", "池", "橋", "蔵", "鐘", "楼", "殿"};
  return std::string(kPool[k % 64]) + kPool[(k / 64) % 64];
}

/// A Japanese sentence of `n` words, Zipf-like over 4096 words, joined by particles.
std::string japaneseSentence(std::mt19937_64& rng, size_t n) {
  static const char* kParticles[4] = {"の", "で", "を", "が"};
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::string s;
  for (size_t i = 0; i < n; ++i) {
    const size_t rank = size_t(std::pow(4096.0, u(rng))) - 1;
    s += japaneseWord(std::min<size_t>(rank, 4095));
    s += kParticles[rng() % 4];
  }
  return s;
}

Item benchItem(std::mt19937_64& rng, size_t i) {
  Item it;
  it.layer = "bench/layer" + std::to_string(i % 16);
  it.title = sentence(rng, 4, 5000);
  it.text = sentence(rng, 28, 5000);  // ~200 bytes
  if (i % 10 == 0) it.text += " " + japaneseSentence(rng, 8);
  return it;
}

/// A schema v2 database (its full-text index finds words between spaces
/// only), written and queried through the bare C API: the baseline of the search.
class V2Baseline {
 public:
  explicit V2Baseline(const fs::path& file) {
    if (sqlite3_open(file.c_str(), &mDb) != SQLITE_OK ||
        sqlite3_exec(mDb, kSchemaV2Sql, nullptr, nullptr, nullptr) != SQLITE_OK ||
        sqlite3_exec(mDb, "PRAGMA journal_mode = WAL; PRAGMA synchronous = NORMAL", nullptr,
                     nullptr, nullptr) != SQLITE_OK)
      throw std::runtime_error("annotation_db: cannot make the v2 baseline " + file.string());
    sqlite3_prepare_v2(mDb,
                       "INSERT INTO items(layer, kind, title, body, author, created_us, "
                       "modified_us, revision) VALUES (?1, 'text', ?2, ?3, 'bench', 1, 1, 1)",
                       -1, &mInsert, nullptr);
    sqlite3_prepare_v2(mDb, "INSERT OR IGNORE INTO layers(path) VALUES (?1)", -1, &mLayer, nullptr);
    // The same query as AnnotationDb::search() in that release.
    sqlite3_prepare_v2(mDb,
                       "SELECT rowid, bm25(items_fts, 10.0, 1.0, 2.0) AS score, "
                       "snippet(items_fts, -1, '[', ']', '...', 12) FROM items_fts "
                       "WHERE items_fts MATCH ?1 ORDER BY score, rowid LIMIT ?2",
                       -1, &mSearch, nullptr);
  }
  ~V2Baseline() {
    sqlite3_finalize(mInsert);
    sqlite3_finalize(mLayer);
    sqlite3_finalize(mSearch);
    sqlite3_close(mDb);
  }
  void begin() { sqlite3_exec(mDb, "BEGIN", nullptr, nullptr, nullptr); }
  void commit() { sqlite3_exec(mDb, "COMMIT", nullptr, nullptr, nullptr); }
  void add(const Item& it) {
    for (const std::string& layer : {std::string("bench"), it.layer}) {
      sqlite3_bind_text(mLayer, 1, layer.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_step(mLayer);
      sqlite3_reset(mLayer);
    }
    sqlite3_bind_text(mInsert, 1, it.layer.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(mInsert, 2, it.title.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(mInsert, 3, it.text.c_str(), -1, SQLITE_TRANSIENT);
    if (sqlite3_step(mInsert) != SQLITE_DONE)
      throw std::runtime_error(std::string("annotation_db: v2 insert: ") + sqlite3_errmsg(mDb));
    sqlite3_reset(mInsert);
  }
  size_t search(const std::string& query, int limit) {
    sqlite3_bind_text(mSearch, 1, query.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_int(mSearch, 2, limit);
    size_t hits = 0;
    while (sqlite3_step(mSearch) == SQLITE_ROW) ++hits;
    sqlite3_reset(mSearch);
    return hits;
  }

 private:
  sqlite3* mDb = nullptr;
  sqlite3_stmt* mInsert = nullptr;
  sqlite3_stmt* mLayer = nullptr;
  sqlite3_stmt* mSearch = nullptr;
};

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

    // 2. Search time against item count: one database of each schema grown to each size in
    // turn, the same items in both.
    std::ofstream search(res / "annotation_search.csv");
    search << "items,index,query,hits,median_ms,p90_ms\n";
    std::printf("items,index,query,hits,median_ms,p90_ms\n");
    const fs::path file = res / "annotation_bench_search.tadb";
    const fs::path v2_file = res / "annotation_bench_search_v2.tadb";
    removeDb(file);
    removeDb(v2_file);
    std::optional<AnnotationDb> db(std::in_place, file,
                                   AnnotationDbOptions{.read_only = false, .full_sync = false});
    V2Baseline before(v2_file);
    std::mt19937_64 rng(11);
    size_t count = 0;
    const std::vector<std::pair<std::string, std::string>> queries = {
        {"rare-word", word(4000)},
        {"common-word", word(3)},
        {"prefix", word(30).substr(0, 3) + "*"},
        {"phrase", "\"" + word(0) + " " + word(1) + "\""},
        {"OR", word(2000) + " OR " + word(3000)},
        {"japanese-word", japaneseWord(200)},
        {"japanese-phrase", japaneseWord(3) + "の" + japaneseWord(5)},
    };
    // The chart's table: one row per size, one median column per query and index.
    std::ofstream wide(res / "annotation_search_wide.csv");
    wide << "items";
    for (const char* index : {"after", "before"})
      for (const auto& q : queries) wide << ',' << q.first << " (" << index << ")";
    wide << '\n';
    for (size_t target = 1000; target <= size_t(max_items); target *= 10) {
      while (count < target) {
        before.begin();
        db->transaction([&] {
          for (size_t k = 0; k < 1000 && count < target; ++k, ++count) {
            const Item it = benchItem(rng, count);
            db->addItem(it, "bench");
            before.add(it);
          }
        });
        before.commit();
      }
      std::vector<double> medians[2];
      for (int index = 0; index < 2; ++index)
        for (const auto& [name, query] : queries) {
          std::vector<double> ms;
          size_t hits = 0;
          for (int r = 0; r < 30; ++r) {
            const auto start = Clock::now();
            hits = index == 0 ? db->search(query, 50).size() : before.search(query, 50);
            ms.push_back(1000.0 * seconds(start));
          }
          const double median = tessera::bench::percentile(ms, 0.5);
          const double p90 = tessera::bench::percentile(ms, 0.9);
          const char* label = index == 0 ? "after" : "before";
          search << target << ',' << label << ",\"" << name << "\"," << hits << ',' << median << ','
                 << p90 << '\n';
          std::printf("%zu,%s,\"%s\",%zu,%.3f,%.3f\n", target, label, name.c_str(), hits, median,
                      p90);
          std::fflush(stdout);
          medians[index].push_back(hits ? median : NAN);  // nothing found: no point
        }
      wide << target;
      for (const auto& m : medians)
        for (double v : m) wide << ',' << v;
      wide << '\n';
    }
    wide.close();
    search.close();
    db.reset();

    // 3. Opening the largest database, with the page check and without (best of 5).
    std::ofstream opening(res / "annotation_open.csv");
    opening << "items,check,ms\n";
    for (const DbCheck check : {DbCheck::kQuick, DbCheck::kNone, DbCheck::kFull}) {
      double best = 1e300;
      for (int r = 0; r < 5; ++r) {
        const auto start = Clock::now();
        AnnotationDb opened(file, {.read_only = true, .check = check});
        best = std::min(best, 1000.0 * seconds(start));
      }
      const char* name = check == DbCheck::kQuick  ? "quick_check (the default)"
                         : check == DbCheck::kNone ? "none"
                                                   : "integrity_check (tessera-annotate check)";
      opening << count << ",\"" << name << "\"," << best << '\n';
      std::printf("open %zu items, %s: %.1f ms\n", count, name, best);
    }
    opening.close();
    removeDb(res / "annotation_bench_writes.tadb");
    removeDb(file);
    removeDb(v2_file);

    // The chart.
    const std::string w = (res / "annotation_writes.csv").string();
    const std::string q = (res / "annotation_search_wide.csv").string();
    std::ofstream gp(res / "annotation_db.gp");
    gp << "set terminal pngcairo noenhanced size 1500,620 font ',10'\n"
       << "set output '" << (res / "annotation_db.png").string() << "'\n"
       << "set datafile separator ','\nset multiplot layout 1,2\nset grid\n"
       << "set title 'Annotation writes per second (WAL; an item + its point per edit)'\n"
       << "set style fill solid 0.7\nset boxwidth 0.6\nset logscale y\nset yrange [1:*]\n"
       << "set ylabel 'edits per second (log)'\nset xtics rotate by -12\nunset key\n"
       << "plot '" << w << "' skip 1 using 0:4:xtic(1) with boxes lc rgb '#1f77b4', \\\n"
       << "  '' skip 1 using 0:4:(sprintf('%.0f', $4)) with labels offset 0,1\n"
       << "unset logscale y\nset yrange [*:*]\nset xtics norotate\n"
       << "set title 'Search, 50 best: any script (solid), words between spaces (dashed)'\n"
       << "set logscale xy\nset xrange [700:150000]\nset xlabel 'items (log)'\n"
       << "set ylabel 'median query time (ms, log)'\nset key top left font ',8'\n"
       << "plot for [c=2:8] '" << q << "' using 1:c w lp pt 7 lw 2 lc c-1 title columnhead(c), \\\n"
       << "  for [c=9:15] '" << q << "' using 1:c w lp pt 6 lw 1 dt 2 lc c-8 title columnhead(c)\n"
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
