// SqlConnection over a PostgreSQL server (sql_connection.h), built on the libpq wrappers of
// postgres_connection.h. A statement runs when first stepped and keeps its whole result; values come
// back as text (PostgreSQL prints doubles exactly since version 12) and bytea is decoded on demand.

#include <algorithm>
#include <cstdlib>
#include <functional>
#include <map>

#include "sql_backends.h"
#include "textile_handling/db/postgres_connection.h"

namespace textile_handling {
namespace db {
namespace internal {

namespace {

// Transaction-level advisory lock every writing transaction takes: writers queue one behind the other as
// SQLite's do, while readers go on reading their snapshot.
constexpr std::int64_t kWriterLockKey = 0x5448444257524954;  // "THDBWRIT"


class PostgresStatementBackend final : public SqlStatementBackend {
 public:
  PostgresStatementBackend(PgConnection& conn, int* changes, std::string sql, std::function<bool()> recover)
      : conn_(conn), changes_(changes), sql_(numberedPlaceholders(sql)), recover_(std::move(recover)) {}
  void bindInt(int index, std::int64_t value) override { slot(index) = PgParam(value); }
  void bindDouble(int index, double value) override { slot(index) = PgParam(value); }
  void bindText(int index, const std::string& value) override { slot(index) = PgParam(value); }
  void bindBlob(int index, const std::vector<std::uint8_t>& blob) override { slot(index) = PgParam::bytes(blob); }
  void bindNull(int index) override { slot(index) = PgParam::null(); }

  bool step() override {
    if (!ran_) {
      // Outside a transaction a statement that met a dropped connection is sent once more on a new one
      // (inside one, the server has rolled the transaction back and the caller must hear of it).
      const bool in_transaction = conn_.inTransaction();
      try {
        result_ = conn_.query(sql_, params_);
      } catch (const PostgresError& e) {
        if (!e.connectionLost() || in_transaction || !recover_()) throw;
        result_ = conn_.query(sql_, params_);
      }
      ran_ = true;
      row_ = -1;
      *changes_ = result_.affectedRows();
    }
    blobs_.clear();
    return ++row_ < result_.rows();
  }
  void reset() override {
    ran_ = false;
    result_ = PgResult();
    params_.clear();
    blobs_.clear();
  }
  int columnCount() const override { return ran_ ? result_.columns() : 0; }
  bool isNull(int col) const override { return result_.isNull(row(), col); }
  std::int64_t getInt(int col) const override {
    if (isNull(col)) return 0;
    const std::string t = result_.getText(row(), col);
    if (t == "t") return 1;  // booleans (comparisons in a select list)
    if (t == "f") return 0;
    if (t.find_first_of(".eE") != std::string::npos) return static_cast<std::int64_t>(std::strtod(t.c_str(), nullptr));
    return std::strtoll(t.c_str(), nullptr, 10);
  }
  double getDouble(int col) const override { return isNull(col) ? 0.0 : result_.getDouble(row(), col); }
  std::string getText(int col) const override { return isNull(col) ? std::string() : result_.getText(row(), col); }
  const std::uint8_t* blobData(int col) const override {
    const std::vector<std::uint8_t>& b = blob(col);
    return b.empty() ? nullptr : b.data();
  }
  std::size_t blobSize(int col) const override { return blob(col).size(); }

 private:
  PgParam& slot(int index) {
    if (index < 1 || index > 65535)
      throw PostgresError("bind index " + std::to_string(index) + " out of range in: " + sql_.substr(0, 200), "", false);
    if (params_.size() < static_cast<std::size_t>(index)) params_.resize(static_cast<std::size_t>(index), PgParam::null());
    ran_ = false;
    return params_[static_cast<std::size_t>(index - 1)];
  }
  int row() const {
    if (!ran_ || row_ < 0 || row_ >= result_.rows())
      throw PostgresError("no current row in: " + sql_.substr(0, 200), "", false);
    return row_;
  }
  const std::vector<std::uint8_t>& blob(int col) const {
    auto it = blobs_.find(col);
    if (it == blobs_.end())
      it = blobs_.emplace(col, isNull(col) ? std::vector<std::uint8_t>() : result_.getBytes(row(), col)).first;
    return it->second;
  }

  PgConnection& conn_;
  int* changes_;
  std::string sql_;
  std::function<bool()> recover_;  // reconnects the backend's connection; false if the server is away
  std::vector<PgParam> params_;
  PgResult result_;
  bool ran_ = false;
  int row_ = -1;
  mutable std::map<int, std::vector<std::uint8_t>> blobs_;  // decoded bytea of the current row
};

class PostgresBackend final : public SqlConnection {
 public:
  PostgresBackend(const std::string& url, const SqlOpenOptions& options)
      : conn_(url, options.connect_timeout_s), name_(redactedUrl(url)), options_(options) {
    configureSession();
  }
  SqlDialect dialect() const override { return SqlDialect::kPostgres; }
  const std::string& name() const override { return name_; }
  void exec(const std::string& sql) override {
    reconnectIfLost();
    conn_.exec(sql);
    changes_ = 0;
  }
  SqlStatement prepare(const std::string& sql) override {
    reconnectIfLost();
    return SqlStatement(std::make_unique<PostgresStatementBackend>(conn_, &changes_, sql, [this] { return recover(); }));
  }
  bool inTransaction() const override { return conn_.inTransaction(); }
  int changes() const override { return changes_; }
  void beginWrite() override {
    reconnectIfLost();
    try {
      conn_.exec("BEGIN");
    } catch (const PostgresError& e) {
      if (!e.connectionLost() || !recover()) throw;
      conn_.exec("BEGIN");  // nothing had happened yet: begin on the new connection
    }
    try {
      conn_.query("SELECT pg_advisory_xact_lock($1)", {PgParam(kWriterLockKey)});
    } catch (...) {
      if (conn_.isOk()) conn_.exec("ROLLBACK");
      throw;
    }
  }
  void commit() override { conn_.exec("COMMIT"); }
  void rollback() override { conn_.exec("ROLLBACK"); }

 private:
  // Lock waits (another writer, a schema change) give up after the busy timeout, as SQLite's do.
  void configureSession() {
    conn_.exec("SET lock_timeout = " + std::to_string(std::max(1, options_.busy_timeout_ms)));
    if (options_.read_only) conn_.exec("SET default_transaction_read_only = on");
  }
  // A connection the server dropped (restart, network) is opened again before the next statement; one
  // that cannot be opened throws, and the call after it tries again. Never inside a transaction: a
  // transaction cut by a lost connection was rolled back by the server, and the caller gets its error.
  void reconnectIfLost() {
    if (conn_.isOk()) return;
    if (!recover())
      throw PostgresError("PostgreSQL at " + name_ + ": connection lost and the server does not answer yet", "", true);
  }
  bool recover() {
    if (!conn_.reconnect()) return false;
    try {
      configureSession();
    } catch (const PostgresError&) {
      return false;
    }
    return true;
  }

  PgConnection conn_;
  std::string name_;
  SqlOpenOptions options_;
  int changes_ = 0;
};

}  // namespace

std::unique_ptr<SqlConnection> openPostgresBackend(const std::string& url, const SqlOpenOptions& options) {
  return std::make_unique<PostgresBackend>(url, options);
}

}  // namespace internal
}  // namespace db
}  // namespace textile_handling
