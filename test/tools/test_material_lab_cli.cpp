// material_lab as a process: usage errors exit 2 naming the option, a run writes its curves, charts,
// figures and the measured material, and a test the model cannot complete exits 3 after the others ran.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "../test_support.h"
#include "tool_process.h"

namespace {

using textile_handling::tool_process::readAll;
using textile_handling::tool_process::runTool;

const std::string kMaterialLab = MATERIAL_LAB_EXE;

TEST(MaterialLabCli, BadArgumentsExitWithTwoNamingTheOption) {
  const auto r1 = runTool(kMaterialLab, {"--tests", "bending,twist"});
  EXPECT_EQ(r1.exit_code, 2);
  EXPECT_NE(r1.err.find("unknown test 'twist'"), std::string::npos) << r1.err;
  const auto r2 = runTool(kMaterialLab, {"--spacing", "nan"});
  EXPECT_EQ(r2.exit_code, 2);
  EXPECT_NE(r2.err.find("--spacing"), std::string::npos) << r2.err;
  const auto r3 = runTool(kMaterialLab, {"--model", "no_such_model", "--out", "/tmp/unused"});
  EXPECT_EQ(r3.exit_code, 2);
  EXPECT_NE(r3.err.find("no_such_model"), std::string::npos) << r3.err;
  const auto r4 = runTool(kMaterialLab, {"--material", "/nonexistent/material.yaml"});
  EXPECT_EQ(r4.exit_code, 2);
  EXPECT_NE(r4.err.find("/nonexistent/material.yaml"), std::string::npos) << r4.err;
  const auto r5 = runTool(kMaterialLab, {"--directions"});
  EXPECT_EQ(r5.exit_code, 2);
  const auto r6 = runTool(kMaterialLab, {"--shear-max-angle", "60"});
  EXPECT_EQ(r6.exit_code, 2);
  EXPECT_NE(r6.err.find("shear.max_angle_deg"), std::string::npos) << r6.err;
  const auto r7 = runTool(kMaterialLab, {"--bending-bias-deg", "45", "--fit", "particle_kes"});
  EXPECT_EQ(r7.exit_code, 2);
  EXPECT_NE(r7.err.find("--fit"), std::string::npos) << r7.err;
  const auto r8 = runTool(kMaterialLab, {"--fit", "choi_ko", "--fit-bending", "elastica"});
  EXPECT_EQ(r8.exit_code, 2);
  EXPECT_NE(r8.err.find("fit.bending_figure"), std::string::npos) << r8.err;
  const auto r9 = runTool(kMaterialLab, {"--fit", "choi_ko", "--fit-model-option", "particle_kes:jacobian=exact"});
  EXPECT_EQ(r9.exit_code, 2);
  EXPECT_NE(r9.err.find("particle_kes, which --fit does not fit"), std::string::npos) << r9.err;
  const auto r10 = runTool(kMaterialLab, {"--fit", "choi_ko", "--fit-bending", "cantilever", "--tests", "bending,shear,tensile"});
  EXPECT_EQ(r10.exit_code, 2);
  EXPECT_NE(r10.err.find("cantilever test in both directions"), std::string::npos) << r10.err;
  const auto r11 = runTool(kMaterialLab, {"--fit", "choi_ko", "--fit-model-option", "choi_ko:no_such_key=1", "--out", "/tmp/unused"});
  EXPECT_EQ(r11.exit_code, 2);
  EXPECT_NE(r11.err.find("no_such_key"), std::string::npos) << r11.err;
  const auto r12 = runTool(kMaterialLab, {"--fit-spacing", "1"});
  EXPECT_EQ(r12.exit_code, 2);
  EXPECT_NE(r12.err.find("--fit-spacing"), std::string::npos) << r12.err;
}

TEST(MaterialLabCli, ARunWritesCurvesChartsFiguresAndTheMeasuredMaterial) {
  const std::string dir = textile_handling::test_support::freshTempDir("material_lab_cli");
  const auto r = runTool(kMaterialLab, {"--tests", "bending,shear", "--directions", "warp", "--shear-max-angle", "20", "--out", dir});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* f : {"figures.csv", "bending_warp.csv", "shear_warp.csv", "bending.png", "shear.png", "lab_material.yaml"})
    EXPECT_TRUE(std::filesystem::is_regular_file(dir + "/" + f)) << f;
  const std::string figures = readAll(dir + "/figures.csv");
  EXPECT_NE(figures.find("\nB,warp,gf*cm^2/cm,"), std::string::npos) << figures;
  EXPECT_NE(figures.find("\nG,warp,gf/(cm*deg),"), std::string::npos) << figures;
  EXPECT_NE(readAll(dir + "/lab_material.yaml").find("name: cotton_lab"), std::string::npos);
  // The shear cycle went to 20 degrees (0.349 rad): 4 n + 1 points, the n-th at the maximum.
  const std::string shear = readAll(dir + "/shear_warp.csv");
  EXPECT_NE(shear.find("\n0.3490658504,"), std::string::npos) << shear.substr(0, 400);
  std::filesystem::remove_all(dir);
}

TEST(MaterialLabCli, ATestTheModelCannotCompleteExitsThreeAfterTheOthersRan) {
  // choi_ko's default tensile stiffness (100 N/m) never reaches KES's 500 gf/cm within 50 % strain.
  const std::string dir = textile_handling::test_support::freshTempDir("material_lab_cli_fail");
  const auto r = runTool(kMaterialLab, {"--model", "choi_ko", "--tests", "tensile,shear", "--directions", "warp", "--out", dir});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("tensile.max_strain"), std::string::npos) << r.err;
  EXPECT_TRUE(std::filesystem::is_regular_file(dir + "/shear_warp.csv"));
  std::filesystem::remove_all(dir);
}

}  // namespace
