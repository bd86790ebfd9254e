// Generations of a textile's entries: a rebuild (resimulation) is built as a staged generation beside the
// active one, invisible to readers, and swapped in by one transaction (promoteStagedGeneration), so a
// reader sees either the old complete set or the new one, and a kill at any moment loses neither.
// docs/database.md, "Generations".
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "database_sql.h"
#include "textile_handling/db/hanging_drape_database.h"

namespace textile_handling {
namespace db {

using internal::now;

namespace {

constexpr const char* kStagedColumns =
    "SELECT textile_id, generation, material_yaml, spacing, model, created_at FROM staged_generations";

StagedGeneration readStaged(SqlStatement& st) {
  StagedGeneration g;
  g.textile_id = st.getInt(0);
  g.generation = st.getInt(1);
  try {
    g.material = parseMaterialYaml(st.getText(2));
  } catch (const std::exception& e) {
    throw BlobFormatError("staged generation of textile " + std::to_string(g.textile_id) +
                          ": stored material does not parse: " + e.what());
  }
  g.spacing = st.getDouble(3);
  g.model = st.getText(4);
  g.created_at = st.getText(5);
  return g;
}

// Deletes simulations of a textile matching `where` (SQL on s.*; ?1 = textile id, ?2 = `text`); derived
// rows first, since they reference their sources; views go by ON DELETE CASCADE. Returns the rows deleted.
std::int64_t deleteSimulations(SqlConnection& conn, std::int64_t textile_id, const std::string& where,
                               const std::string& text = "") {
  std::int64_t n = 0;
  for (const char* derived : {"s.source_simulation_id IS NOT NULL AND ", ""}) {
    SqlStatement del =
        conn.prepare(std::string("DELETE FROM simulations AS s WHERE s.textile_id = ?1 AND ") + derived + "(" + where + ")");
    del.bind(1, textile_id);
    if (where.find("?2") != std::string::npos) del.bind(2, text);
    del.run();
    n += conn.changes();
  }
  return n;
}

}  // namespace

StagedGeneration HangingDrapeDatabase::stageGeneration(std::int64_t textile_id, const Material& material, Real spacing,
                                                       const std::string& model) {
  requireWritable("stageGeneration");
  std::string err;
  if (!material.validate(&err)) throw InvalidInputError("material: " + err);
  if (!std::isfinite(spacing) || spacing < 0) throw InvalidInputError("spacing must be finite and >= 0 (0 = default)");
  const std::string yaml = materialToYaml(material);
  std::lock_guard<std::mutex> lock(mutex_);
  SqlTransaction tx(*conn_);
  SqlStatement top = conn_->prepare(
      "SELECT max(g) FROM (SELECT generation AS g FROM textiles WHERE id = ?1 UNION ALL "
      "SELECT generation FROM simulations WHERE textile_id = ?1 UNION ALL "
      "SELECT generation FROM staged_generations WHERE textile_id = ?1) AS generations");
  top.bind(1, textile_id);
  if (!top.step() || top.isNull(0)) throw NotFoundError("no textile with id " + std::to_string(textile_id));
  const std::int64_t generation = top.getInt(0) + 1;
  // A staged generation that was never promoted is superseded by this request.
  deleteSimulations(*conn_, textile_id, "s.generation != (SELECT generation FROM textiles WHERE id = ?1)");
  SqlStatement ins = conn_->prepare(
      std::string("INSERT INTO staged_generations(textile_id, generation, material_name, material_yaml, "
                  "spacing, model, created_at) VALUES (?, ?, ?, ?, ?, ?, ") +
      now(*conn_) +
      ") ON CONFLICT (textile_id) DO UPDATE SET generation = excluded.generation, material_name = "
      "excluded.material_name, material_yaml = excluded.material_yaml, spacing = excluded.spacing, model = "
      "excluded.model, created_at = excluded.created_at");
  ins.bind(1, textile_id).bind(2, generation).bind(3, material.name).bind(4, yaml).bind(5, spacing).bind(6, model);
  ins.run();
  SqlStatement sel = conn_->prepare(std::string(kStagedColumns) + " WHERE textile_id = ?");
  sel.bind(1, textile_id);
  sel.step();
  StagedGeneration out = readStaged(sel);
  tx.commit();
  return out;
}

std::optional<StagedGeneration> HangingDrapeDatabase::stagedGeneration(std::int64_t textile_id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  SqlStatement st = conn_->prepare(std::string(kStagedColumns) + " WHERE textile_id = ?");
  st.bind(1, textile_id);
  if (!st.step()) return std::nullopt;
  return readStaged(st);
}

std::vector<StagedGeneration> HangingDrapeDatabase::stagedGenerations() const {
  std::lock_guard<std::mutex> lock(mutex_);
  SqlStatement st = conn_->prepare(std::string(kStagedColumns) + " ORDER BY textile_id");
  std::vector<StagedGeneration> out;
  while (st.step()) out.push_back(readStaged(st));
  return out;
}

PromotionReport HangingDrapeDatabase::promoteStagedGeneration(std::int64_t textile_id, std::int64_t generation,
                                                              const std::vector<std::string>& parameter_texts,
                                                              double max_failed_fraction) {
  requireWritable("promoteStagedGeneration");
  if (parameter_texts.empty()) throw InvalidInputError("promotion needs the parameter texts of the build");
  if (!(max_failed_fraction >= 0 && max_failed_fraction <= 1))
    throw InvalidInputError("max_failed_fraction must be in [0, 1]");
  std::lock_guard<std::mutex> lock(mutex_);
  SqlTransaction tx(*conn_);
  const std::string what = "staged generation " + std::to_string(generation) + " of textile " + std::to_string(textile_id);
  SqlStatement staged =
      conn_->prepare("SELECT material_name, material_yaml FROM staged_generations WHERE textile_id = ? AND generation = ?");
  staged.bind(1, textile_id).bind(2, generation);
  if (!staged.step()) throw NotFoundError("no " + what);
  PromotionReport rep;
  rep.generation = generation;
  // Every parameter text of the build is complete: rows exist, none pending, few enough failed.
  SqlStatement count = conn_->prepare(
      "SELECT count(*), " + internal::countWhere("status = 'pending'") + ", " + internal::countWhere("status = 'done'") +
      ", " + internal::countWhere("status = 'failed'") + " FROM simulations WHERE textile_id = ? AND generation = ? AND parameters = ?");
  for (const std::string& p : parameter_texts) {
    count.bind(1, textile_id).bind(2, generation).bind(3, p);
    count.step();
    const std::int64_t rows = count.getInt(0), pending = count.getInt(1), done = count.getInt(2), failed = count.getInt(3);
    count.reset();
    if (rows == 0) throw InvalidInputError(what + " is incomplete: a pass of the build planned no rows yet");
    if (pending > 0)
      throw InvalidInputError(what + " is incomplete: " + std::to_string(pending) + " of " + std::to_string(rows) +
                              " simulations pending");
    if (done == 0 || static_cast<double>(failed) > max_failed_fraction * static_cast<double>(rows))
      throw InvalidInputError(what + ": " + std::to_string(failed) + " of " + std::to_string(rows) +
                              " simulations failed (at most " + std::to_string(max_failed_fraction * 100) +
                              " % allowed); the active entries are kept");
    rep.done += done;
    rep.failed += failed;
  }
  // Everything else of the textile goes: older generations and staged rows of other parameter texts.
  rep.removed_simulations = deleteSimulations(*conn_, textile_id, "s.generation != " + std::to_string(generation));
  std::vector<std::string> other_texts;
  {
    SqlStatement texts = conn_->prepare("SELECT DISTINCT parameters FROM simulations WHERE textile_id = ? AND generation = ?");
    texts.bind(1, textile_id).bind(2, generation);
    while (texts.step())
      if (std::find(parameter_texts.begin(), parameter_texts.end(), texts.getText(0)) == parameter_texts.end())
        other_texts.push_back(texts.getText(0));
  }
  for (const std::string& p : other_texts) rep.removed_simulations += deleteSimulations(*conn_, textile_id, "s.parameters = ?2", p);
  SqlStatement up = conn_->prepare(
      "UPDATE textiles SET generation = ?, material_name = ?, material_yaml = ? WHERE id = ?");
  up.bind(1, generation).bind(2, staged.getText(0)).bind(3, staged.getText(1)).bind(4, textile_id);
  up.run();
  SqlStatement del = conn_->prepare("DELETE FROM staged_generations WHERE textile_id = ?");
  del.bind(1, textile_id);
  del.run();
  notifyReaders();
  tx.commit();
  return rep;
}

bool HangingDrapeDatabase::discardStagedGeneration(std::int64_t textile_id) {
  requireWritable("discardStagedGeneration");
  std::lock_guard<std::mutex> lock(mutex_);
  SqlTransaction tx(*conn_);
  deleteSimulations(*conn_, textile_id, "s.generation != (SELECT generation FROM textiles WHERE id = ?1)");
  SqlStatement del = conn_->prepare("DELETE FROM staged_generations WHERE textile_id = ?");
  del.bind(1, textile_id);
  del.run();
  const bool existed = conn_->changes() > 0;
  tx.commit();
  return existed;
}

}  // namespace db
}  // namespace textile_handling
