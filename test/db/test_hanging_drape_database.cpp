// The hanging-drape database: round trips, atomic writes, bad input, damaged blobs, schema versions and
// migrations.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <set>
#include <thread>

#include "../test_support.h"
#include "test_database.h"
#include "schema_history.h"
#include "textile_handling/db/blob_codec.h"
#include "textile_handling/db/drape_export.h"
#include "textile_handling/db/drape_match_index.h"
#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/db/sqlite_wrapper.h"
#include "textile_handling/sim/drape_scene.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

using test_support::TestDatabase;

// A towel at d = 4 cm hanging straight down from the middle of its top edge, with a gentle wave.
VecX hangingTowel(Index* held) {
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(presetTextile("towel"), 0.04, &err);
  const Vec2 hold(0.32, 0.44);
  *held = g.nearestActive(hold);
  VecX x(3 * g.numActive());
  for (Index k = 0; k < g.numActive(); ++k) {
    const Vec2 p = g.activePosition(k);
    x.segment<3>(3 * k) = Vec3(p.x() - 0.32, 0.03 * std::sin(12 * p.x()), 1.0 - (0.44 - p.y()));
  }
  return x;
}

SimulationResult makeResult(std::int64_t id, int views = 4) {
  SimulationResult r;
  r.simulation_id = id;
  Index held = 0;
  r.positions = hangingTowel(&held);
  r.held_particle = held;
  r.rest_reached = true;
  r.sim_time_s = 3.5;
  r.wall_time_s = 1.25;
  r.render_time_s = 0.01;
  r.hanging_depth_m = 0.44;
  r.steps = 321;
  r.rejected_steps = 4;
  std::string err;
  const auto tris = vision::trianglesFromTopology(
      ParticleTopology::fromGrid(ParticleGrid::rasterize(presetTextile("towel"), 0.04, &err)));
  vision::ViewSet vs;
  vs.count = views;
  vs.step_deg = 360.0 / views;
  for (const auto& v : vision::renderViews(r.positions, tris, r.positions.segment<3>(3 * held), vs))
    r.views.push_back({v.view_angle_deg, v.mask});
  return r;
}

NewSimulation newRow(std::int64_t textile, const Vec2& hold, const std::string& params = "p: 1\n") {
  NewSimulation s;
  s.textile_id = textile;
  s.hold = hold;
  s.integrator = "semi_implicit";
  s.spacing = 0.04;
  s.parameters = params;
  return s;
}

/// A connection to the test's database behind the library's back (either backend).
std::unique_ptr<SqlConnection> rawConnection(const std::string& path) {
  SqlOpenOptions o;
  o.create = false;
  return openSqlConnection(path, o);
}

void rawExec(const std::string& path, const std::string& sql) { rawConnection(path)->exec(sql); }

}  // namespace

TEST(HangingDrapeDatabase, CreatesTheCurrentSchemaVersionInWalMode) {
  TestDatabase t("create");
  HangingDrapeDatabase db(t.path());
  EXPECT_EQ(db.schemaVersion(), HangingDrapeDatabase::kSchemaVersion);
  EXPECT_EQ(db.integrityCheck(), "ok");
  EXPECT_TRUE(db.consistencyProblems().empty());
  if (t.isPostgres()) return;  // the rest is about the SQLite file
  db.withConnection([](SqlConnection& c) {
    EXPECT_EQ(c.queryText("PRAGMA journal_mode"), "wal");
    EXPECT_EQ(c.queryInt("PRAGMA foreign_keys"), 1);
    EXPECT_EQ(c.queryInt("PRAGMA application_id"), HangingDrapeDatabase::kApplicationId);
    return 0;
  });
  EXPECT_TRUE(db.consistencyProblems().empty());
}

TEST(HangingDrapeDatabase, TextileRoundTrip) {
  TestDatabase t("textile");
  std::int64_t id = 0;
  {
    HangingDrapeDatabase db(t.path());
    id = db.addTextile(presetTextile("towel"), Material::cotton());
    EXPECT_EQ(db.ensureTextile(presetTextile("towel"), Material::cotton()), id);
    EXPECT_GT(db.addTextile(presetTextile("tshirt"), Material::cotton()), id);
  }
  HangingDrapeDatabase db(t.path());  // reopened: everything persisted
  const TextileRecord r = db.textile(id);
  const TextileOutline towel = presetTextile("towel");
  EXPECT_EQ(r.outline.name, "towel");
  ASSERT_EQ(r.outline.outline.size(), towel.outline.size());
  for (std::size_t k = 0; k < towel.outline.size(); ++k) EXPECT_EQ(r.outline.outline[k], towel.outline[k]);
  ASSERT_EQ(r.outline.named_points.size(), towel.named_points.size());
  for (std::size_t k = 0; k < towel.named_points.size(); ++k) {
    EXPECT_EQ(r.outline.named_points[k].name, towel.named_points[k].name);
    EXPECT_EQ(r.outline.named_points[k].kind, towel.named_points[k].kind);
    EXPECT_EQ(r.outline.named_points[k].position, towel.named_points[k].position);
  }
  EXPECT_TRUE(r.material == Material::cotton());
  EXPECT_EQ(r.symmetry.name(), "xy");
  const auto shirt = db.findTextile("tshirt");
  ASSERT_TRUE(shirt.has_value());
  EXPECT_TRUE(shirt->outline.mirrored);
  EXPECT_EQ(shirt->symmetry.name(), "x");
  EXPECT_FALSE(db.findTextile("sock").has_value());
  EXPECT_EQ(db.textiles().size(), 2u);
  EXPECT_THROW(db.textile(999), NotFoundError);
}

