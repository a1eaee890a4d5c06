#include <tessera/annotate/annotation_db.h>

#include <algorithm>
#include <cassert>
#include <cctype>
#include <chrono>
#include <cmath>
#include <thread>
#include <utility>

#include <glm/geometric.hpp>

#include <tessera/core/check.h>
#include <tessera/sync/view.h>

#include "fts_tokenizer.h"
#include "sqlite_statement.h"
#include "utf8.h"

namespace tessera::annotate {

using detail::Statement;

// The first release's schema: one table of text notes, a layer name and an optional point,
// times in seconds. Kept verbatim so tests can write the files that release wrote.
const char* const kSchemaV1Sql = R"sql(
CREATE TABLE notes(
  id INTEGER PRIMARY KEY,
  layer TEXT NOT NULL DEFAULT '',
  title TEXT NOT NULL,
  body TEXT NOT NULL DEFAULT '',
  model TEXT,
  x REAL, y REAL, z REAL,
  author TEXT NOT NULL DEFAULT '',
  created INTEGER NOT NULL
);
PRAGMA user_version = 1;
)sql";

// Schema v2. Items and places take AUTOINCREMENT ids: an id is never reused after a removal,
// because documents outside the database link to items by id (Bettio et al. 3.4: links from a
// web page into the viewer). The full-text index is an FTS5 external-content table over
// items(title, body, layer), kept in step by triggers, so the text is stored once.
const char* const kSchemaV2Sql = R"sql(
CREATE TABLE meta(key TEXT PRIMARY KEY NOT NULL, value ANY NOT NULL) STRICT, WITHOUT ROWID;
CREATE TABLE layers(
  path TEXT PRIMARY KEY NOT NULL,
  visible INTEGER NOT NULL DEFAULT 1 CHECK (visible IN (0, 1))
) STRICT, WITHOUT ROWID;
CREATE TABLE items(
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  layer TEXT NOT NULL REFERENCES layers(path),
  kind TEXT NOT NULL CHECK (kind IN ('text', 'number', 'image', 'link')),
  title TEXT NOT NULL,
  body TEXT NOT NULL DEFAULT '',
  number REAL NOT NULL DEFAULT 0,
  unit TEXT NOT NULL DEFAULT '',
  mime TEXT NOT NULL DEFAULT '',
  path TEXT NOT NULL DEFAULT '',
  data BLOB,
  link_item INTEGER REFERENCES items(id),
  link_uri TEXT NOT NULL DEFAULT '',
  author TEXT NOT NULL,
  created_us INTEGER NOT NULL,
  modified_us INTEGER NOT NULL,
  revision INTEGER NOT NULL CHECK (revision >= 1)
) STRICT;
CREATE INDEX items_layer ON items(layer);
CREATE INDEX items_link ON items(link_item);
CREATE TABLE places(
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  kind TEXT NOT NULL CHECK (kind IN ('selection', 'point', 'hotspot')),
  model TEXT NOT NULL,
  x REAL NOT NULL DEFAULT 0, y REAL NOT NULL DEFAULT 0, z REAL NOT NULL DEFAULT 0,
  radius REAL NOT NULL DEFAULT 0,
  has_view INTEGER NOT NULL DEFAULT 0,
  eye_x REAL NOT NULL DEFAULT 0, eye_y REAL NOT NULL DEFAULT 0, eye_z REAL NOT NULL DEFAULT 0,
  target_x REAL NOT NULL DEFAULT 0, target_y REAL NOT NULL DEFAULT 0,
  target_z REAL NOT NULL DEFAULT 0,
  up_x REAL NOT NULL DEFAULT 0, up_y REAL NOT NULL DEFAULT 0, up_z REAL NOT NULL DEFAULT 0,
  fovy_deg REAL NOT NULL DEFAULT 0,
  selection_id TEXT NOT NULL DEFAULT '',
  selection BLOB
) STRICT;
CREATE INDEX places_model ON places(model, x);
CREATE TABLE attachments(
  item INTEGER NOT NULL REFERENCES items(id) ON DELETE CASCADE,
  place INTEGER NOT NULL REFERENCES places(id) ON DELETE CASCADE,
  PRIMARY KEY (item, place)
) STRICT, WITHOUT ROWID;
CREATE INDEX attachments_place ON attachments(place, item);
CREATE VIRTUAL TABLE items_fts USING fts5(
  title, body, layer, content='items', content_rowid='id',
  tokenize='unicode61 remove_diacritics 2', prefix='2 3');
CREATE TRIGGER items_fts_insert AFTER INSERT ON items BEGIN
  INSERT INTO items_fts(rowid, title, body, layer) VALUES (new.id, new.title, new.body, new.layer);
END;
CREATE TRIGGER items_fts_delete AFTER DELETE ON items BEGIN
  INSERT INTO items_fts(items_fts, rowid, title, body, layer)
  VALUES ('delete', old.id, old.title, old.body, old.layer);
END;
CREATE TRIGGER items_fts_update AFTER UPDATE OF title, body, layer ON items BEGIN
  INSERT INTO items_fts(items_fts, rowid, title, body, layer)
  VALUES ('delete', old.id, old.title, old.body, old.layer);
  INSERT INTO items_fts(rowid, title, body, layer) VALUES (new.id, new.title, new.body, new.layer);
END;
PRAGMA user_version = 2;
)sql";

namespace {

// Schema v3: the full-text index in any script (fts_tokenizer.h) and over links' addresses
// too. The v2 index and its triggers are replaced and the new index built from the items.
const char* const kSchemaV3Sql = R"sql(
DROP TRIGGER items_fts_insert;
DROP TRIGGER items_fts_delete;
DROP TRIGGER items_fts_update;
DROP TABLE items_fts;
CREATE VIRTUAL TABLE items_fts USING fts5(
  title, body, layer, link, content='items_fts_source', content_rowid='id',
  tokenize='tessera', prefix='2 3');
CREATE VIEW items_fts_source AS SELECT id, title, body, layer, link_uri AS link FROM items;
CREATE TRIGGER items_fts_insert AFTER INSERT ON items BEGIN
  INSERT INTO items_fts(rowid, title, body, layer, link)
  VALUES (new.id, new.title, new.body, new.layer, new.link_uri);
END;
CREATE TRIGGER items_fts_delete AFTER DELETE ON items BEGIN
  INSERT INTO items_fts(items_fts, rowid, title, body, layer, link)
  VALUES ('delete', old.id, old.title, old.body, old.layer, old.link_uri);
END;
CREATE TRIGGER items_fts_update AFTER UPDATE OF title, body, layer, link_uri ON items BEGIN
  INSERT INTO items_fts(items_fts, rowid, title, body, layer, link)
  VALUES ('delete', old.id, old.title, old.body, old.layer, old.link_uri);
  INSERT INTO items_fts(rowid, title, body, layer, link)
  VALUES (new.id, new.title, new.body, new.layer, new.link_uri);
END;
INSERT INTO items_fts(items_fts) VALUES ('rebuild');
PRAGMA user_version = 3;
)sql";

