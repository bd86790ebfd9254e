#include "textile_handling/db/sqlite_wrapper.h"

#include <sqlite3.h>

#include <utility>

namespace textile_handling {
namespace db {

namespace {
std::string errorText(sqlite3* db, int rc) {
  std::string msg = sqlite3_errstr(rc);
  if (db) {
    const char* m = sqlite3_errmsg(db);
    if (m && msg != m) msg += std::string(": ") + m;
  }
  return msg;
}
}  // namespace

// ---- connection -------------------------------------------------------------------------------

SqliteConnection::SqliteConnection(const std::string& path, int flags) : path_(path) {
  int f = SQLITE_OPEN_NOMUTEX;
  if (flags & kReadWrite) {
    f |= SQLITE_OPEN_READWRITE;
    if (flags & kCreate) f |= SQLITE_OPEN_CREATE;
  } else {
    f |= SQLITE_OPEN_READONLY;
  }
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &db, f, nullptr);
  if (rc != SQLITE_OK) {
    const std::string msg = errorText(db, rc);
    sqlite3_close_v2(db);
    throw SqliteError("cannot open database '" + path + "': " + msg, rc);
  }
  sqlite3_extended_result_codes(db, 1);
  db_ = db;
}

SqliteConnection::~SqliteConnection() {
  if (db_) sqlite3_close_v2(db_);
}

SqliteConnection::SqliteConnection(SqliteConnection&& o) noexcept
    : db_(std::exchange(o.db_, nullptr)), path_(std::move(o.path_)) {}

SqliteConnection& SqliteConnection::operator=(SqliteConnection&& o) noexcept {
  if (this != &o) {
    if (db_) sqlite3_close_v2(db_);
    db_ = std::exchange(o.db_, nullptr);
    path_ = std::move(o.path_);
  }
  return *this;
}

void SqliteConnection::check(int rc, const std::string& context) const {
  if (rc == SQLITE_OK || rc == SQLITE_ROW || rc == SQLITE_DONE) return;
  throw SqliteError(context + ": " + errorText(db_, rc) + " (database '" + path_ + "')", rc);
}

void SqliteConnection::exec(const std::string& sql) {
  if (!db_) throw SqliteError("exec on a closed database", SQLITE_MISUSE);
  char* err = nullptr;
  const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err);
  if (rc != SQLITE_OK) {
    std::string msg = err ? err : sqlite3_errstr(rc);
    sqlite3_free(err);
    throw SqliteError("SQL failed: " + msg + " [" + sql.substr(0, 200) + "] (database '" + path_ + "')", rc);
  }
}

SqliteStatement SqliteConnection::prepare(const std::string& sql) const {
  if (!db_) throw SqliteError("prepare on a closed database", SQLITE_MISUSE);
  sqlite3_stmt* stmt = nullptr;
  const int rc = sqlite3_prepare_v2(db_, sql.c_str(), static_cast<int>(sql.size()), &stmt, nullptr);
  if (rc != SQLITE_OK) {
    sqlite3_finalize(stmt);
    throw SqliteError("cannot prepare [" + sql.substr(0, 200) + "]: " + errorText(db_, rc), rc);
  }
  return SqliteStatement(db_, stmt, sql);
}

std::int64_t SqliteConnection::queryInt(const std::string& sql, std::int64_t fallback) const {
  SqliteStatement st = prepare(sql);
  if (!st.step() || st.isNull(0)) return fallback;
  return st.getInt(0);
}

std::string SqliteConnection::queryText(const std::string& sql, const std::string& fallback) const {
  SqliteStatement st = prepare(sql);
  if (!st.step() || st.isNull(0)) return fallback;
  return st.getText(0);
}

std::int64_t SqliteConnection::lastInsertRowId() const { return sqlite3_last_insert_rowid(db_); }
int SqliteConnection::changes() const { return sqlite3_changes(db_); }
bool SqliteConnection::inTransaction() const { return db_ && sqlite3_get_autocommit(db_) == 0; }

// ---- statement --------------------------------------------------------------------------------

SqliteStatement::~SqliteStatement() {
  if (stmt_) sqlite3_finalize(stmt_);
}

