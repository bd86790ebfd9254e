// Generations: a rebuild of a textile is built as a staged generation beside the active entries, is
// invisible to readers until it is complete, and is swapped in by one transaction; incomplete or
// failed staged builds are not promoted; version-1 files migrate to generations.
#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <string>

#include "../test_support.h"
#include "test_database.h"
#include "schema_history.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/drape_match_index.h"
#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/db/sqlite_wrapper.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

using test_support::TestDatabase;

// 30 x 30 cm square, d = 5 cm, lattice 15 cm: 4 simulated hold points, 9 in all, 8 views each.
DrapeBuildConfig tinySquare() {
  DrapeBuildConfig c;
  c.textile = presetTextile("square");
  c.spacing = 0.05;
  c.lattice_spacing = 0.15;
  c.views.count = 8;
  c.views.step_deg = 45;
  c.frame = vision::CanonicalFrame::fromMetric(0.5, 0.5, 64);
  c.workers = 1;
  return c;
}

Material heavierCotton() {
  Material m = Material::cotton();
  m.name = "heavy_cotton";
  m.areal_density *= 1.5;
  return m;
}

std::set<std::int64_t> loadedSimulations(const HangingDrapeDatabase& db) {
  std::set<std::int64_t> out;
  for (const IndexedHoldPoint& h : loadDrapeMatchIndex(db).hold_points) out.insert(h.simulation_id);
  return out;
}

// Builds tinySquare() into `db` and stages a rebuild with a heavier material; returns the staged config.
DrapeBuildConfig buildAndStage(HangingDrapeDatabase& db, std::int64_t* textile_id) {
  const DrapeBuildReport first = DrapeDatabaseBuilder(db, tinySquare()).build();
  EXPECT_EQ(first.failed_now, 0);
  *textile_id = first.textile_id;
  DrapeBuildConfig c = tinySquare();
  c.material = heavierCotton();
  c.staged_textile_id = *textile_id;
  db.stageGeneration(*textile_id, c.material);
  return c;
}

}  // namespace

TEST(StagedGenerations, RebuildIsInvisibleUntilPromotedThenReplacesEverything) {
  TestDatabase t("gen_swap");
  HangingDrapeDatabase db(t.path());
  std::int64_t id = 0;
  const DrapeBuildConfig staged_config = buildAndStage(db, &id);
  const std::set<std::int64_t> old_sims = loadedSimulations(db);
  ASSERT_EQ(old_sims.size(), 9u);
  EXPECT_EQ(db.textile(id).generation, 0);
  const auto staged = db.stagedGeneration(id);
  ASSERT_TRUE(staged.has_value());
  EXPECT_EQ(staged->generation, 1);
  EXPECT_EQ(staged->material, heavierCotton());

  const DrapeBuildReport rep = DrapeDatabaseBuilder(db, staged_config).build();
  EXPECT_EQ(rep.generation, 1);
  EXPECT_EQ(rep.simulated_now, 4);
  // Readers still see exactly the old set; the staged rows are counted apart.
  EXPECT_EQ(loadedSimulations(db), old_sims);
  EXPECT_EQ(db.textile(id).material, Material::cotton());
  DatabaseCounts c = db.counts(id);
  EXPECT_EQ(c.done, 9);
  EXPECT_EQ(c.views, 9 * 8);
  EXPECT_EQ(c.staged_simulations, 9);
  EXPECT_EQ(c.staged_done, 9);
  EXPECT_TRUE(db.consistencyProblems().empty());

  const PromotionReport p = db.promoteStagedGeneration(id, 1, DrapeDatabaseBuilder::parameterTexts(staged_config));
  EXPECT_EQ(p.generation, 1);
  EXPECT_EQ(p.done, 9);
  EXPECT_EQ(p.removed_simulations, 9);
  const std::set<std::int64_t> new_sims = loadedSimulations(db);
  EXPECT_EQ(new_sims.size(), 9u);
  for (std::int64_t s : new_sims) EXPECT_EQ(old_sims.count(s), 0u) << "an old row survived the swap";
  for (std::int64_t s : old_sims) EXPECT_THROW(db.simulation(s), NotFoundError);
  EXPECT_EQ(db.textile(id).generation, 1);
  EXPECT_EQ(db.textile(id).material, heavierCotton());
  EXPECT_FALSE(db.stagedGeneration(id).has_value());
  c = db.counts(id);
  EXPECT_EQ(c.done, 9);
  EXPECT_EQ(c.views, 9 * 8);
  EXPECT_EQ(c.staged_simulations, 0);
  EXPECT_TRUE(db.consistencyProblems().empty());
  EXPECT_EQ(db.integrityCheck(), "ok");
  // An ordinary rebuild with the new material now finds every row done in the active generation.
  DrapeBuildConfig again = tinySquare();
  again.material = heavierCotton();
  const DrapeBuildReport r2 = DrapeDatabaseBuilder(db, again).build();
  EXPECT_EQ(r2.generation, 1);
  EXPECT_EQ(r2.already_done, 4);
  EXPECT_EQ(r2.simulated_now, 0);
}

