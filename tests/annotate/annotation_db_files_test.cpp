// The annotation database as a file people keep: search in every script, a v2 file migrated,
// damaged files refused with their bytes unchanged (seeded damage of a real database, judged by
// SQLite's own integrity_check through the bare C API), several processes creating one new
// file at once, a read-only folder read by an unprivileged user, and the tool's smaller rules.
// Real processes of tessera-annotate, real files.
#include <tessera/annotate/annotation_db.h>

#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "../../annotate/src/sqlite_statement.h"
#include "../support/process.h"
#include "../support/temp_dir.h"
#include "annotation_test_support.h"

namespace {

using namespace tessera::annotate;
using tessera::test::Process;
using tessera::test::runTool;
using tessera::test::slurp;
using tessera::test::TempDir;
using tessera::test::textItem;
using Kind = AnnotationError::Kind;

std::set<int64_t> hitsOf(AnnotationDb& db, const std::string& query) {
  std::set<int64_t> ids;
  for (const SearchHit& h : db.search(query)) ids.insert(h.item);
  return ids;
}

/// SQLite's own verdict on `file` through the bare C API: "ok" or its first problem.
std::string integrityOf(const std::filesystem::path& file) {
  sqlite3* db = nullptr;
  std::string verdict = "cannot open";
  if (sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    sqlite3_stmt* s = nullptr;
    if (sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &s, nullptr) != SQLITE_OK) {
      verdict = sqlite3_errmsg(db);
    } else {
      const int rc = sqlite3_step(s);
      verdict = rc == SQLITE_ROW ? reinterpret_cast<const char*>(sqlite3_column_text(s, 0))
                                 : sqlite3_errmsg(db);
    }
    sqlite3_finalize(s);
  }
  sqlite3_close(db);
  return verdict;
}

// Japanese and Chinese are written without spaces: a word inside a sentence is found, as are
// emoji, words of a link's address, Greek, Arabic, and Latin as before.
TEST(AnnotationDbFiles, SearchFindsWordsInEveryScript) {
  TempDir dir;
  AnnotationDb db(dir / "a.tadb");
  const int64_t ja =
      db.addItem(textItem("survey", "亀裂の記録", "東京の調査で見つかった亀裂です"), "s");
  const int64_t zh = db.addItem(textItem("survey", "北京故宫的壁画修复"), "s");
  const int64_t rabbit = db.addItem(textItem("survey", "The ears 🐇", "left ear 👍🏽"), "s");
  Item link = textItem("docs", "Report");
  link.kind = ItemKind::kLink;
  link.link_uri = "https://example.org/report.pdf";
  const int64_t report = db.addItem(link, "s");
  const int64_t el = db.addItem(textItem("survey", "Ναός του Ποσειδώνα", "ρωγμή"), "s");
  const int64_t ar = db.addItem(textItem("survey", "الشقوق في العمود"), "s");
  const int64_t th = db.addItem(textItem("survey", "รอยร้าวบนเสา"), "s");
  const int64_t latin = db.addItem(textItem("survey", "Crack in the plaster"), "s");

  for (const char* q : {"東京", "調査", "亀裂", "見つかった", "東京の調査", "亀", "東*"})
    EXPECT_EQ(hitsOf(db, q), (std::set<int64_t>{ja}));
  EXPECT_EQ(hitsOf(db, "title:亀裂"), (std::set<int64_t>{ja}));
  EXPECT_TRUE(hitsOf(db, "京都").empty());      // 京 and 都 apart, never side by side
  EXPECT_TRUE(hitsOf(db, "調査東京").empty());  // both words, not in that order
  EXPECT_EQ(hitsOf(db, "故宫"), (std::set<int64_t>{zh}));
  EXPECT_EQ(hitsOf(db, "壁画 AND 修复"), (std::set<int64_t>{zh}));
  EXPECT_EQ(hitsOf(db, "🐇"), (std::set<int64_t>{rabbit}));
  EXPECT_EQ(hitsOf(db, "👍"), (std::set<int64_t>{rabbit}));  // whatever its skin tone
  EXPECT_EQ(hitsOf(db, "example"), (std::set<int64_t>{report}));
  EXPECT_EQ(hitsOf(db, "\"report.pdf\""), (std::set<int64_t>{report}));
  EXPECT_EQ(hitsOf(db, "Ποσειδώνα"), (std::set<int64_t>{el}));
  EXPECT_EQ(hitsOf(db, "العمود"), (std::set<int64_t>{ar}));
  EXPECT_EQ(hitsOf(db, "บนเสา"), (std::set<int64_t>{th}));
  EXPECT_EQ(hitsOf(db, "crack"), (std::set<int64_t>{latin}));
  EXPECT_EQ(hitsOf(db, "亀裂 OR crack"), (std::set<int64_t>{ja, latin}));
  EXPECT_EQ(hitsOf(db, "亀裂 NOT 東京"), (std::set<int64_t>{}));
  // The snippet marks the word found.
  EXPECT_NE(db.search("調査")[0].snippet.find("[調査]"), std::string::npos)
      << db.search("調査")[0].snippet;
  // The index follows edits of the address.
  Item moved = *db.item(report);
  moved.link_uri = "https://archive.test/scan.e57";
  db.updateItem(moved, 1, "s");
  EXPECT_TRUE(hitsOf(db, "example").empty());
  EXPECT_EQ(hitsOf(db, "archive"), (std::set<int64_t>{report}));
}

