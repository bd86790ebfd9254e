// The two storage backends hold the same data and give the same answers: one build into an SQLite file
// and one into a PostgreSQL schema (the throw-away test server, ../db/test_database.h) store bit-identical
// rest shapes and silhouettes, and a recognizer on each returns the same result for the same camera
// images.
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "../db/test_database.h"
#include "recognition_test_support.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/drape_export.h"
#include "textile_handling/recognition/textile_recognizer.h"
#include "textile_handling/vision/shaded_renderer.h"

using namespace textile_handling;


TEST(StorageBackends, StoreIdenticalShapesAndRecogniseAlike) {
  test_support::TempDatabase file("backends_sqlite");
  // A schema of its own on the test server, whatever backend this run tests.
  const std::string server = test_support::ThrowawayPostgres::url();
  const std::string schema = "t" + std::to_string(::getpid()) + "_backends_agree";
  db::PgConnection(server).exec("DROP SCHEMA IF EXISTS " + schema + " CASCADE; CREATE SCHEMA " + schema);
  const std::string url = test_support::schemaUrl(server, schema);
  {
    db::HangingDrapeDatabase sqlite(file.path()), postgres(url);
    ASSERT_EQ(db::DrapeDatabaseBuilder(sqlite, test_support::smallTowelBuildConfig()).build().failed_now, 0);
    ASSERT_EQ(db::DrapeDatabaseBuilder(postgres, test_support::smallTowelBuildConfig()).build().failed_now, 0);
    const auto a = sqlite.simulations(0, db::SimulationStatus::kDone);
    const auto b = postgres.simulations(0, db::SimulationStatus::kDone);
    ASSERT_EQ(a.size(), b.size());
    ASSERT_GE(a.size(), 4u);
    for (std::size_t k = 0; k < a.size(); ++k) {
      EXPECT_TRUE(a[k].hold == b[k].hold);
      EXPECT_EQ(a[k].parameters, b[k].parameters);
      EXPECT_EQ(a[k].held_particle, b[k].held_particle);
      EXPECT_EQ(a[k].hanging_depth_m, b[k].hanging_depth_m);  // doubles round-trip exactly on both
      EXPECT_TRUE(sqlite.positions(a[k].id) == postgres.positions(b[k].id)) << "row " << k;
      const auto va = sqlite.views(a[k].id), vb = postgres.views(b[k].id);
      ASSERT_EQ(va.size(), vb.size());
      for (std::size_t v = 0; v < va.size(); ++v) {
        EXPECT_EQ(va[v].view_angle_deg, vb[v].view_angle_deg);
        EXPECT_EQ(va[v].metres_per_pixel, vb[v].metres_per_pixel);
        EXPECT_TRUE(va[v].mask == vb[v].mask);
      }
    }
    const auto ta = sqlite.textile(a.front().textile_id), tb = postgres.textile(b.front().textile_id);
    ASSERT_EQ(ta.outline.named_points.size(), tb.outline.named_points.size());
    for (std::size_t k = 0; k < ta.outline.named_points.size(); ++k)
      EXPECT_EQ(ta.outline.named_points[k].name, tb.outline.named_points[k].name);
    EXPECT_TRUE(ta.material == tb.material);
  }
  // The same images give the same answer on both.
  const recognition::TextileRecognizer on_file(file.path()), on_server(url);
  EXPECT_EQ(on_file.silhouetteCount(), on_server.silhouetteCount());
  db::DatabaseOpenOptions ro;
  ro.read_only = true;
  const db::HangingDrapeDatabase reader(file.path(), ro);
  const auto sims = reader.simulations(0, db::SimulationStatus::kDone);
  for (std::size_t k : {std::size_t{0}, sims.size() / 2}) {
    const db::StoredDrapeMesh mesh = db::loadDrapeMesh(reader, sims[k].id);
    for (double az : {30.0, 200.0}) {
      const recognition::RecognitionResult r1 = on_file.recognize(test_support::renderedObservation(mesh, az));
      const recognition::RecognitionResult r2 = on_server.recognize(test_support::renderedObservation(mesh, az));
      EXPECT_EQ(r1.textile_name, r2.textile_name);
      EXPECT_TRUE(r1.hold_point == r2.hold_point) << "row " << k << " azimuth " << az;
      EXPECT_EQ(r1.view_angle_deg, r2.view_angle_deg);
      EXPECT_EQ(r1.score, r2.score);
      ASSERT_EQ(r1.grasp_poses.size(), r2.grasp_poses.size());
      for (std::size_t g = 0; g < r1.grasp_poses.size(); ++g)
        EXPECT_TRUE(r1.grasp_poses[g].position == r2.grasp_poses[g].position);
    }
  }
  db::PgConnection(server).exec("DROP SCHEMA IF EXISTS " + schema + " CASCADE");
}
