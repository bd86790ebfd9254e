// Typed errors of the hanging-drape database (ROS-free). Every failure of the database layer is one
// of these, so callers can tell a bad file from bad input from an SQLite failure. See docs/database.md.
#pragma once

#include <stdexcept>
#include <string>

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
