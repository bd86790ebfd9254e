// Thin RAII wrappers over the SQLite C API: a connection, a prepared statement and a transaction.
// Every failing call throws SqliteError (database_errors.h) with the SQLite message and the SQL.
// Not thread-safe: one thread at a time per connection (the database class serialises access).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "textile_handling/db/database_errors.h"

struct sqlite3;
struct sqlite3_stmt;

namespace textile_handling {
namespace db {

class SqliteStatement;

/// An open database connection (closed by the destructor).
class SqliteConnection {
 public:
  enum OpenFlags : int { kReadOnly = 1, kReadWrite = 2, kCreate = 4 };

  SqliteConnection() = default;
  /// Opens `path` (flags: kReadOnly, or kReadWrite optionally | kCreate). Throws SqliteError.
  SqliteConnection(const std::string& path, int flags);
  ~SqliteConnection();
  SqliteConnection(SqliteConnection&& o) noexcept;
  SqliteConnection& operator=(SqliteConnection&& o) noexcept;
  SqliteConnection(const SqliteConnection&) = delete;
  SqliteConnection& operator=(const SqliteConnection&) = delete;

  bool isOpen() const { return db_ != nullptr; }
  const std::string& path() const { return path_; }
  sqlite3* handle() const { return db_; }

  /// Runs one or more SQL statements without results. Throws SqliteError.
  void exec(const std::string& sql);
  /// Prepares a statement. Throws SqliteError.
  SqliteStatement prepare(const std::string& sql) const;
  /// Single integer of a query returning one row (e.g. "PRAGMA user_version"); `fallback` if no row.
  std::int64_t queryInt(const std::string& sql, std::int64_t fallback = 0) const;
  /// Single text value of a query returning one row; `fallback` if no row or NULL.
  std::string queryText(const std::string& sql, const std::string& fallback = "") const;
  std::int64_t lastInsertRowId() const;
  int changes() const;
  bool inTransaction() const;
  /// Throws SqliteError built from the connection's last error if rc is not OK/ROW/DONE.
  void check(int rc, const std::string& context) const;

 private:
  sqlite3* db_ = nullptr;
  std::string path_;
};

/// A prepared statement. Bind indices are 1-based (as in SQLite); column indices are 0-based.
class SqliteStatement {
 public:
  SqliteStatement() = default;
  SqliteStatement(sqlite3* db, sqlite3_stmt* stmt, std::string sql) : db_(db), stmt_(stmt), sql_(std::move(sql)) {}
  ~SqliteStatement();
  SqliteStatement(SqliteStatement&& o) noexcept;
  SqliteStatement& operator=(SqliteStatement&& o) noexcept;
  SqliteStatement(const SqliteStatement&) = delete;
  SqliteStatement& operator=(const SqliteStatement&) = delete;

  SqliteStatement& bind(int index, std::int64_t value);
  SqliteStatement& bind(int index, int value) { return bind(index, static_cast<std::int64_t>(value)); }
  SqliteStatement& bind(int index, double value);
  SqliteStatement& bind(int index, const std::string& value);
  SqliteStatement& bind(int index, const char* value) { return bind(index, std::string(value)); }
  SqliteStatement& bindBlob(int index, const std::vector<std::uint8_t>& blob);
  SqliteStatement& bindNull(int index);

  /// Advances: true if a row is available, false when done. Throws SqliteError.
  bool step();
  /// Runs a statement without results to completion (step until done).
  void run();
  /// Resets the statement and clears its bindings for reuse.
  void reset();

  int columnCount() const;
  bool isNull(int col) const;
  std::int64_t getInt(int col) const;
  double getDouble(int col) const;
  std::string getText(int col) const;
  /// Pointer to the blob bytes (valid until the next step/reset) and its size.
  const std::uint8_t* blobData(int col) const;
  int blobSize(int col) const;
  std::vector<std::uint8_t> getBlob(int col) const;

 private:
  void checkBind(int rc, int index);
  sqlite3* db_ = nullptr;
  sqlite3_stmt* stmt_ = nullptr;
  std::string sql_;
};

/// BEGIN IMMEDIATE ... COMMIT; rolls back in the destructor unless commit() was called (so an
/// exception leaves the database as it was).
class SqliteTransaction {
 public:
  explicit SqliteTransaction(SqliteConnection& conn);
  ~SqliteTransaction();
  SqliteTransaction(const SqliteTransaction&) = delete;
  SqliteTransaction& operator=(const SqliteTransaction&) = delete;
  void commit();

 private:
  SqliteConnection& conn_;
  bool done_ = false;
};

}  // namespace db
}  // namespace textile_handling