/// Tries of the switch to WAL while another process holds the new file (5 to 24 ms apart: about
/// the busy timeout's 5 s).
constexpr int kWalSwitchAttempts = 350;

constexpr const char* kItemColumns =
    "id, layer, kind, title, body, number, unit, mime, path, data, link_item, link_uri, author, "
    "created_us, modified_us, revision";
constexpr const char* kPlaceColumns =
    "id, kind, model, x, y, z, radius, has_view, eye_x, eye_y, eye_z, target_x, target_y, "
    "target_z, up_x, up_y, up_z, fovy_deg, selection_id, selection";

int64_t nowMicroseconds() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string prefix(const std::filesystem::path& file) {
  return "AnnotationDb: " + file.string() + ": ";
}

Item readItem(const Statement& s) {
  Item it;
  it.id = s.integer(0);
  it.layer = s.text(1);
  it.kind = parseItemKind(s.text(2)).value_or(ItemKind::kText);
  it.title = s.text(3);
  it.text = s.text(4);
  it.number = s.real(5);
  it.unit = s.text(6);
  it.mime = s.text(7);
  it.path = s.text(8);
  it.data = s.blob(9);
  it.link_item = s.isNull(10) ? 0 : s.integer(10);
  it.link_uri = s.text(11);
  it.author = s.text(12);
  it.created_us = s.integer(13);
  it.modified_us = s.integer(14);
  it.revision = s.integer(15);
  return it;
}

glm::dvec3 readVec(const Statement& s, int c) {
  return {s.real(c), s.real(c + 1), s.real(c + 2)};
}

Place readPlace(const Statement& s) {
  Place p;
  p.id = s.integer(0);
  p.kind = parsePlaceKind(s.text(1)).value_or(PlaceKind::kPoint);
  p.model = s.text(2);
  p.position = readVec(s, 3);
  p.radius = s.real(6);
  if (s.integer(7)) p.view = StoredView{readVec(s, 8), readVec(s, 11), readVec(s, 14), s.real(17)};
  p.selection_id = s.text(18);
  p.selection = s.blob(19);
  return p;
}

std::vector<int64_t> ids(Statement& s) {
  std::vector<int64_t> out;
  while (s.step()) out.push_back(s.integer(0));
  return out;
}

/// The layer's segments, or the reason `path` is not a layer path.
std::string layerPathProblem(const std::string& path) {
  if (path.empty()) return "is empty";
  if (path.size() > kMaxLayerPathBytes)
    return "is longer than " + std::to_string(kMaxLayerPathBytes) + " bytes";
  if (!detail::validUtf8(path)) return "is not valid UTF-8";
  int levels = 1;
  for (size_t i = 0; i < path.size(); ++i) {
    const auto c = static_cast<unsigned char>(path[i]);
    if (c < 0x20 || c == 0x7f) return "holds a control character";
    if (c == '/') {
      ++levels;
      if (i == 0 || i + 1 == path.size() || path[i + 1] == '/') return "has an empty level";
    }
  }
  if (levels > 16) return "has more than 16 levels";
  return {};
}

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

bool inRange(const glm::dvec3& v) {
  return finite(v) && std::abs(v.x) <= kMaxCoordinate && std::abs(v.y) <= kMaxCoordinate &&
         std::abs(v.z) <= kMaxCoordinate;
}

}  // namespace

namespace detail {

std::string purposeOf(std::string_view sql) {
  // The words of the SQL, upper-cased keywords as they are, up to the table it touches.
  std::vector<std::string> words;
  std::string word;
  for (size_t i = 0; i <= sql.size() && words.size() < 12; ++i) {
    const char c = i < sql.size() ? sql[i] : ' ';
    if (std::isalnum(static_cast<unsigned char>(c)) || c == '_') {
      word += c;
    } else if (!word.empty()) {
      words.push_back(word);
      word.clear();
    }
  }
  if (words.empty()) return "an empty statement";
  auto upper = [](std::string w) {
    for (char& ch : w) ch = char(std::toupper(static_cast<unsigned char>(ch)));
    return w;
  };
  auto after = [&](const char* keyword) -> std::string {
    for (size_t i = 0; i + 1 < words.size(); ++i)
      if (upper(words[i]) == keyword) return words[i + 1];
    return "the database";
  };
  const std::string first = upper(words[0]);
  if (first == "SELECT" || first == "WITH") return "reading " + after("FROM");
  if (first == "INSERT" || first == "REPLACE") return "adding to " + after("INTO");
  if (first == "UPDATE")
    return words.size() > 1 ? "changing " + words[1] : std::string("changing the database");
  if (first == "DELETE") return "removing from " + after("FROM");
  if (first == "PRAGMA") return "PRAGMA " + (words.size() > 1 ? words[1] : std::string());
  if (first == "BEGIN" || first == "COMMIT" || first == "ROLLBACK")
    return "a transaction (" + first + ")";
  if (first == "CREATE" || first == "DROP" || first == "ALTER") return "changing the schema";
  return first;
}

void throwSqlite(sqlite3* db, int rc, const std::filesystem::path& file, const std::string& what) {
  using Kind = AnnotationError::Kind;
  const std::string reason = db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  Kind kind = Kind::kIo;
  std::string hint;
  switch (rc & 0xff) {
    case SQLITE_NOTADB:
      kind = Kind::kNotADatabase;
      hint = " (not an SQLite database, or its header is damaged)";
      break;
    case SQLITE_CORRUPT:
      kind = Kind::kCorrupt;
      hint = " (the file is damaged; restore it from a copy)";
      break;
    case SQLITE_READONLY:
      kind = Kind::kReadOnly;
      hint = " (opened read-only, or the file or its folder is not writable)";
      break;
    case SQLITE_CANTOPEN:
    case SQLITE_PERM:
    case SQLITE_AUTH:
      kind = Kind::kCannotOpen;
      hint = " (WAL mode needs the folder writable for FILE-wal and FILE-shm)";
      break;
    case SQLITE_CONSTRAINT:
    case SQLITE_TOOBIG:
    case SQLITE_MISMATCH:
    case SQLITE_RANGE:
      kind = Kind::kBadInput;
      break;
    default:
      break;
  }
  throw AnnotationError(kind, prefix(file) + what + ": " + reason + hint);
}

}  // namespace detail

