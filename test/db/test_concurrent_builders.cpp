// Several builders on one database (docs/database.md, "Concurrent builders"): row claims, two builders
// sharing one build without running any simulation twice, and a builder killed with SIGKILL mid-build
// whose claimed row another builder takes over once its lease has run out. Runs on SQLite files and,
// as test_concurrent_builders_postgres, on PostgreSQL (test_database.h).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "../test_support.h"
#include "test_database.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/sim/textile_geometry.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

using test_support::TestDatabase;

// 30 x 30 cm square, d = 3 cm, lattice 10 cm: 9 simulated rows, 16 mirrored.
DrapeBuildConfig smallSquare(const std::string& owner, double lease_s) {
  DrapeBuildConfig c;
  c.textile = presetTextile("square");
  c.spacing = 0.03;
  c.lattice_spacing = 0.10;
  c.frame = vision::CanonicalFrame::fromMetric(0.5, 0.5, 64);
  c.workers = 1;
  c.threads_per_simulation = 1;
  c.claim_owner = owner;
  c.claim_lease_s = lease_s;
  return c;
}

NewSimulation row(std::int64_t textile, double x) {
  NewSimulation s;
  s.textile_id = textile;
  s.hold = Vec2(x, 0.1);
  s.integrator = "semi_implicit";
  s.spacing = 0.04;
  s.parameters = "p: 1\n";
  return s;
}

// The owner name a builder of process `pid` of this machine uses (as defaultClaimOwner, without its
// counter): "<host>:<pid>:".
std::string doomedOwner(pid_t pid = ::getpid()) {
  char host[256] = "";
  ::gethostname(host, sizeof host);
  host[sizeof host - 1] = '\0';
  return std::string(host) + ":" + std::to_string(pid) + ":";
}

}  // namespace

TEST(SimulationClaims, OneBuilderHoldsARowUntilItsLeaseRunsOut) {
  TestDatabase t("claims");
  HangingDrapeDatabase db(t.path());
  const std::int64_t tex = db.addTextile(presetTextile("towel"), Material::cotton());
  const auto ids = db.addSimulations({row(tex, 0.1), row(tex, 0.2)});
  EXPECT_TRUE(db.claimSimulation(ids[0], "a", 60));
  EXPECT_FALSE(db.claimSimulation(ids[0], "b", 60));
  EXPECT_TRUE(db.claimSimulation(ids[0], "a", 60));  // its own claim again: not counted twice
  HangingDrapeDatabase::ClaimState s = db.claimState(ids[0]);
  EXPECT_EQ(s.claimed_by, "a");
  EXPECT_FALSE(s.expired);
  EXPECT_EQ(s.claims, 1);
  // A short lease that is not renewed runs out; then another builder takes the row over.
  EXPECT_TRUE(db.claimSimulation(ids[1], "a", 0.2));
  EXPECT_EQ(db.renewClaims("a", 0.2), 2);
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  EXPECT_TRUE(db.claimState(ids[1]).expired);
  EXPECT_TRUE(db.claimSimulation(ids[1], "b", 60));
  s = db.claimState(ids[1]);
  EXPECT_EQ(s.claimed_by, "b");
  EXPECT_EQ(s.claims, 2);
  // Releasing frees only the owner's pending rows; a failed row is no longer claimable.
  EXPECT_EQ(db.releaseClaims("b"), 1);
  EXPECT_EQ(db.claimState(ids[1]).claimed_by, "");
  db.markFailed(ids[1], "no rest");
  EXPECT_FALSE(db.claimSimulation(ids[1], "b", 60));
  EXPECT_EQ(db.claimState(ids[1]).status, SimulationStatus::kFailed);
  // A row held by a builder known to be dead is taken over before its lease runs out.
  const auto more = db.addSimulations({row(tex, 0.3)});
  EXPECT_TRUE(db.claimSimulation(more[0], "x", 600));
  EXPECT_FALSE(db.claimSimulation(more[0], "y", 600));
  EXPECT_FALSE(db.claimSimulation(more[0], "y", 600, "z")) << "only the named dead owner's claim is taken";
  EXPECT_TRUE(db.claimSimulation(more[0], "y", 600, "x"));
  EXPECT_EQ(db.claimState(more[0]).claims, 2);
  // Bad input.
  EXPECT_THROW(db.claimSimulation(999999, "a", 60), NotFoundError);
  EXPECT_THROW(db.claimSimulation(ids[0], "", 60), InvalidInputError);
  EXPECT_THROW(db.claimSimulation(ids[0], "a", 0), InvalidInputError);
  EXPECT_THROW(db.claimSimulation(ids[0], "a", std::nan("")), InvalidInputError);
  EXPECT_THROW(db.claimState(999999), NotFoundError);
  EXPECT_TRUE(db.consistencyProblems().empty());
}

