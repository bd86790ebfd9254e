// Typed errors of the hanging-drape database (ROS-free). Every failure of the database layer is one
// of these, so callers can tell a bad file from bad input from an SQLite or PostgreSQL failure. See docs/database.md.
#pragma once

#include <stdexcept>
#include <string>
#include <utility>

namespace textile_handling {
namespace db {

/// Base class of every database-layer error.
class DrapeDatabaseError : public std::runtime_error {
 public:
  explicit DrapeDatabaseError(const std::string& what) : std::runtime_error(what) {}
};

/// An SQLite call failed (I/O error, locked file, constraint violation, not a database, ...).
/// `code()` is the SQLite extended result code.
class SqliteError : public DrapeDatabaseError {
 public:
  SqliteError(const std::string& what, int code) : DrapeDatabaseError(what), code_(code) {}
  int code() const { return code_; }

 private:
  int code_;
};

/// A PostgreSQL call failed: the server refused the connection, a statement failed, or the connection was
/// lost. `sqlstate()` is the five-character SQLSTATE ("23505" unique violation, "42P01" undefined table,
/// ...; empty when the server sent none, e.g. no connection); `connectionLost()` tells a dead connection
/// (retry after reconnecting) from a failed statement. Messages name the URL without its password.
class PostgresError : public DrapeDatabaseError {
 public:
  PostgresError(const std::string& what, std::string sqlstate, bool connection_lost)
      : DrapeDatabaseError(what), sqlstate_(std::move(sqlstate)), connection_lost_(connection_lost) {}
  const std::string& sqlstate() const { return sqlstate_; }
  bool connectionLost() const { return connection_lost_; }

 private:
  std::string sqlstate_;
  bool connection_lost_;
};

/// The file's schema version is unknown (newer than this program), or the file is not a drape
/// database at all, or a migration failed. The file is left unchanged.
class SchemaVersionError : public DrapeDatabaseError {
 public:
  explicit SchemaVersionError(const std::string& what) : DrapeDatabaseError(what) {}
};

/// A stored blob (particle positions or a silhouette mask) is truncated, corrupted, or of an unknown
/// format version. The message names the row.
class BlobFormatError : public DrapeDatabaseError {
 public:
  explicit BlobFormatError(const std::string& what) : DrapeDatabaseError(what) {}
};

/// A textile, simulation or view that the caller named does not exist.
class NotFoundError : public DrapeDatabaseError {
 public:
  explicit NotFoundError(const std::string& what) : DrapeDatabaseError(what) {}
};

/// Bad input (invalid polygon, NaN parameter, conflicting textile definition, ...). Raised before
/// anything is written, so stored data stay intact.
class InvalidInputError : public DrapeDatabaseError {
 public:
  explicit InvalidInputError(const std::string& what) : DrapeDatabaseError(what) {}
};

}  // namespace db
}  // namespace textile_handling
