// The hanging-drape database: the textiles, the drape simulations (one per textile, hold point and
// parameter set, with status, timings and final particle positions) and the rendered silhouette views of
// every finished simulation, in an embedded SQLite file or on a PostgreSQL server (the setting: a path or
// a postgresql:// URL; sql_connection.h). ROS-free. Schema, blob formats, crash safety, migrations,
// backends and concurrent builders: docs/database.md.
//
// Guarantees:
//  * (SQLite) WAL journal, foreign keys on; every write in a transaction under the writers' lock; a simulation's positions, its views and
//    its status change are committed together (storeResults), so a killed writer loses at most the
//    simulations it had not committed, and the file always opens cleanly;
//  * bad input (unknown id, invalid polygon or material, NaN, mismatched sizes) is rejected with a typed
//    error before anything is written;
//  * blobs are versioned and checksummed (blob_codec.h); a damaged blob raises BlobFormatError naming
//    the row; an unknown schema version raises SchemaVersionError and leaves the file untouched.
// Thread-safe: every public method locks an internal mutex (one connection per object).
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "textile_handling/db/database_errors.h"
#include "textile_handling/db/sql_connection.h"
#include "textile_handling/db/textile_symmetry.h"
#include "textile_handling/sim/material.h"
#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/vision/bit_mask.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace db {

struct DatabaseOpenOptions {
  bool read_only = false;
  bool create = true;          ///< create the file (and the schema) if it does not exist
  int busy_timeout_ms = 10000; ///< wait this long for a lock held by another process
};

struct TextileRecord {
  std::int64_t id = 0;
  TextileOutline outline;      ///< as stored (named points = the textile's predefined grasp points)
  Material material;           ///< the material of the active generation
  /// The active generation: the simulations that readers (match index, recognizer, rest shapes) use.
  /// A resimulation builds a staged generation beside it and promotes it in one transaction.
  std::int64_t generation = 0;
  TextileSymmetry symmetry;    ///< detected when the textile was added
  std::string created_at;      ///< UTC, ISO 8601
};

enum class SimulationStatus { kPending, kDone, kFailed };
std::string toString(SimulationStatus s);           ///< "pending", "done", "failed"
SimulationStatus simulationStatusFromString(const std::string& s);

/// A simulation row to plan (status pending).
struct NewSimulation {
  std::int64_t textile_id = 0;
  /// The textile's active generation or its staged one (stageGeneration); any other is refused.
  std::int64_t generation = 0;
  Vec2 hold = Vec2::Zero();     ///< hold point [m], textile frame; must lie on the textile
  int lattice_i = 0, lattice_j = 0;
  MirrorKind source = MirrorKind::kIdentity;  ///< identity = simulated; otherwise derived by mirroring
  /// For derived rows: the simulated row, either by id (> 0) or by index into the same addSimulations()
  /// call (source_index >= 0, an earlier simulated row).
  std::int64_t source_simulation_id = 0;
  int source_index = -1;
  std::string model = "particle_kes";
  std::string integrator;
  Real spacing = 0;             ///< particle grid spacing d [m]
  std::string parameters;       ///< canonical text of every simulation setting (the builder's YAML)
};

struct SimulationRecord {
  std::int64_t id = 0;
  std::int64_t textile_id = 0;
  std::int64_t generation = 0;
  bool active = false;          ///< generation is the textile's active one (what readers use)
  std::string textile_name;
  Vec2 hold = Vec2::Zero();
  int lattice_i = 0, lattice_j = 0;
  MirrorKind source = MirrorKind::kIdentity;
  std::int64_t source_simulation_id = 0;  ///< 0 for simulated rows
  std::string model, integrator;
  Real spacing = 0;
  std::string parameters;
  SimulationStatus status = SimulationStatus::kPending;
  std::string failure_reason;
  bool rest_reached = false;
  Real sim_time_s = 0, wall_time_s = 0, render_time_s = 0, hanging_depth_m = 0;
  long steps = 0, rejected_steps = 0;
  int particles = 0, held_particle = -1, view_count = 0;
  std::string created_at, finished_at;
};

/// One silhouette to store.
struct ViewInput {
  double view_angle_deg = 0;
  vision::BitMask mask;
};

/// The result of one finished simulation (or of a derived mirror entry).
struct SimulationResult {
  std::int64_t simulation_id = 0;
  VecX positions;                 ///< final particle positions, 3 per particle [m]
  bool rest_reached = false;
  Real sim_time_s = 0, wall_time_s = 0, render_time_s = 0, hanging_depth_m = 0;
  long steps = 0, rejected_steps = 0;
  int held_particle = -1;
  std::string projection = "orthographic";
  vision::CanonicalFrame frame;   ///< canonical frame of the masks
  std::vector<ViewInput> views;   ///< at least one; masks of frame size, distinct finite angles
};

struct StoredView {
  std::int64_t id = 0;
  std::int64_t simulation_id = 0;
  double view_angle_deg = 0;
  std::string projection;
  int width_px = 0, height_px = 0;
  double metres_per_pixel = 0, top_margin_px = 0;
  std::int64_t area = 0;
  vision::BitMask mask;
};

