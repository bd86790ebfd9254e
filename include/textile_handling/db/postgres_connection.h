// Thin RAII wrappers over libpq (PostgreSQL's C client): a connection, a query result and a transaction,
// the PostgreSQL counterpart of sqlite_wrapper.h. Every failing call throws PostgresError
// (database_errors.h) with the server's message, its SQLSTATE and the statement; messages name the
// server by its URL with the password replaced. Not thread-safe: one thread at a time per connection.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "textile_handling/db/database_errors.h"

struct pg_conn;
struct pg_result;

namespace textile_handling {
namespace db {

/// True when a database setting names a PostgreSQL server ("postgresql://..." or "postgres://..."); any
/// other setting is an SQLite file path.
bool isPostgresUrl(const std::string& setting);

/// `url` with the password of its user-info part (postgresql://user:PASSWORD@host...) replaced by "***".
std::string redactedUrl(const std::string& url);

/// One query parameter ($1, $2, ...): SQL NULL, text (integers and reals as round-trip text) or bytes
/// (sent in binary, for bytea columns).
class PgParam {
 public:
  static PgParam null() { return PgParam(); }
  static PgParam bytes(std::vector<std::uint8_t> b);
  PgParam(std::int64_t v);          // NOLINT(google-explicit-constructor): parameters read as a list
  PgParam(int v) : PgParam(static_cast<std::int64_t>(v)) {}  // NOLINT(google-explicit-constructor)
  PgParam(double v);                // NOLINT(google-explicit-constructor)
  PgParam(std::string v);           // NOLINT(google-explicit-constructor)
  PgParam(const char* v) : PgParam(std::string(v)) {}  // NOLINT(google-explicit-constructor)

  bool isNull() const { return null_; }
  bool isBinary() const { return binary_; }
  const std::string& value() const { return value_; }

 private:
  PgParam() = default;
  std::string value_;
  bool null_ = true;
  bool binary_ = false;
};

/// The rows of one statement (owns the libpq result). Row and column indices are 0-based.
class PgResult {
 public:
  PgResult() = default;
  explicit PgResult(pg_result* r);
  int rows() const;
  int columns() const;
  /// Rows changed by INSERT, UPDATE or DELETE (0 for other statements).
  int affectedRows() const;
  bool isNull(int row, int col) const;
  std::string getText(int row, int col) const;
  /// Throws PostgresError if the value is NULL or not an integer.
  std::int64_t getInt(int row, int col) const;
  /// Throws PostgresError if the value is NULL or not a number.
  double getDouble(int row, int col) const;
  /// A bytea column's bytes. Throws PostgresError if the value is NULL or not bytea text.
  std::vector<std::uint8_t> getBytes(int row, int col) const;

 private:
  void checkCell(int row, int col) const;
  std::shared_ptr<pg_result> result_;
};

/// A notification received on a channel this connection listens to (LISTEN/NOTIFY).
struct PgNotification {
  std::string channel;
  std::string payload;
  int sender_pid = 0;  ///< the notifying server process
};

/// An open connection to a PostgreSQL server (closed by the destructor).
class PgConnection {
 public:
  /// Connects to `url` (postgresql://[user[:password]@]host[:port]/database[?params]) within
  /// `connect_timeout_s` seconds. Throws PostgresError (connectionLost() true) naming the redacted URL.
  explicit PgConnection(const std::string& url, int connect_timeout_s = 10);
  ~PgConnection();
  PgConnection(PgConnection&& o) noexcept;
  PgConnection& operator=(PgConnection&& o) noexcept;
  PgConnection(const PgConnection&) = delete;
  PgConnection& operator=(const PgConnection&) = delete;

  /// The URL without its password.
  const std::string& url() const { return url_; }
  /// Whether the connection is still usable (false after the server went away).
  bool isOk() const;
  /// After a lost connection: connects again with the same parameters (session settings and LISTENs
  /// are gone with the old one). True if the server answered.
  bool reconnect();
  /// Runs one or more statements without parameters or results. Throws PostgresError.
  void exec(const std::string& sql);
  /// Runs one statement with parameters $1..$n and returns its rows. Throws PostgresError.
  PgResult query(const std::string& sql, const std::vector<PgParam>& params = {});
  /// Single integer of a query returning one row and column; `fallback` when no row.
  std::int64_t queryInt(const std::string& sql, std::int64_t fallback = 0);
  bool inTransaction() const;
  /// Starts listening on `channel` (a lower-case identifier: letters, digits, '_', at most 63 characters;
  /// anything else is an InvalidInputError, so no text reaches the SQL unchecked). Throws PostgresError.
  void listen(const std::string& channel);
  /// Sends `payload` (at most 7999 bytes) to the listeners of `channel`; delivered when the current
  /// transaction commits (at once outside one). Throws InvalidInputError, PostgresError.
  void notify(const std::string& channel, const std::string& payload);
  /// The next notification, waiting at most `timeout_ms` (0: only what has arrived); nullopt on timeout.
  /// Throws PostgresError (connectionLost()) if the connection dies while waiting.
  std::optional<PgNotification> waitForNotification(int timeout_ms);
  pg_conn* handle() const { return conn_; }

 private:
  [[noreturn]] void fail(pg_result* r, const std::string& sql) const;
  pg_conn* conn_ = nullptr;
  std::string url_;
};

/// BEGIN ... COMMIT; rolls back in the destructor unless commit() was called, so an exception leaves the
/// database as it was.
class PgTransaction {
 public:
  explicit PgTransaction(PgConnection& conn);
  ~PgTransaction();
  PgTransaction(const PgTransaction&) = delete;
  PgTransaction& operator=(const PgTransaction&) = delete;
  void commit();

 private:
  PgConnection& conn_;
  bool done_ = false;
};

}  // namespace db
}  // namespace textile_handling