const char* toString(ItemKind kind) {
  switch (kind) {
    case ItemKind::kText:
      return "text";
    case ItemKind::kNumber:
      return "number";
    case ItemKind::kImage:
      return "image";
    case ItemKind::kLink:
      return "link";
  }
  return "text";
}

const char* toString(PlaceKind kind) {
  switch (kind) {
    case PlaceKind::kSelection:
      return "selection";
    case PlaceKind::kPoint:
      return "point";
    case PlaceKind::kHotSpot:
      return "hotspot";
  }
  return "point";
}

std::optional<ItemKind> parseItemKind(const std::string& text) {
  for (ItemKind k : {ItemKind::kText, ItemKind::kNumber, ItemKind::kImage, ItemKind::kLink})
    if (text == toString(k)) return k;
  return std::nullopt;
}

std::optional<PlaceKind> parsePlaceKind(const std::string& text) {
  for (PlaceKind k : {PlaceKind::kSelection, PlaceKind::kPoint, PlaceKind::kHotSpot})
    if (text == toString(k)) return k;
  return std::nullopt;
}

namespace {

/// `file` as an SQLite URI opened immutable (read without locks or a shared index).
std::string immutableUri(const std::filesystem::path& file) {
  const std::string path = std::filesystem::absolute(file).string();
  std::string uri = "file:";
  static const char* kHex = "0123456789ABCDEF";
  for (unsigned char c : path) {
    if (c == '%' || c == '?' || c == '#' || c < 0x21 || c >= 0x7F) {
      uri += '%';
      uri += kHex[c >> 4];
      uri += kHex[c & 15];
    } else {
      uri += char(c);
    }
  }
  return uri + "?immutable=1";
}

}  // namespace

