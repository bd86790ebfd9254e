#include "textile_handling/db/postgres_connection.h"

#include <libpq-fe.h>

#include <poll.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace textile_handling {
namespace db {

namespace {

std::string trimmed(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

std::string shortSql(const std::string& sql) { return sql.size() > 200 ? sql.substr(0, 200) + "..." : sql; }

}  // namespace

bool isPostgresUrl(const std::string& setting) {
  return setting.rfind("postgresql://", 0) == 0 || setting.rfind("postgres://", 0) == 0;
}

std::string redactedUrl(const std::string& url) {
  const std::size_t scheme = url.find("://");
  if (scheme == std::string::npos) return url;
  const std::size_t start = scheme + 3;
  const std::size_t at = url.find('@', start);
  const std::size_t slash = url.find('/', start);
  if (at == std::string::npos || (slash != std::string::npos && slash < at)) return url;
  const std::size_t colon = url.find(':', start);
  if (colon == std::string::npos || colon > at) return url;
  return url.substr(0, colon + 1) + "***" + url.substr(at);
}

// ---- parameters -------------------------------------------------------------------------------

PgParam PgParam::bytes(std::vector<std::uint8_t> b) {
  PgParam p;
  p.value_.assign(b.begin(), b.end());
  p.null_ = false;
  p.binary_ = true;
  return p;
}

PgParam::PgParam(std::int64_t v) : value_(std::to_string(v)), null_(false) {}

PgParam::PgParam(double v) : null_(false) {
  if (std::isnan(v)) {
    value_ = "NaN";
  } else if (std::isinf(v)) {
    value_ = v > 0 ? "Infinity" : "-Infinity";
  } else {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    value_ = buf;
  }
}

PgParam::PgParam(std::string v) : value_(std::move(v)), null_(false) {}

// ---- result -----------------------------------------------------------------------------------

PgResult::PgResult(pg_result* r) : result_(r, PQclear) {}

int PgResult::rows() const { return result_ ? PQntuples(result_.get()) : 0; }
int PgResult::columns() const { return result_ ? PQnfields(result_.get()) : 0; }

int PgResult::affectedRows() const {
  if (!result_) return 0;
  const char* n = PQcmdTuples(result_.get());
  return n && *n ? std::atoi(n) : 0;
}

void PgResult::checkCell(int row, int col) const {
  if (row < 0 || row >= rows() || col < 0 || col >= columns())
    throw PostgresError("PostgreSQL result: no cell (" + std::to_string(row) + ", " + std::to_string(col) + ") in " +
                            std::to_string(rows()) + " x " + std::to_string(columns()),
                        "", false);
}

bool PgResult::isNull(int row, int col) const {
  checkCell(row, col);
  return PQgetisnull(result_.get(), row, col) != 0;
}

std::string PgResult::getText(int row, int col) const {
  checkCell(row, col);
  return std::string(PQgetvalue(result_.get(), row, col),
                     static_cast<std::size_t>(PQgetlength(result_.get(), row, col)));
}

std::int64_t PgResult::getInt(int row, int col) const {
  if (isNull(row, col)) throw PostgresError("PostgreSQL result: column " + std::to_string(col) + " is NULL", "", false);
  const std::string t = getText(row, col);
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(t.c_str(), &end, 10);
  if (t.empty() || errno != 0 || *end != '\0')
    throw PostgresError("PostgreSQL result: column " + std::to_string(col) + " is not an integer: '" + t + "'", "", false);
  return v;
}

double PgResult::getDouble(int row, int col) const {
  if (isNull(row, col)) throw PostgresError("PostgreSQL result: column " + std::to_string(col) + " is NULL", "", false);
  const std::string t = getText(row, col);
  if (t == "NaN") return std::nan("");
  if (t == "Infinity") return HUGE_VAL;
  if (t == "-Infinity") return -HUGE_VAL;
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (t.empty() || *end != '\0')
    throw PostgresError("PostgreSQL result: column " + std::to_string(col) + " is not a number: '" + t + "'", "", false);
  return v;
}

std::vector<std::uint8_t> PgResult::getBytes(int row, int col) const {
  if (isNull(row, col)) throw PostgresError("PostgreSQL result: column " + std::to_string(col) + " is NULL", "", false);
  std::size_t n = 0;
  unsigned char* raw = PQunescapeBytea(reinterpret_cast<const unsigned char*>(PQgetvalue(result_.get(), row, col)), &n);
  if (!raw) throw PostgresError("PostgreSQL result: column " + std::to_string(col) + " is not bytea", "", false);
  std::vector<std::uint8_t> out(raw, raw + n);
  PQfreemem(raw);
  return out;
}

// ---- connection -------------------------------------------------------------------------------

PgConnection::PgConnection(const std::string& url, int connect_timeout_s) : url_(redactedUrl(url)) {
  if (!isPostgresUrl(url))
    throw PostgresError("PostgreSQL: '" + url_ + "' is not a postgresql:// URL", "", true);
  const std::string timeout = std::to_string(connect_timeout_s > 0 ? connect_timeout_s : 10);
  const char* keys[] = {"dbname", "connect_timeout", "application_name", nullptr};
  const char* values[] = {url.c_str(), timeout.c_str(), "textile_handling", nullptr};
  conn_ = PQconnectdbParams(keys, values, 1);
  if (!conn_ || PQstatus(conn_) != CONNECTION_OK) {
    const std::string msg = conn_ ? trimmed(PQerrorMessage(conn_)) : "out of memory";
    if (conn_) PQfinish(conn_);
    conn_ = nullptr;
    throw PostgresError("PostgreSQL at " + url_ + ": cannot connect: " + msg, "", true);
  }
  // Server notices (e.g. "relation already exists, skipping") are not errors: keep them off stderr.
  PQsetNoticeProcessor(conn_, [](void*, const char*) {}, nullptr);
}

PgConnection::~PgConnection() {
  if (conn_) PQfinish(conn_);
}

PgConnection::PgConnection(PgConnection&& o) noexcept : conn_(o.conn_), url_(std::move(o.url_)) { o.conn_ = nullptr; }

PgConnection& PgConnection::operator=(PgConnection&& o) noexcept {
  if (this != &o) {
    if (conn_) PQfinish(conn_);
    conn_ = o.conn_;
    url_ = std::move(o.url_);
    o.conn_ = nullptr;
  }
  return *this;
}

bool PgConnection::isOk() const { return conn_ && PQstatus(conn_) == CONNECTION_OK; }

bool PgConnection::reconnect() {
  if (!conn_) return false;
  PQreset(conn_);  // closes the old connection and opens a new one with the same parameters
  return PQstatus(conn_) == CONNECTION_OK;
}

bool PgConnection::inTransaction() const {
  return conn_ && PQtransactionStatus(conn_) != PQTRANS_IDLE && PQtransactionStatus(conn_) != PQTRANS_UNKNOWN;
}

void PgConnection::fail(pg_result* r, const std::string& sql) const {
  std::string state;
  std::string msg;
  if (r) {
    const char* s = PQresultErrorField(r, PG_DIAG_SQLSTATE);
    if (s) state = s;
    msg = trimmed(PQresultErrorMessage(r));
    PQclear(r);
  }
  if (msg.empty() && conn_) msg = trimmed(PQerrorMessage(conn_));
  const bool lost = !conn_ || PQstatus(conn_) == CONNECTION_BAD;
  throw PostgresError("PostgreSQL at " + url_ + ": " + (lost ? "connection lost: " : "") + msg +
                          (state.empty() ? "" : " (SQLSTATE " + state + ")") + " in: " + shortSql(sql),
                      state, lost);
}

void PgConnection::exec(const std::string& sql) {
  if (!conn_) fail(nullptr, sql);
  pg_result* r = PQexec(conn_, sql.c_str());
  const ExecStatusType st = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
  if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) fail(r, sql);
  PQclear(r);
}

PgResult PgConnection::query(const std::string& sql, const std::vector<PgParam>& params) {
  if (!conn_) fail(nullptr, sql);
  std::vector<const char*> values(params.size());
  std::vector<int> lengths(params.size()), formats(params.size());
  for (std::size_t i = 0; i < params.size(); ++i) {
    values[i] = params[i].isNull() ? nullptr : params[i].value().data();
    lengths[i] = static_cast<int>(params[i].value().size());
    formats[i] = params[i].isBinary() ? 1 : 0;
  }
  pg_result* r = PQexecParams(conn_, sql.c_str(), static_cast<int>(params.size()), nullptr, values.data(),
                              lengths.data(), formats.data(), 0);
  const ExecStatusType st = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
  if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) fail(r, sql);
  return PgResult(r);
}