TEST(HangingDrapeDatabase, SimulationRoundTripIsAtomicAndExact) {
  TestDatabase t("sim");
  HangingDrapeDatabase db(t.path());
  const std::int64_t tex = db.addTextile(presetTextile("towel"), Material::cotton());
  std::vector<NewSimulation> rows = {newRow(tex, Vec2(0.32, 0.44)), newRow(tex, Vec2(0.0, 0.0))};
  NewSimulation mirror = newRow(tex, Vec2(0.64, 0.0));
  mirror.source = MirrorKind::kMirrorX;
  mirror.source_index = 1;
  mirror.lattice_j = 8;
  rows.push_back(mirror);
  const auto ids = db.addSimulations(rows);
  ASSERT_EQ(ids.size(), 3u);
  EXPECT_EQ(db.addSimulations({rows[0]}).front(), ids[0]);  // same key: same row
  const SimulationRecord m = db.simulation(ids[2]);
  EXPECT_EQ(m.source, MirrorKind::kMirrorX);
  EXPECT_EQ(m.source_simulation_id, ids[1]);
  EXPECT_EQ(m.lattice_j, 8);
  EXPECT_EQ(m.status, SimulationStatus::kPending);
  EXPECT_EQ(m.textile_name, "towel");

  const SimulationResult res = makeResult(ids[0]);
  db.storeResults({res});
  const SimulationRecord r = db.simulation(ids[0]);
  EXPECT_EQ(r.status, SimulationStatus::kDone);
  EXPECT_TRUE(r.rest_reached);
  EXPECT_EQ(r.steps, 321);
  EXPECT_EQ(r.rejected_steps, 4);
  EXPECT_DOUBLE_EQ(r.wall_time_s, 1.25);
  EXPECT_EQ(r.particles, res.positions.size() / 3);
  EXPECT_EQ(r.held_particle, res.held_particle);
  EXPECT_EQ(r.view_count, 4);
  EXPECT_FALSE(r.finished_at.empty());
  const VecX x = db.positions(ids[0]);
  ASSERT_EQ(x.size(), res.positions.size());
  EXPECT_EQ(std::memcmp(x.data(), res.positions.data(), sizeof(double) * x.size()), 0);
  const auto views = db.views(ids[0]);
  ASSERT_EQ(views.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(views[k].view_angle_deg, res.views[k].view_angle_deg);
    EXPECT_EQ(views[k].mask, res.views[k].mask);
    EXPECT_EQ(views[k].area, res.views[k].mask.count());
    EXPECT_EQ(views[k].projection, "orthographic");
    EXPECT_DOUBLE_EQ(views[k].metres_per_pixel, 1.0 / 64.0);
  }
  const DatabaseCounts c = db.counts();
  EXPECT_EQ(c.simulations, 3);
  EXPECT_EQ(c.done, 1);
  EXPECT_EQ(c.pending, 2);
  EXPECT_EQ(c.derived, 1);
  EXPECT_EQ(c.views, 4);
  EXPECT_TRUE(db.consistencyProblems().empty());
  EXPECT_THROW(db.positions(ids[1]), NotFoundError);  // still pending
  EXPECT_TRUE(db.views(ids[1]).empty());

  // A batch whose second row fails inside the transaction stores nothing.
  SimulationResult bad = makeResult(ids[2]);
  SimulationResult good = makeResult(ids[1]);
  bad.simulation_id = 987654;  // unknown row
  EXPECT_THROW(db.storeResults({good, bad}), NotFoundError);
  EXPECT_EQ(db.simulation(ids[1]).status, SimulationStatus::kPending);
  EXPECT_EQ(db.counts().views, 4);
  // Storing a done row twice is refused, and leaves it as it was.
  EXPECT_THROW(db.storeResults({makeResult(ids[0])}), InvalidInputError);
  EXPECT_EQ(db.views(ids[0]).size(), 4u);
  // Source then mirror: all done and consistent.
  SimulationResult mres = makeResult(ids[2], 3);
  db.storeResults({good, mres});
  EXPECT_EQ(db.counts().done, 3);
  EXPECT_TRUE(db.consistencyProblems().empty());

  // Export of the stored shape: PLY, OBJ, PNGs.
  const std::string dir = t.path() + "_export";
  const StoredDrapeMesh mesh = loadDrapeMesh(db, ids[0]);
  EXPECT_EQ(mesh.triangles.size(), vision::trianglesFromTopology(ParticleTopology::fromGrid(
                                       ParticleGrid::rasterize(presetTextile("towel"), 0.04, nullptr)))
                                       .size());
  std::filesystem::create_directories(dir);
  writePly(dir + "/shape.ply", mesh.positions, mesh.triangles);
  writeObj(dir + "/shape.obj", mesh.positions, mesh.triangles);
  const auto pngs = exportViewPngs(db, ids[0], dir + "/png");
  EXPECT_EQ(pngs.size(), 5u);
  std::ifstream ply(dir + "/shape.ply");
  std::string first;
  std::getline(ply, first);
  EXPECT_EQ(first, "ply");
  EXPECT_GT(std::filesystem::file_size(dir + "/shape.obj"), 1000u);
  EXPECT_THROW(writePly("/nonexistent_dir_xyz/a.ply", mesh.positions, mesh.triangles), std::runtime_error);
  std::filesystem::remove_all(dir);
}