/// Counts of the active generations (what readers see); the staged_* fields count staged generations.
struct DatabaseCounts {
  std::int64_t textiles = 0, simulations = 0, pending = 0, done = 0, failed = 0, views = 0;
  std::int64_t derived = 0;       ///< mirror-derived rows (any status)
  std::int64_t staged_simulations = 0, staged_done = 0, staged_failed = 0;
};

/// A generation being built beside a textile's active one (a resimulation). Its rows are invisible to
/// readers until promoteStagedGeneration swaps them in.
struct StagedGeneration {
  std::int64_t textile_id = 0;
  std::int64_t generation = 0;
  Material material;            ///< the material the new generation is simulated with
  Real spacing = 0;             ///< the request's particle spacing [m]; 0 = the builder's default
  std::string model;            ///< the request's cloth model; empty = the builder's default
  std::string created_at;
};

/// What promoteStagedGeneration swapped.
struct PromotionReport {
  std::int64_t generation = 0;          ///< the new active generation
  std::int64_t done = 0, failed = 0;    ///< rows of the new generation
  std::int64_t removed_simulations = 0; ///< rows of older generations deleted with their views
};

class HangingDrapeDatabase {
 public:
  static constexpr int kSchemaVersion = 3;
  /// PRAGMA application_id of drape databases ("THDB").
  static constexpr std::int32_t kApplicationId = 0x54484442;

  /// Opens (and, if allowed, creates or migrates) a database. Throws SqliteError, SchemaVersionError.
  explicit HangingDrapeDatabase(const std::string& path, const DatabaseOpenOptions& options = {});
  ~HangingDrapeDatabase();
  HangingDrapeDatabase(const HangingDrapeDatabase&) = delete;
  HangingDrapeDatabase& operator=(const HangingDrapeDatabase&) = delete;

  const std::string& path() const { return path_; }
  bool readOnly() const { return read_only_; }
  int schemaVersion() const;

  // ---- textiles -------------------------------------------------------------------------------
  /// Adds a textile (name unique). Throws InvalidInputError for an invalid outline/material or a taken name.
  std::int64_t addTextile(const TextileOutline& outline, const Material& material);
  /// The id of an identical stored textile (same name, outline, named points and material), or adds it.
  /// Look-up and insert are one write transaction (concurrent callers get the same row). Throws
  /// InvalidInputError for invalid input or if a textile of that name exists with a different definition.
  std::int64_t ensureTextile(const TextileOutline& outline, const Material& material);
  TextileRecord textile(std::int64_t id) const;  ///< throws NotFoundError
  std::optional<TextileRecord> findTextile(const std::string& name) const;
  std::vector<TextileRecord> textiles() const;

  // ---- generations: replacing a textile's entries atomically (docs/database.md) ----------------
  /// Starts a staged generation for a rebuild of a stored textile, in one transaction: a generation
  /// number above every one the textile has used, with `material`, `spacing` and `model` recorded so
  /// that an interrupted rebuild can be resumed. A staged generation the textile already had is
  /// discarded with its rows. The active entries are untouched. Throws NotFoundError (unknown id),
  /// InvalidInputError (invalid material, negative or non-finite spacing).
  StagedGeneration stageGeneration(std::int64_t textile_id, const Material& material, Real spacing = 0,
                                   const std::string& model = "");
  std::optional<StagedGeneration> stagedGeneration(std::int64_t textile_id) const;
  std::vector<StagedGeneration> stagedGenerations() const;
  /// Makes the staged generation `generation` the textile's active one, in one transaction: checks that
  /// each text of `parameter_texts` has rows in it, none pending, and at most `max_failed_fraction` of
  /// them failed; deletes every other simulation of the textile (older generations, and staged rows of
  /// other parameter texts) with their views; sets the textile's material to the staged one. Readers see
  /// the old complete set before the commit and the new one after it. Throws NotFoundError (no such
  /// staged generation) or InvalidInputError naming what is incomplete (nothing changed then).
  PromotionReport promoteStagedGeneration(std::int64_t textile_id, std::int64_t generation,
                                          const std::vector<std::string>& parameter_texts,
                                          double max_failed_fraction = 0);
  /// Deletes a textile's staged generation and its rows (no-op if none). Returns true if one existed.
  bool discardStagedGeneration(std::int64_t textile_id);

