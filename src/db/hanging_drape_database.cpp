#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/db/postgres_connection.h"
#include "textile_handling/db/database_change_watcher.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "textile_handling/db/blob_codec.h"
#include "database_sql.h"

namespace textile_handling {
namespace db {

using internal::fmt17;
using internal::holdKey;
using internal::now;

namespace {

bool finite(double v) { return std::isfinite(v); }

}  // namespace

std::string toString(SimulationStatus s) {
  switch (s) {
    case SimulationStatus::kPending: return "pending";
    case SimulationStatus::kDone: return "done";
    case SimulationStatus::kFailed: return "failed";
  }
  return "pending";
}

SimulationStatus simulationStatusFromString(const std::string& s) {
  if (s == "pending") return SimulationStatus::kPending;
  if (s == "done") return SimulationStatus::kDone;
  if (s == "failed") return SimulationStatus::kFailed;
  throw BlobFormatError("unknown simulation status '" + s + "'");
}

std::string outlineToText(const std::vector<Vec2>& vertices) {
  std::string out;
  for (const Vec2& v : vertices) out += fmt17(v.x()) + " " + fmt17(v.y()) + "\n";
  return out;
}

std::vector<Vec2> outlineFromText(const std::string& text) {
  std::vector<Vec2> out;
  std::istringstream is(text);
  std::string line;
  while (std::getline(is, line)) {
    if (line.empty()) continue;
    std::istringstream ls(line);
    double x, y;
    std::string rest;
    if (!(ls >> x >> y) || (ls >> rest)) throw InvalidInputError("malformed outline line '" + line + "'");
    out.emplace_back(x, y);
  }
  return out;
}


// ---- open -------------------------------------------------------------------------------------

HangingDrapeDatabase::HangingDrapeDatabase(const std::string& path, const DatabaseOpenOptions& options)
    : path_(path), read_only_(options.read_only), busy_timeout_ms_(options.busy_timeout_ms) {
  SqlOpenOptions o;
  o.read_only = options.read_only;
  o.create = options.create;
  o.busy_timeout_ms = options.busy_timeout_ms;
  conn_ = openSqlConnection(path, o);
  if (isPostgresUrl(path)) path_ = conn_->name();  // messages never show the password
  initialiseSchema();
}

HangingDrapeDatabase::~HangingDrapeDatabase() = default;


int HangingDrapeDatabase::schemaVersion() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(conn_->queryInt("SELECT version FROM schema_version"));
}

void HangingDrapeDatabase::requireWritable(const char* what) const {
  if (read_only_) throw InvalidInputError(std::string(what) + ": database '" + path_ + "' is open read-only");
}

// ---- textiles ---------------------------------------------------------------------------------

namespace {

TextileRecord readTextileRow(SqlStatement& st, SqlConnection& conn) {
  TextileRecord r;
  r.id = st.getInt(0);
  r.outline.name = st.getText(1);
  const std::string what = "textile " + std::to_string(r.id);
  try {
    r.outline.outline = outlineFromText(st.getText(2));
  } catch (const InvalidInputError& e) {
    throw BlobFormatError(what + ": " + e.what());
  }
  r.outline.mirrored = st.getInt(3) != 0;
  r.outline.mirror_x = st.getDouble(4);
  try {
    r.material = parseMaterialYaml(st.getText(6));
  } catch (const MaterialError& e) {
    throw BlobFormatError(what + ": stored material does not parse: " + e.what());
  }
  const std::string sym = st.getText(7);
  r.symmetry.mirror_x = sym == "x" || sym == "xy";
  r.symmetry.mirror_y = sym == "y" || sym == "xy";
  r.symmetry.cx = st.getDouble(8);
  r.symmetry.cy = st.getDouble(9);
  r.created_at = st.getText(10);
  r.generation = st.getInt(11);
  SqlStatement gp = conn.prepare("SELECT name, kind, x, y FROM grasp_points WHERE textile_id = ? ORDER BY ordinal");
  gp.bind(1, r.id);
  while (gp.step()) {
    NamedPoint p;
    p.name = gp.getText(0);
    p.kind = gp.getText(1);
    p.position = Vec2(gp.getDouble(2), gp.getDouble(3));
    r.outline.named_points.push_back(p);
  }
  return r;
}

constexpr const char* kTextileColumns =
    "SELECT id, name, outline, mirrored, mirror_x, material_name, material_yaml, symmetry, symmetry_cx, symmetry_cy, "
    "created_at, generation FROM textiles";

bool sameTextile(const TextileRecord& r, const TextileOutline& o, const Material& m) {
  if (r.outline.outline.size() != o.outline.size() || r.outline.mirrored != o.mirrored) return false;
  if (o.mirrored && r.outline.mirror_x != o.mirror_x) return false;
  for (std::size_t k = 0; k < o.outline.size(); ++k)
    if (r.outline.outline[k] != o.outline[k]) return false;
  if (r.outline.named_points.size() != o.named_points.size()) return false;
  for (std::size_t k = 0; k < o.named_points.size(); ++k) {
    const auto &a = r.outline.named_points[k], &b = o.named_points[k];
    if (a.name != b.name || a.kind != b.kind || a.position != b.position) return false;
  }
  return r.material == m;
}

}  // namespace

namespace {

void validateTextileInput(const TextileOutline& outline, const Material& material) {
  std::string err;
  if (outline.name.empty()) throw InvalidInputError("textile: empty name");
  if (!validateTextileOutline(outline, &err)) throw InvalidInputError("textile '" + outline.name + "': " + err);
  if (!material.validate(&err)) throw InvalidInputError("textile '" + outline.name + "': material: " + err);
  if (outline.mirrored && !std::isfinite(outline.mirror_x))
    throw InvalidInputError("textile '" + outline.name + "': mirror_x is not finite");
}

// Inserts a validated textile; the caller holds the lock and an open write transaction.
std::int64_t insertTextile(SqlConnection& conn, const TextileOutline& outline, const Material& material) {
  const TextileSymmetry sym = detectSymmetry(outline);
  SqlStatement ins = conn.prepare(
      std::string("INSERT INTO textiles(name, outline, mirrored, mirror_x, material_name, material_yaml, symmetry, "
                  "symmetry_cx, symmetry_cy, created_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ") +
      now(conn) + ") RETURNING id");
  ins.bind(1, outline.name)
      .bind(2, outlineToText(outline.outline))
      .bind(3, outline.mirrored ? 1 : 0)
      .bind(4, outline.mirrored ? outline.mirror_x : 0.0)
      .bind(5, material.name)
      .bind(6, materialToYaml(material))
      .bind(7, sym.name())
      .bind(8, sym.cx)
      .bind(9, sym.cy);
  if (!ins.step()) throw DrapeDatabaseError("inserting textile '" + outline.name + "' returned no id");
  const std::int64_t id = ins.getInt(0);
  ins.run();
  SqlStatement gp =
      conn.prepare("INSERT INTO grasp_points(textile_id, name, kind, x, y, ordinal) VALUES (?, ?, ?, ?, ?, ?)");
  for (std::size_t k = 0; k < outline.named_points.size(); ++k) {
    const NamedPoint& p = outline.named_points[k];
    gp.bind(1, id).bind(2, p.name).bind(3, p.kind).bind(4, p.position.x()).bind(5, p.position.y());
    gp.bind(6, static_cast<std::int64_t>(k));
    gp.run();
    gp.reset();
  }
  return id;
}

std::optional<TextileRecord> findTextileByName(SqlConnection& conn, const std::string& name) {
  SqlStatement st = conn.prepare(std::string(kTextileColumns) + " WHERE name = ?");
  st.bind(1, name);
  if (!st.step()) return std::nullopt;
  return readTextileRow(st, conn);
}

}  // namespace

std::int64_t HangingDrapeDatabase::addTextile(const TextileOutline& outline, const Material& material) {
  requireWritable("addTextile");
  validateTextileInput(outline, material);
  std::lock_guard<std::mutex> lock(mutex_);
  // The name check and the insert are one write transaction, so a concurrent writer cannot slip in
  // between (which used to surface as a raw UNIQUE-constraint SqliteError).
  SqlTransaction tx(*conn_);
  {
    SqlStatement st = conn_->prepare("SELECT count(*) FROM textiles WHERE name = ?");
    st.bind(1, outline.name);
    st.step();
    if (st.getInt(0) > 0) throw InvalidInputError("a textile named '" + outline.name + "' is already stored");
  }
  const std::int64_t id = insertTextile(*conn_, outline, material);
  tx.commit();
  return id;
}

std::int64_t HangingDrapeDatabase::ensureTextile(const TextileOutline& outline, const Material& material) {
  requireWritable("ensureTextile");
  validateTextileInput(outline, material);
  std::lock_guard<std::mutex> lock(mutex_);
  // Look-up and insert in one write transaction: two builders of the same textile started at once
  // (separate processes) both get the one row instead of one of them failing.
  SqlTransaction tx(*conn_);
  if (const auto existing = findTextileByName(*conn_, outline.name)) {
    if (!sameTextile(*existing, outline, material))
      throw InvalidInputError("textile '" + outline.name +
                              "' is already stored with a different outline, grasp points or material; store this "
                              "variant under another name");
    return existing->id;  // nothing written: the transaction rolls back
  }
  const std::int64_t id = insertTextile(*conn_, outline, material);
  tx.commit();
  return id;
}

TextileRecord HangingDrapeDatabase::textile(std::int64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  SqlStatement st = conn_->prepare(std::string(kTextileColumns) + " WHERE id = ?");
  st.bind(1, id);
  if (!st.step()) throw NotFoundError("no textile with id " + std::to_string(id));
  return readTextileRow(st, *conn_);
}

std::optional<TextileRecord> HangingDrapeDatabase::findTextile(const std::string& name) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return findTextileByName(*conn_, name);
}