TEST(HangingDrapeDatabase, BadInputIsRejectedAndStoredDataStayIntact) {
  TestDatabase t("bad");
  HangingDrapeDatabase db(t.path());
  const std::int64_t tex = db.addTextile(presetTextile("towel"), Material::cotton());
  const auto ids = db.addSimulations({newRow(tex, Vec2(0.1, 0.1))});
  db.storeResults({makeResult(ids[0])});
  const DatabaseCounts before = db.counts();

  TextileOutline bowtie;
  bowtie.name = "bowtie";
  bowtie.outline = {Vec2(0, 0), Vec2(1, 1), Vec2(1, 0), Vec2(0, 1)};
  EXPECT_THROW(db.addTextile(bowtie, Material::cotton()), InvalidInputError);
  TextileOutline nan_outline = presetTextile("square");
  nan_outline.outline[1].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(db.addTextile(nan_outline, Material::cotton()), InvalidInputError);
  Material nan_material = Material::cotton();
  nan_material.areal_density = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(db.addTextile(presetTextile("square"), nan_material), InvalidInputError);
  EXPECT_THROW(db.addTextile(presetTextile("towel"), Material::cotton()), InvalidInputError);  // name taken
  Material other = Material::cotton();
  other.areal_density = 0.3;
  EXPECT_THROW(db.ensureTextile(presetTextile("towel"), other), InvalidInputError);

  EXPECT_THROW(db.addSimulations({newRow(tex + 41, Vec2(0.1, 0.1))}), NotFoundError);
  EXPECT_THROW(db.addSimulations({newRow(tex, Vec2(std::nan(""), 0.1))}), InvalidInputError);
  EXPECT_THROW(db.addSimulations({newRow(tex, Vec2(0.9, 0.1))}), InvalidInputError);  // off the towel
  NewSimulation bad_spacing = newRow(tex, Vec2(0.2, 0.2));
  bad_spacing.spacing = std::numeric_limits<double>::infinity();
  EXPECT_THROW(db.addSimulations({newRow(tex, Vec2(0.3, 0.3)), bad_spacing}), InvalidInputError);
  EXPECT_THROW(db.addSimulations({newRow(tex, Vec2(0.3, 0.3), "")}), InvalidInputError);
  NewSimulation orphan = newRow(tex, Vec2(0.2, 0.2));
  orphan.source = MirrorKind::kMirrorY;
  orphan.source_simulation_id = 12345;
  EXPECT_THROW(db.addSimulations({orphan}), NotFoundError);

  const auto pending = db.addSimulations({newRow(tex, Vec2(0.5, 0.3))});
  SimulationResult r = makeResult(pending[0]);
  r.positions[7] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(db.storeResults({r}), InvalidInputError);
  r = makeResult(pending[0]);
  r.views[1].mask = vision::BitMask(32, 32);
  EXPECT_THROW(db.storeResults({r}), InvalidInputError);
  r = makeResult(pending[0]);
  r.views[1].view_angle_deg = r.views[0].view_angle_deg;
  EXPECT_THROW(db.storeResults({r}), InvalidInputError);
  r = makeResult(pending[0]);
  r.views.clear();
  EXPECT_THROW(db.storeResults({r}), InvalidInputError);
  r = makeResult(pending[0]);
  r.sim_time_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(db.storeResults({r}), InvalidInputError);
  r = makeResult(pending[0]);
  r.held_particle = 1 << 20;
  EXPECT_THROW(db.storeResults({r}), InvalidInputError);

  const DatabaseCounts after = db.counts();
  EXPECT_EQ(after.textiles, before.textiles);
  EXPECT_EQ(after.done, before.done);
  EXPECT_EQ(after.views, before.views);
  EXPECT_EQ(after.simulations, before.simulations + 1);  // only the valid pending row was added
  EXPECT_EQ(db.views(ids[0]).size(), 4u);
  EXPECT_TRUE(db.consistencyProblems().empty());
  EXPECT_EQ(db.integrityCheck(), "ok");
}