  // ---- simulations ----------------------------------------------------------------------------
  /// Plans simulations in one transaction. A row with the same (textile, parameters, hold point) is
  /// kept with its status (its lattice indices are updated). Returns the ids in input order.
  /// Throws NotFoundError (unknown textile / source) or InvalidInputError (NaN, hold point off the
  /// textile, bad spacing, empty parameters); nothing is written then.
  std::vector<std::int64_t> addSimulations(const std::vector<NewSimulation>& rows);
  SimulationRecord simulation(std::int64_t id) const;  ///< throws NotFoundError
  /// Rows of one textile (0 = all), every generation, optionally only one status, ordered by id
  /// (SimulationRecord::active tells the rows readers use).
  std::vector<SimulationRecord> simulations(std::int64_t textile_id = 0,
                                            std::optional<SimulationStatus> status = std::nullopt) const;
  /// Stores results atomically: all rows become done with their positions and views (their claims
  /// cleared), or (on any error) nothing changes. Rows must exist and not be done; a mirror-derived row
  /// needs its source done already or in the same batch. With `skip_done`, rows another builder finished
  /// meanwhile are left as they are instead of refused. Returns the rows stored. Throws
  /// InvalidInputError / NotFoundError.
  std::size_t storeResults(const std::vector<SimulationResult>& results, bool skip_done = false);
  /// Marks a row failed with a reason (not allowed for done rows; with `skip_done` a done row is left
  /// as it is and false returned).
  bool markFailed(std::int64_t id, const std::string& reason, bool skip_done = false);

  // ---- claims: several builders on one database (docs/database.md, "Concurrent builders") ----------
  /// The claim state of one row.
  struct ClaimState {
    SimulationStatus status = SimulationStatus::kPending;
    std::string claimed_by;     ///< empty: unclaimed
    bool expired = false;       ///< the claim's lease has run out (its builder stopped renewing it)
    std::int64_t claims = 0;    ///< claims ever made on the row (a row run twice has 2)
  };
  /// Claims pending row `id` for `owner` for `lease_s` seconds of the database's clock: true if the row is
  /// pending and unclaimed, already `owner`'s, its claim expired, or it is claimed by `dead_owner` (a
  /// builder known to have died, whose lease need not be waited for). A new claim is counted. Throws
  /// NotFoundError (unknown id), InvalidInputError (empty owner, lease not in (0, 1e6]).
  bool claimSimulation(std::int64_t id, const std::string& owner, double lease_s, const std::string& dead_owner = "");
  /// Extends every claim `owner` holds on pending rows to `lease_s` from now; returns their number.
  int renewClaims(const std::string& owner, double lease_s);
  /// Gives up `owner`'s claims on pending rows (a builder stopping early); returns their number.
  int releaseClaims(const std::string& owner);
  ClaimState claimState(std::int64_t id) const;  ///< throws NotFoundError
  /// Failed rows of a textile (0 = all) back to pending; returns how many.
  int resetFailed(std::int64_t textile_id = 0);
  /// Final positions of a done simulation. Throws NotFoundError, BlobFormatError.
  VecX positions(std::int64_t simulation_id) const;
  /// Views of a simulation ordered by angle (empty unless done). Throws NotFoundError for an unknown
  /// id, BlobFormatError for a damaged mask.
  std::vector<StoredView> views(std::int64_t simulation_id) const;

  // ---- health ---------------------------------------------------------------------------------
  DatabaseCounts counts(std::int64_t textile_id = 0) const;
  /// Invariants a crash must never break: every done row has positions and exactly view_count (> 0)
  /// views, pending/failed rows have neither, derived rows point to a simulated row of the same
  /// textile and generation, no orphan views, every row belongs to its textile's active or staged
  /// generation. Returns the violations (empty = consistent).
  std::vector<std::string> consistencyProblems() const;
  /// Result of PRAGMA integrity_check ("ok" when healthy).
  std::string integrityCheck() const;

  /// Runs f(connection) under the object's lock (for loaders that need one custom query).
  template <typename F>
  auto withConnection(F&& f) const -> decltype(f(std::declval<SqlConnection&>())) {
    std::lock_guard<std::mutex> lock(mutex_);
    return f(*conn_);
  }

 private:
  void initialiseSchema();
  void initialisePostgresSchema(std::int64_t objects, std::int64_t version);
  void requireWritable(const char* what) const;
  /// Within a write transaction whose commit changes what readers see: notifies PostgreSQL listeners
  /// (DatabaseChangeWatcher) on commit.
  void notifyReaders();
  SimulationRecord readSimulation(SqlStatement& st) const;

  std::string path_;
  bool read_only_ = false;
  int busy_timeout_ms_ = 10000;
  std::unique_ptr<SqlConnection> conn_;  // SQLite or PostgreSQL (openSqlConnection)
  mutable std::mutex mutex_;
};

/// The schema migrations: migrateSchemaStep(conn, from) upgrades a database of version `from` to
/// `from + 1` inside the caller's transaction, which runs with foreign keys off (v0 -> v1: views get the
/// `area` column, filled from the mask blobs; v1 -> v2: generations; v2 -> v3: grasp points get their
/// `ordinal`; see docs/database.md). Exposed for
/// tests. Throws on failure (the caller rolls back).
void migrateSchemaStep(SqlConnection& conn, int from_version);

/// The DDL of the current schema version (docs/database.md).
std::string schemaSql(SqlDialect dialect = SqlDialect::kSqlite);

/// Outline vertices as text ("x y" per line, round-trip precision) and back. fromText throws
/// InvalidInputError for malformed text.
std::string outlineToText(const std::vector<Vec2>& vertices);
std::vector<Vec2> outlineFromText(const std::string& text);

}  // namespace db
}  // namespace textile_handling