// A schema v2 file (its index: words between spaces only) is
// migrated on opening, and its items are found in any script afterwards.
TEST(AnnotationDbFiles, MigratesAVersion2File) {
  TempDir dir;
  const auto file = dir / "v2.tadb";
  {
    sqlite3* raw = nullptr;
    ASSERT_EQ(sqlite3_open(file.c_str(), &raw), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(raw, kSchemaV2Sql, nullptr, nullptr, nullptr), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(raw,
                           "INSERT INTO layers(path) VALUES ('old');"
                           "INSERT INTO items(layer, kind, title, body, author, created_us, "
                           "modified_us, revision) VALUES ('old', 'text', '石柱の亀裂', "
                           "'東京の調査', 'ana', 1, 1, 1);",
                           nullptr, nullptr, nullptr),
              SQLITE_OK);
    sqlite3_close(raw);
  }
  AnnotationDb db(file);
  EXPECT_EQ(db.schemaVersion(), kSchemaVersion);
  EXPECT_EQ(hitsOf(db, "調査"), (std::set<int64_t>{1}));
  EXPECT_EQ(hitsOf(db, "亀裂"), (std::set<int64_t>{1}));
  EXPECT_EQ(db.addItem(textItem("old", "新しい"), "s"), 2);
  EXPECT_EQ(hitsOf(db, "新しい"), (std::set<int64_t>{2}));
}

// A negative schema version is no file of ours.
TEST(AnnotationDbFiles, RefusesANegativeSchemaVersion) {
  TempDir dir;
  const auto file = dir / "odd.tadb";
  { AnnotationDb db(file); }
  sqlite3* raw = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &raw), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(raw, "PRAGMA user_version = -4", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(raw);
  try {
    AnnotationDb db(file);
    ADD_FAILURE() << "a negative schema version was opened";
  } catch (const AnnotationError& e) {
    EXPECT_EQ(int(e.kind()), int(Kind::kNotADatabase)) << e.what();
    EXPECT_NE(std::string(e.what()).find("odd.tadb: has schema version -4"), std::string::npos)
        << e.what();
  }
}

