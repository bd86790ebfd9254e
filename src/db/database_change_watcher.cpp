// DatabaseChangeWatcher (database_change_watcher.h): LISTEN on PostgreSQL, data_version polling on SQLite.
#include "textile_handling/db/database_change_watcher.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <optional>
#include <thread>

#include "textile_handling/db/postgres_connection.h"
#include "textile_handling/db/sqlite_wrapper.h"

namespace textile_handling {
namespace db {

struct DatabaseChangeWatcher::Impl {
  std::unique_ptr<PgConnection> pg;
  std::string schema;  // the drape database's schema: notifications of other schemas are not ours
  std::unique_ptr<SqliteConnection> sqlite;
  std::int64_t data_version = 0;
};

DatabaseChangeWatcher::DatabaseChangeWatcher(const std::string& setting) : impl_(std::make_unique<Impl>()) {
  if (isPostgresUrl(setting)) {
    impl_->pg = std::make_unique<PgConnection>(setting);
    const PgResult r = impl_->pg->query("SELECT current_schema()");
    impl_->schema = r.rows() == 1 && !r.isNull(0, 0) ? r.getText(0, 0) : "";
    impl_->pg->listen(kDrapeDatabaseChannel);
  } else {
    impl_->sqlite = std::make_unique<SqliteConnection>(setting, SqliteConnection::kReadOnly);
    impl_->data_version = impl_->sqlite->queryInt("PRAGMA data_version");
  }
}

DatabaseChangeWatcher::~DatabaseChangeWatcher() = default;

bool DatabaseChangeWatcher::waitForChange(int timeout_ms) {
  if (impl_->pg) {
    // Everything of this schema queued counts as one change; wait (until the deadline) only while nothing
    // of it has come.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms > 0 ? timeout_ms : 0);
    bool changed = false;
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      const std::optional<PgNotification> n =
          impl_->pg->waitForNotification(changed ? 0 : static_cast<int>(std::max<std::int64_t>(0, left.count())));
      if (!n) return changed;
      if (n->payload == impl_->schema) changed = true;
    }
  }
  // SQLite has no notifications: poll the file's commit counter (cheap: no table is read).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms > 0 ? timeout_ms : 0);
  for (;;) {
    const std::int64_t v = impl_->sqlite->queryInt("PRAGMA data_version");
    if (v != impl_->data_version) {
      impl_->data_version = v;
      return true;
    }
    const auto left = deadline - std::chrono::steady_clock::now();
    if (left <= std::chrono::milliseconds(0)) return false;
    std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(left, std::chrono::milliseconds(100)));
  }
}

}  // namespace db
}  // namespace textile_handling
