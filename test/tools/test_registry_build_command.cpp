// TextileRegistry handing its builds to an external command (RegistryOptions::build_command, the
// drape_simulator node's ~database_build_command; docs/build_farm.md): a registration and a
// resimulation built by `mpirun -np 3 drape_db build --mpi` store exactly what the registry's own worker
// stores and report progress; a command that cannot run or fails fails the job with its reason and the
// registry goes on; stopping the registry stops the farm, and the build resumes without losing or
// repeating a simulation. On SQLite files and, as test_registry_build_command_postgres, on PostgreSQL.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "../db/test_database.h"
#include "../registry/registry_test_support.h"
#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/registry/textile_registry.h"

namespace textile_handling {
namespace registry {
namespace {

using textile_handling::test_support::TestDatabase;

// The resimulations' material: cotton, half as heavy again.
std::string heavyCottonYaml() {
  Material m = Material::cotton();
  m.name = "heavy_cotton";
  m.areal_density *= 1.5;
  return materialToYaml(m);
}

std::vector<std::string> farmCommand(int ranks) {
  std::vector<std::string> c = {MPIRUN_EXE, "--oversubscribe", "-np", std::to_string(ranks)};
  if (::geteuid() == 0) c.push_back("--allow-run-as-root");
  for (const char* w : {DRAPE_DB_EXE, "build", "--mpi"}) c.push_back(w);
  return c;
}

struct Events {
  std::mutex mu;
  std::vector<BuildProgressEvent> all;
  std::vector<BuildProgressEvent> copy() {
    std::lock_guard<std::mutex> l(mu);
    return all;
  }
};

TextileRegistry::ProgressCallback recordInto(Events& ev) {
  return [&ev](const BuildProgressEvent& e) {
    std::lock_guard<std::mutex> l(ev.mu);
    ev.all.push_back(e);
  };
}

// The active done rows' positions by hold point and parameter text.
std::map<std::string, VecX> activeShapes(const std::string& path) {
  db::DatabaseOpenOptions ro;
  ro.read_only = true;
  db::HangingDrapeDatabase database(path, ro);
  std::map<std::string, VecX> out;
  for (const db::SimulationRecord& s : database.simulations(0, db::SimulationStatus::kDone))
    if (s.active)
      out[std::to_string(s.hold.x()) + "," + std::to_string(s.hold.y()) + "\n" + s.parameters] = database.positions(s.id);
  return out;
}

void expectSameShapes(const std::string& a_path, const std::string& b_path, std::size_t rows) {
  const auto a = activeShapes(a_path), b = activeShapes(b_path);
  EXPECT_EQ(a.size(), rows);
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [key, x] : a) {
    ASSERT_TRUE(b.count(key)) << "row only in the farm's database: " << key;
    EXPECT_TRUE(x == b.at(key)) << "positions differ: " << key;
  }
}

TEST(RegistryBuildCommand, AnMpiFarmStoresWhatTheRegistrysOwnWorkerStores) {
  TestDatabase farm_db("reg_farm"), here_db("reg_here");
  RegistryOptions farm_options = test_support::smallOptions();
  farm_options.build_command = farmCommand(3);
  Events ev;
  std::int64_t id = 0;
  {
    TextileRegistry farm(farm_db.path(), farm_options, recordInto(ev));
    id = farm.registerTextile(test_support::napkin()).textile_id;
    ASSERT_TRUE(farm.waitIdle(300));
    const std::vector<BuildProgressEvent> events = ev.copy();
    ASSERT_FALSE(events.empty());
    EXPECT_EQ(events.back().state, "done") << events.back().message;
    EXPECT_EQ(events.back().failed, 0);
    EXPECT_EQ(events.back().total, 4) << "the quadrant's 4 hold points are simulated";
    int progress = 0;
    for (const BuildProgressEvent& e : events) progress += e.state == "running" && e.done > 0 && e.total == 4;
    EXPECT_GE(progress, 1) << "no progress from the farm";
    // A resimulation through the farm: staged, then promoted.
    ResimulationRequest r;
    r.textile_id = id;
    r.material_yaml = heavyCottonYaml();
    farm.resimulate(r);
    ASSERT_TRUE(farm.waitIdle(300));
    EXPECT_EQ(ev.copy().back().state, "done") << ev.copy().back().message;
    EXPECT_NE(ev.copy().back().message.find("active"), std::string::npos) << ev.copy().back().message;
  }
  {
    TextileRegistry here(here_db.path(), test_support::smallOptions());
    const std::int64_t same = here.registerTextile(test_support::napkin()).textile_id;
    ASSERT_TRUE(here.waitIdle(300));
    ResimulationRequest r;
    r.textile_id = same;
    r.material_yaml = heavyCottonYaml();
    here.resimulate(r);
    ASSERT_TRUE(here.waitIdle(300));
  }
  // 9 hold points (4 simulated, 5 mirrored), the resimulated generation active on both.
  expectSameShapes(farm_db.path(), here_db.path(), 9);
  db::HangingDrapeDatabase check(farm_db.path());
  EXPECT_EQ(check.textile(id).material.name, "heavy_cotton");
  EXPECT_TRUE(check.consistencyProblems().empty());
}

TEST(RegistryBuildCommand, ACommandThatFailsFailsTheJobWithItsReasonAndTheRegistryGoesOn) {
  TestDatabase t("reg_bad_command");
  struct Case {
    std::vector<std::string> command;
    std::string needle;
  };
  const Case cases[] = {
      {{"/nonexistent/drape_db", "build"}, "cannot run '/nonexistent/drape_db'"},
      {{"/bin/sh", "-c", "echo no database here >&2; exit 3", "sh"}, "exit status 3: no database here"},
      {{"/bin/sh", "-c", "kill -9 $$", "sh"}, "killed by signal 9"},
      {{"/bin/true"}, "printed no build report"},
      {{DRAPE_DB_EXE, "build", "--no-such-option"}, "exit status 2"},
  };
  int k = 0;
  for (const Case& c : cases) {
    RegistryOptions o = test_support::smallOptions();
    o.build_command = c.command;
    Events ev;
    TextileRegistry reg(t.path(), o, recordInto(ev));
    const std::string name = "napkin_" + std::to_string(k++);
    reg.registerTextile(test_support::napkin(name));
    ASSERT_TRUE(reg.waitIdle(60));
    const BuildProgressEvent last = ev.copy().back();
    EXPECT_EQ(last.state, "failed") << c.command.front();
    EXPECT_NE(last.message.find(c.needle), std::string::npos) << "'" << last.message << "'";
    // The registry still answers and stored the textile (its build can be run again).
    bool listed = false;
    for (const TextileSummary& s : reg.list()) listed = listed || s.record.outline.name == name;
    EXPECT_TRUE(listed);
  }
  RegistryOptions empty = test_support::smallOptions();
  empty.build_command = {""};
  EXPECT_THROW(TextileRegistry(t.path(), empty), std::invalid_argument);
}

TEST(RegistryBuildCommand, StoppingTheRegistryStopsTheFarmAndTheBuildResumesWithoutLossOrRepetition) {
  TestDatabase t("reg_farm_stop");
  RegistryOptions o = test_support::smallOptions();
  // d = 3 cm, lattice 5 cm on the 30 cm napkin: 16 simulated hold points, long enough to stop midway.
  o.build.spacing = 0.03;
  o.build.lattice_spacing = 0.05;
  o.build_command = farmCommand(2);
  o.build_stop_grace_s = 20;
  Events ev;
  std::int64_t id = 0;
  int total = 0;
  {
    auto reg = std::make_unique<TextileRegistry>(t.path(), o, recordInto(ev));
    id = reg->registerTextile(test_support::napkin()).textile_id;
    const auto t0 = std::chrono::steady_clock::now();
    for (;;) {  // until the farm reports its second finished simulation
      bool started = false;
      for (const BuildProgressEvent& e : ev.copy()) {
        ASSERT_TRUE(e.state == "queued" || e.state == "running") << "the build ended first: " << e.message;
        if (e.state == "running" && e.done >= 2) {
          started = true;
          total = e.total;
        }
      }
      if (started) break;
      ASSERT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(240)) << "no progress from the farm";
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    const auto stop0 = std::chrono::steady_clock::now();
    reg.reset();
    EXPECT_LT(std::chrono::steady_clock::now() - stop0, std::chrono::seconds(30)) << "the registry did not stop the farm";
  }
  EXPECT_EQ(ev.copy().back().state, "stopped") << ev.copy().back().message;
  ASSERT_EQ(total, 16);
  std::int64_t done_before = 0;
  {
    db::HangingDrapeDatabase database(t.path());
    done_before = database.counts(id).done;
  }
  // The registry's own worker completes the build (the farm's rows are the same settings).
  RegistryOptions here = o;
  here.build_command.clear();
  TextileRegistry reg(t.path(), here);
  reg.ensureBuilt(id);
  ASSERT_TRUE(reg.waitIdle(300));
  db::HangingDrapeDatabase database(t.path());
  const db::DatabaseCounts c = database.counts(id);
  EXPECT_GE(c.done, done_before) << "stopping lost stored rows";
  EXPECT_EQ(c.failed, 0);
  EXPECT_EQ(c.pending, 0);
  // One row per hold point (the schema's unique key), each done once; only the simulations running when
  // the farm was stopped (at most one per rank) were started a second time.
  int simulated = 0, rerun = 0;
  for (const db::SimulationRecord& s : database.simulations(id)) {
    if (s.source != db::MirrorKind::kIdentity) continue;
    ++simulated;
    const int claims = database.claimState(s.id).claims;
    EXPECT_GE(claims, 1);
    EXPECT_LE(claims, 2) << "simulation " << s.id;
    rerun += claims == 2;
  }
  EXPECT_EQ(simulated, 16);
  EXPECT_LE(rerun, 2);
  std::printf("stopped with %lld rows done; %d simulations started again\n", static_cast<long long>(done_before), rerun);
  EXPECT_TRUE(database.consistencyProblems().empty());
}

}  // namespace
}  // namespace registry
}  // namespace textile_handling
