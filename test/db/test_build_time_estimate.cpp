// BuildTimeEstimate (include/textile_handling/db/build_time_estimate.h): the remaining time of a build
// pass from finished simulations, with running ones credited and the queue scheduled on the workers.
#include <gtest/gtest.h>

#include "textile_handling/db/build_time_estimate.h"

using textile_handling::db::BuildTimeEstimate;

TEST(BuildTimeEstimate, UnknownBeforeTheFirstFinishAndZeroAtTheEnd) {
  BuildTimeEstimate e(2, 2);
  EXPECT_EQ(e.remainingSeconds(0.0), -1.0);
  e.started(1, 0.0);
  e.started(2, 0.0);
  EXPECT_EQ(e.remainingSeconds(5.0), -1.0);
  e.finished(1, 10.0);
  EXPECT_DOUBLE_EQ(e.remainingSeconds(10.0), 1.0);  // the other one: at least a tenth of 10 s more
  e.finished(2, 12.0);
  EXPECT_EQ(e.remainingSeconds(12.0), 0.0);
}

TEST(BuildTimeEstimate, QueuedSimulationsAreScheduledOnTheWorkers) {
  // Two workers, 5 simulations of 10 s each: after the first two finish at 10 s, three remain:
  // two in parallel (10 s) and the last alone (10 s more) = 20 s, not 3 x 10 / 2 = 15 s.
  BuildTimeEstimate e(2, 5);
  e.started(1, 0.0);
  e.started(2, 0.0);
  e.finished(1, 10.0);
  e.finished(2, 10.0);
  EXPECT_DOUBLE_EQ(e.remainingSeconds(10.0), 20.0);
  // A third started at 10 s and has run 4 s at 14 s: 6 s left on that worker, the other worker takes
  // the fourth (10 s, until 24 s), the first takes the fifth at 20 s (until 30 s): 16 s from 14 s.
  e.started(3, 10.0);
  EXPECT_DOUBLE_EQ(e.remainingSeconds(14.0), 16.0);
  EXPECT_EQ(e.runningCount(), 1);
  EXPECT_EQ(e.finishedCount(), 2);
}

TEST(BuildTimeEstimate, ARareLongSimulationDoesNotInflateTheRest) {
  // Durations 10, 10, 50 s (one hold point that swings long): the median 10 s, not the mean 23 s, is
  // what the remaining simulations are expected to take.
  BuildTimeEstimate e(1, 5);
  double t = 0;
  for (int id = 1; id <= 3; ++id) {
    e.started(id, t);
    t += id == 3 ? 50.0 : 10.0;
    e.finished(id, t);
  }
  EXPECT_DOUBLE_EQ(e.remainingSeconds(t), 20.0);
}

TEST(BuildTimeEstimate, UnknownIdsAndBadCountsAreHarmless) {
  BuildTimeEstimate e(0, -3);  // clamped to 1 worker, nothing to run
  EXPECT_EQ(e.remainingSeconds(0.0), 0.0);
  BuildTimeEstimate f(1, 2);
  f.finished(99, 5.0);  // never started: ignored
  EXPECT_EQ(f.finishedCount(), 0);
  EXPECT_EQ(f.remainingSeconds(5.0), -1.0);
}