std::int64_t PgConnection::queryInt(const std::string& sql, std::int64_t fallback) {
  const PgResult r = query(sql);
  if (r.rows() == 0 || r.isNull(0, 0)) return fallback;
  return r.getInt(0, 0);
}

namespace {

void checkChannel(const std::string& channel) {
  bool ok = !channel.empty() && channel.size() <= 63 && !(channel[0] >= '0' && channel[0] <= '9');
  for (char c : channel) ok = ok && ((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_');
  if (!ok)
    throw InvalidInputError("PostgreSQL channel '" + channel.substr(0, 80) +
                            "': use a lower-case identifier (letters, digits, '_', at most 63 characters)");
}

}  // namespace

void PgConnection::listen(const std::string& channel) {
  checkChannel(channel);
  exec("LISTEN " + channel);
}

void PgConnection::notify(const std::string& channel, const std::string& payload) {
  checkChannel(channel);
  if (payload.size() > 7999) throw InvalidInputError("PostgreSQL notification payload longer than 7999 bytes");
  query("SELECT pg_notify($1, $2)", {PgParam(channel), PgParam(payload)});
}

std::optional<PgNotification> PgConnection::waitForNotification(int timeout_ms) {
  if (!conn_) fail(nullptr, "(waiting for a notification)");
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms > 0 ? timeout_ms : 0);
  for (;;) {
    if (PQconsumeInput(conn_) == 0) fail(nullptr, "(waiting for a notification)");
    if (PGnotify* n = PQnotifies(conn_)) {
      PgNotification out{n->relname ? n->relname : "", n->extra ? n->extra : "", n->be_pid};
      PQfreemem(n);
      return out;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return std::nullopt;
    pollfd p{PQsocket(conn_), POLLIN, 0};
    if (p.fd < 0) fail(nullptr, "(waiting for a notification)");
    ::poll(&p, 1, static_cast<int>(left.count()));
  }
}

// ---- transaction ------------------------------------------------------------------------------

PgTransaction::PgTransaction(PgConnection& conn) : conn_(conn) { conn_.exec("BEGIN"); }

PgTransaction::~PgTransaction() {
  if (!done_ && conn_.isOk() && conn_.inTransaction()) {
    try {
      conn_.exec("ROLLBACK");
    } catch (...) {
      // The server rolls back an open transaction when the connection closes.
    }
  }
}

void PgTransaction::commit() {
  conn_.exec("COMMIT");
  done_ = true;
}

}  // namespace db
}  // namespace textile_handling
