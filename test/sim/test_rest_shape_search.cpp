// The quasi-static rest-shape path: the static equilibrium solver, the coarse-to-fine prolongation and
// findRestShape's methods and fallbacks, each against the dynamic simulation run to rest.
#include <gtest/gtest.h>

#include <cmath>

#include "sim_test_support.h"
#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/cloth_triangles.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/grid_prolongation.h"
#include "textile_handling/sim/rest_shape_search.h"
#include "textile_handling/sim/sim_errors.h"

namespace textile_handling {
namespace {

// The database builder's simulation settings (DrapeBuildConfig::defaultSimulationSettings), which the
// simulation core cannot include.
DrapeSceneSpec builderLikeSpec(Real side, Real d) {
  DrapeSceneSpec s = sim_test_support::heldSquareSpec(side, d);
  s.model = settlingModelSpec("particle_kes", 4.0);
  s.settings.integrator = IntegratorType::kSemiImplicitEuler;
  s.settings.policy = StepPolicy::kErrorControlled;
  s.settings.dt = 1e-3;
  s.settings.dt_max = 0.04;
  s.settings.error_tolerance = 1e-4;
  s.settings.max_time = 20;
  return s;
}

Real largestDistance(const VecX& a, const VecX& b) {
  Real worst = 0;
  for (Index i = 0; i < a.size() / 3; ++i) worst = std::max(worst, (a.segment<3>(3 * i) - b.segment<3>(3 * i)).norm());
  return worst;
}

VecX dynamicRest(const DrapeSceneSpec& spec) {
  DrapeScene s = buildDrapeScene(spec);
  RestShapeSettings dyn;
  dyn.method = RestShapeMethod::kDynamic;
  const RestShapeResult r = findRestShape(s, dyn);
  EXPECT_TRUE(r.rest_reached);
  EXPECT_EQ(r.method_used, "dynamic");
  return r.positions;
}

TEST(StaticEquilibrium, FinishesAHalfSettledDrapeAtTheDynamicRestShape) {
  const DrapeSceneSpec spec = builderLikeSpec(0.2, 0.02);
  const VecX reference = dynamicRest(spec);
  // Stop the dynamics early, while the square still moves, and let Newton finish.
  DrapeScene s = buildDrapeScene(spec);
  DrapeSimulation sim(*s.model, s.pins, s.spec.settings, s.x0, s.v0);
  const RunResult early = sim.run(0.8);
  ASSERT_FALSE(early.rest_reached);
  VecX x = sim.state();
  const Real moving = largestDistance(x, reference);
  EXPECT_GT(moving, 5e-3);  // the start is visibly away from rest
  const StaticEquilibriumResult r = solveStaticEquilibrium(*s.model, s.pins, sim.time(), x);
  ASSERT_TRUE(r.converged) << r.failure;
  EXPECT_LE(r.residual_ratio, 1e-3);
  EXPECT_GE(r.energy_drop, 0);
  EXPECT_LT(largestDistance(x, reference), 2e-3);
  // The held particle stays on its pin.
  EXPECT_EQ(Vec3(x.segment<3>(3 * s.pins.nodes[0])), s.pins.anchors[0]);
  // The residual it reports is the one of its result.
  VecX f;
  s.model->computeForces(x, VecX::Zero(x.size()), f, nullptr);
  for (Index p : s.pins.nodes) f.segment<3>(3 * p).setZero();
  EXPECT_NEAR(staticResidualRatio(*s.model, f, pinnedMask(s.model->numNodes(), s.pins)), r.residual_ratio, 1e-12);
}

TEST(StaticEquilibrium, StartingAtEquilibriumStopsAtOnce) {
  const DrapeSceneSpec spec = builderLikeSpec(0.2, 0.02);
  DrapeScene s = buildDrapeScene(spec);
  VecX x = s.x0;
  s.model->setPositions(dynamicRest(spec), x);
  const StaticEquilibriumResult first = solveStaticEquilibrium(*s.model, s.pins, 0, x);
  ASSERT_TRUE(first.converged) << first.failure;
  const VecX at_rest = x;
  const StaticEquilibriumResult again = solveStaticEquilibrium(*s.model, s.pins, 0, x);
  EXPECT_TRUE(again.converged);
  EXPECT_EQ(again.iterations, 0);
  EXPECT_EQ(x, at_rest);
}

TEST(StaticEquilibrium, RejectsBadInputNamingTheField) {
  DrapeScene s = buildDrapeScene(builderLikeSpec(0.1, 0.02));
  VecX x = s.x0;
  StaticEquilibriumSettings bad;
  bad.force_tolerance = std::nan("");
  try {
    solveStaticEquilibrium(*s.model, s.pins, 0, x, bad);
    FAIL() << "no error";
  } catch (const SimError& e) {
    EXPECT_NE(std::string(e.what()).find("force_tolerance"), std::string::npos) << e.what();
  }
  VecX wrong = VecX::Zero(5);
  EXPECT_THROW(solveStaticEquilibrium(*s.model, s.pins, 0, wrong), SimError);
  x[4] = std::numeric_limits<Real>::infinity();
  EXPECT_THROW(solveStaticEquilibrium(*s.model, s.pins, 0, x), SimError);
}

// An affine deformation of the flat textile is reproduced exactly, inside and at the outline.
void expectAffineReproduced(const TextileOutline& t, Real coarse_d, Real fine_d) {
  std::string err;
  const ParticleGrid coarse = ParticleGrid::rasterize(t, coarse_d, &err);
  const ParticleGrid fine = ParticleGrid::rasterize(t, fine_d, &err);
  ASSERT_FALSE(coarse.empty());
  ASSERT_FALSE(fine.empty());
  Eigen::Matrix<Real, 3, 2> A;
  A << 0.9, 0.2, -0.1, 0.3, 0.7, -1.1;
  const Vec3 b(0.1, -0.2, 1.0);
  auto affine = [&](const Vec2& p) -> Vec3 { return A * p + b; };
  VecX xc(3 * coarse.numActive());
  for (Index i = 0; i < coarse.numActive(); ++i) xc.segment<3>(3 * i) = affine(coarse.activePosition(i));
  const VecX xf = prolongPositions(coarse, xc, fine);
  ASSERT_EQ(xf.size(), 3 * fine.numActive());
  for (Index i = 0; i < fine.numActive(); ++i)
    ASSERT_LT((Vec3(xf.segment<3>(3 * i)) - affine(fine.activePosition(i))).norm(), 1e-12) << "particle " << i;
}

TEST(GridProlongation, ReproducesAffineDeformations) {
  expectAffineReproduced(presetTextile("towel"), 0.04, 0.01);
  expectAffineReproduced(presetTextile("towel"), 0.02, 0.02 / 3);
  // A T-shirt outline: cells cut by the outline use the affine fallback (extrapolation).
  expectAffineReproduced(presetTextile("tshirt"), 0.05, 0.02);
}

TEST(GridProlongation, RejectsMismatchingSizes) {
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(presetTextile("towel"), 0.04, &err);
  EXPECT_THROW(prolongPositions(g, VecX::Zero(7), g), SimError);
  EXPECT_THROW(prolongPositions(ParticleGrid(), VecX::Zero(0), g), SimError);
}

TEST(RestShapeSearch, QuasiStaticWithACoarseLevelMatchesTheDynamicRestShape) {
  const DrapeSceneSpec spec = builderLikeSpec(0.3, 0.01);
  const VecX reference = dynamicRest(spec);
  DrapeScene s = buildDrapeScene(spec);
  RestShapeSettings fast;
  fast.method = RestShapeMethod::kQuasiStatic;
  fast.coarse_spacing = 0.03;
  const RestShapeResult r = findRestShape(s, fast);
  ASSERT_TRUE(r.rest_reached) << r.failure;
  EXPECT_EQ(r.method_used, "quasi_static");
  EXPECT_TRUE(r.coarse_level);
  EXPECT_TRUE(r.coarse_finish.converged) << r.coarse_finish.failure;
  EXPECT_EQ(r.positions.size(), reference.size());
  EXPECT_LT(largestDistance(r.positions, reference), 5e-3);
  EXPECT_EQ(Vec3(r.positions.segment<3>(3 * s.hold_particle)), spec.hold_position);
}

TEST(RestShapeSearch, NewtonFinishWithoutACoarseLevel) {
  const DrapeSceneSpec spec = builderLikeSpec(0.2, 0.02);
  const VecX reference = dynamicRest(spec);
  DrapeScene s = buildDrapeScene(spec);
  RestShapeSettings fast;
  fast.method = RestShapeMethod::kQuasiStatic;  // coarse 2 cm = the scene's spacing: no coarse level
  const RestShapeResult r = findRestShape(s, fast);
  ASSERT_TRUE(r.rest_reached) << r.failure;
  EXPECT_EQ(r.method_used, "quasi_static");
  EXPECT_FALSE(r.coarse_level);
  EXPECT_TRUE(r.finish.converged);
  EXPECT_LT(largestDistance(r.positions, reference), 2e-3);
}

TEST(RestShapeSearch, AFailedFinishFallsBackToTheDynamicRun) {
  const DrapeSceneSpec spec = builderLikeSpec(0.2, 0.02);
  const VecX reference = dynamicRest(spec);
  DrapeScene s = buildDrapeScene(spec);
  RestShapeSettings starved;
  starved.method = RestShapeMethod::kQuasiStatic;
  starved.settle_speed = starved.settle_mean_speed = 10;  // the dynamic phase stops at once
  starved.finish.max_iterations = 1;
  const RestShapeResult r = findRestShape(s, starved);
  ASSERT_TRUE(r.rest_reached);
  EXPECT_EQ(r.method_used.rfind("dynamic (quasi-static finish failed: ", 0), 0u) << r.method_used;
  EXPECT_EQ(r.positions, reference);  // the dynamic run itself, from a fresh scene
}

TEST(RestShapeSearch, ScenesWithCollisionHandlingStayDynamic) {
  DrapeSceneSpec spec = builderLikeSpec(0.1, 0.02);
  spec.self_collision = true;
  DrapeScene s = buildDrapeScene(spec);
  EXPECT_FALSE(quasiStaticApplies(s));
  RestShapeSettings fast;
  fast.method = RestShapeMethod::kQuasiStatic;
  const RestShapeResult r = findRestShape(s, fast);
  EXPECT_TRUE(r.rest_reached);
  EXPECT_EQ(r.method_used, "dynamic");
}

TEST(RestShapeSearch, MethodNamesAndSettingsText) {
  EXPECT_EQ(restShapeMethodFromString("dynamic"), RestShapeMethod::kDynamic);
  EXPECT_EQ(restShapeMethodFromString("quasi_static"), RestShapeMethod::kQuasiStatic);
  EXPECT_THROW(restShapeMethodFromString("fast"), SimError);
  RestShapeSettings r;
  r.method = RestShapeMethod::kDynamic;
  EXPECT_EQ(r.text(), "");
  r.method = RestShapeMethod::kQuasiStatic;
  EXPECT_EQ(r.text().rfind("rest_method: quasi_static coarse_spacing: 0.02", 0), 0u) << r.text();
  r.coarse_spacing = -1;
  EXPECT_THROW(r.validate(), SimError);
}

}  // namespace
}  // namespace textile_handling
