// drape_sim as a process: usage errors, bad scenes, the memory budget, unwritable outputs and the
// output directory's mode, each with its documented exit status (docs/simulation.md, "Programs").
// The child runs with a 4 GiB address-space limit and a time limit, so that a regression fails the
// test instead of taking the machine down or hanging it.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "tool_process.h"

namespace {

const std::string kDrapeSim = DRAPE_SIM_EXECUTABLE;
const std::string kSourceDir = TEXTILE_HANDLING_SOURCE_DIR;

using textile_handling::tool_process::ToolRun;
using Outcome = ToolRun;

// Runs drape_sim with `args` (umask 000, 4 GiB of address space, at most 120 s).
Outcome runDrapeSim(const std::vector<std::string>& args) {
  const Outcome o = textile_handling::tool_process::runTool(kDrapeSim, args);
  EXPECT_FALSE(o.timed_out) << "drape_sim did not finish within 120 s";
  return o;
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// Scene files and output directories of one test, removed at the end.
struct Scratch {
  std::string dir = ::testing::TempDir() + "/th_cli_scratch_" + std::to_string(::getpid());
  Scratch() {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  ~Scratch() { std::filesystem::remove_all(dir); }
  std::string scene(const std::string& name, const std::string& text) const {
    const std::string path = dir + "/" + name;
    std::ofstream(path) << text;
    return path;
  }
};

// A small, quick scene (7 x 7 particles, 0.05 s simulated).
const std::string kSmallScene =
    "textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {points: [corner_ul]}\n"
    "model: {jacobian: definite_fix}\nsimulation: {max_time_s: 0.05}\n";

TEST(DrapeSimCli, ThreadCountsOutOfRangeAreUsageErrors) {
  Scratch s;
  const std::string scene = s.scene("small.yaml", kSmallScene);
  for (const std::string n : {"100000", "0", "-3", "many"}) {
    const Outcome o = runDrapeSim({scene, "--out", s.dir + "/out", "--threads", n});
    EXPECT_EQ(o.exit_code, 2) << n << ": " << o.err;
    EXPECT_TRUE(contains(o.err, "--threads")) << o.err;
    EXPECT_TRUE(contains(o.err, "usage:")) << o.err;
    EXPECT_FALSE(contains(o.out, "simulating")) << o.out;
  }
}

TEST(DrapeSimCli, ManyThreadsAreClampedWithANote) {
  Scratch s;
  const Outcome o = runDrapeSim({s.scene("small.yaml", kSmallScene), "--out", s.dir + "/out", "--threads", "1000"});
  EXPECT_EQ(o.exit_code, 0) << o.err;
  EXPECT_TRUE(contains(o.out, "1000 threads requested; using")) << o.out;
  EXPECT_FALSE(contains(o.out, "1000 threads\n")) << o.out;
}

TEST(DrapeSimCli, SuccessWritesOutputsInADirectoryOfMode0755) {
  Scratch s;
  const std::string out = s.dir + "/new/out";
  const Outcome o = runDrapeSim({s.scene("small.yaml", kSmallScene), "--out", out, "--threads", "1"});
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_TRUE(contains(o.out, "outputs in " + out)) << o.out;
  for (const char* f : {"result.yaml", "rest_positions.csv", "rest_shape.png", "state.txt"})
    EXPECT_TRUE(std::filesystem::exists(out + "/" + f)) << f;
  // Created under umask 000, still 0755.
  for (const std::string& d : std::vector<std::string>{s.dir + "/new", out}) {
    struct stat st{};
    ASSERT_EQ(::stat(d.c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 07777, 0755u) << d;
  }
}

TEST(DrapeSimCli, AnUnwritableOutputDirectoryFailsBeforeSimulating) {
  Scratch s;
  const std::string blocker = s.scene("not_a_directory", "x");
  const Outcome o = runDrapeSim({s.scene("small.yaml", kSmallScene), "--out", blocker + "/out", "--threads", "1"});
  EXPECT_EQ(o.exit_code, 4) << o.err;
  EXPECT_TRUE(contains(o.err, blocker)) << o.err;
  EXPECT_FALSE(contains(o.out, "outputs in")) << o.out;
  EXPECT_FALSE(contains(o.out, "simulating")) << o.out;
}

TEST(DrapeSimCli, AFailedWriteExitsWithFourAndClaimsNoOutputs) {
  // Each output goes through NAME.tmp; linking those to /dev/full makes every write fail (ENOSPC).
  Scratch s;
  const std::string out = s.dir + "/full";
  std::filesystem::create_directories(out);
  for (const char* f : {"result.yaml", "rest_positions.csv", "state.txt", "rest_shape.png"})
    std::filesystem::create_symlink("/dev/full", out + "/" + f + ".tmp");
  const Outcome o = runDrapeSim({s.scene("small.yaml", kSmallScene), "--out", out, "--threads", "1"});
  EXPECT_EQ(o.exit_code, 4) << o.err;
  EXPECT_TRUE(contains(o.err, "cannot write outputs")) << o.err;
  EXPECT_TRUE(contains(o.err, out + "/result.yaml")) << o.err;
  EXPECT_FALSE(contains(o.out, "outputs in")) << o.out;
}

TEST(DrapeSimCli, ATowelAtTwoTenthsOfAMillimetreIsRefusedByTheMemoryBudget) {
  Scratch s;
  const std::string scene =
      s.scene("fine.yaml", "textile: towel\nmaterial: cotton\nspacing_m: 2e-4\nhold: {points: [corner_ul]}\n");
  // An explicit budget, so that the outcome does not depend on this machine's memory.
  const Outcome o = runDrapeSim({scene, "--out", s.dir + "/out", "--threads", "1", "--memory-budget-mb", "16384"});
  EXPECT_EQ(o.exit_code, 2) << o.err;
  EXPECT_TRUE(contains(o.err, "memory budget of 16.0 GiB")) << o.err;
  EXPECT_TRUE(contains(o.err, "--memory-budget-mb")) << o.err;
  // The default budget (half of physical memory) refuses it too on any machine under ~100 GiB.
  const Outcome d = runDrapeSim({scene, "--out", s.dir + "/out", "--threads", "1"});
  if (sysconf(_SC_PHYS_PAGES) * sysconf(_SC_PAGESIZE) < (100LL << 30)) {
    EXPECT_EQ(d.exit_code, 2) << d.err;
    EXPECT_TRUE(contains(d.err, "memory budget")) << d.err;
  }
}

TEST(DrapeSimCli, BadScenesExitWithTwoNamingTheKey) {
  Scratch s;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {kSmallScene + "simulaton: {dt_s: 0.001}\n", "unknown key 'simulaton'"},
      {"textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {points: [corner_ul]}\nsimulation: {dt_mx: 1}\n",
       "unknown key 'simulation.dt_mx'"},
      {"textile: square\nmaterial: cotton\nhold: {points: [corner_ul]}\n", "missing required key 'spacing_m'"},
      {"textile: square\nmaterial: cotton\nspacing_m: 0.05\n", "missing required key 'hold'"},
      {"textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {points: [[5, 5]]}\n", "hold point 0 (5.000,5.000)"},
  };
  for (const auto& c : cases) {
    const Outcome o = runDrapeSim({s.scene("bad.yaml", c.first), "--out", s.dir + "/out", "--threads", "1"});
    EXPECT_EQ(o.exit_code, 2) << c.first << o.err;
    EXPECT_TRUE(contains(o.err, c.second)) << c.first << o.err;
    EXPECT_FALSE(contains(o.out, "outputs in")) << o.out;
  }
  const Outcome missing = runDrapeSim({s.dir + "/no_such_scene.yaml", "--out", s.dir + "/out"});
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_TRUE(contains(missing.err, "no_such_scene.yaml")) << missing.err;
}

TEST(DrapeSimCli, TheDemoSceneIsAccepted) {
  // Parsed, built and checked against the budget; one short step range only.
  Scratch s;
  const Outcome o = runDrapeSim({kSourceDir + "/config/scenes/towel_corner.yaml", "--out", s.dir + "/out", "--until",
                                 "0.002", "--threads", "1"});
  EXPECT_EQ(o.exit_code, 0) << o.err;
}

}  // namespace

TEST(DrapeSimCli, ModelAutoChoosesPrintsItsEvidenceAndRuns) {
  const Scratch s;
  const std::string scene = s.scene(
      "auto.yaml",
      "textile: square\nmaterial: cotton\nhold: {points: [corner_ul]}\n"
      "model: {name: auto, spacings_m: [0.06, 0.05], named_point_tolerance_m: 10, min_mean_iou: 0}\n");
  const Outcome o = runDrapeSim({scene, "--out", s.dir + "/out", "--threads", "1"});
  EXPECT_EQ(o.exit_code, 0) << o.out << o.err;
  EXPECT_TRUE(contains(o.out, "automatic choice")) << o.out;
  EXPECT_TRUE(contains(o.out, "model particle_kes (hanging scene), spacing 0.06 m")) << o.out;
  EXPECT_TRUE(contains(o.out, "evidence particle_kes hold corner_ul d 0.06 vs 0.05")) << o.out;
  EXPECT_TRUE(std::filesystem::exists(s.dir + "/out/result.yaml"));
  // An unknown yarn-scale question is bad input, before any simulation.
  const std::string bad = s.scene("bad_auto.yaml",
                                  "textile: square\nmaterial: cotton\nhold: {points: [corner_ul]}\n"
                                  "model: {name: auto, question: unravel}\n");
  const Outcome b = runDrapeSim({bad, "--out", s.dir + "/bad"});
  EXPECT_EQ(b.exit_code, 2) << b.err;
  EXPECT_TRUE(contains(b.err, "unravel")) << b.err;
}