TEST(StagedGenerations, IncompleteOrFailedStagedBuildsAreNotPromoted) {
  TestDatabase t("gen_incomplete");
  HangingDrapeDatabase db(t.path());
  std::int64_t id = 0;
  DrapeBuildConfig staged_config = buildAndStage(db, &id);
  const std::set<std::int64_t> old_sims = loadedSimulations(db);
  const std::vector<std::string> texts = DrapeDatabaseBuilder::parameterTexts(staged_config);
  // Nothing planned yet.
  EXPECT_THROW(db.promoteStagedGeneration(id, 1, texts), InvalidInputError);
  // Planned, one simulation done, then stopped: pending rows.
  int started = 0;
  staged_config.should_stop = [&] { return started++ >= 1; };
  DrapeDatabaseBuilder(db, staged_config).build();
  EXPECT_GT(db.counts(id).staged_simulations, db.counts(id).staged_done);
  try {
    db.promoteStagedGeneration(id, 1, texts);
    ADD_FAILURE() << "promoted an incomplete generation";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find("pending"), std::string::npos) << e.what();
  }
  EXPECT_THROW(db.promoteStagedGeneration(id, 2, texts), NotFoundError);  // not the staged generation
  EXPECT_EQ(loadedSimulations(db), old_sims);
  EXPECT_EQ(db.textile(id).material, Material::cotton());
  // The pending rows fail: too many failures for the default (none allowed) and for 10 %.
  for (const SimulationRecord& s : db.simulations(id, SimulationStatus::kPending))
    if (!s.active) db.markFailed(s.id, "test failure");
  EXPECT_THROW(db.promoteStagedGeneration(id, 1, texts), InvalidInputError);
  EXPECT_THROW(db.promoteStagedGeneration(id, 1, texts, 0.1), InvalidInputError);
  EXPECT_EQ(loadedSimulations(db), old_sims);
  EXPECT_EQ(db.textile(id).generation, 0);
  EXPECT_TRUE(db.consistencyProblems().empty());
  // Retrying the failed rows completes the staged build, which is then promoted.
  staged_config.should_stop = nullptr;
  staged_config.retry_failed = true;
  DrapeDatabaseBuilder(db, staged_config).build();
  EXPECT_NO_THROW(db.promoteStagedGeneration(id, 1, texts));
  EXPECT_EQ(db.counts(id).done, 9);
  EXPECT_TRUE(db.consistencyProblems().empty());
}

TEST(StagedGenerations, StagingAgainDiscardsTheUnpromotedGeneration) {
  TestDatabase t("gen_restage");
  HangingDrapeDatabase db(t.path());
  std::int64_t id = 0;
  DrapeBuildConfig staged_config = buildAndStage(db, &id);
  int started = 0;
  staged_config.should_stop = [&] { return started++ >= 1; };
  DrapeDatabaseBuilder(db, staged_config).build();
  ASSERT_GT(db.counts(id).staged_simulations, 0);
  const StagedGeneration g2 = db.stageGeneration(id, Material::cotton(), 0.03, "choi_ko");
  EXPECT_EQ(g2.generation, 2);
  EXPECT_DOUBLE_EQ(g2.spacing, 0.03);
  EXPECT_EQ(g2.model, "choi_ko");
  EXPECT_EQ(db.counts(id).staged_simulations, 0);
  EXPECT_EQ(db.counts(id).done, 9);
  EXPECT_EQ(db.stagedGenerations().size(), 1u);
  EXPECT_TRUE(db.consistencyProblems().empty());
  EXPECT_TRUE(db.discardStagedGeneration(id));
  EXPECT_FALSE(db.discardStagedGeneration(id));
  EXPECT_FALSE(db.stagedGeneration(id).has_value());
  EXPECT_EQ(db.counts(id).done, 9);
}

