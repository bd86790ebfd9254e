// A resimulation is atomic from the reader's side. A child process runs TextileRegistry::resimulate
// (another material and particle spacing) and is killed with SIGKILL at moments spread over the whole
// rebuild: when the job starts, mid-build, and at random times up to past its end (so also around the
// swap). After every kill the textile's active entries are one complete set, the old one or the new
// one, never a mix or a partial set, and what a recogniser loads is that set; a restarted registry
// resumes the staged build and swaps it in.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <thread>

#include "textile_handling/db/drape_match_index.h"
#include "registry_test_support.h"
#include "textile_handling/registry/textile_registry.h"

namespace textile_handling {
namespace registry {
namespace {

using Clock = std::chrono::steady_clock;

constexpr int kHoldPoints = 9;  // 0.3 m square, lattice 0.15 m
constexpr int kViews = 4;
constexpr Real kOldSpacing = 0.05, kNewSpacing = 0.03;

RegistryOptions options() {
  RegistryOptions o = test_support::smallOptions();
  o.build.spacing = kOldSpacing;
  o.build.views.count = kViews;
  return o;
}

ResimulationRequest newSettings(std::int64_t id) {
  ResimulationRequest r;
  r.textile_id = id;
  r.material_name = "linear_test";
  r.spacing = kNewSpacing;
  return r;
}

std::string dbPath(const std::string& tag) {
  return (std::filesystem::temp_directory_path() / ("th_resim_kill_" + std::to_string(::getpid()) + "_" + tag + ".sqlite"))
      .string();
}

void removeDb(const std::string& path) {
  std::error_code ec;
  for (const char* s : {"", "-wal", "-shm"}) std::filesystem::remove(path + s, ec);
}

void copyDb(const std::string& from, const std::string& to) {
  removeDb(to);
  std::filesystem::copy_file(from, to);  // `from` was closed cleanly: no WAL content left
}

// Runs `job` (which returns an exit status) in a child process; returns its pid. The child never returns
// into gtest. Every registry runs in a child: libgomp's thread pool does not survive a fork, so the
// parent itself never simulates.
template <typename Job>
pid_t startChild(Job job) {
  const pid_t child = ::fork();
  if (child != 0) return child;
  int status = 3;
  try {
    status = job();
  } catch (...) {
  }
  ::_exit(status);
}

pid_t startResimulation(const std::string& path, std::int64_t id) {
  return startChild([&] {
    TextileRegistry reg(path, options());
    reg.resimulate(newSettings(id));
    return reg.waitIdle(600.0) ? 0 : 4;
  });
}

// Waits for a child and returns its exit status (-1 if it did not exit normally).
int finish(pid_t child) {
  int status = 0;
  if (::waitpid(child, &status, 0) != child || !WIFEXITED(status)) return -1;
  return WEXITSTATUS(status);
}

enum class Active { kOld, kNew };

// The invariant a kill must never break: the active entries of the textile are one complete set.
Active checkOneCompleteSet(const std::string& path, std::int64_t id, const std::string& when) {
  db::HangingDrapeDatabase db(path);
  EXPECT_EQ(db.integrityCheck(), "ok") << when;
  const auto problems = db.consistencyProblems();
  EXPECT_TRUE(problems.empty()) << when << ": " << (problems.empty() ? "" : problems.front());
  const db::DatabaseCounts c = db.counts(id);
  EXPECT_EQ(c.done, kHoldPoints) << when;
  EXPECT_EQ(c.pending + c.failed, 0) << when;
  EXPECT_EQ(c.views, kHoldPoints * kViews) << when;
  const db::TextileRecord rec = db.textile(id);
  const bool is_new = rec.material.name != "cotton";
  for (const db::SimulationRecord& s : db.simulations(id)) {
    if (!s.active) continue;
    EXPECT_DOUBLE_EQ(s.spacing, is_new ? kNewSpacing : kOldSpacing) << when << ": a mixed set";
  }
  db::MatchIndexOptions o;
  o.textile = rec.outline.name;
  EXPECT_EQ(db::loadDrapeMatchIndex(db, o).hold_points.size(), static_cast<std::size_t>(kHoldPoints)) << when;
  return is_new ? Active::kNew : Active::kOld;
}

}  // namespace

TEST(ResimulationCrashSafety, KillsAtAnyMomentLeaveTheOldOrTheNewCompleteSet) {
  const std::string pristine = dbPath("pristine");
  removeDb(pristine);
  ASSERT_EQ(finish(startChild([&] {
              TextileRegistry reg(pristine, options());
              reg.registerTextile(test_support::napkin());
              return reg.waitIdle(300.0) ? 0 : 4;
            })),
            0);
  const std::int64_t id = db::HangingDrapeDatabase(pristine).textiles().at(0).id;
  ASSERT_EQ(checkOneCompleteSet(pristine, id, "before"), Active::kOld);

  // An uninterrupted resimulation: how long it takes, and that it ends with the new set.
  const std::string work = dbPath("work");
  copyDb(pristine, work);
  const auto t0 = Clock::now();
  ASSERT_EQ(finish(startResimulation(work, id)), 0);
  const double duration_s = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_EQ(checkOneCompleteSet(work, id, "uninterrupted"), Active::kNew);
  std::printf("uninterrupted resimulation: %.2f s\n", duration_s);

  // Kill moments: as soon as the staged generation exists, after some staged rows are done, and at
  // random times over 1.2 x the whole run (fixed seed).
  std::mt19937 rng(20261202);
  std::uniform_real_distribution<double> uniform(0.0, 1.2 * duration_s);
  struct Kill {
    std::string what;
    int staged_done_at_least = -1;  // >= 0: wait for this many staged rows done
    double after_s = 0;
  };
  std::vector<Kill> kills = {{"staged generation created", 0, 0}, {"staged rows done", 3, 0}};
  for (int k = 0; k < 8; ++k) kills.push_back({"random", -1, uniform(rng)});
  int saw_old = 0, saw_new = 0;
  for (const Kill& k : kills) {
    copyDb(pristine, work);
    const pid_t child = startResimulation(work, id);
    ASSERT_GT(child, 0);
    const auto start = Clock::now();
    bool exited = false;
    int status = 0;
    if (k.staged_done_at_least >= 0) {
      db::HangingDrapeDatabase watch(work);
      for (;;) {
        const auto g = watch.stagedGeneration(id);
        if (g && watch.counts(id).staged_done >= k.staged_done_at_least) break;
        if (::waitpid(child, &status, WNOHANG) == child) {
          exited = true;
          break;
        }
        ASSERT_LT(Clock::now() - start, std::chrono::seconds(120)) << "the resimulation made no progress";
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
    } else {
      std::this_thread::sleep_for(std::chrono::duration<double>(k.after_s));
    }
    const double at_s = std::chrono::duration<double>(Clock::now() - start).count();
    if (!exited) {
      ::kill(child, SIGKILL);
      ASSERT_EQ(::waitpid(child, &status, 0), child);
    }
    const std::string when = k.what + " at " + std::to_string(at_s) + " s";
    bool staged_left = false;
    {
      db::HangingDrapeDatabase check(work);
      staged_left = check.stagedGeneration(id).has_value();
    }
    const Active a = checkOneCompleteSet(work, id, when);
    (a == Active::kOld ? saw_old : saw_new)++;
    std::printf("kill %-26s %6.2f s: %s set active%s\n", k.what.c_str(), at_s, a == Active::kOld ? "old" : "new",
                staged_left ? ", staged build left" : "");
    if (k.staged_done_at_least >= 0) {
      EXPECT_EQ(a, Active::kOld) << when;
      EXPECT_TRUE(staged_left) << when;
    }
    // A restarted registry finishes what was staged and swaps it in (exit status: jobs resumed).
    const int resumed = finish(startChild([&] {
      TextileRegistry reg(work, options());
      const int n = reg.resumeStagedBuilds();
      return reg.waitIdle(300.0) ? n : 100;
    }));
    EXPECT_EQ(resumed, staged_left ? 1 : 0) << when;
    const Active after = checkOneCompleteSet(work, id, when + ", resumed");
    if (staged_left || a == Active::kNew) {
      EXPECT_EQ(after, Active::kNew) << when << ", resumed";
    }
  }
  EXPECT_GT(saw_old, 0);
  removeDb(work);
  removeDb(pristine);
}

}  // namespace registry
}  // namespace textile_handling
