// One SQL interface over the drape database's two storage backends: the embedded SQLite file (default)
// and a PostgreSQL server. The database layer writes its statements once, with `?` placeholders and the
// SQL both backends accept; what differs (column types, the current time, write locks, integrity
// checks) is asked of the connection's SqlDialect. ROS-free. docs/database.md, "Storage backends".
//
// Errors: a backend throws its own typed error (SqliteError or PostgresError, both DrapeDatabaseError).
// Not thread-safe: one thread at a time per connection (HangingDrapeDatabase serialises access).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "textile_handling/db/database_errors.h"

namespace textile_handling {
namespace db {

enum class SqlDialect { kSqlite, kPostgres };

/// What a backend's statement does; SqlStatement is the handle callers hold.
class SqlStatementBackend {
 public:
  virtual ~SqlStatementBackend() = default;
  virtual void bindInt(int index, std::int64_t value) = 0;
  virtual void bindDouble(int index, double value) = 0;
  virtual void bindText(int index, const std::string& value) = 0;
  virtual void bindBlob(int index, const std::vector<std::uint8_t>& blob) = 0;
  virtual void bindNull(int index) = 0;
  virtual bool step() = 0;
  virtual void reset() = 0;
  virtual int columnCount() const = 0;
  virtual bool isNull(int col) const = 0;
  virtual std::int64_t getInt(int col) const = 0;
  virtual double getDouble(int col) const = 0;
  virtual std::string getText(int col) const = 0;
  /// The blob's bytes (valid until the next step or reset) and their number.
  virtual const std::uint8_t* blobData(int col) const = 0;
  virtual std::size_t blobSize(int col) const = 0;
};

/// A prepared statement. Bind indices are 1-based, column indices 0-based (as in SQLite).
class SqlStatement {
 public:
  SqlStatement() = default;
  explicit SqlStatement(std::unique_ptr<SqlStatementBackend> impl) : impl_(std::move(impl)) {}

  SqlStatement& bind(int index, std::int64_t value) { return impl().bindInt(index, value), *this; }
  SqlStatement& bind(int index, int value) { return bind(index, static_cast<std::int64_t>(value)); }
  SqlStatement& bind(int index, double value) { return impl().bindDouble(index, value), *this; }
  SqlStatement& bind(int index, const std::string& value) { return impl().bindText(index, value), *this; }
  SqlStatement& bind(int index, const char* value) { return bind(index, std::string(value)); }
  SqlStatement& bindBlob(int index, const std::vector<std::uint8_t>& blob) { return impl().bindBlob(index, blob), *this; }
  SqlStatement& bindNull(int index) { return impl().bindNull(index), *this; }

  /// Advances: true if a row is available, false when done. Throws the backend's error.
  bool step() { return impl().step(); }
  /// Runs a statement without results to completion.
  void run() {
    while (impl().step()) {
    }
  }
  /// Resets the statement and clears its bindings for reuse.
  void reset() { impl().reset(); }

  int columnCount() const { return impl().columnCount(); }
  bool isNull(int col) const { return impl().isNull(col); }
  std::int64_t getInt(int col) const { return impl().getInt(col); }
  double getDouble(int col) const { return impl().getDouble(col); }
  std::string getText(int col) const { return impl().getText(col); }
  std::vector<std::uint8_t> getBlob(int col) const {
    const std::uint8_t* p = impl().blobData(col);
    return std::vector<std::uint8_t>(p, p + impl().blobSize(col));
  }
  const std::uint8_t* blobData(int col) const { return impl().blobData(col); }
  std::size_t blobSize(int col) const { return impl().blobSize(col); }

 private:
  SqlStatementBackend& impl() const;
  std::unique_ptr<SqlStatementBackend> impl_;
};

/// An open connection to one drape database, SQLite or PostgreSQL.
class SqlConnection {
 public:
  virtual ~SqlConnection() = default;
  virtual SqlDialect dialect() const = 0;
  /// The database as the user named it (a file path, or the URL with its password hidden).
  virtual const std::string& name() const = 0;
  /// Runs one or more SQL statements without results.
  virtual void exec(const std::string& sql) = 0;
  /// Prepares a statement written with `?` placeholders.
  virtual SqlStatement prepare(const std::string& sql) = 0;
  virtual bool inTransaction() const = 0;
  /// Rows changed by the last INSERT, UPDATE or DELETE run on this connection.
  virtual int changes() const = 0;
  /// Starts a transaction that writes: it waits for (and then excludes) every other writer of the
  /// database, as SQLite's BEGIN IMMEDIATE does, so read-then-write logic inside it cannot race.
  virtual void beginWrite() = 0;
  virtual void commit() = 0;
  virtual void rollback() = 0;

  /// Single integer of a query returning one row; `fallback` if no row or NULL.
  std::int64_t queryInt(const std::string& sql, std::int64_t fallback = 0);
  /// Single text value of a query returning one row; `fallback` if no row or NULL.
  std::string queryText(const std::string& sql, const std::string& fallback = "");
};

/// beginWrite() ... commit(); rolls back in the destructor unless commit() was called (so an exception
/// leaves the database as it was).
class SqlTransaction {
 public:
  explicit SqlTransaction(SqlConnection& conn) : conn_(conn) { conn_.beginWrite(); }
  ~SqlTransaction();
  SqlTransaction(const SqlTransaction&) = delete;
  SqlTransaction& operator=(const SqlTransaction&) = delete;
  void commit();

 private:
  SqlConnection& conn_;
  bool done_ = false;
};

/// Options of openSqlConnection().
struct SqlOpenOptions {
  bool read_only = false;
  bool create = true;            ///< SQLite: create the file if missing
  int busy_timeout_ms = 10000;   ///< wait this long for another writer's lock
  int connect_timeout_s = 10;    ///< PostgreSQL: give up connecting after this long
};

/// Opens `setting`: a `postgresql://` (or `postgres://`) URL connects to that server, anything else is an
/// SQLite file path. Throws SqliteError / PostgresError.
std::unique_ptr<SqlConnection> openSqlConnection(const std::string& setting, const SqlOpenOptions& options);

/// `sql` with every `?` outside quotes replaced by $1, $2, ... (PostgreSQL's placeholders).
std::string numberedPlaceholders(const std::string& sql);

// ---- what differs between the dialects ----------------------------------------------------------

/// The current UTC time as the *_at columns store it: ISO 8601 with milliseconds and 'Z'.
std::string sqlNow(SqlDialect d);
/// DDL written with SQLite's types (INTEGER PRIMARY KEY, INTEGER, REAL, BLOB) in `d`'s types: 64-bit
/// integers and identities, double precision, bytea.
std::string dialectDdl(const std::string& sqlite_ddl, SqlDialect d);

}  // namespace db
}  // namespace textile_handling