// Seeded damage of a real database (random bytes inside a page, a page zeroed, a page's header
// overwritten), each on a fresh copy: every copy SQLite's integrity_check finds damaged is
// refused by `tessera-annotate add` (exit 1, the file named, the advice to restore a copy) and
// keeps its bytes; copies whose damage lies where no check can see it (inside a text) may be
// written. Without the check at opening, add writes into most of the damaged files.
TEST(AnnotationDbFiles, DamagedFilesAreRefusedAndKeepTheirBytes) {
  TempDir dir;
  const auto good = dir / "good.tadb";
  {
    AnnotationDb db(good);
    db.transaction([&] {
      for (int i = 0; i < 400; ++i)
        db.addItem(textItem("survey/" + std::to_string(i % 7), "item " + std::to_string(i),
                            std::string(size_t(40 + i % 200), char('a' + i % 26))),
                   "s");
    });
  }
  ASSERT_EQ(integrityOf(good), "ok");
  const std::string pristine = slurp(good);
  const size_t page = 4096, pages = pristine.size() / page;
  ASSERT_GT(pages, 20u);
  int damaged = 0, refused = 0;
  for (uint32_t seed = 0; seed < 30; ++seed) {
    std::string bytes = pristine;
    std::mt19937 rng(seed);
    auto below = [&](size_t n) { return size_t(rng() % n); };
    switch (seed % 3) {
      case 0: {  // 64 random bytes anywhere after the file header
        const size_t at = 100 + below(bytes.size() - 164);
        for (size_t i = 0; i < 64; ++i) bytes[at + i] = char(rng());
        break;
      }
      case 1: {  // a page zeroed
        const size_t p = 1 + below(pages - 1);
        std::fill_n(bytes.begin() + std::ptrdiff_t(p * page), page, '\0');
        break;
      }
      default: {  // a page's b-tree header overwritten
        const size_t p = 1 + below(pages - 1);
        for (size_t i = 0; i < 12; ++i) bytes[p * page + i] = char(rng());
      }
    }
    const auto copy = dir / ("copy-" + std::to_string(seed) + ".tadb");
    { std::ofstream(copy, std::ios::binary) << bytes; }
    const bool is_damaged = integrityOf(copy) != "ok";
    const auto log = dir / ("add-" + std::to_string(seed) + ".txt");
    const int code = runTool({"-d", copy.string(), "add", "--layer", "x", "--title", "y"}, log);
    if (!is_damaged) continue;
    ++damaged;
    EXPECT_EQ(code, 1) << "seed " << seed << ": " << slurp(log);
    EXPECT_NE(slurp(log).find(copy.filename().string()), std::string::npos) << slurp(log);
    EXPECT_NE(slurp(log).find("restore"), std::string::npos) << slurp(log);
    EXPECT_TRUE(slurp(copy) == bytes) << "seed " << seed << ": the damaged file was changed";
    refused += code == 1 && slurp(copy) == bytes;
  }
  std::printf("%d of 30 seeded copies damaged, %d refused with their bytes unchanged\n", damaged,
              refused);
  EXPECT_GE(damaged, 15);  // the sweep reaches the b-tree, not only texts
  // The full check on request, and a good file passes both.
  const auto log = dir / "check.txt";
  EXPECT_EQ(runTool({"-d", good.string(), "check"}, log), 0) << slurp(log);
  EXPECT_NE(slurp(log).find("ok"), std::string::npos);
}

// Several processes creating the same new database at once all succeed (the switch to WAL is
// retried while another holds the new file), 20 times over.
TEST(AnnotationDbFiles, ProcessesCreatingOneFileAtOnceAllSucceed) {
  TempDir dir;
  for (int round = 0; round < 20; ++round) {
    const auto file = dir / ("race-" + std::to_string(round) + ".tadb");
    std::vector<std::unique_ptr<Process>> writers;
    for (int k = 0; k < 6; ++k)
      writers.push_back(std::make_unique<Process>(
          std::vector<std::string>{TESSERA_ANNOTATE_TOOL, "-d", file.string(), "add", "--layer",
                                   "l", "--title", "writer " + std::to_string(k)},
          dir / ("w-" + std::to_string(round) + "-" + std::to_string(k) + ".txt")));
    for (int k = 0; k < 6; ++k) {
      const auto code = writers[size_t(k)]->wait(60.0);
      EXPECT_EQ(code.value_or(-1), 0)
          << "round " << round << ": "
          << slurp(dir / ("w-" + std::to_string(round) + "-" + std::to_string(k) + ".txt"));
    }
    AnnotationDb db(file, {.read_only = true});
    EXPECT_EQ(db.items().size(), 6u) << "round " << round;
  }
}

