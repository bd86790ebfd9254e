// Internal to the database core: SQL fragments and text forms shared by its source files.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

#include "textile_handling/db/sql_connection.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace db {
namespace internal {

/// The current UTC time as the *_at columns store it (ISO 8601 with milliseconds), in `conn`'s dialect.
inline std::string now(SqlConnection& conn) { return sqlNow(conn.dialect()); }

/// The current time in seconds since 1970 (UTC) on the database's clock, as SQL of `conn`'s dialect: the
/// clock every builder of a shared database agrees on.
inline std::string epochNow(SqlConnection& conn) {
  if (conn.dialect() == SqlDialect::kPostgres) return "CAST(extract(epoch from clock_timestamp()) AS DOUBLE PRECISION)";
  return "((julianday('now') - 2440587.5) * 86400.0)";
}

/// Number of rows meeting `condition` in an aggregate query: 0 when none (SQL both backends accept;
/// PostgreSQL cannot sum booleans).
inline std::string countWhere(const std::string& condition) {
  return "coalesce(sum(CASE WHEN " + condition + " THEN 1 ELSE 0 END), 0)";
}

/// A hold point in whole micrometres: "same hold point" is exact in the UNIQUE constraint.
inline std::string holdKey(const Vec2& p) {
  return std::to_string(std::llround(p.x() * 1e6)) + "," + std::to_string(std::llround(p.y() * 1e6));
}

/// Round-trip text of a double.
inline std::string fmt17(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

}  // namespace internal
}  // namespace db
}  // namespace textile_handling
