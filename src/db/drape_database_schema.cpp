// The drape database's schema: the DDL of the current version, the migrations from older versions, and
// opening a file (look before writing, WAL, create or migrate). docs/database.md, "File and schema".
#include <sqlite3.h>

#include <chrono>
#include <string>
#include <thread>

#include "database_sql.h"
#include "textile_handling/db/blob_codec.h"
#include "textile_handling/db/hanging_drape_database.h"

namespace textile_handling {
namespace db {

using internal::now;

namespace {

// The simulations table under `name` (the v1 -> v2 migration builds it under another name and renames
// it), with the claim columns of version 3 or without them (version 2). `generation` tells which build of
// the textile a row belongs to: readers use the textile's active generation only, so a rebuild can run
// beside the rows it replaces. `claimed_by` / `claim_expires_at` (seconds since 1970, the database's
// clock) say which builder runs a pending row and until when; `claims` counts the claims ever made.
constexpr const char* kClaimColumnsSql =
    "  claimed_by            TEXT,\n"
    "  claim_expires_at      REAL,\n"
    "  claims                INTEGER NOT NULL DEFAULT 0,\n";

std::string simulationsTableSql(const std::string& name, bool with_claims) {
  return "CREATE TABLE " + name + R"SQL( (
  id                    INTEGER PRIMARY KEY,
  textile_id            INTEGER NOT NULL REFERENCES textiles(id) ON DELETE CASCADE,
  generation            INTEGER NOT NULL DEFAULT 0,
  hold_x                REAL NOT NULL,
  hold_y                REAL NOT NULL,
  hold_key              TEXT NOT NULL,
  lattice_i             INTEGER NOT NULL,
  lattice_j             INTEGER NOT NULL,
  source                TEXT NOT NULL CHECK (source IN ('identity', 'mirror_x', 'mirror_y', 'mirror_xy')),
  source_simulation_id  INTEGER REFERENCES simulations(id) ON DELETE CASCADE,
  model                 TEXT NOT NULL,
  integrator            TEXT NOT NULL,
  spacing               REAL NOT NULL CHECK (spacing > 0),
  parameters            TEXT NOT NULL,
  status                TEXT NOT NULL DEFAULT 'pending' CHECK (status IN ('pending', 'done', 'failed')),
  failure_reason        TEXT,
  rest_reached          INTEGER,
  sim_time_s            REAL,
  wall_time_s           REAL,
  render_time_s         REAL,
  steps                 INTEGER,
  rejected_steps        INTEGER,
  particles             INTEGER,
  held_particle         INTEGER,
  hanging_depth_m       REAL,
  view_count            INTEGER NOT NULL DEFAULT 0,
  positions             BLOB,
  created_at            TEXT NOT NULL,
  finished_at           TEXT,
)SQL" + std::string(with_claims ? kClaimColumnsSql : "") + R"SQL(  CHECK ((status = 'done') = (positions IS NOT NULL)),
  CHECK ((source = 'identity') = (source_simulation_id IS NULL)),
  UNIQUE (textile_id, generation, parameters, hold_key)
);
)SQL";
}

constexpr const char* kSimulationsIndexSql =
    "CREATE INDEX simulations_by_textile_status ON simulations(textile_id, generation, status);\n";

// One staged generation per textile at most: what a resimulation builds beside the active entries.
constexpr const char* kStagedGenerationsSql = R"SQL(
CREATE TABLE staged_generations (
  textile_id     INTEGER PRIMARY KEY REFERENCES textiles(id) ON DELETE CASCADE,
  generation     INTEGER NOT NULL CHECK (generation > 0),
  material_name  TEXT NOT NULL,
  material_yaml  TEXT NOT NULL,
  spacing        REAL NOT NULL CHECK (spacing >= 0),
  model          TEXT NOT NULL,
  created_at     TEXT NOT NULL
);
)SQL";