AnnotationDb::AnnotationDb(const std::filesystem::path& file, AnnotationDbOptions options)
    : mFile(file) {
  using Kind = AnnotationError::Kind;
  std::error_code ec;
  const bool memory = file == ":memory:";
  const bool exists = memory || std::filesystem::exists(file, ec);
  if (options.read_only && !exists)
    throw AnnotationError(Kind::kCannotOpen, prefix(file) + "does not exist");
  if (exists && std::filesystem::is_directory(file, ec))
    throw AnnotationError(Kind::kCannotOpen, prefix(file) + "is a folder, not a database file");
  const int flags =
      (options.read_only ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE) |
      SQLITE_OPEN_NOMUTEX;
  auto open = [&](const std::string& name, int how) {
    const int rc = sqlite3_open_v2(name.c_str(), &mDb, how, nullptr);
    if (rc != SQLITE_OK) {
      // The handle exists even on failure (for its message) and must be closed.
      const std::string reason = mDb ? sqlite3_errmsg(mDb) : sqlite3_errstr(rc);
      sqlite3_close(std::exchange(mDb, nullptr));
      throw AnnotationError(rc == SQLITE_NOTADB ? Kind::kNotADatabase : Kind::kCannotOpen,
                            prefix(file) + "cannot open: " + reason);
    }
    sqlite3_extended_result_codes(mDb, 1);
    sqlite3_busy_timeout(mDb, 5000);
    // Defensive mode: SQL cannot corrupt the file on purpose (writable_schema, raw page edits).
    sqlite3_db_config(mDb, SQLITE_DBCONFIG_DEFENSIVE, 1, nullptr);
    if (const int trc = detail::registerTokenizer(mDb); trc != SQLITE_OK) {
      sqlite3_close(std::exchange(mDb, nullptr));
      throw AnnotationError(Kind::kIo, prefix(file) + "cannot register the full-text tokenizer: " +
                                           sqlite3_errstr(trc));
    }
  };
  open(file.string(), flags);
  try {
    // The first read of the header: NOTADB or CORRUPT surface here, before anything is written.
    auto countObjects = [&] {
      Statement probe(mDb, mFile, "SELECT count(*) FROM sqlite_schema");
      probe.step();
      return probe.integer(0);
    };  // finalized: an open statement would hold a read transaction
    int64_t objects = 0;
    try {
      objects = countObjects();
    } catch (const AnnotationError& e) {
      // A WAL file read where its FILE-shm cannot be made (a read-only folder or medium, no
      // writer at work: a writer would have left FILE-wal and FILE-shm there): read it as
      // immutable, without the shared index.
      if (!options.read_only && !memory && e.kind() == Kind::kReadOnly)
        throw AnnotationError(Kind::kReadOnly,
                              prefix(file) +
                                  "cannot be written: the file or its folder is read-only (list, "
                                  "search, show and export still read it)");
      if (!options.read_only || memory || e.kind() != Kind::kReadOnly ||
          std::filesystem::exists(file.string() + "-wal", ec) ||
          std::filesystem::exists(file.string() + "-shm", ec))
        throw;
      sqlite3_close_v2(std::exchange(mDb, nullptr));
      open(immutableUri(file), flags | SQLITE_OPEN_URI);
      objects = countObjects();
    }
    // Damage is refused before anything is written: a write into a damaged b-tree spreads the
    // damage and buries the copy a restore needs. quick_check reads every page (O(pages), 0.3 s
    // at 10^5 items); integrity_check also matches every index to its table.
    if (!memory && objects > 0 && options.check != DbCheck::kNone) {
      Statement check(
          mDb, mFile,
          options.check == DbCheck::kFull ? "PRAGMA integrity_check(8)" : "PRAGMA quick_check(8)");
      std::string problems;
      while (check.step()) {
        const std::string line = check.text(0);
        if (line == "ok") break;
        problems += (problems.empty() ? "" : "; ") + line;
      }
      if (!problems.empty())
        throw AnnotationError(Kind::kCorrupt,
                              prefix(file) + "is damaged (" + problems.substr(0, 300) +
                                  "); nothing was written to it: restore it from a copy");
    }
    const int version = schemaVersion();
    if (version < 0)
      throw AnnotationError(Kind::kNotADatabase,
                            prefix(file) + "has schema version " + std::to_string(version) +
                                ", which no Tessera writes (damaged, or another program's file)");
    if (version > kSchemaVersion)
      throw AnnotationError(Kind::kNewerSchema,
                            prefix(file) + "has schema version " + std::to_string(version) +
                                "; this build reads versions up to " +
                                std::to_string(kSchemaVersion) + " (use a newer Tessera)");
    if (version == 0 && objects > 0)
      throw AnnotationError(Kind::kNotADatabase, prefix(file) +
                                                     "is an SQLite database but not an annotation "
                                                     "database (no schema version, " +
                                                     std::to_string(objects) +
                                                     " tables or indexes)");

    if (!options.read_only && !memory) {
      // WAL: readers (the exporter, a second tool) never block the master's writes, and a
      // commit is one append to the log. It must be set outside a transaction.
      // The switch needs the file to itself: a process creating the same new file at the same
      // moment may hold it, and SQLite answers SQLITE_BUSY at once (no busy handler there), so
      // the switch is retried for as long as the busy timeout.
      for (int attempt = 0;; ++attempt) {
        sqlite3_stmt* raw = nullptr;
        int wal_rc = sqlite3_prepare_v2(mDb, "PRAGMA journal_mode = WAL", -1, &raw, nullptr);
        std::string mode;
        if (wal_rc == SQLITE_OK) {
          wal_rc = sqlite3_step(raw);
          if (wal_rc == SQLITE_ROW) {
            mode = reinterpret_cast<const char*>(sqlite3_column_text(raw, 0));
            wal_rc = SQLITE_OK;
          }
        }
        sqlite3_finalize(raw);
        if (wal_rc == SQLITE_OK && mode == "wal") break;
        if ((wal_rc & 0xff) == SQLITE_BUSY && attempt < kWalSwitchAttempts) {
          std::this_thread::sleep_for(std::chrono::milliseconds(5 + attempt % 20));
          continue;
        }
        if (wal_rc != SQLITE_OK) fail(wal_rc, "switching to WAL journal mode");
        throw AnnotationError(Kind::kIo, prefix(file) + "cannot switch to WAL journal mode");
      }
    }
    exec(options.full_sync ? "PRAGMA synchronous = FULL" : "PRAGMA synchronous = NORMAL");
    exec("PRAGMA foreign_keys = ON");

    if (version < kSchemaVersion) {
      if (options.read_only)
        throw AnnotationError(Kind::kReadOnly,
                              prefix(file) + "has schema version " + std::to_string(version) +
                                  " and must be migrated to " + std::to_string(kSchemaVersion) +
                                  "; open it read-write once");
      transaction([&] {
        // Another process may have created or migrated it while this one waited for the lock.
        const int now = schemaVersion();
        if (now == 0) exec(kSchemaV2Sql);
        if (now == 1) migrate(1);
        if (now < 3) exec(kSchemaV3Sql);
      });
    }
  } catch (...) {
    sqlite3_close_v2(std::exchange(mDb, nullptr));
    throw;
  }
}

AnnotationDb::~AnnotationDb() {
  if (mDb) sqlite3_close_v2(mDb);
}

AnnotationDb::AnnotationDb(AnnotationDb&& other) noexcept
    : mFile(std::move(other.mFile)),
      mDb(std::exchange(other.mDb, nullptr)),
      mDepth(std::exchange(other.mDepth, 0)) {}

AnnotationDb& AnnotationDb::operator=(AnnotationDb&& other) noexcept {
  if (this != &other) {
    if (mDb) sqlite3_close_v2(mDb);
    mFile = std::move(other.mFile);
    mDb = std::exchange(other.mDb, nullptr);
    mDepth = std::exchange(other.mDepth, 0);
  }
  return *this;
}

void AnnotationDb::exec(const char* sql) {
  char* message = nullptr;
  const int rc = sqlite3_exec(mDb, sql, nullptr, nullptr, &message);
  if (rc != SQLITE_OK) {
    sqlite3_free(message);
    fail(rc, detail::purposeOf(sql));
  }
}

void AnnotationDb::fail(int rc, const std::string& what) {
  detail::throwSqlite(mDb, rc, mFile, what);
}

int AnnotationDb::schemaVersion() {
  Statement s(mDb, mFile, "PRAGMA user_version");
  s.step();
  return int(s.integer(0));
}

void AnnotationDb::begin() {
  TESSERA_CHECK(mDb, "AnnotationDb: used after a move");
  // IMMEDIATE takes the write lock up front, so two writers queue (busy timeout) instead of
  // failing half-way with SQLITE_BUSY on their first write.
  if (mDepth == 0) exec("BEGIN IMMEDIATE");
  ++mDepth;
}