TEST(HangingDrapeDatabase, FailedRowsKeepTheirReasonAndCanBeRetried) {
  TestDatabase t("failed");
  HangingDrapeDatabase db(t.path());
  const std::int64_t tex = db.addTextile(presetTextile("towel"), Material::cotton());
  const auto ids = db.addSimulations({newRow(tex, Vec2(0.1, 0.1)), newRow(tex, Vec2(0.2, 0.1))});
  db.markFailed(ids[0], "diverged at t = 0.1 s: edge stretched");
  EXPECT_EQ(db.simulation(ids[0]).status, SimulationStatus::kFailed);
  EXPECT_EQ(db.simulation(ids[0]).failure_reason, "diverged at t = 0.1 s: edge stretched");
  EXPECT_EQ(db.counts().failed, 1);
  db.storeResults({makeResult(ids[1])});
  EXPECT_THROW(db.markFailed(ids[1], "x"), InvalidInputError);
  EXPECT_THROW(db.markFailed(777, "x"), NotFoundError);
  EXPECT_EQ(db.resetFailed(tex), 1);
  EXPECT_EQ(db.simulation(ids[0]).status, SimulationStatus::kPending);
  EXPECT_TRUE(db.simulation(ids[0]).failure_reason.empty());
  // A failed row can still be completed later.
  db.markFailed(ids[0], "no rest");
  db.storeResults({makeResult(ids[0])});
  EXPECT_EQ(db.simulation(ids[0]).status, SimulationStatus::kDone);
  EXPECT_TRUE(db.consistencyProblems().empty());
}

