// The MPI build farm (docs/build_farm.md) as processes: `mpirun -np 3 --oversubscribe drape_db build
// --mpi` on localhost builds exactly what one process builds, and a rank killed with SIGKILL mid-build
// ends the job without losing or duplicating a simulation; running the command again completes it.
// On SQLite files and, as test_build_farm_postgres, on PostgreSQL (../db/test_database.h).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "../db/test_database.h"
#include "tool_process.h"
#include "textile_handling/db/hanging_drape_database.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

struct Spawned {
  pid_t pid = -1;
  std::string out_path, err_path;
};

// mpirun with `ranks` ranks of drape_db (`args` after the executable), output to files.
Spawned spawnFarm(int ranks, const std::vector<std::string>& args) {
  static int counter = 0;
  Spawned s;
  const std::string base = "/tmp/th_farm_" + std::to_string(::getpid()) + "_" + std::to_string(counter++);
  s.out_path = base + ".out";
  s.err_path = base + ".err";
  std::vector<std::string> argv = {MPIRUN_EXE, "--oversubscribe", "-np", std::to_string(ranks)};
  if (::geteuid() == 0) argv.push_back("--allow-run-as-root");
  argv.push_back(DRAPE_DB_EXE);
  argv.insert(argv.end(), args.begin(), args.end());
  std::fflush(stdout);  // else the child writes this process's buffered output again
  std::fflush(stderr);
  s.pid = ::fork();
  if (s.pid == 0) {
    std::freopen(s.out_path.c_str(), "w", stdout);
    std::freopen(s.err_path.c_str(), "w", stderr);
    ::setenv("OMP_WAIT_POLICY", "passive", 1);
    std::vector<char*> c;
    for (auto& a : argv) c.push_back(a.data());
    c.push_back(nullptr);
    ::execv(c[0], c.data());
    ::_exit(127);
  }
  return s;
}