constexpr const char* kTablesBeforeSimulations = R"SQL(
CREATE TABLE schema_version (
  version     INTEGER NOT NULL,
  written_at  TEXT NOT NULL
);
CREATE TABLE textiles (
  id             INTEGER PRIMARY KEY,
  name           TEXT NOT NULL UNIQUE CHECK (length(name) > 0),
  outline        TEXT NOT NULL,
  mirrored       INTEGER NOT NULL DEFAULT 0 CHECK (mirrored IN (0, 1)),
  mirror_x       REAL NOT NULL DEFAULT 0,
  material_name  TEXT NOT NULL,
  material_yaml  TEXT NOT NULL,
  symmetry       TEXT NOT NULL CHECK (symmetry IN ('none', 'x', 'y', 'xy')),
  symmetry_cx    REAL NOT NULL,
  symmetry_cy    REAL NOT NULL,
  created_at     TEXT NOT NULL,
  generation     INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE grasp_points (
  textile_id  INTEGER NOT NULL REFERENCES textiles(id) ON DELETE CASCADE,
  name        TEXT NOT NULL,
  kind        TEXT NOT NULL CHECK (kind IN ('corner', 'grasp')),
  x           REAL NOT NULL,
  y           REAL NOT NULL,
  ordinal     INTEGER NOT NULL DEFAULT 0,
  PRIMARY KEY (textile_id, name)
);
)SQL";

constexpr const char* kViewsSql = R"SQL(
CREATE TABLE views (
  id                INTEGER PRIMARY KEY,
  simulation_id     INTEGER NOT NULL REFERENCES simulations(id) ON DELETE CASCADE,
  view_angle_deg    REAL NOT NULL,
  projection        TEXT NOT NULL,
  width_px          INTEGER NOT NULL CHECK (width_px > 0),
  height_px         INTEGER NOT NULL CHECK (height_px > 0),
  metres_per_pixel  REAL NOT NULL CHECK (metres_per_pixel > 0),
  top_margin_px     REAL NOT NULL,
  area              INTEGER NOT NULL,
  mask              BLOB NOT NULL,
  UNIQUE (simulation_id, view_angle_deg)
);
)SQL";

// v1 -> v2: textiles get their active generation, simulations a generation (the table is rebuilt: the
// UNIQUE constraint gains the generation), and staged generations get their table. Every existing row
// is generation 0, the active one. Runs with foreign keys off (SQLite's table-rebuild procedure).
void migrateV1ToV2(SqlConnection& conn) {
  conn.exec("ALTER TABLE textiles ADD COLUMN generation INTEGER NOT NULL DEFAULT 0");
  conn.exec(simulationsTableSql("simulations_v2", false));
  const char* columns =
      "id, textile_id, hold_x, hold_y, hold_key, lattice_i, lattice_j, source, source_simulation_id, model, "
      "integrator, spacing, parameters, status, failure_reason, rest_reached, sim_time_s, wall_time_s, "
      "render_time_s, steps, rejected_steps, particles, held_particle, hanging_depth_m, view_count, positions, "
      "created_at, finished_at";
  conn.exec(std::string("INSERT INTO simulations_v2(") + columns + ") SELECT " + columns + " FROM simulations");
  conn.exec("DROP TABLE simulations");
  conn.exec("ALTER TABLE simulations_v2 RENAME TO simulations");
  conn.exec(kSimulationsIndexSql);
  conn.exec(kStagedGenerationsSql);
}

// v2 -> v3: grasp points keep their order in a column of their own (they were read in SQLite's rowid
// order, which PostgreSQL does not have); simulations get the claim columns of concurrent builders.
void migrateV2ToV3(SqlConnection& conn) {
  conn.exec("ALTER TABLE grasp_points ADD COLUMN ordinal INTEGER NOT NULL DEFAULT 0");
  conn.exec("UPDATE grasp_points SET ordinal = rowid");
  conn.exec("ALTER TABLE simulations ADD COLUMN claimed_by TEXT");
  conn.exec("ALTER TABLE simulations ADD COLUMN claim_expires_at REAL");
  conn.exec("ALTER TABLE simulations ADD COLUMN claims INTEGER NOT NULL DEFAULT 0");
}

}  // namespace

std::string schemaSql(SqlDialect dialect) {
  return dialectDdl(std::string(kTablesBeforeSimulations) + simulationsTableSql("simulations", true) + kSimulationsIndexSql +
                        kViewsSql + kStagedGenerationsSql,
                    dialect);
}

