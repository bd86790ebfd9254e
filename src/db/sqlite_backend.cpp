// SqlConnection over an SQLite file (sql_connection.h), built on the RAII wrappers of sqlite_wrapper.h.
#include <sqlite3.h>

#include "sql_backends.h"
#include "textile_handling/db/sqlite_wrapper.h"

namespace textile_handling {
namespace db {
namespace internal {

namespace {

class SqliteStatementBackend final : public SqlStatementBackend {
 public:
  explicit SqliteStatementBackend(SqliteStatement st) : st_(std::move(st)) {}
  void bindInt(int index, std::int64_t value) override { st_.bind(index, value); }
  void bindDouble(int index, double value) override { st_.bind(index, value); }
  void bindText(int index, const std::string& value) override { st_.bind(index, value); }
  void bindBlob(int index, const std::vector<std::uint8_t>& blob) override { st_.bindBlob(index, blob); }
  void bindNull(int index) override { st_.bindNull(index); }
  bool step() override { return st_.step(); }
  void reset() override { st_.reset(); }
  int columnCount() const override { return st_.columnCount(); }
  bool isNull(int col) const override { return st_.isNull(col); }
  std::int64_t getInt(int col) const override { return st_.getInt(col); }
  double getDouble(int col) const override { return st_.getDouble(col); }
  std::string getText(int col) const override { return st_.getText(col); }
  const std::uint8_t* blobData(int col) const override { return st_.blobData(col); }
  std::size_t blobSize(int col) const override { return static_cast<std::size_t>(st_.blobSize(col)); }

 private:
  SqliteStatement st_;
};

class SqliteBackend final : public SqlConnection {
 public:
  SqliteBackend(const std::string& path, const SqlOpenOptions& options)
      : conn_(path, options.read_only ? SqliteConnection::kReadOnly
                                      : SqliteConnection::kReadWrite | (options.create ? SqliteConnection::kCreate : 0)) {
    sqlite3_busy_timeout(conn_.handle(), options.busy_timeout_ms);
    conn_.exec("PRAGMA foreign_keys = ON");
  }
  SqlDialect dialect() const override { return SqlDialect::kSqlite; }
  const std::string& name() const override { return conn_.path(); }
  void exec(const std::string& sql) override { conn_.exec(sql); }
  SqlStatement prepare(const std::string& sql) override {
    return SqlStatement(std::make_unique<SqliteStatementBackend>(conn_.prepare(sql)));
  }
  bool inTransaction() const override { return conn_.inTransaction(); }
  int changes() const override { return conn_.changes(); }
  void beginWrite() override { conn_.exec("BEGIN IMMEDIATE"); }
  void commit() override { conn_.exec("COMMIT"); }
  void rollback() override { conn_.exec("ROLLBACK"); }

 private:
  SqliteConnection conn_;
};

}  // namespace

std::unique_ptr<SqlConnection> openSqliteBackend(const std::string& path, const SqlOpenOptions& options) {
  return std::make_unique<SqliteBackend>(path, options);
}

}  // namespace internal
}  // namespace db
}  // namespace textile_handling