// The exit status of `s` (-1: killed or still running after `timeout_s`, then killed).
int waitFarm(const Spawned& s, int timeout_s, std::string* out) {
  int status = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(timeout_s);
  while (::waitpid(s.pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(s.pid, SIGKILL);
      ::waitpid(s.pid, &status, 0);
      *out = "timed out";
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  *out = tool_process::readAll(s.out_path) + tool_process::readAll(s.err_path);
  std::remove(s.out_path.c_str());
  std::remove(s.err_path.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The pid of rank `rank` of the drape_db job started by mpirun `mpirun_pid` (0 if not found).
pid_t rankPid(pid_t mpirun_pid, int rank) {
  for (const auto& e : std::filesystem::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    const std::string stat = tool_process::readAll(e.path().string() + "/stat");
    const std::size_t close = stat.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream rest(stat.substr(close + 2));
    char state = 0;
    int ppid = 0;
    rest >> state >> ppid;
    if (ppid != mpirun_pid) continue;
    std::string env = tool_process::readAll(e.path().string() + "/environ");
    for (char& ch : env)
      if (ch == '\0') ch = '\n';
    if (env.find("\nOMPI_COMM_WORLD_RANK=" + std::to_string(rank) + "\n") != std::string::npos ||
        env.rfind("OMPI_COMM_WORLD_RANK=" + std::to_string(rank) + "\n", 0) == 0)
      return static_cast<pid_t>(std::stoi(name));
  }
  return 0;
}

std::vector<std::string> buildArgs(const std::string& db, const std::string& lattice) {
  return {"build", "--mpi", "--db", db, "--textile", "square", "--spacing", "0.03", "--lattice", lattice,
          "--frame", "64x64@0.5", "--quiet"};
}

// Positions and masks of every row, by hold point.
std::map<std::pair<double, double>, std::pair<VecX, std::vector<vision::BitMask>>> shapes(const std::string& db_path) {
  DatabaseOpenOptions ro;
  ro.read_only = true;
  HangingDrapeDatabase db(db_path, ro);
  std::map<std::pair<double, double>, std::pair<VecX, std::vector<vision::BitMask>>> out;
  for (const SimulationRecord& s : db.simulations(0, SimulationStatus::kDone)) {
    std::vector<vision::BitMask> masks;
    for (const StoredView& v : db.views(s.id)) masks.push_back(v.mask);
    out[{s.hold.x(), s.hold.y()}] = {db.positions(s.id), masks};
  }
  return out;
}

}  // namespace

TEST(BuildFarm, ThreeRanksBuildExactlyWhatOneProcessBuilds) {
  test_support::TestDatabase farm("farm3"), local("farm_local");
  std::string out;
  const int rc = waitFarm(spawnFarm(3, buildArgs(farm.path(), "0.1")), 300, &out);
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("farm: 3 ranks"), std::string::npos) << out;
  EXPECT_NE(out.find("these settings: 25 of 25 hold points done, 0 failed"), std::string::npos) << out;
  const tool_process::ToolRun one = tool_process::runTool(
      DRAPE_DB_EXE, {"build", "--db", local.path(), "--textile", "square", "--spacing", "0.03", "--lattice", "0.1",
                     "--frame", "64x64@0.5", "--quiet", "--threads", "2", "--sim-threads", "1"}, 300);
  ASSERT_EQ(one.exit_code, 0) << one.err;
  const auto a = shapes(farm.path()), b = shapes(local.path());
  ASSERT_EQ(a.size(), 25u);
  ASSERT_EQ(b.size(), 25u);
  for (const auto& [hold, shape] : a) {
    ASSERT_TRUE(b.count(hold));
    const auto& other = b.at(hold);
    EXPECT_TRUE(shape.first == other.first) << "positions differ at (" << hold.first << ", " << hold.second << ")";
    ASSERT_EQ(shape.second.size(), other.second.size());
    for (std::size_t k = 0; k < shape.second.size(); ++k) EXPECT_TRUE(shape.second[k] == other.second[k]);
  }
  // Every simulation ran once.
  HangingDrapeDatabase db(farm.path());
  for (const SimulationRecord& s : db.simulations())
    if (s.source == MirrorKind::kIdentity) EXPECT_EQ(db.claimState(s.id).claims, 1) << "simulation " << s.id;
}

namespace {

// Starts the farm on `db`, kills rank `victim` with SIGKILL once `kill_after` more rows are done, and checks
// that mpirun ends the job and the database kept every stored row. Returns false if the farm finished
// before the kill (nothing to check).
bool killRankMidBuild(const std::string& db_path, int victim, std::int64_t kill_after) {
  Spawned job;
  std::int64_t done_at_kill = 0;
  {
    HangingDrapeDatabase watch(db_path);
    kill_after += watch.counts().done;  // rows this run stores, not rows an earlier run left
    job = spawnFarm(3, buildArgs(db_path, "0.05"));
    const auto t0 = std::chrono::steady_clock::now();
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      int status = 0;
      if (::waitpid(job.pid, &status, WNOHANG) == job.pid) return false;
      EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(180)) << "the farm made no progress";
      if (std::chrono::steady_clock::now() - t0 > std::chrono::seconds(180)) break;
      if (watch.counts().done >= kill_after) break;
    }
    const pid_t pid = rankPid(job.pid, victim);
    EXPECT_GT(pid, 0) << "no rank " << victim << " among mpirun's children";
    if (pid > 0) EXPECT_EQ(::kill(pid, SIGKILL), 0);
    done_at_kill = watch.counts().done;
  }
  std::string out;
  EXPECT_NE(waitFarm(job, 120, &out), 0) << "mpirun ends the job when a rank dies: " << out;
  HangingDrapeDatabase db(db_path);
  EXPECT_TRUE(db.consistencyProblems().empty());
  EXPECT_EQ(db.integrityCheck(), "ok");
  const DatabaseCounts c = db.counts();
  EXPECT_GE(c.done, done_at_kill) << "the kill lost stored simulations";
  EXPECT_EQ(c.failed, 0);
  std::printf("killed rank %d with %lld of %lld rows done\n", victim, static_cast<long long>(c.done),
              static_cast<long long>(c.simulations));
  return true;
}

}  // namespace

TEST(BuildFarm, KilledRanksLoseNothingAndRunningTheCommandAgainCompletesTheBuild) {
  test_support::TestDatabase t("farm_kill");
  { HangingDrapeDatabase create(t.path()); }
  // 30 x 30 cm square at d = 3 cm, lattice 5 cm: 16 simulated rows, 49 in all. First a simulating rank
  // dies, then (SQLite: the writer) rank 0.
  int kills = 0;
  if (killRankMidBuild(t.path(), 1, 8)) ++kills;
  if (!HasFailure() && killRankMidBuild(t.path(), 0, 8)) ++kills;
  ASSERT_FALSE(HasFailure());
  EXPECT_GE(kills, 1);
  // The same command again resumes: the rows the dead jobs had claimed (60 s leases) are taken over at
  // once, since the processes that claimed them are gone from this machine.
  std::string out;
  const int rc = waitFarm(spawnFarm(3, buildArgs(t.path(), "0.05")), 300, &out);
  ASSERT_EQ(rc, 0) << out;
  HangingDrapeDatabase db(t.path());
  const DatabaseCounts c = db.counts();
  EXPECT_EQ(c.done, 49);
  EXPECT_EQ(c.failed, 0);
  EXPECT_TRUE(db.consistencyProblems().empty());
  int twice = 0;
  for (const SimulationRecord& s : db.simulations()) {
    if (s.source != MirrorKind::kIdentity) continue;
    const std::int64_t claims = db.claimState(s.id).claims;
    EXPECT_GE(claims, 1);
    EXPECT_LE(claims, 1 + kills) << "simulation " << s.id;
    twice += claims >= 2;
  }
  // Only rows in flight at a kill (at most one per rank and kill) ran again.
  EXPECT_LE(twice, 3 * kills);
}
