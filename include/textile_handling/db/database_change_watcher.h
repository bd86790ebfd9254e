// Tells a reader (the recognizer) that a drape database may have changed, without it having to reload
// on a timer: on PostgreSQL through LISTEN/NOTIFY (writers notify channel kDrapeDatabaseChannel, with their
// schema as the payload, in the transaction that stores results or swaps a generation, so the notification
// arrives with the commit, from any machine; a watcher counts only its own schema's); on an SQLite file by polling `PRAGMA data_version`, which changes whenever another
// connection commits. "May have changed": the reader decides by its own fingerprint
// (TextileRecognizer::reloadIfChanged). ROS-free. docs/database.md, "Readers and change notification".
#pragma once

#include <memory>
#include <string>

namespace textile_handling {
namespace db {

/// The PostgreSQL notification channel of drape database content changes.
constexpr const char* kDrapeDatabaseChannel = "textile_handling_drapes_changed";

class DatabaseChangeWatcher {
 public:
  /// Watches the database `setting` (an SQLite file path or a postgresql:// URL) on a connection of its
  /// own. Throws SqliteError / PostgresError if it cannot be opened.
  explicit DatabaseChangeWatcher(const std::string& setting);
  ~DatabaseChangeWatcher();
  DatabaseChangeWatcher(const DatabaseChangeWatcher&) = delete;
  DatabaseChangeWatcher& operator=(const DatabaseChangeWatcher&) = delete;

  /// Waits up to `timeout_ms` for a change committed by another connection since the last call (or since
  /// construction); true if there was one. Throws PostgresError when the server is gone (a new watcher
  /// reconnects) and SqliteError on a failing file.
  bool waitForChange(int timeout_ms);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace db
}  // namespace textile_handling
