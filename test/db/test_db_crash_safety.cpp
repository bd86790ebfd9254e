// Crash safety: a child process runs the builder and is killed with SIGKILL in the middle of the build
// (three times, at different points); after every kill the database opens cleanly, passes SQLite's
// integrity check, and is consistent (every done simulation has its positions and all its views,
// nothing unfinished has any, mirrored rows are done only with their source). A final rebuild resumes
// and completes everything without re-running what was done.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "textile_handling/db/drape_database_builder.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

// 30 x 30 cm square at d = 2 cm (256 particles), hold points on a 5 cm lattice over one quadrant:
// 16 simulated, 49 in all; one worker, so that the build takes a few seconds.
DrapeBuildConfig crashConfig() {
  DrapeBuildConfig c;
  c.textile = presetTextile("square");
  c.spacing = 0.02;
  c.lattice_spacing = 0.05;
  c.frame = vision::CanonicalFrame::fromMetric(0.5, 0.5, 64);
  c.workers = 1;
  return c;
}

void checkConsistent(const std::string& path, int round) {
  HangingDrapeDatabase db(path);  // opens cleanly (WAL recovery after the kill)
  EXPECT_EQ(db.integrityCheck(), "ok") << "round " << round;
  const auto problems = db.consistencyProblems();
  EXPECT_TRUE(problems.empty()) << "round " << round << ": " << (problems.empty() ? "" : problems.front());
  const DatabaseCounts c = db.counts();
  EXPECT_EQ(c.simulations, 49) << "round " << round;
  EXPECT_EQ(c.pending + c.done + c.failed, c.simulations);
  EXPECT_EQ(c.views, 36 * c.done) << "round " << round;
  // Every stored blob decodes.
  for (const auto& s : db.simulations(0, SimulationStatus::kDone)) {
    EXPECT_EQ(db.positions(s.id).size(), 3 * s.particles);
    EXPECT_EQ(static_cast<int>(db.views(s.id).size()), s.view_count);
  }
}

}  // namespace

TEST(DrapeDatabaseCrashSafety, KilledBuilderLeavesAConsistentResumableDatabase) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("th_db_crash_" + std::to_string(::getpid()) + ".sqlite"))
                               .string();
  for (const char* s : {"", "-wal", "-shm"}) std::filesystem::remove(path + s);
  {
    // Create the file and plan the rows, so that the parent can watch progress from the start.
    HangingDrapeDatabase db(path);
  }
  std::int64_t done_before = 0;
  int kills = 0;
  for (int round = 0; round < 3; ++round) {
    const pid_t child = ::fork();
    ASSERT_GE(child, 0) << "fork failed";
    if (child == 0) {
      // Child: run the builder until killed; never return into gtest.
      try {
        HangingDrapeDatabase db(path);
        DrapeDatabaseBuilder(db, crashConfig()).build();
      } catch (...) {
        ::_exit(3);
      }
      ::_exit(0);
    }
    // Parent: wait until the child has committed two more simulations (plus a little), then kill it.
    const auto t0 = std::chrono::steady_clock::now();
    std::int64_t done = done_before;
    bool finished = false;
    {
      HangingDrapeDatabase watch(path);
      while (done < done_before + 2 * 4) {  // each simulated row commits with up to 3 mirrors
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        done = watch.counts().done;
        int status = 0;
        if (::waitpid(child, &status, WNOHANG) == child) {
          finished = true;
          break;
        }
        ASSERT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(120)) << "builder made no progress";
      }
    }
    if (finished) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(37 * (round + 1)));  // land mid-simulation or mid-write
    ASSERT_EQ(::kill(child, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
    ++kills;
    checkConsistent(path, round);
    HangingDrapeDatabase db(path);
    const DatabaseCounts c = db.counts();
    EXPECT_GE(c.done, done_before) << "a kill lost committed simulations";
    EXPECT_LT(c.done, 49) << "killed too late to test anything";
    std::printf("round %d: killed the builder with %lld of 49 rows done, %lld pending\n", round,
                static_cast<long long>(c.done), static_cast<long long>(c.pending));
    done_before = c.done;
  }
  EXPECT_GE(kills, 1);
  // Resume: completes everything, without re-running the simulations that were done.
  HangingDrapeDatabase db(path);
  const std::int64_t simulated_done = [&] {
    std::int64_t n = 0;
    for (const auto& s : db.simulations(0, SimulationStatus::kDone)) n += s.source == MirrorKind::kIdentity;
    return n;
  }();
  DrapeBuildConfig c = crashConfig();
  c.workers = 2;
  const DrapeBuildReport r = DrapeDatabaseBuilder(db, c).build();
  EXPECT_EQ(r.already_done, simulated_done);
  EXPECT_EQ(r.simulated_now, 16 - simulated_done);
  EXPECT_EQ(r.failed_now, 0);
  const DatabaseCounts end = db.counts();
  EXPECT_EQ(end.done, 49);
  EXPECT_EQ(end.pending, 0);
  EXPECT_EQ(end.views, 49 * 36);
  EXPECT_TRUE(db.consistencyProblems().empty());
  EXPECT_EQ(db.integrityCheck(), "ok");
  for (const char* s : {"", "-wal", "-shm"}) std::filesystem::remove(path + s);
}