void migrateSchemaStep(SqlConnection& conn, int from_version) {
  if (from_version == 0) {
    // v0 (the prototype layout) stored views without their foreground area; v1 keeps the area so
    // that statistics and loaders need not decode masks. Fill it from the mask blobs.
    conn.exec("ALTER TABLE views ADD COLUMN area INTEGER NOT NULL DEFAULT 0");
    SqlStatement sel = conn.prepare("SELECT id, mask FROM views");
    SqlStatement upd = conn.prepare("UPDATE views SET area = ? WHERE id = ?");
    while (sel.step()) {
      const std::int64_t id = sel.getInt(0);
      const vision::BitMask m =
          decodeMask(sel.blobData(1), static_cast<std::size_t>(sel.blobSize(1)), "view " + std::to_string(id));
      upd.bind(1, static_cast<std::int64_t>(m.count())).bind(2, id);
      upd.run();
      upd.reset();
    }
    return;
  }
  if (from_version == 1) {
    migrateV1ToV2(conn);
    return;
  }
  if (from_version == 2) {
    migrateV2ToV3(conn);
    return;
  }
  throw SchemaVersionError("no migration from schema version " + std::to_string(from_version));
}

// ---- open -------------------------------------------------------------------------------------

namespace {

// What an opened database is, read without writing anything.
struct FileState {
  std::int64_t objects = 0;   // schema objects other than the backend's own
  std::int64_t version = -1;  // schema_version.version (objects > 0)
};

std::int64_t countTables(SqlConnection& conn, const std::string& only_name = "") {
  const std::string name_clause = only_name.empty() ? "" : " AND table_name = '" + only_name + "'";
  if (conn.dialect() == SqlDialect::kPostgres)
    return conn.queryInt("SELECT count(*) FROM information_schema.tables WHERE table_schema = current_schema()" +
                         name_clause);
  if (only_name.empty()) return conn.queryInt("SELECT count(*) FROM sqlite_master WHERE name NOT LIKE 'sqlite_%'");
  return conn.queryInt("SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = '" + only_name + "'");
}

// Reads the database's state and refuses databases that are not (or not yet) drape databases this program
// can use. Only reads: a refused file or server database is left as it was.
FileState inspectFile(SqlConnection& conn, const std::string& path, int supported) {
  FileState f;
  f.objects = countTables(conn);  // SQLite: also checks "not a database"
  if (conn.dialect() == SqlDialect::kSqlite) {
    const std::int64_t app_id = conn.queryInt("PRAGMA application_id");
    if (app_id != 0 && app_id != HangingDrapeDatabase::kApplicationId)
      throw SchemaVersionError("'" + path + "' is an SQLite file of another application (application_id " +
                               std::to_string(app_id) + "), not a drape database");
  }
  if (f.objects == 0) return f;
  if (countTables(conn, "schema_version") == 0)
    throw SchemaVersionError("'" + path + "' has no schema_version table: not a drape database");
  if (conn.queryInt("SELECT count(*) FROM schema_version") != 1)
    throw SchemaVersionError("'" + path + "' has a damaged schema_version table (expected exactly one row)");
  f.version = conn.queryInt("SELECT version FROM schema_version");
  if (f.version > supported)
    throw SchemaVersionError("'" + path + "' has schema version " + std::to_string(f.version) +
                             ", newer than this program supports (" + std::to_string(supported) +
                             "); use a newer textile_handling");
  if (f.version < 0) throw SchemaVersionError("'" + path + "' has an invalid schema version " + std::to_string(f.version));
  return f;
}

}  // namespace

