// A prepared SQLite statement as a move-only RAII object (finalized in the destructor), with
// binds and column reads that keep blobs and embedded NULs whole. Every failure throws
// AnnotationError naming the database file (throwSqlite()).
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <tessera/annotate/annotation_db.h>

namespace tessera::annotate::detail {

/// Throws the AnnotationError that SQLite's result code `rc` means: "AnnotationDb: FILE: WHAT:
/// SQLite's message".
[[noreturn]] void throwSqlite(sqlite3* db, int rc, const std::filesystem::path& file,
                              const std::string& what);

/// What a statement is for, in words, from its SQL ("reading items", "adding to places",
/// "changing layers", "PRAGMA journal_mode"): what an error names instead of the whole SQL.
std::string purposeOf(std::string_view sql);

class Statement {
 public:
  Statement(sqlite3* db, const std::filesystem::path& file, const char* sql)
      : mDb(db), mFile(&file) {
    const int rc = sqlite3_prepare_v2(db, sql, -1, &mStmt, nullptr);
    if (rc != SQLITE_OK) throwSqlite(db, rc, file, "preparing " + purposeOf(sql));
  }
  ~Statement() { sqlite3_finalize(mStmt); }
  Statement(Statement&& o) noexcept
      : mDb(o.mDb), mFile(o.mFile), mStmt(std::exchange(o.mStmt, nullptr)) {}
  Statement& operator=(Statement&&) = delete;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  // Binds by 1-based index.
  Statement& bind(int i, int64_t v) { return check(sqlite3_bind_int64(mStmt, i, v)); }
  Statement& bind(int i, int v) { return check(sqlite3_bind_int64(mStmt, i, v)); }
  Statement& bind(int i, double v) { return check(sqlite3_bind_double(mStmt, i, v)); }
  Statement& bind(int i, const std::string& v) {
    return check(sqlite3_bind_text64(mStmt, i, v.data(), v.size(), SQLITE_TRANSIENT, SQLITE_UTF8));
  }
  Statement& bind(int i, const char* v) { return bind(i, std::string(v)); }
  /// An empty vector binds NULL.
  Statement& bind(int i, const std::vector<uint8_t>& v) {
    if (v.empty()) return check(sqlite3_bind_null(mStmt, i));
    return check(sqlite3_bind_blob64(mStmt, i, v.data(), v.size(), SQLITE_TRANSIENT));
  }
  Statement& bindNull(int i) { return check(sqlite3_bind_null(mStmt, i)); }

  /// True with a row to read, false when done.
  bool step() {
    const int rc = sqlite3_step(mStmt);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throwSqlite(mDb, rc, *mFile, purposeOf(sqlite3_sql(mStmt)));
  }
  /// Steps a statement that returns no rows (INSERT, UPDATE...).
  void run() {
    while (step()) {
    }
  }
  void reset() {
    sqlite3_reset(mStmt);
    sqlite3_clear_bindings(mStmt);
  }

  bool isNull(int c) const { return sqlite3_column_type(mStmt, c) == SQLITE_NULL; }
  int64_t integer(int c) const { return sqlite3_column_int64(mStmt, c); }
  double real(int c) const { return sqlite3_column_double(mStmt, c); }
  std::string text(int c) const {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(mStmt, c));
    return p ? std::string(p, size_t(sqlite3_column_bytes(mStmt, c))) : std::string();
  }
  std::vector<uint8_t> blob(int c) const {
    const auto* p = static_cast<const uint8_t*>(sqlite3_column_blob(mStmt, c));
    return p ? std::vector<uint8_t>(p, p + sqlite3_column_bytes(mStmt, c)) : std::vector<uint8_t>();
  }

 private:
  Statement& check(int rc) {
    if (rc != SQLITE_OK) throwSqlite(mDb, rc, *mFile, "binding a value");
    return *this;
  }

  sqlite3* mDb;
  const std::filesystem::path* mFile;
  sqlite3_stmt* mStmt = nullptr;
};

}  // namespace tessera::annotate::detail