TEST(StagedGenerations, BadStagingAndRowsOfOtherGenerationsAreRefused) {
  TestDatabase t("gen_refuse");
  HangingDrapeDatabase db(t.path());
  std::int64_t id = 0;
  DrapeBuildConfig staged_config = buildAndStage(db, &id);
  EXPECT_THROW(db.stageGeneration(id + 100, Material::cotton()), NotFoundError);
  Material bad = Material::cotton();
  bad.areal_density = -1;
  EXPECT_THROW(db.stageGeneration(id, bad), InvalidInputError);
  EXPECT_THROW(db.stageGeneration(id, Material::cotton(), std::nan("")), InvalidInputError);
  EXPECT_EQ(db.stagedGeneration(id)->generation, 1);  // the refused calls changed nothing
  NewSimulation row;
  row.textile_id = id;
  row.generation = 7;
  row.hold = Vec2(0.15, 0.15);
  row.integrator = "semi_implicit";
  row.spacing = 0.05;
  row.parameters = "p";
  EXPECT_THROW(db.addSimulations({row}), InvalidInputError);
  // A staged build whose material is not the staged one is refused before it writes.
  staged_config.material = Material::cotton();
  EXPECT_THROW(DrapeDatabaseBuilder(db, staged_config).build(), InvalidInputError);
  staged_config.staged_textile_id = id + 100;
  EXPECT_THROW(DrapeDatabaseBuilder(db, staged_config).build(), NotFoundError);
  EXPECT_EQ(db.counts(id).staged_simulations, 0);
}

TEST(StagedGenerations, VersionOneFileIsMigratedToGenerations) {
  TH_SQLITE_FILES_ONLY();
  TestDatabase t("gen_v1");
  const std::string v1 = schema_history::schemaV1Sql();
  {
    SqliteConnection c(t.path(), SqliteConnection::kReadWrite | SqliteConnection::kCreate);
    c.exec(v1);
    c.exec("PRAGMA foreign_keys = ON");
    c.exec("INSERT INTO schema_version VALUES (1, 'then'); PRAGMA application_id = " +
           std::to_string(HangingDrapeDatabase::kApplicationId) + ";");
    c.exec("INSERT INTO textiles VALUES (1, 'cloth', '0 0\n1 0\n1 1\n0 1\n', 0, 0, 'cotton', '" +
           materialToYaml(Material::cotton()) + "', 'xy', 0.5, 0.5, 'then');");
    c.exec("INSERT INTO grasp_points VALUES (1, 'c', 'corner', 0, 0);");
    c.exec(
        "INSERT INTO simulations(id, textile_id, hold_x, hold_y, hold_key, lattice_i, lattice_j, source, model, "
        "integrator, spacing, parameters, status, created_at) VALUES (1, 1, 0.25, 0.25, 'a', 0, 0, 'identity', "
        "'particle_kes', 'semi_implicit', 0.1, 'p', 'pending', 'then'), (2, 1, 0.25, 0.75, 'b', 1, 0, 'identity', "
        "'particle_kes', 'semi_implicit', 0.1, 'p', 'pending', 'then');");
    c.exec(
        "INSERT INTO simulations(id, textile_id, hold_x, hold_y, hold_key, lattice_i, lattice_j, source, "
        "source_simulation_id, model, integrator, spacing, parameters, status, created_at) VALUES (3, 1, 0.75, 0.25, "
        "'c', 0, 1, 'mirror_x', 1, 'particle_kes', 'semi_implicit', 0.1, 'p', 'pending', 'then');");
  }
  {
    HangingDrapeDatabase db(t.path());
    EXPECT_EQ(db.schemaVersion(), HangingDrapeDatabase::kSchemaVersion);
    EXPECT_EQ(db.textile(1).generation, 0);
    const auto sims = db.simulations(1);
    ASSERT_EQ(sims.size(), 3u);
    for (const auto& s : sims) {
      EXPECT_EQ(s.generation, 0);
      EXPECT_TRUE(s.active);
    }
    EXPECT_EQ(sims[2].source_simulation_id, 1);
    EXPECT_TRUE(db.consistencyProblems().empty());
    EXPECT_EQ(db.integrityCheck(), "ok");
    // Foreign keys are on again and still cascade: deleting through a staged swap works.
    EXPECT_EQ(db.stageGeneration(1, Material::cotton()).generation, 1);
    EXPECT_EQ(db.counts(1).simulations, 3);
  }
  SqliteConnection c(t.path(), SqliteConnection::kReadOnly);
  EXPECT_EQ(c.queryInt("SELECT count(*) FROM pragma_foreign_key_check"), 0);
  EXPECT_EQ(c.queryInt("SELECT count(*) FROM sqlite_master WHERE name = 'simulations_v2'"), 0);
}
