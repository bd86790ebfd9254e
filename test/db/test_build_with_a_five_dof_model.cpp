// The database builder with a model that is not one of the built-in ones: a 5-DOF test model with a
// non-diagonal mass (test/sim/sliding_particle_model.h), registered in ClothModelRegistry by the test.
// Its rows store node positions (3 per node), its parameter text records its options, and its rest
// shapes agree with the particle model's (an equilibrium does not depend on the mass).
#include <gtest/gtest.h>

#include <string>

#include "../sim/sliding_particle_model.h"
#include "../test_support.h"
#include "test_database.h"
#include "textile_handling/db/drape_database_builder.h"

namespace textile_handling {
namespace db {
namespace {

using test_support::TestDatabase;
using test_support::ThreadScope;

DrapeBuildConfig smallSquare(const ClothModelSpec& model) {
  DrapeBuildConfig c;
  c.textile = presetTextile("square");
  c.spacing = 0.05;
  c.lattice_spacing = 0.25;
  c.frame = vision::CanonicalFrame::fromMetric(0.5, 0.5, 32);
  c.views.count = 4;
  c.views.step_deg = 90;
  c.workers = 1;
  c.model = model;
  return c;
}

TEST(BuildWithAFiveDofModel, StoresPositionsAndMatchesTheParticleModelsRestShapes) {
  ThreadScope threads(1);
  testing_models::registerSlidingParticleModel();
  ClothModelSpec five = DrapeBuildConfig::defaultModelSpec("test_sliding_particles");
  five.set("coupling", 0.3).set("neighbour_mass", 0.02);
  EXPECT_EQ(five.options.at("jacobian"), "definite_fix");  // the build defaults follow the model's keys

  TestDatabase t5("five_dof"), t3("three_dof");
  HangingDrapeDatabase db5(t5.path()), db3(t3.path());
  const DrapeBuildReport r5 = DrapeDatabaseBuilder(db5, smallSquare(five)).build();
  const DrapeBuildReport r3 = DrapeDatabaseBuilder(db3, smallSquare(DrapeBuildConfig::defaultModelSpec("particle_kes"))).build();
  ASSERT_EQ(r5.failed_now, 0) << (r5.failures.empty() ? "" : r5.failures[0]);
  ASSERT_EQ(r3.failed_now, 0);
  ASSERT_GT(r5.simulated_now, 0);
  const auto rows5 = db5.simulations(r5.textile_id, SimulationStatus::kDone);
  const auto rows3 = db3.simulations(r3.textile_id, SimulationStatus::kDone);
  ASSERT_EQ(rows5.size(), rows3.size());
  for (size_t k = 0; k < rows5.size(); ++k) {
    EXPECT_EQ(rows5[k].model, "test_sliding_particles");
    EXPECT_NE(rows5[k].parameters.find("model_options.coupling: 0.29999999999999999"), std::string::npos)
        << rows5[k].parameters;
    const VecX p5 = db5.positions(rows5[k].id), p3 = db3.positions(rows3[k].id);
    ASSERT_EQ(p5.size(), p3.size());  // 3 values per node, not 5
    EXPECT_LE((p5 - p3).cwiseAbs().maxCoeff(), 5e-3) << "hold " << rows5[k].hold.transpose();
  }
  // A rebuild with the same spec resumes (nothing to simulate); other options plan new rows.
  EXPECT_EQ(DrapeDatabaseBuilder(db5, smallSquare(five)).build().simulated_now, 0);
  ClothModelSpec other = five;
  other.set("coupling", 0.1);
  EXPECT_NE(DrapeDatabaseBuilder::parametersText(smallSquare(other)), DrapeDatabaseBuilder::parametersText(smallSquare(five)));
}

TEST(BuildWithAFiveDofModel, ChoiKoBuildsUseAndRecordTheirOwnOptions) {
  // drape_db build --model choi_ko: the build defaults for choi_ko (settle damping 4/s), and the
  // parameter text names Choi-Ko's options, not the particle model's.
  const DrapeBuildConfig c = smallSquare(DrapeBuildConfig::defaultModelSpec("choi_ko"));
  const std::string text = DrapeDatabaseBuilder::parametersText(c);
  EXPECT_NE(text.find("model: choi_ko\n"), std::string::npos);
  EXPECT_NE(text.find("bending_version: beam\n"), std::string::npos);
  EXPECT_NE(text.find("model_options.settle_damping_per_s: 4\n"), std::string::npos) << text;
  EXPECT_EQ(text.find("jacobian: definite_fix"), std::string::npos);
  const DrapeSceneSpec scene = DrapeDatabaseBuilder::sceneSpec(c, Vec2(0.1, 0.1));
  EXPECT_EQ(scene.model, c.model);
}

TEST(BuildWithAFiveDofModel, ParticleParameterTextIsUnchanged) {
  // Databases built before the model registry resume: the particle model's lines keep their order
  // (values are the builder's defaults: warm-started CG).
  const DrapeBuildConfig c = smallSquare(DrapeBuildConfig::defaultModelSpec("particle_kes"));
  const std::string text = DrapeDatabaseBuilder::parametersText(c);
  const std::string expected_start =
      "format: 1\nmodel: particle_kes\nintegrator: semi_implicit\npolicy: error\nlinear_solver: cg\n"
      "preconditioner: two_level\ncg_warm_start: false\njacobian: definite_fix\nforces: gravity drag shear bending\n"
      "require_rest: true\nretry_with_smaller_steps: true\nprojection: orthographic\nspacing_m: 0.050000000000000003\n"
      "hold_height_m: 1\nmodel_options.settle_damping_per_s: 4\nsimulation.cg_max_iterations: 400\n";
  EXPECT_EQ(text.substr(0, expected_start.size()), expected_start) << text;
}

}  // namespace
}  // namespace db
}  // namespace textile_handling