TEST(ConcurrentBuilders, TwoBuildersShareOneBuildAndRunNoSimulationTwice) {
  TestDatabase t("two_builders");
  { HangingDrapeDatabase create(t.path()); }
  DrapeBuildReport ra, rb;
  std::string ea, eb;
  auto build = [&t](const std::string& owner, DrapeBuildReport* out, std::string* error) {
    try {
      HangingDrapeDatabase db(t.path());
      *out = DrapeDatabaseBuilder(db, smallSquare(owner, 30)).build();
    } catch (const std::exception& e) {
      *error = e.what();
    }
  };
  std::thread a(build, "builder_a", &ra, &ea), b(build, "builder_b", &rb, &eb);
  a.join();
  b.join();
  ASSERT_TRUE(ea.empty()) << ea;
  ASSERT_TRUE(eb.empty()) << eb;
  HangingDrapeDatabase db(t.path());
  const DatabaseCounts c = db.counts();
  EXPECT_EQ(c.done, 25);
  EXPECT_EQ(c.failed, 0);
  EXPECT_TRUE(db.consistencyProblems().empty());
  // Every simulated row ran once, by one of the two; together they ran all nine.
  int simulated = 0;
  for (const SimulationRecord& s : db.simulations()) {
    if (s.source != MirrorKind::kIdentity) continue;
    ++simulated;
    const HangingDrapeDatabase::ClaimState st = db.claimState(s.id);
    EXPECT_EQ(st.claims, 1) << "simulation " << s.id << " was claimed " << st.claims << " times";
    EXPECT_EQ(st.claimed_by, "");  // the claim ends with the stored result
  }
  EXPECT_EQ(simulated, 9);
  EXPECT_EQ(ra.simulated_now + rb.simulated_now, 9);
  EXPECT_GT(ra.simulated_now, 0);
  EXPECT_GT(rb.simulated_now, 0);
}

TEST(ConcurrentBuilders, AKilledBuildersRowIsTakenOverAndNothingIsLostOrDuplicated) {
  TestDatabase t("killed_builder");
  { HangingDrapeDatabase create(t.path()); }
  const pid_t child = ::fork();
  ASSERT_GE(child, 0) << "fork failed";
  if (child == 0) {
    try {
      HangingDrapeDatabase db(t.path());
      DrapeDatabaseBuilder(db, smallSquare(doomedOwner(), 600)).build();
    } catch (...) {
      ::_exit(3);
    }
    ::_exit(0);
  }
  // Wait until the child has stored a simulation and claimed the next one, then kill it.
  const auto t0 = std::chrono::steady_clock::now();
  bool finished = false;
  {
    HangingDrapeDatabase watch(t.path());
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      int status = 0;
      if (::waitpid(child, &status, WNOHANG) == child) {
        finished = true;
        break;
      }
      ASSERT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(120)) << "the builder made no progress";
      if (watch.counts().done == 0) continue;
      bool holds_one = false;
      for (const SimulationRecord& s : watch.simulations(0, SimulationStatus::kPending))
        holds_one = holds_one || watch.claimState(s.id).claimed_by.rfind(doomedOwner(child), 0) == 0;
      if (holds_one) break;
    }
  }
  ASSERT_FALSE(finished) << "the builder finished before it could be killed";
  ASSERT_EQ(::kill(child, SIGKILL), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status));

  HangingDrapeDatabase db(t.path());
  std::vector<std::int64_t> orphaned;  // pending rows the dead builder still claims
  for (const SimulationRecord& s : db.simulations(0, SimulationStatus::kPending))
    if (db.claimState(s.id).claimed_by.rfind(doomedOwner(child), 0) == 0) orphaned.push_back(s.id);
  // One worker holds at most one row (none if the kill fell between storing one row and claiming the next).
  ASSERT_LE(orphaned.size(), 1u);
  std::printf("killed the builder holding %zu pending row(s)\n", orphaned.size());
  // Its lease (600 s) has not run out, but its owner names a process of this machine that is gone: the
  // survivor takes the row over at once.
  const auto t_resume = std::chrono::steady_clock::now();
  const DrapeBuildReport r = DrapeDatabaseBuilder(db, smallSquare("survivor", 600)).build();
  EXPECT_LT(std::chrono::steady_clock::now() - t_resume, std::chrono::seconds(60)) << "waited for the dead builder's lease";
  EXPECT_EQ(r.failed_now, 0);
  const DatabaseCounts c = db.counts();
  EXPECT_EQ(c.done, 25) << "the build completes";
  EXPECT_TRUE(db.consistencyProblems().empty());
  // Only the row the dead builder held ran twice (its first run never finished); every other once.
  for (const SimulationRecord& s : db.simulations()) {
    if (s.source != MirrorKind::kIdentity) continue;
    const bool was_orphaned = !orphaned.empty() && s.id == orphaned.front();
    EXPECT_EQ(db.claimState(s.id).claims, was_orphaned ? 2 : 1) << "simulation " << s.id;
  }
}
