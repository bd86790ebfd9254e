// speed_accuracy_bench as a process: --bending-scales runs one configuration per factor under its own label,
// --align-mirror adds the mirrored column, --max-sim-time caps the drapes' simulated time, and bad options exit 2
// naming the option.
#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "../test_support.h"
#include "tool_process.h"

namespace {

using textile_handling::tool_process::readAll;
using textile_handling::tool_process::runTool;

const std::string kBench = SPEED_ACCURACY_BENCH_EXE;

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

TEST(SpeedAccuracyBenchCli, BendingScalesRunOneLabelledVariantPerFactor) {
  const std::string dir = textile_handling::test_support::freshTempDir("speed_accuracy_bench_cli");
  const auto r = runTool(kBench, {"--scenes", "small_square_corner", "--models", "particle_kes", "--bending-scales",
                                  "particle_kes=1,4", "--align-mirror", "--integrators", "semi_implicit", "--spacings",
                                  "0.025", "--reference-spacing", "0.02", "--repeats", "1", "--threads", "1", "--out", dir});
  ASSERT_EQ(r.exit_code, 0) << r.err << r.out;
  const std::vector<std::string> rows = lines(readAll(dir + "/speed_accuracy.csv"));
  ASSERT_EQ(rows.size(), 3u) << readAll(dir + "/speed_accuracy.csv");
  EXPECT_NE(rows[0].find(",yaw_deg,mirrored,rounds,"), std::string::npos) << rows[0];
  EXPECT_EQ(rows[1].rfind("small_square_corner,particle_kes bend x1,semi_implicit,", 0), 0u) << rows[1];
  EXPECT_EQ(rows[2].rfind("small_square_corner,particle_kes bend x4,semi_implicit,", 0), 0u) << rows[2];
  // Each variant is compared with its own reference: the x1 run against the x1 reference, not the x4 one.
  EXPECT_NE(rows[1].find(",particle_kes bend x1@0.02,"), std::string::npos) << rows[1];
  EXPECT_NE(rows[2].find(",particle_kes bend x4@0.02,"), std::string::npos) << rows[2];
  // Four times the bending hangs stiffer: the runs' outputs differ (the rows' distances are not asserted).
  EXPECT_NE(rows[1].substr(rows[1].find("@0.02,")), rows[2].substr(rows[2].find("@0.02,")));
  std::filesystem::remove_all(dir);
}

TEST(SpeedAccuracyBenchCli, ASimulatedTimeCapEndsTheDrapesThere) {
  const std::string dir = textile_handling::test_support::freshTempDir("speed_accuracy_bench_cli_cap");
  const auto r = runTool(kBench, {"--scenes", "small_square_corner", "--models", "particle_kes", "--max-sim-time", "0.2",
                                  "--integrators", "semi_implicit", "--spacings", "0.025", "--reference-spacing", "0.02",
                                  "--repeats", "1", "--threads", "1", "--out", dir});
  ASSERT_EQ(r.exit_code, 0) << r.err << r.out;
  // runs.csv: scene,model,integrator,spacing_m,round,status,wall_s,steps,sim_time_s,nodes,note
  const std::vector<std::string> rows = lines(readAll(dir + "/runs.csv"));
  ASSERT_EQ(rows.size(), 3u);  // header, reference, one configuration
  for (std::size_t k = 1; k < rows.size(); ++k) {
    std::vector<std::string> field;
    std::istringstream in(rows[k]);
    for (std::string f; std::getline(in, f, ',');) field.push_back(f);
    ASSERT_GE(field.size(), 9u) << rows[k];
    EXPECT_EQ(field[5], "time_cap") << rows[k];  // a sheet dropped 0.2 s ago is still moving
    EXPECT_NEAR(std::stod(field[8]), 0.2, 0.02) << rows[k];
  }
  const auto bad = runTool(kBench, {"--max-sim-time", "-1"});
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--max-sim-time"), std::string::npos) << bad.err;
  std::filesystem::remove_all(dir);
}

TEST(SpeedAccuracyBenchCli, BadMaterialVariantsExitWithTwoNamingTheOption) {
  const auto r1 = runTool(kBench, {"--bending-scales", "particle_kes"});
  EXPECT_EQ(r1.exit_code, 2);
  EXPECT_NE(r1.err.find("--bending-scales"), std::string::npos) << r1.err;
  const auto r2 = runTool(kBench, {"--bending-scales", "particle_kes=2,-1"});
  EXPECT_EQ(r2.exit_code, 2);
  EXPECT_NE(r2.err.find("--bending-scales"), std::string::npos) << r2.err;
  const auto r3 = runTool(kBench, {"--models", "choi_ko", "--bending-scales", "particle_kes=2"});
  EXPECT_EQ(r3.exit_code, 2);
  EXPECT_NE(r3.err.find("particle_kes"), std::string::npos) << r3.err;
  const auto r4 = runTool(kBench, {"--models", "yarn_woven", "--reference-model", "yarn_woven", "--bending-scales",
                                   "yarn_woven=2"});
  EXPECT_EQ(r4.exit_code, 2);
  EXPECT_NE(r4.err.find("--reference-model"), std::string::npos) << r4.err;
}

}  // namespace
