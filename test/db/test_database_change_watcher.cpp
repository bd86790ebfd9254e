// DatabaseChangeWatcher on both backends (test_database.h): quiet while nothing is committed, a change
// reported once after another handle stores results, and open errors typed.
#include <gtest/gtest.h>

#include <string>

#include "../test_support.h"
#include "test_database.h"
#include "textile_handling/db/database_change_watcher.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/sim/textile_geometry.h"

using namespace textile_handling;
using namespace textile_handling::db;

TEST(DatabaseChangeWatcher, ReportsAnotherHandlesCommittedResultsOnce) {
  test_support::TestDatabase t("watcher");
  { HangingDrapeDatabase create(t.path()); }
  DatabaseChangeWatcher watcher(t.path());
  EXPECT_FALSE(watcher.waitForChange(150)) << "nothing was committed";
  DrapeBuildConfig c;
  c.textile = presetTextile("square");
  c.spacing = 0.05;
  c.hold_points = {Vec2(0.0, 0.0)};
  c.frame = vision::CanonicalFrame::fromMetric(0.5, 0.5, 32);
  c.views.count = 4;
  c.views.step_deg = 90;
  c.workers = 1;
  {
    // Another drape database (another file; on PostgreSQL another schema of the same server database,
    // whose notifications share the channel) changes: not ours.
    test_support::TestDatabase other_db("watcher_other");
    HangingDrapeDatabase other(other_db.path());
    ASSERT_EQ(DrapeDatabaseBuilder(other, c).build().failed_now, 0);
    EXPECT_FALSE(watcher.waitForChange(300)) << "another database's change was reported";
  }
  {
    HangingDrapeDatabase writer(t.path());
    ASSERT_EQ(DrapeDatabaseBuilder(writer, c).build().failed_now, 0);
  }
  EXPECT_TRUE(watcher.waitForChange(5000));
  EXPECT_FALSE(watcher.waitForChange(150)) << "one change is reported once";
}

TEST(DatabaseChangeWatcher, OpenErrorsAreTyped) {
  EXPECT_THROW(DatabaseChangeWatcher("/nonexistent_dir_xyz/drapes.sqlite"), SqliteError);
  EXPECT_THROW(DatabaseChangeWatcher("postgresql://cell:s3cret@127.0.0.1:1/drapes"), PostgresError);
}