void AnnotationDb::commit() {
  assert(mDepth > 0);
  if (--mDepth > 0) return;
  try {
    exec("COMMIT");  // with synchronous=FULL, returns after the WAL is on the disk
  } catch (...) {
    sqlite3_exec(mDb, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

void AnnotationDb::rollback() {
  assert(mDepth > 0);
  if (--mDepth > 0) return;
  sqlite3_exec(mDb, "ROLLBACK", nullptr, nullptr, nullptr);
}

// v1 -> v2: each note becomes a text item in its layer (empty or malformed layer names are
// cleaned: empty levels dropped, "unfiled" when nothing is left), its point a point place
// attached to it; seconds become microseconds, the author "unknown" when the note had none.
void AnnotationDb::migrate(int from) {
  assert(from == 1);
  (void)from;
  exec("ALTER TABLE notes RENAME TO notes_v1");
  exec(kSchemaV2Sql);
  Statement notes(mDb, mFile,
                  "SELECT id, layer, title, body, model, x, y, z, author, created FROM notes_v1 "
                  "ORDER BY id");
  Statement insert(mDb, mFile,
                   "INSERT INTO items(id, layer, kind, title, body, author, created_us, "
                   "modified_us, revision) VALUES (?1, ?2, 'text', ?3, ?4, ?5, ?6, ?6, 1)");
  Statement place(mDb, mFile,
                  "INSERT INTO places(kind, model, x, y, z) VALUES ('point', ?1, ?2, ?3, ?4)");
  Statement attachment(mDb, mFile, "INSERT INTO attachments(item, place) VALUES (?1, ?2)");
  while (notes.step()) {
    const std::string raw = notes.text(1);
    std::string layer;
    for (size_t i = 0, n = 0; i <= raw.size(); i = n + 1) {
      n = std::min(raw.find('/', i), raw.size());
      if (n > i) layer += (layer.empty() ? "" : "/") + raw.substr(i, n - i);
    }
    if (!layerPathProblem(layer).empty()) layer = "unfiled";
    ensureLayer(layer);
    const std::string author = notes.text(8).empty() ? "unknown" : notes.text(8);
    std::string title = notes.text(2).empty() ? "(untitled)" : notes.text(2);
    insert.bind(1, notes.integer(0)).bind(2, layer).bind(3, title).bind(4, notes.text(3));
    insert.bind(5, author).bind(6, notes.integer(9) * 1000000);
    insert.run();
    insert.reset();
    if (!notes.isNull(5) && !notes.isNull(6) && !notes.isNull(7)) {
      const std::string model = notes.isNull(4) ? "model" : notes.text(4);
      place.bind(1, model).bind(2, notes.real(5)).bind(3, notes.real(6)).bind(4, notes.real(7));
      place.run();
      place.reset();
      attachment.bind(1, notes.integer(0)).bind(2, int64_t(sqlite3_last_insert_rowid(mDb)));
      attachment.run();
      attachment.reset();
    }
  }
  exec("DROP TABLE notes_v1");
}

// --- Layers ---------------------------------------------------------------------------------

void AnnotationDb::ensureLayer(const std::string& path) {
  if (const std::string problem = layerPathProblem(path); !problem.empty())
    throw AnnotationError(AnnotationError::Kind::kBadInput,
                          prefix(mFile) + "layer \"" + path + "\" " + problem);
  Statement s(mDb, mFile, "INSERT OR IGNORE INTO layers(path) VALUES (?1)");
  for (size_t slash = path.find('/'); slash != std::string::npos;
       slash = path.find('/', slash + 1)) {
    s.bind(1, path.substr(0, slash)).run();
    s.reset();
  }
  s.bind(1, path).run();
}

void AnnotationDb::addLayer(const std::string& path) {
  transaction([&] { ensureLayer(path); });
}

void AnnotationDb::setLayerVisible(const std::string& path, bool visible) {
  transaction([&] {
    Statement s(mDb, mFile, "UPDATE layers SET visible = ?2 WHERE path = ?1");
    s.bind(1, path).bind(2, visible ? 1 : 0).run();
    if (sqlite3_changes(mDb) == 0)
      throw AnnotationError(AnnotationError::Kind::kNotFound,
                            prefix(mFile) + "no layer \"" + path + "\"");
  });
}

std::vector<Layer> AnnotationDb::layers() {
  Statement s(mDb, mFile, "SELECT path, visible FROM layers ORDER BY path");
  std::vector<Layer> out;
  while (s.step()) out.push_back({s.text(0), s.integer(1) != 0});
  return out;
}

bool AnnotationDb::layerShown(const std::string& path) {
  Statement s(mDb, mFile, "SELECT visible FROM layers WHERE path = ?1");
  for (size_t end = 0; end != std::string::npos;) {
    end = path.find('/', end + 1);
    s.bind(1, path.substr(0, end));
    if (!s.step())
      throw AnnotationError(AnnotationError::Kind::kNotFound,
                            prefix(mFile) + "no layer \"" + path + "\"");
    if (!s.integer(0)) return false;
    s.reset();
  }
  return true;
}

// --- Items ----------------------------------------------------------------------------------

void AnnotationDb::checkItem(const Item& it, bool check_link_target) {
  auto bad = [&](const std::string& what) {
    throw AnnotationError(AnnotationError::Kind::kBadInput,
                          prefix(mFile) + "item \"" + it.title.substr(0, 40) + "\": " + what);
  };
  auto text = [&](const std::string& value, size_t max, const char* field) {
    if (value.size() > max)
      bad(std::string(field) + " is longer than " + std::to_string(max) + " bytes");
    if (!detail::validUtf8(value)) bad(std::string(field) + " is not valid UTF-8");
  };
  if (const std::string problem = layerPathProblem(it.layer); !problem.empty())
    bad("layer \"" + it.layer + "\" " + problem);
  if (it.title.empty()) bad("title is empty");
  text(it.title, kMaxTitleBytes, "title");
  text(it.text, kMaxTextBytes, "text");
  text(it.unit, kMaxNameBytes, "unit");
  text(it.mime, kMaxNameBytes, "mime");
  text(it.path, kMaxTextBytes, "path");
  text(it.link_uri, kMaxTextBytes, "link_uri");
  if (it.data.size() > kMaxBlobBytes)
    bad("image data is larger than " + std::to_string(kMaxBlobBytes) + " bytes");
  const bool number = it.kind == ItemKind::kNumber, image = it.kind == ItemKind::kImage,
             link = it.kind == ItemKind::kLink;
  if (!std::isfinite(it.number)) bad("number is not finite");
  if (!number && (it.number != 0.0 || !it.unit.empty()))
    bad("number and unit belong to number items only");
  if (!image && (!it.mime.empty() || !it.path.empty() || !it.data.empty()))
    bad("mime, path and data belong to image items only");
  if (!link && (it.link_item != 0 || !it.link_uri.empty()))
    bad("link_item and link_uri belong to link items only");
  if (image) {
    if (it.mime.rfind("image/", 0) != 0) bad("mime \"" + it.mime + "\" is not image/...");
    if (it.path.empty() == it.data.empty()) bad("an image has either a path or data, not both");
  }
  if (link) {
    if ((it.link_item != 0) == !it.link_uri.empty())
      bad("a link has either link_item or link_uri, not both");
    if (it.link_item < 0) bad("link_item is negative");
    if (!it.link_uri.empty()) {
      const size_t colon = it.link_uri.find(':');
      if (colon == 0 || colon == std::string::npos ||
          !std::all_of(it.link_uri.begin(), it.link_uri.begin() + colon, [](char c) {
            return std::isalnum(static_cast<unsigned char>(c)) || c == '+' || c == '-' || c == '.';
          }))
        bad("link_uri \"" + it.link_uri.substr(0, 60) + "\" has no scheme (https:, file:...)");
    }
    if (check_link_target && it.link_item != 0 && !item(it.link_item))
      throw AnnotationError(AnnotationError::Kind::kNotFound, prefix(mFile) + "link to item " +
                                                                  std::to_string(it.link_item) +
                                                                  ", which does not exist");
  }
}

int64_t AnnotationDb::importItem(const Item& it, bool keep_id, bool link_later) {
  checkItem(it, !link_later);
  if (it.author.empty() || it.author.size() > kMaxNameBytes || !detail::validUtf8(it.author))
    throw AnnotationError(AnnotationError::Kind::kBadInput,
                          prefix(mFile) + "item \"" + it.title.substr(0, 40) +
                              "\": author must be 1 to " + std::to_string(kMaxNameBytes) +
                              " bytes of UTF-8");
  if (it.revision < 1 || it.created_us < 0 || it.modified_us < it.created_us)
    throw AnnotationError(AnnotationError::Kind::kBadInput,
                          prefix(mFile) + "item \"" + it.title.substr(0, 40) +
                              "\": revision must be >= 1 and created_us <= modified_us");
  int64_t id = 0;
  transaction([&] {
    ensureLayer(it.layer);
    Statement s(mDb, mFile,
                "INSERT INTO items(id, layer, kind, title, body, number, unit, mime, path, data, "
                "link_item, link_uri, author, created_us, modified_us, revision) VALUES "
                "(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16)");
    if (keep_id)
      s.bind(1, it.id);
    else
      s.bindNull(1);
    s.bind(2, it.layer).bind(3, toString(it.kind)).bind(4, it.title).bind(5, it.text);
    s.bind(6, it.number).bind(7, it.unit).bind(8, it.mime).bind(9, it.path).bind(10, it.data);
    if (it.link_item)
      s.bind(11, it.link_item);
    else
      s.bindNull(11);
    s.bind(12, it.link_uri).bind(13, it.author).bind(14, it.created_us);
    s.bind(15, it.modified_us).bind(16, it.revision);
    s.run();
    id = sqlite3_last_insert_rowid(mDb);
  });
  return id;
}

int64_t AnnotationDb::addItem(const Item& item_in, const std::string& author) {
  Item it = item_in;
  it.author = author;
  it.created_us = it.modified_us = nowMicroseconds();
  it.revision = 1;
  return importItem(it, false);
}

int64_t AnnotationDb::updateItem(const Item& item_in, int64_t base_revision,
                                 const std::string& author) {
  if (author.empty() || author.size() > kMaxNameBytes || !detail::validUtf8(author))
    throw AnnotationError(AnnotationError::Kind::kBadInput,
                          prefix(mFile) + "an edit's author must be 1 to " +
                              std::to_string(kMaxNameBytes) + " bytes of UTF-8");
  checkItem(item_in);
  if (item_in.link_item == item_in.id && item_in.id != 0)
    throw AnnotationError(
        AnnotationError::Kind::kBadInput,
        prefix(mFile) + "item " + std::to_string(item_in.id) + " cannot link to itself");
  int64_t revision = 0;
  transaction([&] {
    const std::optional<Item> current = item(item_in.id);
    if (!current)
      throw AnnotationError(AnnotationError::Kind::kNotFound,
                            prefix(mFile) + "no item " + std::to_string(item_in.id));
    // The concurrency rule (header): an edit must be based on the current revision.
    if (current->revision != base_revision)
      throw AnnotationError(AnnotationError::Kind::kConflict,
                            prefix(mFile) + "item " + std::to_string(item_in.id) +
                                ": the edit by " + author + " is based on revision " +
                                std::to_string(base_revision) + " but the item is at revision " +
                                std::to_string(current->revision) + " (by " + current->author +
                                "); re-read it and edit again");
    ensureLayer(item_in.layer);
    revision = current->revision + 1;
    Statement s(mDb, mFile,
                "UPDATE items SET layer = ?2, kind = ?3, title = ?4, body = ?5, number = ?6, "
                "unit = ?7, mime = ?8, path = ?9, data = ?10, link_item = ?11, link_uri = ?12, "
                "author = ?13, modified_us = max(?14, created_us), revision = ?15 WHERE id = ?1");
    s.bind(1, item_in.id).bind(2, item_in.layer).bind(3, toString(item_in.kind));
    s.bind(4, item_in.title).bind(5, item_in.text).bind(6, item_in.number).bind(7, item_in.unit);
    s.bind(8, item_in.mime).bind(9, item_in.path).bind(10, item_in.data);
    if (item_in.link_item)
      s.bind(11, item_in.link_item);
    else
      s.bindNull(11);
    s.bind(12, item_in.link_uri).bind(13, author).bind(14, nowMicroseconds()).bind(15, revision);
    s.run();
  });
  return revision;
}

void AnnotationDb::removeItem(int64_t id, int64_t base_revision) {
  transaction([&] {
    const std::optional<Item> current = item(id);
    if (!current)
      throw AnnotationError(AnnotationError::Kind::kNotFound,
                            prefix(mFile) + "no item " + std::to_string(id));
    if (current->revision != base_revision)
      throw AnnotationError(
          AnnotationError::Kind::kConflict,
          prefix(mFile) + "item " + std::to_string(id) + ": removal based on revision " +
              std::to_string(base_revision) + " but the item is at revision " +
              std::to_string(current->revision) + " (by " + current->author + ")");
    // A link with nothing at its end would be a dangling reference in every export; the
    // linking items are someone's work, so they are not removed behind their author's back.
    if (const std::vector<int64_t> from = linksTo(id); !from.empty()) {
      std::string list;
      for (int64_t f : from) list += (list.empty() ? "" : ", ") + std::to_string(f);
      throw AnnotationError(AnnotationError::Kind::kBadInput,
                            prefix(mFile) + "item " + std::to_string(id) +
                                " is linked from items " + list +
                                "; remove or re-point those links first");
    }
    Statement(mDb, mFile, "DELETE FROM items WHERE id = ?1").bind(1, id).run();
  });
}

std::optional<Item> AnnotationDb::item(int64_t id) {
  Statement s(mDb, mFile,
              (std::string("SELECT ") + kItemColumns + " FROM items WHERE id = ?1").c_str());
  s.bind(1, id);
  if (!s.step()) return std::nullopt;
  return readItem(s);
}

std::vector<Item> AnnotationDb::items(const std::string& layer) {
  Statement s(mDb, mFile,
              (std::string("SELECT ") + kItemColumns +
               " FROM items WHERE ?1 = '' OR layer = ?1 OR "
               "substr(layer, 1, length(?1) + 1) = ?1 || '/' ORDER BY id")
                  .c_str());
  s.bind(1, layer);
  std::vector<Item> out;
  while (s.step()) out.push_back(readItem(s));
  return out;
}

std::vector<int64_t> AnnotationDb::linksTo(int64_t id) {
  Statement s(mDb, mFile, "SELECT id FROM items WHERE link_item = ?1 ORDER BY id");
  s.bind(1, id);
  return ids(s);
}

// --- Places ---------------------------------------------------------------------------------

void AnnotationDb::checkPlace(const Place& p) {
  auto bad = [&](const std::string& what) {
    throw AnnotationError(
        AnnotationError::Kind::kBadInput,
        prefix(mFile) + toString(p.kind) + " on \"" + p.model.substr(0, 40) + "\": " + what);
  };
  if (p.model.empty() || p.model.size() > kMaxNameBytes || !detail::validUtf8(p.model))
    bad("model must be 1 to " + std::to_string(kMaxNameBytes) + " bytes of UTF-8");
  if (!finite(p.position)) bad("position is not finite (NaN or infinite)");
  if (!inRange(p.position))
    bad("position is beyond " + std::to_string(kMaxCoordinate) + " m from the origin");
  const bool hot = p.kind == PlaceKind::kHotSpot, sel = p.kind == PlaceKind::kSelection;
  if (hot && !(std::isfinite(p.radius) && p.radius > 0.0 && p.radius <= kMaxCoordinate))
    bad("a hot spot's radius must be finite and > 0");
  if (!hot && p.radius != 0.0) bad("only hot spots have a radius");
  if (hot && !p.view) bad("a hot spot needs a stored view");
  if (p.view) {
    const StoredView& v = *p.view;
    if (!inRange(v.eye) || !inRange(v.target) || !inRange(v.up))
      bad("the view's eye, target or up is not finite or out of range");
    if (const auto problem = sync::viewProblem(v.eye, v.target, v.up))
      bad("the view: " + problem->what);
    if (!(v.fovy_deg > 0.0 && v.fovy_deg < 180.0)) bad("the view's fovy must be in (0, 180)");
  }
  if (sel) {
    if (p.selection_id.empty() || p.selection_id.size() > kMaxNameBytes ||
        !detail::validUtf8(p.selection_id))
      bad("selection_id must be 1 to " + std::to_string(kMaxNameBytes) + " bytes of UTF-8");
    if (p.selection.size() > kMaxSelectionBytes)
      bad("selection is larger than " + std::to_string(kMaxSelectionBytes) + " bytes");
  } else if (!p.selection_id.empty() || !p.selection.empty()) {
    bad("selection_id and selection belong to selections only");
  }
}

int64_t AnnotationDb::importPlace(const Place& p, bool keep_id) {
  checkPlace(p);
  int64_t id = 0;
  transaction([&] {
    Statement s(mDb, mFile,
                "INSERT INTO places(id, kind, model, x, y, z, radius, has_view, eye_x, eye_y, "
                "eye_z, target_x, target_y, target_z, up_x, up_y, up_z, fovy_deg, selection_id, "
                "selection) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, "
                "?15, ?16, ?17, ?18, ?19, ?20)");
    if (keep_id)
      s.bind(1, p.id);
    else
      s.bindNull(1);
    s.bind(2, toString(p.kind)).bind(3, p.model);
    s.bind(4, p.position.x).bind(5, p.position.y).bind(6, p.position.z).bind(7, p.radius);
    const StoredView v =
        p.view.value_or(StoredView{glm::dvec3(0.0), glm::dvec3(0.0), glm::dvec3(0.0), 0.0});
    s.bind(8, p.view ? 1 : 0);
    for (int a = 0; a < 3; ++a) {
      s.bind(9 + a, v.eye[a]).bind(12 + a, v.target[a]).bind(15 + a, v.up[a]);
    }
    s.bind(18, v.fovy_deg).bind(19, p.selection_id).bind(20, p.selection);
    s.run();
    id = sqlite3_last_insert_rowid(mDb);
  });
  return id;
}

int64_t AnnotationDb::addPlace(const Place& place) {
  return importPlace(place, false);
}

std::optional<Place> AnnotationDb::place(int64_t id) {
  Statement s(mDb, mFile,
              (std::string("SELECT ") + kPlaceColumns + " FROM places WHERE id = ?1").c_str());
  s.bind(1, id);
  if (!s.step()) return std::nullopt;
  return readPlace(s);
}

std::vector<Place> AnnotationDb::places() {
  Statement s(mDb, mFile,
              (std::string("SELECT ") + kPlaceColumns + " FROM places ORDER BY id").c_str());
  std::vector<Place> out;
  while (s.step()) out.push_back(readPlace(s));
  return out;
}

void AnnotationDb::attach(int64_t item_id, int64_t place_id) {
  transaction([&] {
    if (!item(item_id))
      throw AnnotationError(AnnotationError::Kind::kNotFound,
                            prefix(mFile) + "no item " + std::to_string(item_id));
    if (!place(place_id))
      throw AnnotationError(AnnotationError::Kind::kNotFound,
                            prefix(mFile) + "no place " + std::to_string(place_id));
    Statement(mDb, mFile, "INSERT OR IGNORE INTO attachments(item, place) VALUES (?1, ?2)")
        .bind(1, item_id)
        .bind(2, place_id)
        .run();
  });
}

void AnnotationDb::detach(int64_t item_id, int64_t place_id) {
  transaction([&] {
    Statement(mDb, mFile, "DELETE FROM attachments WHERE item = ?1 AND place = ?2")
        .bind(1, item_id)
        .bind(2, place_id)
        .run();
  });
}

void AnnotationDb::removePlace(int64_t place_id) {
  transaction([&] {
    Statement(mDb, mFile, "DELETE FROM places WHERE id = ?1").bind(1, place_id).run();
    if (sqlite3_changes(mDb) == 0)
      throw AnnotationError(AnnotationError::Kind::kNotFound,
                            prefix(mFile) + "no place " + std::to_string(place_id));
  });
}

std::vector<int64_t> AnnotationDb::itemsAt(int64_t place_id) {
  Statement s(mDb, mFile, "SELECT item FROM attachments WHERE place = ?1 ORDER BY item");
  s.bind(1, place_id);
  return ids(s);
}

std::vector<int64_t> AnnotationDb::placesOf(int64_t item_id) {
  Statement s(mDb, mFile, "SELECT place FROM attachments WHERE item = ?1 ORDER BY place");
  s.bind(1, item_id);
  return ids(s);
}

std::vector<int64_t> AnnotationDb::placesNear(const std::string& model, const glm::dvec3& centre,
                                              double radius) {
  if (!inRange(centre) || !(std::isfinite(radius) && radius >= 0.0))
    throw AnnotationError(AnnotationError::Kind::kBadInput,
                          prefix(mFile) + "placesNear(): centre and radius must be finite");
  // The index on (model, x) cuts the scan to a slab; the sphere test is exact.
  Statement s(mDb, mFile,
              "SELECT id, x, y, z FROM places WHERE model = ?1 AND kind IN ('point', 'hotspot') "
              "AND x BETWEEN ?2 AND ?3");
  s.bind(1, model).bind(2, centre.x - radius).bind(3, centre.x + radius);
  std::vector<std::pair<double, int64_t>> hits;
  while (s.step()) {
    const double d = glm::length(glm::dvec3(s.real(1), s.real(2), s.real(3)) - centre);
    if (d <= radius) hits.emplace_back(d, s.integer(0));
  }
  std::sort(hits.begin(), hits.end());
  std::vector<int64_t> out;
  for (const auto& h : hits) out.push_back(h.second);
  return out;
}

// --- Search ---------------------------------------------------------------------------------

std::vector<SearchHit> AnnotationDb::search(const std::string& query, int limit) {
  using Kind = AnnotationError::Kind;
  if (query.empty() || query.size() > 4096 || !detail::validUtf8(query))
    throw AnnotationError(Kind::kBadQuery,
                          prefix(mFile) + "a search query is 1 to 4096 bytes of UTF-8");
  if (limit < 1) throw AnnotationError(Kind::kBadInput, prefix(mFile) + "search limit < 1");
  // bm25 weights: a word in the title says more than one in a long text (thesis 5.2: labels
  // and captions are what users scan first); the layer name in between.
  Statement s(mDb, mFile,
              "SELECT rowid, bm25(items_fts, 10.0, 1.0, 2.0, 1.0) AS score, "
              "snippet(items_fts, -1, '[', ']', '...', 12) FROM items_fts "
              "WHERE items_fts MATCH ?1 ORDER BY score, rowid LIMIT ?2");
  s.bind(1, query).bind(2, limit);
  std::vector<SearchHit> out;
  try {
    while (s.step()) out.push_back({s.integer(0), s.real(1), s.text(2)});
  } catch (const AnnotationError& e) {
    // A malformed query is SQLITE_ERROR from the step ("fts5: syntax error near ...").
    if (e.kind() != Kind::kIo) throw;
    throw AnnotationError(Kind::kBadQuery, prefix(mFile) + "search \"" + query.substr(0, 80) +
                                               "\": malformed query (" + sqlite3_errmsg(mDb) + ")");
  }
  return out;
}

// --- Georeference ---------------------------------------------------------------------------

void AnnotationDb::setGeoreference(const std::string& crs, const glm::dvec3& origin) {
  if (crs.empty() || crs.size() > kMaxNameBytes || !detail::validUtf8(crs) || !finite(origin))
    throw AnnotationError(AnnotationError::Kind::kBadInput,
                          prefix(mFile) + "a georeference needs a CRS name and a finite origin");
  transaction([&] {
    Statement s(mDb, mFile, "INSERT OR REPLACE INTO meta(key, value) VALUES (?1, ?2)");
    s.bind(1, "crs").bind(2, crs).run();
    const char* keys[] = {"origin_x", "origin_y", "origin_z"};
    for (int a = 0; a < 3; ++a) {
      s.reset();
      s.bind(1, keys[a]).bind(2, origin[a]).run();
    }
  });
}

std::optional<std::pair<std::string, glm::dvec3>> AnnotationDb::georeference() {
  Statement s(mDb, mFile,
              "SELECT (SELECT value FROM meta WHERE key = 'crs'), "
              "(SELECT value FROM meta WHERE key = 'origin_x'), "
              "(SELECT value FROM meta WHERE key = 'origin_y'), "
              "(SELECT value FROM meta WHERE key = 'origin_z')");
  s.step();
  if (s.isNull(0)) return std::nullopt;
  return std::make_pair(s.text(0), glm::dvec3(s.real(1), s.real(2), s.real(3)));
}

int64_t AnnotationDb::dataVersion() {
  Statement s(mDb, mFile, "PRAGMA data_version");
  s.step();
  return s.integer(0);
}

std::string AnnotationDb::integrityCheck() {
  Statement s(mDb, mFile, "PRAGMA integrity_check");
  std::string out;
  while (s.step()) out += (out.empty() ? "" : "\n") + s.text(0);
  return out;
}

}  // namespace tessera::annotate