TEST(HangingDrapeDatabase, DamagedBlobsGiveTypedErrors) {
  TestDatabase t("damaged");
  std::vector<std::int64_t> ids;
  {
    HangingDrapeDatabase db(t.path());
    const std::int64_t tex = db.addTextile(presetTextile("towel"), Material::cotton());
    ids = db.addSimulations({newRow(tex, Vec2(0.1, 0.1)), newRow(tex, Vec2(0.2, 0.2))});
    db.storeResults({makeResult(ids[0]), makeResult(ids[1])});
  }
  // Truncate one positions blob and flip a byte in one mask, behind the library's back.
  rawExec(t.path(), "UPDATE simulations SET positions = substr(positions, 1, 100) WHERE id = " + std::to_string(ids[0]));
  rawExec(t.path(),
          "UPDATE views SET mask = substr(mask, 1, length(mask) - 1) WHERE id = (SELECT min(id) FROM views WHERE "
          "simulation_id = " + std::to_string(ids[1]) + ")");
  const std::string byte_ff = t.isPostgres() ? "'\\xff'::bytea" : "X'FF'";
  rawExec(t.path(),
          "UPDATE views SET mask = substr(mask, 1, 40) || " + byte_ff + " || substr(mask, 42) WHERE id = (SELECT max(id) "
          "FROM views WHERE simulation_id = " + std::to_string(ids[1]) + ")");
  HangingDrapeDatabase db(t.path());
  EXPECT_EQ(db.integrityCheck(), "ok");  // SQLite-level fine; our blobs are not
  try {
    db.positions(ids[0]);
    FAIL() << "truncated positions read without error";
  } catch (const BlobFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("simulation " + std::to_string(ids[0])), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(db.positions(ids[1]));
  EXPECT_THROW(db.views(ids[1]), BlobFormatError);
  EXPECT_NO_THROW(db.views(ids[0]));
  // The match index skips the two damaged views and records them (docs/recognition.md, "Evidence").
  const DrapeMatchIndex index = loadDrapeMatchIndex(db);
  ASSERT_EQ(index.skipped_views.size(), 2u);
  for (const SkippedView& v : index.skipped_views) EXPECT_EQ(v.simulation_id, ids[1]);
  EXPECT_THROW(loadDrapeMesh(db, ids[0]), BlobFormatError);
}

TEST(HangingDrapeDatabase, NewerSchemaIsRefusedAndLeftUntouched) {
  TestDatabase t("future");
  { HangingDrapeDatabase db(t.path()); }
  rawExec(t.path(), "UPDATE schema_version SET version = 7");
  for (bool ro : {false, true}) {
    DatabaseOpenOptions o;
    o.read_only = ro;
    try {
      HangingDrapeDatabase db(t.path(), o);
      FAIL() << "opened a version-7 file";
    } catch (const SchemaVersionError& e) {
      EXPECT_NE(std::string(e.what()).find("schema version 7"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("newer"), std::string::npos) << e.what();
    }
  }
  const auto c = rawConnection(t.path());
  EXPECT_EQ(c->queryInt("SELECT version FROM schema_version"), 7);
  EXPECT_EQ(c->queryInt("SELECT count(*) FROM views"), 0);  // the tables are all still there
}

TEST(HangingDrapeDatabase, VersionZeroFileIsMigrated) {
  TH_SQLITE_FILES_ONLY();
  TestDatabase t("v0");
  const std::string v0 = schema_history::schemaV0Sql();
  const vision::BitMask mask = makeResult(1).views[0].mask;
  const auto blob = encodeMask(mask);
  std::string hex;
  for (std::uint8_t b : blob) {
    char h[3];
    std::snprintf(h, sizeof h, "%02X", b);
    hex += h;
  }
  const std::string fill =
      "INSERT INTO textiles VALUES (1, 'cloth', '0 0\n1 0\n1 1\n0 1\n', 0, 0, 'cotton', '" +
      materialToYaml(Material::cotton()) +
      "', 'xy', 0.5, 0.5, 'then');"
      "INSERT INTO simulations(id, textile_id, hold_x, hold_y, hold_key, lattice_i, lattice_j, source, model, "
      "integrator, spacing, parameters, status, positions, view_count, created_at) VALUES (1, 1, 0.5, 0.5, '1', 0, 0, "
      "'identity', 'particle_kes', 'semi_implicit', 0.1, 'p', 'done', X'00', 1, 'then');"
      "INSERT INTO views(id, simulation_id, view_angle_deg, projection, width_px, height_px, metres_per_pixel, "
      "top_margin_px, mask) VALUES (1, 1, 0, 'orthographic', 64, 64, 0.015625, 2, X'" + hex + "');";
  {
    SqliteConnection c(t.path(), SqliteConnection::kReadWrite | SqliteConnection::kCreate);
    c.exec(v0);
    c.exec("INSERT INTO schema_version VALUES (0, 'then');" + fill);
  }
  {
    HangingDrapeDatabase db(t.path());
    EXPECT_EQ(db.schemaVersion(), HangingDrapeDatabase::kSchemaVersion);
    const auto views = db.views(1);
    ASSERT_EQ(views.size(), 1u);
    EXPECT_EQ(views[0].area, mask.count());
    EXPECT_GT(views[0].area, 0);
  }
  // A v0 file whose mask is damaged cannot be migrated: clear error, file left at v0.
  TestDatabase t2("v0bad");
  {
    SqliteConnection c(t2.path(), SqliteConnection::kReadWrite | SqliteConnection::kCreate);
    c.exec(v0);
    std::string bad = fill;
    bad.replace(bad.rfind("X'") + 2, 8, "00000000");
    c.exec("INSERT INTO schema_version VALUES (0, 'then');" + bad);
  }
  try {
    HangingDrapeDatabase db(t2.path());
    FAIL() << "migrated a damaged file";
  } catch (const SchemaVersionError& e) {
    EXPECT_NE(std::string(e.what()).find("left unchanged"), std::string::npos) << e.what();
  }
  SqliteConnection c(t2.path(), SqliteConnection::kReadOnly);
  EXPECT_EQ(c.queryInt("SELECT version FROM schema_version"), 0);
  EXPECT_EQ(c.queryInt("SELECT count(*) FROM pragma_table_info('views') WHERE name = 'area'"), 0);
  // Read-only opening of a v0 file asks for a read-write open.
  DatabaseOpenOptions ro;
  ro.read_only = true;
  EXPECT_THROW(HangingDrapeDatabase(t2.path(), ro), SchemaVersionError);
}

TEST(HangingDrapeDatabase, ADatabaseOfAnotherApplicationIsRefusedUntouched) {
  TestDatabase t("other_app");
  {
    const auto c = openSqlConnection(t.path(), SqlOpenOptions{});
    c->exec("CREATE TABLE recipes(name TEXT); INSERT INTO recipes VALUES ('soup')");
  }
  for (bool ro : {false, true}) {
    DatabaseOpenOptions o;
    o.read_only = ro;
    EXPECT_THROW(HangingDrapeDatabase db(t.path(), o), SchemaVersionError);
  }
  const auto c = rawConnection(t.path());
  EXPECT_EQ(c->queryText("SELECT name FROM recipes"), "soup");
  EXPECT_THROW(c->queryInt("SELECT count(*) FROM schema_version"), DrapeDatabaseError);
}

TEST(HangingDrapeDatabase, VersionTwoFileKeepsTheOrderOfItsGraspPoints) {
  TH_SQLITE_FILES_ONLY();
  TestDatabase t("v2");
  {
    SqliteConnection c(t.path(), SqliteConnection::kReadWrite | SqliteConnection::kCreate);
    c.exec(schema_history::schemaV2Sql());
    c.exec("INSERT INTO schema_version VALUES (2, 'then');"
           "INSERT INTO textiles(id, name, outline, material_name, material_yaml, symmetry, symmetry_cx, symmetry_cy, "
           "created_at) VALUES (1, 'cloth', '0 0\n1 0\n1 1\n0 1\n', 'cotton', '" +
           materialToYaml(Material::cotton()) +
           "', 'xy', 0.5, 0.5, 'then');"
           "INSERT INTO grasp_points VALUES (1, 'z', 'corner', 0, 0), (1, 'a', 'corner', 1, 0), (1, 'm', 'grasp', 1, 1);");
  }
  HangingDrapeDatabase db(t.path());
  EXPECT_EQ(db.schemaVersion(), 3);
  const TextileRecord r = db.textile(1);
  ASSERT_EQ(r.outline.named_points.size(), 3u);
  EXPECT_EQ(r.outline.named_points[0].name, "z");
  EXPECT_EQ(r.outline.named_points[1].name, "a");
  EXPECT_EQ(r.outline.named_points[2].name, "m");
  EXPECT_TRUE(db.consistencyProblems().empty());
}

TEST(HangingDrapeDatabase, ForeignFilesAreRefused) {
  TH_SQLITE_FILES_ONLY();
  TestDatabase other("other");
  {
    SqliteConnection c(other.path(), SqliteConnection::kReadWrite | SqliteConnection::kCreate);
    c.exec("CREATE TABLE recipes(name TEXT)");
  }
  EXPECT_THROW(HangingDrapeDatabase db(other.path()), SchemaVersionError);
  TestDatabase garbage("garbage");
  {
    std::ofstream f(garbage.path());
    f << "this is not an SQLite database, just text that is long enough to look like a header........";
  }
  EXPECT_THROW(HangingDrapeDatabase db(garbage.path()), SqliteError);
  DatabaseOpenOptions no_create;
  no_create.create = false;
  EXPECT_THROW(HangingDrapeDatabase db("/nonexistent_dir_xyz/db.sqlite", no_create), SqliteError);
}

TEST(HangingDrapeDatabase, ReadOnlyHandleRefusesWrites) {
  TestDatabase t("ro");
  { HangingDrapeDatabase db(t.path()); }
  DatabaseOpenOptions o;
  o.read_only = true;
  HangingDrapeDatabase db(t.path(), o);
  EXPECT_THROW(db.addTextile(presetTextile("towel"), Material::cotton()), InvalidInputError);
  EXPECT_EQ(db.counts().textiles, 0);
}

TEST(HangingDrapeDatabase, ConcurrentWritersThroughOneHandle) {
  TestDatabase t("threads");
  HangingDrapeDatabase db(t.path());
  const std::int64_t tex = db.addTextile(presetTextile("towel"), Material::cotton());
  std::vector<NewSimulation> rows;
  for (int k = 0; k < 8; ++k) rows.push_back(newRow(tex, Vec2(0.05 * k, 0.1)));
  const auto ids = db.addSimulations(rows);
  std::vector<std::thread> pool;
  for (int w = 0; w < 4; ++w)
    pool.emplace_back([&, w] {
      for (int k = w; k < 8; k += 4) db.storeResults({makeResult(ids[static_cast<std::size_t>(k)], 2)});
    });
  for (auto& th : pool) th.join();
  EXPECT_EQ(db.counts().done, 8);
  EXPECT_EQ(db.counts().views, 16);
  EXPECT_TRUE(db.consistencyProblems().empty());
}

// ---- review fixes -------------------------------------------------------------------------------

namespace {
std::string fileBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}
}  // namespace

TEST(HangingDrapeDatabase, RefusedFilesAreNotSwitchedToWal) {
  TH_SQLITE_FILES_ONLY();
  // Opening read-write used to switch the journal to WAL before checking what the file is, which
  // rewrote the header of foreign and newer files that it then refused.
  TestDatabase other("foreign_rollback");
  {
    SqliteConnection c(other.path(), SqliteConnection::kReadWrite | SqliteConnection::kCreate);
    c.exec("CREATE TABLE recipes(name TEXT); INSERT INTO recipes VALUES ('soup')");
  }
  const std::string before = fileBytes(other.path());
  EXPECT_THROW(HangingDrapeDatabase db(other.path()), SchemaVersionError);
  EXPECT_TRUE(fileBytes(other.path()) == before) << "the refused file was modified";
  EXPECT_FALSE(std::filesystem::exists(other.path() + "-wal"));
  {
    SqliteConnection c(other.path(), SqliteConnection::kReadOnly);
    EXPECT_EQ(c.queryText("PRAGMA journal_mode"), "delete");
  }

  TestDatabase future("future_rollback");
  { HangingDrapeDatabase db(future.path()); }
  rawExec(future.path(), "PRAGMA journal_mode = DELETE; UPDATE schema_version SET version = 9");
  const std::string fbefore = fileBytes(future.path());
  EXPECT_THROW(HangingDrapeDatabase db(future.path()), SchemaVersionError);
  EXPECT_TRUE(fileBytes(future.path()) == fbefore) << "the refused file was modified";
  SqliteConnection c(future.path(), SqliteConnection::kReadOnly);
  EXPECT_EQ(c.queryText("PRAGMA journal_mode"), "delete");
}

TEST(HangingDrapeDatabase, EmptyFileOfAnotherApplicationIsRefused) {
  TH_SQLITE_FILES_ONLY();
  TestDatabase t("foreign_empty");
  {
    SqliteConnection c(t.path(), SqliteConnection::kReadWrite | SqliteConnection::kCreate);
    c.exec("PRAGMA application_id = 1234");  // no tables, but claimed by another program
  }
  EXPECT_THROW(HangingDrapeDatabase db(t.path()), SchemaVersionError);
  SqliteConnection c(t.path(), SqliteConnection::kReadOnly);
  EXPECT_EQ(c.queryInt("SELECT count(*) FROM sqlite_master"), 0);
  EXPECT_EQ(c.queryInt("PRAGMA application_id"), 1234);
}

TEST(HangingDrapeDatabase, ConcurrentOpeningOfANewFileCreatesOneSchema) {
  // Several processes (here: handles on their own connections) opening a fresh path at once: the
  // check "file is empty" and the creation of the schema must be one atomic step.
  for (int round = 0; round < 5; ++round) {
    TestDatabase t("concurrent_create_" + std::to_string(round));
    std::vector<std::thread> pool;
    std::vector<std::string> errors(6);
    std::atomic<int> ready{0};
    for (int w = 0; w < 6; ++w)
      pool.emplace_back([&, w] {
        ++ready;
        while (ready.load() < 6) std::this_thread::yield();
        try {
          HangingDrapeDatabase db(t.path());
          if (db.schemaVersion() != HangingDrapeDatabase::kSchemaVersion) errors[static_cast<std::size_t>(w)] = "wrong version";
        } catch (const std::exception& e) {
          errors[static_cast<std::size_t>(w)] = e.what();
        }
      });
    for (auto& th : pool) th.join();
    for (const auto& e : errors) EXPECT_TRUE(e.empty()) << e;
    EXPECT_EQ(rawConnection(t.path())->queryInt("SELECT count(*) FROM schema_version"), 1);
  }
}

TEST(HangingDrapeDatabase, ConcurrentEnsureTextileGivesOneRow) {
  // Two builders of the same textile started at once (separate handles, as separate processes) must
  // both get the one stored row; neither may fail with "already stored" or a UNIQUE violation.
  for (int round = 0; round < 5; ++round) {
    TestDatabase t("concurrent_textile_" + std::to_string(round));
    { HangingDrapeDatabase db(t.path()); }
    std::vector<std::int64_t> ids(6, -1);
    std::vector<std::string> errors(6);
    std::atomic<int> ready{0};
    std::vector<std::thread> pool;
    for (int w = 0; w < 6; ++w)
      pool.emplace_back([&, w] {
        try {
          HangingDrapeDatabase db(t.path());
          ++ready;
          while (ready.load() < 6) std::this_thread::yield();
          ids[static_cast<std::size_t>(w)] = db.ensureTextile(presetTextile("towel"), Material::cotton());
        } catch (const std::exception& e) {
          errors[static_cast<std::size_t>(w)] = e.what();
          ++ready;
        }
      });
    for (auto& th : pool) th.join();
    for (const auto& e : errors) EXPECT_TRUE(e.empty()) << e;
    for (std::int64_t id : ids) EXPECT_EQ(id, ids[0]);
    HangingDrapeDatabase db(t.path());
    EXPECT_EQ(db.counts().textiles, 1);
    EXPECT_EQ(db.findTextile("towel")->outline.named_points.size(), presetTextile("towel").named_points.size());
  }
}

TEST(HangingDrapeDatabase, DerivedRowCannotBeStoredBeforeItsSource) {
  TestDatabase t("derived_first");
  HangingDrapeDatabase db(t.path());
  const std::int64_t tex = db.addTextile(presetTextile("towel"), Material::cotton());
  NewSimulation src = newRow(tex, Vec2(0.0, 0.0));
  NewSimulation mirror = newRow(tex, Vec2(0.64, 0.0));
  mirror.source = MirrorKind::kMirrorX;
  mirror.source_index = 0;
  const auto ids = db.addSimulations({src, mirror});
  // The mirror alone, while its source is pending: refused, nothing written.
  try {
    db.storeResults({makeResult(ids[1])});
    FAIL() << "stored a derived row before its source";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find("source simulation " + std::to_string(ids[0])), std::string::npos) << e.what();
  }
  EXPECT_EQ(db.simulation(ids[1]).status, SimulationStatus::kPending);
  EXPECT_EQ(db.counts().views, 0);
  // Also refused while the source is failed.
  db.markFailed(ids[0], "diverged");
  EXPECT_THROW(db.storeResults({makeResult(ids[1])}), InvalidInputError);
  EXPECT_TRUE(db.consistencyProblems().empty());
  // In one batch with its source (either order), or after it: accepted.
  db.storeResults({makeResult(ids[1]), makeResult(ids[0])});
  EXPECT_EQ(db.counts().done, 2);
  EXPECT_TRUE(db.consistencyProblems().empty());
}