// A database in a folder the reader cannot write (as an unprivileged user: root ignores
// permissions) is listed, searched, shown, checked and exported, and nothing is left beside
// it; an edit is refused with the reason.
TEST(AnnotationDbFiles, AReadOnlyFolderCanBeRead) {
  TempDir dir;
  const auto shelf = dir / "shelf";
  std::filesystem::create_directory(shelf);
  const auto file = shelf / "notes.tadb";
  {
    AnnotationDb db(file);
    db.addItem(textItem("a", "東京の亀裂"), "s");
    db.addItem(textItem("a", "plaster"), "s");
  }
  // Everyone may enter the test's folders; only the owner may write the shelf.
  chmod(dir.path().c_str(), 0755);
  chmod(shelf.c_str(), 0555);
  chmod(file.c_str(), 0444);
  const auto out = dir / "out";
  std::filesystem::create_directory(out);
  chmod(out.c_str(), 0777);
  std::vector<std::string> as_reader;
  if (geteuid() == 0)
    as_reader = {"/usr/bin/setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"};
  auto run = [&](std::vector<std::string> args, const std::string& name) {
    std::vector<std::string> argv = as_reader;
    argv.push_back(TESSERA_ANNOTATE_TOOL);
    argv.insert(argv.end(), args.begin(), args.end());
    const auto log = dir / (name + ".txt");
    Process p(argv, log);
    const int code = p.wait(60.0).value_or(-1000);  // before the log is read
    return std::make_pair(code, slurp(log));
  };
  if (!as_reader.empty() && !std::filesystem::exists(as_reader[0]))
    GTEST_SKIP() << "setpriv is missing: cannot read as another user";
  const std::string db = file.string();
  auto [list_code, list] = run({"-d", db, "list"}, "list");
  EXPECT_EQ(list_code, 0) << list;
  EXPECT_NE(list.find("東京の亀裂"), std::string::npos) << list;
  auto [search_code, found] = run({"-d", db, "search", "亀裂"}, "search");
  EXPECT_EQ(search_code, 0) << found;
  EXPECT_NE(found.find("[亀裂]"), std::string::npos) << found;
  EXPECT_EQ(run({"-d", db, "show", "2"}, "show").first, 0);
  EXPECT_EQ(run({"-d", db, "check"}, "check").first, 0);
  EXPECT_EQ(run({"-d", db, "layers"}, "layers").first, 0);
  const auto json = out / "notes.json";
  auto [export_code, exported] =
      run({"-d", db, "export", "--format", "json", "-o", json.string()}, "export");
  EXPECT_EQ(export_code, 0) << exported;
  EXPECT_NE(slurp(json).find("plaster"), std::string::npos);
  auto [add_code, refused] = run({"-d", db, "add", "--layer", "a", "--title", "new"}, "add");
  EXPECT_NE(add_code, 0);
  EXPECT_NE(refused.find("read-only"), std::string::npos) << refused;
  EXPECT_FALSE(std::filesystem::exists(db + "-wal"));
  EXPECT_FALSE(std::filesystem::exists(db + "-shm"));
  chmod(shelf.c_str(), 0755);  // so the temporary folder can be removed
}

// The tool's smaller rules: a number item needs its number, an empty file is refused by the
// readers as a missing one is.
TEST(AnnotationDbFiles, ToolRefusesWhatItCannotDo) {
  TempDir dir;
  const std::string db = (dir / "t.tadb").string();
  const auto log = dir / "log.txt";
  EXPECT_EQ(runTool({"-d", db, "add", "--layer", "a", "--title", "n", "--kind", "number"}, log), 2);
  EXPECT_NE(slurp(log).find("--number"), std::string::npos) << slurp(log);
  EXPECT_EQ(runTool({"-d", db, "add", "--layer", "a", "--title", "t", "--number", "3"}, log), 2);
  EXPECT_FALSE(std::filesystem::exists(db));
  const auto empty = dir / "empty.tadb";
  { std::ofstream touch(empty); }
  for (const char* sub : {"list", "export", "layers"}) {
    std::vector<std::string> args{"-d", empty.string(), sub};
    if (std::string(sub) == "export")
      args.insert(args.end(), {"--format", "csv", "-o", (dir / "x.csv").string()});
    EXPECT_EQ(runTool(args, log), 1) << sub;
    EXPECT_NE(slurp(log).find("empty.tadb: is empty"), std::string::npos) << slurp(log);
  }
  EXPECT_EQ(std::filesystem::file_size(empty), 0u);
}

}  // namespace

