// Internal to the database core: the two implementations of SqlConnection (sql_connection.h).
#pragma once

#include <memory>
#include <string>

#include "textile_handling/db/sql_connection.h"

namespace textile_handling {
namespace db {

namespace internal {

/// An SQLite file: foreign keys on, the busy timeout set, the file created only with options.create.
std::unique_ptr<SqlConnection> openSqliteBackend(const std::string& path, const SqlOpenOptions& options);
/// A PostgreSQL server: read-only sessions when options.read_only, lock waits bounded by the busy timeout.
std::unique_ptr<SqlConnection> openPostgresBackend(const std::string& url, const SqlOpenOptions& options);

}  // namespace internal
}  // namespace db
}  // namespace textile_handling