SqliteStatement::SqliteStatement(SqliteStatement&& o) noexcept
    : db_(std::exchange(o.db_, nullptr)), stmt_(std::exchange(o.stmt_, nullptr)), sql_(std::move(o.sql_)) {}

SqliteStatement& SqliteStatement::operator=(SqliteStatement&& o) noexcept {
  if (this != &o) {
    if (stmt_) sqlite3_finalize(stmt_);
    db_ = std::exchange(o.db_, nullptr);
    stmt_ = std::exchange(o.stmt_, nullptr);
    sql_ = std::move(o.sql_);
  }
  return *this;
}

void SqliteStatement::checkBind(int rc, int index) {
  if (rc != SQLITE_OK)
    throw SqliteError("cannot bind parameter " + std::to_string(index) + " of [" + sql_.substr(0, 200) +
                          "]: " + errorText(db_, rc),
                      rc);
}

SqliteStatement& SqliteStatement::bind(int index, std::int64_t value) {
  checkBind(sqlite3_bind_int64(stmt_, index, value), index);
  return *this;
}
SqliteStatement& SqliteStatement::bind(int index, double value) {
  checkBind(sqlite3_bind_double(stmt_, index, value), index);
  return *this;
}
SqliteStatement& SqliteStatement::bind(int index, const std::string& value) {
  checkBind(sqlite3_bind_text(stmt_, index, value.data(), static_cast<int>(value.size()), SQLITE_TRANSIENT), index);
  return *this;
}
SqliteStatement& SqliteStatement::bindBlob(int index, const std::vector<std::uint8_t>& blob) {
  // An empty vector would bind NULL with a null pointer; bind a zero-length blob instead.
  static const std::uint8_t kEmpty = 0;
  checkBind(sqlite3_bind_blob(stmt_, index, blob.empty() ? &kEmpty : blob.data(), static_cast<int>(blob.size()),
                              SQLITE_TRANSIENT),
            index);
  return *this;
}
SqliteStatement& SqliteStatement::bindNull(int index) {
  checkBind(sqlite3_bind_null(stmt_, index), index);
  return *this;
}

bool SqliteStatement::step() {
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  throw SqliteError("statement failed [" + sql_.substr(0, 200) + "]: " + errorText(db_, rc), rc);
}

void SqliteStatement::run() {
  while (step()) {
  }
}

void SqliteStatement::reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

int SqliteStatement::columnCount() const { return sqlite3_column_count(stmt_); }
bool SqliteStatement::isNull(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
std::int64_t SqliteStatement::getInt(int col) const { return sqlite3_column_int64(stmt_, col); }
double SqliteStatement::getDouble(int col) const { return sqlite3_column_double(stmt_, col); }
std::string SqliteStatement::getText(int col) const {
  const unsigned char* t = sqlite3_column_text(stmt_, col);
  const int n = sqlite3_column_bytes(stmt_, col);
  return t ? std::string(reinterpret_cast<const char*>(t), static_cast<std::size_t>(n)) : std::string();
}
const std::uint8_t* SqliteStatement::blobData(int col) const {
  return static_cast<const std::uint8_t*>(sqlite3_column_blob(stmt_, col));
}
int SqliteStatement::blobSize(int col) const { return sqlite3_column_bytes(stmt_, col); }
std::vector<std::uint8_t> SqliteStatement::getBlob(int col) const {
  const std::uint8_t* p = blobData(col);
  const int n = blobSize(col);
  return p && n > 0 ? std::vector<std::uint8_t>(p, p + n) : std::vector<std::uint8_t>();
}

// ---- transaction ------------------------------------------------------------------------------

SqliteTransaction::SqliteTransaction(SqliteConnection& conn) : conn_(conn) { conn_.exec("BEGIN IMMEDIATE"); }

SqliteTransaction::~SqliteTransaction() {
  if (!done_ && conn_.inTransaction()) {
    try {
      conn_.exec("ROLLBACK");
    } catch (...) {
      // Nothing sensible to do in a destructor; SQLite rolls back on close anyway.
    }
  }
}

void SqliteTransaction::commit() {
  conn_.exec("COMMIT");
  done_ = true;
}

}  // namespace db
}  // namespace textile_handling