std::vector<TextileRecord> HangingDrapeDatabase::textiles() const {
  std::lock_guard<std::mutex> lock(mutex_);
  SqlStatement st = conn_->prepare(std::string(kTextileColumns) + " ORDER BY id");
  std::vector<TextileRecord> out;
  while (st.step()) out.push_back(readTextileRow(st, *conn_));
  return out;
}

// ---- simulations ------------------------------------------------------------------------------

namespace {
constexpr const char* kSimulationColumns =
    "SELECT s.id, s.textile_id, t.name, s.generation, s.generation = t.generation, s.hold_x, s.hold_y, s.lattice_i, s.lattice_j, s.source, "
    "s.source_simulation_id, s.model, s.integrator, s.spacing, s.parameters, s.status, s.failure_reason, "
    "s.rest_reached, s.sim_time_s, s.wall_time_s, s.render_time_s, s.hanging_depth_m, s.steps, s.rejected_steps, "
    "s.particles, s.held_particle, s.view_count, s.created_at, s.finished_at "
    "FROM simulations s JOIN textiles t ON t.id = s.textile_id";
}  // namespace

SimulationRecord HangingDrapeDatabase::readSimulation(SqlStatement& st) const {
  SimulationRecord r;
  r.id = st.getInt(0);
  r.textile_id = st.getInt(1);
  r.textile_name = st.getText(2);
  r.generation = st.getInt(3);
  r.active = st.getInt(4) != 0;
  r.hold = Vec2(st.getDouble(5), st.getDouble(6));
  r.lattice_i = static_cast<int>(st.getInt(7));
  r.lattice_j = static_cast<int>(st.getInt(8));
  try {
    r.source = mirrorKindFromString(st.getText(9));
  } catch (const std::invalid_argument& e) {
    throw BlobFormatError("simulation " + std::to_string(r.id) + ": " + e.what());
  }
  r.source_simulation_id = st.isNull(10) ? 0 : st.getInt(10);
  r.model = st.getText(11);
  r.integrator = st.getText(12);
  r.spacing = st.getDouble(13);
  r.parameters = st.getText(14);
  r.status = simulationStatusFromString(st.getText(15));
  r.failure_reason = st.getText(16);
  r.rest_reached = !st.isNull(17) && st.getInt(17) != 0;
  r.sim_time_s = st.getDouble(18);
  r.wall_time_s = st.getDouble(19);
  r.render_time_s = st.getDouble(20);
  r.hanging_depth_m = st.getDouble(21);
  r.steps = static_cast<long>(st.getInt(22));
  r.rejected_steps = static_cast<long>(st.getInt(23));
  r.particles = static_cast<int>(st.getInt(24));
  r.held_particle = st.isNull(25) ? -1 : static_cast<int>(st.getInt(25));
  r.view_count = static_cast<int>(st.getInt(26));
  r.created_at = st.getText(27);
  r.finished_at = st.getText(28);
  return r;
}

