// A recognizer reading a database while a builder writes it (both backends, ../db/test_database.h): the
// recognizer reloads on the watcher's change reports, never fails, never loses silhouettes, sees the
// build grow, and ends with exactly what a fresh recognizer loads.
#include <gtest/gtest.h>

#include <atomic>
#include <string>
#include <thread>

#include "../db/test_database.h"
#include "textile_handling/db/database_change_watcher.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/recognition/textile_recognizer.h"

using namespace textile_handling;

TEST(RecognizerBesideABuilder, ReloadsWhileTheBuilderWritesAndEndsWithTheWholeBuild) {
  test_support::TestDatabase t("reader_writer");
  { db::HangingDrapeDatabase create(t.path()); }
  db::DrapeBuildConfig c;
  c.textile = presetTextile("square");
  c.spacing = 0.03;
  c.lattice_spacing = 0.10;  // 9 simulations, 25 rows
  c.frame = vision::CanonicalFrame::fromMetric(0.5, 0.5, 64);
  c.workers = 1;
  c.threads_per_simulation = 1;
  std::atomic<bool> built{false};
  std::string build_error;
  db::DatabaseChangeWatcher watcher(t.path());
  std::thread builder([&] {
    try {
      db::HangingDrapeDatabase writer(t.path());
      if (db::DrapeDatabaseBuilder(writer, c).build().failed_now != 0) build_error = "simulations failed";
    } catch (const std::exception& e) {
      build_error = e.what();
    }
    built = true;
  });
  // The recognizer starts on an empty database (not ready) and follows the build.
  recognition::TextileRecognizer rec(t.path());
  std::size_t last = rec.silhouetteCount();
  int reloads_during_build = 0;
  std::string read_error;
  while (!built) {
    if (!watcher.waitForChange(200)) continue;
    try {
      const bool was_building = !built;
      if (rec.reloadIfChanged() && was_building) ++reloads_during_build;
    } catch (const std::exception& e) {
      read_error = e.what();
      break;
    }
    EXPECT_GE(rec.silhouetteCount(), last) << "a reload lost silhouettes";
    last = rec.silhouetteCount();
  }
  builder.join();
  ASSERT_TRUE(build_error.empty()) << build_error;
  ASSERT_TRUE(read_error.empty()) << read_error;
  EXPECT_GE(reloads_during_build, 1) << "the recognizer never saw the build grow";
  watcher.waitForChange(1000);
  rec.reloadIfChanged();
  const recognition::TextileRecognizer fresh(t.path());
  EXPECT_TRUE(rec.ready());
  EXPECT_EQ(rec.silhouetteCount(), fresh.silhouetteCount());
  EXPECT_GT(fresh.silhouetteCount(), 0u);
}