void HangingDrapeDatabase::initialiseSchema() {
  // 1. Look before writing: foreign, damaged and newer files are refused untouched (switching the
  //    journal to WAL already rewrites the file header, so it must not happen before this check).
  FileState f = inspectFile(*conn_, path_, kSchemaVersion);
  if (read_only_) {
    if (f.objects == 0) throw SchemaVersionError("'" + path_ + "' is empty, not a drape database");
    if (f.version != kSchemaVersion)
      throw SchemaVersionError("'" + path_ + "' has schema version " + std::to_string(f.version) +
                               " and needs a migration to " + std::to_string(kSchemaVersion) + "; open it read-write");
    return;
  }
  if (conn_->dialect() == SqlDialect::kPostgres) {
    initialisePostgresSchema(f.objects, f.version);
    return;
  }
  // 2. A drape database (or an empty file) opened for writing: WAL, so that readers never block the
  //    writer and a killed writer leaves a consistent file. With WAL, synchronous = NORMAL keeps every
  //    committed transaction across a process crash (only a power loss can drop the last commits).
  //    Switching to WAL needs an exclusive lock, and SQLite answers SQLITE_BUSY at once (without the busy
  //    handler) when another connection is mid-transaction, e.g. another process creating the schema of
  //    the same new file. So retry for up to the busy timeout.
  std::string mode;
  for (const auto start = std::chrono::steady_clock::now();;) {
    try {
      mode = conn_->queryText("PRAGMA journal_mode = WAL");
      break;
    } catch (const SqliteError& e) {
      const int primary = e.code() & 0xff;
      const auto waited = std::chrono::steady_clock::now() - start;
      if ((primary != SQLITE_BUSY && primary != SQLITE_LOCKED) ||
          waited > std::chrono::milliseconds(busy_timeout_ms_))
        throw;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  if (mode != "wal") throw SqliteError("cannot switch '" + path_ + "' to WAL mode (got '" + mode + "')", SQLITE_ERROR);
  conn_->exec("PRAGMA synchronous = NORMAL");
  if (f.objects > 0 && f.version == kSchemaVersion) return;
  // 3. Create or migrate under the write lock. Another process may have created or migrated the file
  //    between the look above and the lock, so look again inside the transaction.
  // Migrations rebuild tables that others reference (v1 -> v2 rebuilds `simulations`), which SQLite
  // allows only with foreign keys off; the pragma is a no-op inside a transaction, so it is switched
  // here and back on below, and foreign_key_check runs before the commit.
  conn_->exec("PRAGMA foreign_keys = OFF");
  struct ForeignKeysBackOn {
    SqlConnection& c;
    ~ForeignKeysBackOn() {
      try {
        c.exec("PRAGMA foreign_keys = ON");
      } catch (...) {
      }
    }
  } keys_on{*conn_};
  try {
    SqlTransaction tx(*conn_);
    f = inspectFile(*conn_, path_, kSchemaVersion);
    if (f.objects == 0) {
      conn_->exec(schemaSql());
      conn_->exec("INSERT INTO schema_version(version, written_at) VALUES (" + std::to_string(kSchemaVersion) + ", " +
                  now(*conn_) + ")");
      conn_->exec("PRAGMA application_id = " + std::to_string(kApplicationId));
      tx.commit();
      return;
    }
    for (int v = static_cast<int>(f.version); v < kSchemaVersion; ++v) {
      migrateSchemaStep(*conn_, v);
      conn_->exec("UPDATE schema_version SET version = " + std::to_string(v + 1) + ", written_at = " + now(*conn_));
    }
    if (conn_->queryInt("SELECT count(*) FROM pragma_foreign_key_check") != 0)
      throw SchemaVersionError("foreign key violations after the migration");
    conn_->exec("PRAGMA application_id = " + std::to_string(kApplicationId));
    tx.commit();
  } catch (const SchemaVersionError&) {
    throw;
  } catch (const std::exception& e) {
    if (f.objects == 0) throw;  // creating the schema failed (I/O, locked): not a migration problem
    throw SchemaVersionError("migrating '" + path_ + "' from schema version " + std::to_string(f.version) + " to " +
                             std::to_string(kSchemaVersion) + " failed (file left unchanged): " + e.what());
  }
}

// A PostgreSQL database: created or migrated in one transaction (PostgreSQL's DDL is transactional) under
// the writers' lock, so concurrent first opens create the tables once. PostgreSQL databases start at the
// version that introduced the backend (3); migrations from it on run on both backends.
void HangingDrapeDatabase::initialisePostgresSchema(std::int64_t objects, std::int64_t version) {
  if (objects > 0 && version == kSchemaVersion) return;
  SqlTransaction tx(*conn_);
  const FileState f = inspectFile(*conn_, path_, kSchemaVersion);
  if (f.objects == 0) {
    conn_->exec(schemaSql(SqlDialect::kPostgres));
    conn_->exec("INSERT INTO schema_version(version, written_at) VALUES (" + std::to_string(kSchemaVersion) + ", " +
                now(*conn_) + ")");
    tx.commit();
    return;
  }
  if (f.version < 3)
    throw SchemaVersionError("'" + path_ + "' has schema version " + std::to_string(f.version) +
                             " on PostgreSQL, which never had it (PostgreSQL databases start at version 3)");
  for (int v = static_cast<int>(f.version); v < kSchemaVersion; ++v) {
    migrateSchemaStep(*conn_, v);
    conn_->exec("UPDATE schema_version SET version = " + std::to_string(v + 1) + ", written_at = " + now(*conn_));
  }
  tx.commit();
}

}  // namespace db
}  // namespace textile_handling