std::vector<std::int64_t> HangingDrapeDatabase::addSimulations(const std::vector<NewSimulation>& rows) {
  requireWritable("addSimulations");
  std::lock_guard<std::mutex> lock(mutex_);
  // Validate everything before the first write.
  std::map<std::int64_t, std::vector<Vec2>> outlines;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const NewSimulation& r = rows[k];
    const std::string what = "simulation " + std::to_string(k) + ": ";
    if (!outlines.count(r.textile_id)) {
      SqlStatement st = conn_->prepare("SELECT outline, mirrored, mirror_x FROM textiles WHERE id = ?");
      st.bind(1, r.textile_id);
      if (!st.step()) throw NotFoundError(what + "no textile with id " + std::to_string(r.textile_id));
      TextileOutline t;
      t.outline = outlineFromText(st.getText(0));
      t.mirrored = st.getInt(1) != 0;
      t.mirror_x = st.getDouble(2);
      std::string err;
      std::vector<Vec2> full;
      if (!buildFullOutline(t, &full, &err)) throw BlobFormatError(what + "stored outline is invalid: " + err);
      outlines[r.textile_id] = full;
    }
    if (!r.hold.allFinite()) throw InvalidInputError(what + "hold point is not finite");
    if (!pointInPolygon(outlines[r.textile_id], r.hold, 1e-6))
      throw InvalidInputError(what + "hold point (" + fmt17(r.hold.x()) + ", " + fmt17(r.hold.y()) +
                              ") is not on the textile");
    if (!finite(r.spacing) || r.spacing <= 0) throw InvalidInputError(what + "spacing must be finite and > 0");
    if (r.parameters.empty()) throw InvalidInputError(what + "empty parameter text");
    if (r.model.empty() || r.integrator.empty()) throw InvalidInputError(what + "model and integrator must be named");
    if (r.source != MirrorKind::kIdentity) {
      if (r.source_index >= 0) {
        if (static_cast<std::size_t>(r.source_index) >= k || rows[static_cast<std::size_t>(r.source_index)].source != MirrorKind::kIdentity)
          throw InvalidInputError(what + "source_index must name an earlier simulated row");
        if (rows[static_cast<std::size_t>(r.source_index)].textile_id != r.textile_id)
          throw InvalidInputError(what + "derived row and its source belong to different textiles");
      } else {
        SqlStatement st = conn_->prepare("SELECT textile_id, source, generation FROM simulations WHERE id = ?");
        st.bind(1, r.source_simulation_id);
        if (!st.step()) throw NotFoundError(what + "no source simulation with id " + std::to_string(r.source_simulation_id));
        if (st.getInt(0) != r.textile_id || st.getText(1) != "identity" || st.getInt(2) != r.generation)
          throw InvalidInputError(what + "source simulation must be a simulated row of the same textile and generation");
      }
    }
  }
  SqlTransaction tx(*conn_);
  // Rows go into the textile's active generation or its staged one; checked under the write lock, so a
  // promotion cannot slip in between.
  {
    SqlStatement gen = conn_->prepare(
        "SELECT t.generation, g.generation FROM textiles t LEFT JOIN staged_generations g ON g.textile_id = t.id "
        "WHERE t.id = ?");
    std::set<std::pair<std::int64_t, std::int64_t>> checked;
    for (const NewSimulation& r : rows) {
      if (!checked.insert({r.textile_id, r.generation}).second) continue;
      gen.bind(1, r.textile_id);
      if (!gen.step()) throw NotFoundError("no textile with id " + std::to_string(r.textile_id));
      if (r.generation != gen.getInt(0) && (gen.isNull(1) || r.generation != gen.getInt(1)))
        throw InvalidInputError("generation " + std::to_string(r.generation) + " of textile " +
                                std::to_string(r.textile_id) + " is neither its active nor its staged generation");
      gen.reset();
    }
  }
  SqlStatement ins = conn_->prepare(
      std::string("INSERT INTO simulations(textile_id, hold_x, hold_y, hold_key, lattice_i, lattice_j, source, "
                  "source_simulation_id, model, integrator, spacing, parameters, generation, created_at) "
                  "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ") +
      now(*conn_) +
      ") ON CONFLICT (textile_id, generation, parameters, hold_key) DO UPDATE SET lattice_i = excluded.lattice_i, "
      "lattice_j = excluded.lattice_j");
  SqlStatement sel = conn_->prepare(
      "SELECT id FROM simulations WHERE textile_id = ? AND parameters = ? AND hold_key = ? AND generation = ?");
  std::vector<std::int64_t> ids;
  for (const NewSimulation& r : rows) {
    const std::string key = holdKey(r.hold);
    ins.bind(1, r.textile_id).bind(2, r.hold.x()).bind(3, r.hold.y()).bind(4, key).bind(5, r.lattice_i).bind(6, r.lattice_j);
    ins.bind(7, toString(r.source));
    if (r.source == MirrorKind::kIdentity)
      ins.bindNull(8);
    else
      ins.bind(8, r.source_index >= 0 ? ids[static_cast<std::size_t>(r.source_index)] : r.source_simulation_id);
    ins.bind(9, r.model).bind(10, r.integrator).bind(11, r.spacing).bind(12, r.parameters).bind(13, r.generation);
    ins.run();
    ins.reset();
    sel.bind(1, r.textile_id).bind(2, r.parameters).bind(3, key).bind(4, r.generation);
    if (!sel.step()) throw DrapeDatabaseError("planned simulation row vanished");
    ids.push_back(sel.getInt(0));
    sel.reset();
  }
  tx.commit();
  return ids;
}