namespace {

// Texts longer than a command line come from a file or standard input; numbers print as
// written, the same in list, show and place.
TEST(AnnotationDbFiles, ToolReadsTextFilesAndPrintsNumbersAsWritten) {
  TempDir dir;
  const std::string db = (dir / "t.tadb").string();
  const auto log = dir / "log.txt";
  std::string long_text;
  for (int i = 0; i < 20000; ++i) long_text += "調査の記録 " + std::to_string(i) + "\n";
  tessera::test::writeText(dir / "long.txt", long_text);
  EXPECT_EQ(runTool({"-d", db, "add", "--layer", "a", "--title", "long", "--text-file",
                     (dir / "long.txt").string()},
                    log),
            0)
      << slurp(log);
  EXPECT_EQ(
      runTool({"-d", db, "add", "--layer", "a", "--title", "n", "--kind", "number", "--number",
               "0.1", "--unit", "m", "--at", "0.1,0.2,1e-07", "--radius", "0.25", "--eye", "1,2,3"},
              log),
      0)
      << slurp(log);
  EXPECT_EQ(runTool({"-d", db, "add", "--layer", "a", "--title", "t", "--text-file",
                     (dir / "missing.txt").string()},
                    log),
            2);
  {
    AnnotationDb read(db, {.read_only = true});
    EXPECT_EQ(read.item(1)->text, long_text);
  }
  const auto listed = dir / "list.txt", shown = dir / "show.txt", place = dir / "place.txt";
  EXPECT_EQ(runTool({"-d", db, "list"}, listed), 0);
  EXPECT_EQ(runTool({"-d", db, "show", "2"}, shown), 0);
  EXPECT_EQ(runTool({"-d", db, "place", "1"}, place), 0);
  for (const auto& out : {listed, shown, place})
    EXPECT_NE(slurp(out).find("at 0.1,0.2,1e-07"), std::string::npos) << slurp(out);
  EXPECT_NE(slurp(listed).find("n = 0.1 m"), std::string::npos) << slurp(listed);
  EXPECT_NE(slurp(shown).find("n = 0.1 m"), std::string::npos) << slurp(shown);
  EXPECT_NE(slurp(place).find("radius 0.25"), std::string::npos) << slurp(place);
  // A hit is one line, whatever line breaks its text holds.
  const auto found = dir / "found.txt";
  EXPECT_EQ(runTool({"-d", db, "search", "記録"}, found), 0);
  const std::string hits = slurp(found);
  EXPECT_EQ(std::count(hits.begin(), hits.end(), '\n'), 1) << hits;
}

}  // namespace

namespace {

// Errors say what a statement was for, never its SQL.
TEST(AnnotationDbFiles, ErrorsNameAStatementsPurpose) {
  using tessera::annotate::detail::purposeOf;
  EXPECT_EQ(purposeOf("SELECT id, title FROM items WHERE layer = ?1"), "reading items");
  EXPECT_EQ(purposeOf("INSERT OR IGNORE INTO layers(path) VALUES (?1)"), "adding to layers");
  EXPECT_EQ(purposeOf("UPDATE items SET title = ?1"), "changing items");
  EXPECT_EQ(purposeOf("DELETE FROM attachments WHERE item = ?1"), "removing from attachments");
  EXPECT_EQ(purposeOf("PRAGMA journal_mode = WAL"), "PRAGMA journal_mode");
  EXPECT_EQ(purposeOf("BEGIN IMMEDIATE"), "a transaction (BEGIN)");
  EXPECT_EQ(purposeOf(""), "an empty statement");
  TempDir dir;
  AnnotationDb db(dir / "a.tadb");
  db.addItem(textItem("a", "t"), "s");
  try {
    AnnotationDb ro(dir / "a.tadb", {.read_only = true});
    ro.addItem(textItem("a", "u"), "s");
    ADD_FAILURE() << "a write through a read-only handle";
  } catch (const AnnotationError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find("INSERT"), std::string::npos) << what;
    EXPECT_EQ(what.find("SELECT"), std::string::npos) << what;
    EXPECT_NE(what.find("a.tadb"), std::string::npos) << what;
  }
}

}  // namespace

namespace {

// Lasso selections and measurements are listed as what they are, with their place; a selection
// no item hangs at is listed too.
TEST(AnnotationDbFiles, SelectionsAndMeasurementsAreListedAsWhatTheyAre) {
  TempDir dir;
  const auto file = dir / "s.tadb";
  {
    AnnotationDb db(file);
    Place region;
    region.kind = PlaceKind::kSelection;
    region.model = "bunny";
    region.selection_id = kSelectionBlob;
    region.selection = std::vector<uint8_t>(120, 7);
    db.addPlace(region);
    Place measured = region;
    measured.model = "scene";
    measured.selection_id = kMeasurementBlob;
    measured.position = {0.5, 0.25, 2};
    Item distance = textItem("measurements", "ear to ear");
    distance.kind = ItemKind::kNumber;
    distance.number = 0.0734;
    distance.unit = "m";
    db.attach(db.addItem(distance, "s"), db.addPlace(measured));
  }
  const auto log = dir / "list.txt";
  ASSERT_EQ(runTool({"-d", file.string(), "list"}, log), 0) << slurp(log);
  const std::string listed = slurp(log);
  EXPECT_NE(listed.find("ear to ear = 0.0734 m"), std::string::npos) << listed;
  EXPECT_NE(listed.find("(a measurement at 0.5,0.25,2"), std::string::npos) << listed;
  EXPECT_NE(listed.find("place 1\tselection on bunny (a selected region, 120 bytes)"),
            std::string::npos)
      << listed;
  EXPECT_EQ(listed.find("scene.SelectionPayload"), std::string::npos) << listed;
}

}  // namespace