TEST(HangingDrapeDatabase, UnknownSimulationIdsAreReportedAsSuch) {
  TestDatabase t("unknown_ids");
  HangingDrapeDatabase db(t.path());
  const std::int64_t tex = db.addTextile(presetTextile("towel"), Material::cotton());
  const auto ids = db.addSimulations({newRow(tex, Vec2(0.1, 0.1))});
  EXPECT_TRUE(db.views(ids[0]).empty());  // pending: no views yet, but it exists
  try {
    db.views(ids[0] + 100);
    FAIL() << "views of an unknown simulation returned";
  } catch (const NotFoundError& e) {
    EXPECT_NE(std::string(e.what()).find("no simulation with id"), std::string::npos) << e.what();
  }
  try {
    exportViewPngs(db, ids[0] + 100, t.path() + "_png");
    FAIL() << "exported an unknown simulation";
  } catch (const NotFoundError& e) {
    EXPECT_NE(std::string(e.what()).find("no simulation with id"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(t.path() + "_png"));
}

TEST(HangingDrapeDatabase, ViewPngsOfFractionalAnglesDoNotOverwriteEachOther) {
  TestDatabase t("png_names");
  HangingDrapeDatabase db(t.path());
  const std::int64_t tex = db.addTextile(presetTextile("towel"), Material::cotton());
  const auto ids = db.addSimulations({newRow(tex, Vec2(0.1, 0.1))});
  SimulationResult r = makeResult(ids[0], 4);
  r.views[0].view_angle_deg = 0.0;
  r.views[1].view_angle_deg = 0.5;  // rounded to whole degrees, 0.5 and 1.0 (and 1.4) named the same file
  r.views[2].view_angle_deg = 1.0;
  r.views[3].view_angle_deg = 1.4;
  db.storeResults({r});
  const std::string dir = t.path() + "_png";
  const auto paths = exportViewPngs(db, ids[0], dir);
  ASSERT_EQ(paths.size(), 5u);
  std::set<std::string> unique(paths.begin(), paths.end());
  EXPECT_EQ(unique.size(), 5u);
  for (const auto& p : paths) EXPECT_TRUE(std::filesystem::exists(p)) << p;
  std::size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 5u);
  std::filesystem::remove_all(dir);
}

TEST(HangingDrapeDatabase, MatchIndexLatticeSpansRowsOfSeveralBuilds) {
  // Two builds with other settings (parameter texts) and other hold points: each stored its own
  // lattice ranks. The index must rank the hold points it loaded together; with the stored ranks,
  // (0, 0.1) and (0.2, 0.1) were "neighbours" (ranks 0 and 1 of the first build) although (0.1, 0.1)
  // of the second build lies between them.
  TestDatabase t("lattice_union");
  HangingDrapeDatabase db(t.path());
  const std::int64_t tex = db.addTextile(presetTextile("towel"), Material::cotton());
  NewSimulation a0 = newRow(tex, Vec2(0.0, 0.1), "build A\n"), a1 = newRow(tex, Vec2(0.2, 0.1), "build A\n");
  a1.lattice_j = 1;
  NewSimulation b0 = newRow(tex, Vec2(0.1, 0.1), "build B\n");  // lattice (0, 0) of its own build
  const auto ids = db.addSimulations({a0, a1, b0});
  db.storeResults({makeResult(ids[0], 2), makeResult(ids[1], 2), makeResult(ids[2], 2)});
  MatchIndexOptions o;
  o.textile = "towel";
  const DrapeMatchIndex index = loadDrapeMatchIndex(db, o);
  ASSERT_EQ(index.hold_points.size(), 3u);
  const auto c0 = index.classOf("towel", Vec2(0.0, 0.1)), c1 = index.classOf("towel", Vec2(0.1, 0.1)),
             c2 = index.classOf("towel", Vec2(0.2, 0.1));
  ASSERT_TRUE(c0 && c1 && c2);
  EXPECT_TRUE(index.classesNeighbour(*c0, *c1, false));
  EXPECT_TRUE(index.classesNeighbour(*c1, *c2, false));
  EXPECT_FALSE(index.classesNeighbour(*c0, *c2, false));
  EXPECT_FALSE(index.classesNeighbour(*c0, *c2, true));
  for (const auto& h : index.hold_points) {
    EXPECT_EQ(h.lattice_i, 0);
    EXPECT_EQ(h.lattice_j, static_cast<int>(std::lround(h.hold.x() / 0.1)));
  }
}