SimulationRecord HangingDrapeDatabase::simulation(std::int64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  SqlStatement st = conn_->prepare(std::string(kSimulationColumns) + " WHERE s.id = ?");
  st.bind(1, id);
  if (!st.step()) throw NotFoundError("no simulation with id " + std::to_string(id));
  return readSimulation(st);
}

std::vector<SimulationRecord> HangingDrapeDatabase::simulations(std::int64_t textile_id,
                                                                std::optional<SimulationStatus> status) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::string sql = std::string(kSimulationColumns) + " WHERE (?1 = 0 OR s.textile_id = ?1)";
  if (status) sql += " AND s.status = ?2";
  sql += " ORDER BY s.id";
  SqlStatement st = conn_->prepare(sql);
  st.bind(1, textile_id);
  if (status) st.bind(2, toString(*status));
  std::vector<SimulationRecord> out;
  while (st.step()) out.push_back(readSimulation(st));
  return out;
}

std::size_t HangingDrapeDatabase::storeResults(const std::vector<SimulationResult>& results, bool skip_done) {
  requireWritable("storeResults");
  // Validate and encode before touching the database.
  struct Encoded {
    std::vector<std::uint8_t> positions;
    std::vector<std::vector<std::uint8_t>> masks;
    std::vector<std::int64_t> areas;
  };
  std::vector<Encoded> enc(results.size());
  std::set<std::int64_t> ids;
  for (std::size_t k = 0; k < results.size(); ++k) {
    const SimulationResult& r = results[k];
    const std::string what = "result for simulation " + std::to_string(r.simulation_id) + ": ";
    if (!ids.insert(r.simulation_id).second) throw InvalidInputError(what + "given twice");
    try {
      r.frame.validate();
    } catch (const std::exception& e) {
      throw InvalidInputError(what + "bad canonical frame: " + e.what());
    }
    if (r.views.empty()) throw InvalidInputError(what + "no views");
    if (!finite(r.sim_time_s) || !finite(r.wall_time_s) || !finite(r.render_time_s) || !finite(r.hanging_depth_m))
      throw InvalidInputError(what + "non-finite timing or depth");
    if (r.projection.empty()) throw InvalidInputError(what + "projection not named");
    try {
      enc[k].positions = encodePositions(r.positions);
    } catch (const InvalidInputError& e) {
      throw InvalidInputError(what + e.what());
    }
    if (r.held_particle < -1 || r.held_particle >= r.positions.size() / 3)
      throw InvalidInputError(what + "held particle out of range");
    std::set<double> angles;
    for (const ViewInput& v : r.views) {
      if (!finite(v.view_angle_deg)) throw InvalidInputError(what + "non-finite view angle");
      if (!angles.insert(v.view_angle_deg).second) throw InvalidInputError(what + "view angle given twice");
      if (v.mask.width() != r.frame.width_px || v.mask.height() != r.frame.height_px)
        throw InvalidInputError(what + "mask size differs from the canonical frame");
      enc[k].masks.push_back(encodeMask(v.mask));
      enc[k].areas.push_back(v.mask.count());
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);
  SqlTransaction tx(*conn_);
  SqlStatement status = conn_->prepare(
      "SELECT s.status, s.source, s.source_simulation_id, src.status FROM simulations s "
      "LEFT JOIN simulations src ON src.id = s.source_simulation_id WHERE s.id = ?");
  SqlStatement upd = conn_->prepare(
      std::string("UPDATE simulations SET status = 'done', failure_reason = NULL, positions = ?, rest_reached = ?, "
                  "sim_time_s = ?, wall_time_s = ?, render_time_s = ?, hanging_depth_m = ?, steps = ?, "
                  "rejected_steps = ?, particles = ?, held_particle = ?, view_count = ?, claimed_by = NULL, "
                  "claim_expires_at = NULL, finished_at = ") +
      now(*conn_) + " WHERE id = ?");
  SqlStatement ins = conn_->prepare(
      "INSERT INTO views(simulation_id, view_angle_deg, projection, width_px, height_px, metres_per_pixel, "
      "top_margin_px, area, mask) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)");
  std::size_t stored = 0;
  for (std::size_t k = 0; k < results.size(); ++k) {
    const SimulationResult& r = results[k];
    status.bind(1, r.simulation_id);
    if (!status.step()) throw NotFoundError("no simulation with id " + std::to_string(r.simulation_id));
    if (status.getText(0) == "done" && skip_done) {
      status.reset();
      continue;
    }
    if (status.getText(0) == "done")
      throw InvalidInputError("simulation " + std::to_string(r.simulation_id) + " is already done");
    // A mirror-derived row holds its source's shape: it may only become done with or after its source
    // (the invariant "derived rows are done only if their source is done").
    if (status.getText(1) != "identity") {
      const std::int64_t src = status.getInt(2);
      if (!ids.count(src) && status.getText(3) != "done")
        throw InvalidInputError("simulation " + std::to_string(r.simulation_id) + " is derived from source simulation " +
                                std::to_string(src) + ", which is " + (status.isNull(3) ? "missing" : status.getText(3)) +
                                "; store the source first or in the same batch");
    }
    status.reset();
    for (std::size_t v = 0; v < r.views.size(); ++v) {
      ins.bind(1, r.simulation_id)
          .bind(2, r.views[v].view_angle_deg)
          .bind(3, r.projection)
          .bind(4, r.frame.width_px)
          .bind(5, r.frame.height_px)
          .bind(6, r.frame.metres_per_pixel)
          .bind(7, r.frame.top_margin_px)
          .bind(8, enc[k].areas[v])
          .bindBlob(9, enc[k].masks[v]);
      ins.run();
      ins.reset();
    }
    upd.bindBlob(1, enc[k].positions)
        .bind(2, r.rest_reached ? 1 : 0)
        .bind(3, r.sim_time_s)
        .bind(4, r.wall_time_s)
        .bind(5, r.render_time_s)
        .bind(6, r.hanging_depth_m)
        .bind(7, static_cast<std::int64_t>(r.steps))
        .bind(8, static_cast<std::int64_t>(r.rejected_steps))
        .bind(9, static_cast<std::int64_t>(r.positions.size() / 3))
        .bind(10, r.held_particle)
        .bind(11, static_cast<std::int64_t>(r.views.size()))
        .bind(12, r.simulation_id);
    upd.run();
    upd.reset();
    ++stored;
  }
  if (stored > 0) notifyReaders();
  tx.commit();
  return stored;
}

void HangingDrapeDatabase::notifyReaders() {
  // Delivered when the caller's transaction commits, never if it rolls back (database_change_watcher.h).
  if (conn_->dialect() != SqlDialect::kPostgres) return;  // SQLite readers poll data_version
  // The payload names the schema: listeners of other drape databases in the same server database (other
  // schemas) ignore it.
  SqlStatement st = conn_->prepare("SELECT pg_notify(?, current_schema())");
  st.bind(1, std::string(kDrapeDatabaseChannel));
  st.run();
}

bool HangingDrapeDatabase::markFailed(std::int64_t id, const std::string& reason, bool skip_done) {
  requireWritable("markFailed");
  std::lock_guard<std::mutex> lock(mutex_);
  SqlTransaction tx(*conn_);
  SqlStatement st = conn_->prepare("SELECT status FROM simulations WHERE id = ?");
  st.bind(1, id);
  if (!st.step()) throw NotFoundError("no simulation with id " + std::to_string(id));
  if (st.getText(0) == "done" && skip_done) return false;
  if (st.getText(0) == "done") throw InvalidInputError("simulation " + std::to_string(id) + " is done; cannot mark it failed");
  SqlStatement upd = conn_->prepare(std::string("UPDATE simulations SET status = 'failed', failure_reason = ?, "
                                                  "claimed_by = NULL, claim_expires_at = NULL, finished_at = ") +
                                      now(*conn_) + " WHERE id = ?");
  upd.bind(1, reason.empty() ? std::string("unknown failure") : reason).bind(2, id);
  upd.run();
  tx.commit();
  return true;
}

int HangingDrapeDatabase::resetFailed(std::int64_t textile_id) {
  requireWritable("resetFailed");
  std::lock_guard<std::mutex> lock(mutex_);
  SqlTransaction tx(*conn_);
  SqlStatement st = conn_->prepare(
      "UPDATE simulations SET status = 'pending', failure_reason = NULL, finished_at = NULL "
      "WHERE status = 'failed' AND (?1 = 0 OR textile_id = ?1)");
  st.bind(1, textile_id);
  st.run();
  const int n = conn_->changes();
  tx.commit();
  return n;
}

VecX HangingDrapeDatabase::positions(std::int64_t simulation_id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  SqlStatement st = conn_->prepare("SELECT status, positions, particles FROM simulations WHERE id = ?");
  st.bind(1, simulation_id);
  if (!st.step()) throw NotFoundError("no simulation with id " + std::to_string(simulation_id));
  if (st.getText(0) != "done" || st.isNull(1))
    throw NotFoundError("simulation " + std::to_string(simulation_id) + " is " + st.getText(0) + ", it has no positions");
  const std::string what = "simulation " + std::to_string(simulation_id);
  VecX x = decodePositions(st.blobData(1), static_cast<std::size_t>(st.blobSize(1)), what);
  if (x.size() != 3 * st.getInt(2))
    throw BlobFormatError("positions blob of " + what + " holds " + std::to_string(x.size() / 3) +
                          " particles but the row says " + std::to_string(st.getInt(2)));
  return x;
}

std::vector<StoredView> HangingDrapeDatabase::views(std::int64_t simulation_id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  SqlStatement st = conn_->prepare(
      "SELECT id, simulation_id, view_angle_deg, projection, width_px, height_px, metres_per_pixel, top_margin_px, "
      "area, mask FROM views WHERE simulation_id = ? ORDER BY view_angle_deg");
  st.bind(1, simulation_id);
  std::vector<StoredView> out;
  {
    SqlStatement exists = conn_->prepare("SELECT 1 FROM simulations WHERE id = ?");
    exists.bind(1, simulation_id);
    if (!exists.step()) throw NotFoundError("no simulation with id " + std::to_string(simulation_id));
  }
  while (st.step()) {
    StoredView v;
    v.id = st.getInt(0);
    v.simulation_id = st.getInt(1);
    v.view_angle_deg = st.getDouble(2);
    v.projection = st.getText(3);
    v.width_px = static_cast<int>(st.getInt(4));
    v.height_px = static_cast<int>(st.getInt(5));
    v.metres_per_pixel = st.getDouble(6);
    v.top_margin_px = st.getDouble(7);
    v.area = st.getInt(8);
    const std::string what = "view " + std::to_string(v.id) + " (simulation " + std::to_string(simulation_id) + ")";
    v.mask = decodeMask(st.blobData(9), static_cast<std::size_t>(st.blobSize(9)), what);
    if (v.mask.width() != v.width_px || v.mask.height() != v.height_px)
      throw BlobFormatError("mask blob of " + what + " does not match the row's window size");
    out.push_back(std::move(v));
  }
  return out;
}

// ---- health -----------------------------------------------------------------------------------

DatabaseCounts HangingDrapeDatabase::counts(std::int64_t textile_id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  DatabaseCounts c;
  c.textiles = conn_->queryInt("SELECT count(*) FROM textiles");
  // Active rows (what readers see) and staged rows separately.
  SqlStatement st = conn_->prepare(
      std::string("SELECT ") + internal::countWhere("a") + ", " + internal::countWhere("a AND status = 'pending'") +
      ", " + internal::countWhere("a AND status = 'done'") + ", " + internal::countWhere("a AND status = 'failed'") +
      ", " + internal::countWhere("a AND source != 'identity'") + ", " + internal::countWhere("NOT a") + ", " +
      internal::countWhere("NOT a AND status = 'done'") + ", " + internal::countWhere("NOT a AND status = 'failed'") +
      " FROM (SELECT s.status, s.source, s.generation = t.generation AS a FROM simulations s "
      "JOIN textiles t ON t.id = s.textile_id WHERE ?1 = 0 OR s.textile_id = ?1) AS rows_of_textile");
  st.bind(1, textile_id);
  st.step();
  c.simulations = st.getInt(0);
  c.pending = st.getInt(1);
  c.done = st.getInt(2);
  c.failed = st.getInt(3);
  c.derived = st.getInt(4);
  c.staged_simulations = st.getInt(5);
  c.staged_done = st.getInt(6);
  c.staged_failed = st.getInt(7);
  SqlStatement vs = conn_->prepare(
      "SELECT count(*) FROM views v JOIN simulations s ON s.id = v.simulation_id JOIN textiles t ON t.id = s.textile_id "
      "WHERE (?1 = 0 OR s.textile_id = ?1) AND s.generation = t.generation");
  vs.bind(1, textile_id);
  vs.step();
  c.views = vs.getInt(0);
  return c;
}

std::vector<std::string> HangingDrapeDatabase::consistencyProblems() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::string> out;
  auto collect = [&](const std::string& sql, const std::string& what, const char* id_of = "simulation") {
    SqlStatement st = conn_->prepare(sql);
    while (st.step()) out.push_back(what + " (" + id_of + " " + std::to_string(st.getInt(0)) + ")");
  };
  collect(
      "SELECT s.id FROM simulations s WHERE s.status = 'done' AND (s.positions IS NULL OR s.view_count <= 0 OR "
      "s.view_count != (SELECT count(*) FROM views v WHERE v.simulation_id = s.id))",
      "done simulation without positions or with a wrong number of views");
  collect(
      "SELECT s.id FROM simulations s WHERE s.status != 'done' AND (s.positions IS NOT NULL OR "
      "EXISTS (SELECT 1 FROM views v WHERE v.simulation_id = s.id))",
      "unfinished simulation with positions or views");
  collect(
      "SELECT s.id FROM simulations s LEFT JOIN simulations src ON src.id = s.source_simulation_id "
      "WHERE s.source != 'identity' AND (src.id IS NULL OR src.source != 'identity' OR src.textile_id != s.textile_id)",
      "derived simulation without a simulated source of the same textile");
  collect(
      "SELECT s.id FROM simulations s JOIN simulations src ON src.id = s.source_simulation_id "
      "WHERE s.status = 'done' AND src.status != 'done'",
      "derived simulation done before its source");
  collect("SELECT v.simulation_id FROM views v LEFT JOIN simulations s ON s.id = v.simulation_id WHERE s.id IS NULL",
          "orphan view");
  collect(
      "SELECT s.id FROM simulations s JOIN textiles t ON t.id = s.textile_id LEFT JOIN staged_generations g "
      "ON g.textile_id = s.textile_id WHERE s.generation != t.generation AND (g.generation IS NULL OR "
      "s.generation != g.generation)",
      "simulation of a generation that is neither active nor staged");
  collect(
      "SELECT s.id FROM simulations s JOIN simulations src ON src.id = s.source_simulation_id "
      "WHERE s.generation != src.generation",
      "derived simulation whose source is of another generation");
  collect(
      "SELECT g.textile_id FROM staged_generations g JOIN textiles t ON t.id = g.textile_id "
      "WHERE g.generation <= t.generation",
      "staged generation not above the active one", "textile");
  // PostgreSQL enforces foreign keys on every statement; SQLite can be made to skip them (foreign_keys off).
  if (conn_->dialect() == SqlDialect::kSqlite) {
    SqlStatement fk = conn_->prepare("PRAGMA foreign_key_check");
    while (fk.step()) out.push_back("foreign key violation in table " + fk.getText(0));
  }
  return out;
}

std::string HangingDrapeDatabase::integrityCheck() const {
  std::lock_guard<std::mutex> lock(mutex_);
  // The server checks its own storage (page checksums, WAL); what a client can check is that it answers.
  if (conn_->dialect() == SqlDialect::kPostgres) return conn_->queryInt("SELECT 1") == 1 ? "ok" : "no answer";
  SqlStatement st = conn_->prepare("PRAGMA integrity_check");
  std::string out;
  while (st.step()) {
    if (!out.empty()) out += "; ";
    out += st.getText(0);
  }
  return out;
}

}  // namespace db
}  // namespace textile_handling
