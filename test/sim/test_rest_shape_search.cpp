// The quasi-static rest-shape path: the static equilibrium solver, the coarse-to-fine prolongation and
// findRestShape's methods and fallbacks, each against the dynamic simulation run to rest.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "sim_test_support.h"
#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/cloth_triangles.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/edge_length_relaxation.h"
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

// The flat textile, particle positions (x, y, 0) in its frame.
VecX flatPositions(const ParticleGrid& g) {
  VecX x(3 * g.numActive());
  for (Index i = 0; i < g.numActive(); ++i) x.segment<3>(3 * i) = Vec3(g.activePosition(i).x(), g.activePosition(i).y(), 0);
  return x;
}

// Shortest and longest grid edge (4-neighbour and diagonal) over its rest length.
std::pair<Real, Real> edgeRatioRange(const ParticleGrid& g, const VecX& x) {
  Real lo = 1e300, hi = 0;
  for (Index c = 0; c < g.numActive(); ++c) {
    const Index i = g.compactRows()[static_cast<std::size_t>(c)], j = g.compactCols()[static_cast<std::size_t>(c)];
    for (const auto& st : {std::make_pair(0, 1), std::make_pair(1, 0), std::make_pair(1, 1), std::make_pair(1, -1)}) {
      const Index n = g.activeIndex(i + st.first, j + st.second);
      if (n < 0) continue;
      const Real r = (x.segment<3>(3 * n) - x.segment<3>(3 * c)).norm() / (g.spacing() * std::hypot(st.first, st.second));
      lo = std::min(lo, r);
      hi = std::max(hi, r);
    }
  }
  return {lo, hi};
}

TEST(EdgeLengthRelaxation, LeavesEdgesInsideTheBandUntouched) {
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(presetTextile("towel"), 0.04, &err);
  VecX x = flatPositions(g);
  // A rigid turn and a 5 % stretch along x: every edge stays within [0.9, 1.1].
  for (Index i = 0; i < g.numActive(); ++i) {
    const Vec3 p = x.segment<3>(3 * i);
    x.segment<3>(3 * i) = Vec3(1.05 * p.x(), 0.6 * p.y(), 0.8 * p.y()) + Vec3(0.1, 0, 1);
  }
  const VecX before = x;
  const EdgeRelaxationResult r = relaxEdgeLengths(g, x, {0}, 0.9, 1.1, 50);
  EXPECT_EQ(r.corrections, 0);
  EXPECT_EQ(r.sweeps, 1);
  EXPECT_EQ(x, before);
}

TEST(EdgeLengthRelaxation, BringsFoldedAndStretchedEdgesIntoTheBandWithThePinsFixed) {
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(presetTextile("towel"), 0.04, &err);
  VecX x = flatPositions(g);
  // A folded patch (a band of columns squeezed to a fifth in x), one particle on top of its neighbour and
  // one pulled 5 cm out of the plane.
  for (Index i = 0; i < g.numActive(); ++i) {
    const Real px = g.activePosition(i).x();
    if (px > 0.2 && px < 0.32) x[3 * i] = 0.2 + 0.2 * (px - 0.2);
    else if (px >= 0.32) x[3 * i] -= 0.8 * 0.12;
  }
  const Index pin = g.nearestActive(Vec2(0.24, 0.2)), collapsed = g.nearestActive(Vec2(0.52, 0.4));
  x.segment<3>(3 * collapsed) = x.segment<3>(3 * g.neighbour(collapsed, ParticleGrid::kLeft));
  const Index lifted = g.nearestActive(Vec2(0.08, 0.08));
  x[3 * lifted + 2] += 0.05;
  const Vec3 pinned = x.segment<3>(3 * pin);
  ASSERT_LT(edgeRatioRange(g, x).first, 0.01);
  ASSERT_GT(edgeRatioRange(g, x).second, 1.2);
  const EdgeRelaxationResult r = relaxEdgeLengths(g, x, {pin}, 0.9, 1.1, 500);
  EXPECT_GT(r.corrections, 0);
  EXPECT_LT(r.sweeps, 500);  // converged: a last sweep without corrections
  EXPECT_LT(r.min_ratio_before, 0.01);
  const std::pair<Real, Real> range = edgeRatioRange(g, x);
  EXPECT_GE(range.first, 0.9 * (1 - 1e-6));
  EXPECT_LE(range.second, 1.1 * (1 + 1e-6));
  EXPECT_NEAR(r.min_ratio_after, range.first, 1e-12);
  EXPECT_NEAR(r.max_ratio_after, range.second, 1e-12);
  EXPECT_EQ(Vec3(x.segment<3>(3 * pin)), pinned);
  EXPECT_TRUE(x.allFinite());
}

TEST(EdgeLengthRelaxation, RejectsBadArgumentsNamingThem) {
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(presetTextile("towel"), 0.08, &err);
  VecX x = flatPositions(g);
  auto message = [&](VecX y, std::vector<Index> fixed, Real lo, Real hi, int sweeps) -> std::string {
    try {
      relaxEdgeLengths(g, y, fixed, lo, hi, sweeps);
    } catch (const SimError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_NE(message(VecX::Zero(5), {}, 0.9, 1.1, 10).find("positions"), std::string::npos);
  EXPECT_NE(message(x, {}, 0, 1.1, 10).find("min_ratio"), std::string::npos);
  EXPECT_NE(message(x, {}, 0.9, 0.95, 10).find("max_ratio"), std::string::npos);
  EXPECT_NE(message(x, {}, 0.9, 1.1, 0).find("max_sweeps"), std::string::npos);
  EXPECT_NE(message(x, {g.numActive()}, 0.9, 1.1, 10).find("fixed index"), std::string::npos);
  VecX bad = x;
  bad[1] = std::numeric_limits<Real>::quiet_NaN();
  EXPECT_NE(message(bad, {}, 0.9, 1.1, 10).find("finite"), std::string::npos);
}

// A 30 x 20 cm sheet held at (0.128, 0) m, settled on a 1 cm grid and prolonged onto the 2/3 cm grid:
// the prolonged shape squeezes edges next to the hold to 0.3 of their rest length, and without the
// edge-length band the fine run fails at its first step and the search falls back to the dynamic run.
TEST(RestShapeSearch, TheEdgeLengthBandLetsAFoldedProlongationSettleOnTheFineGrid) {
  DrapeSceneSpec spec = builderLikeSpec(0.3, 0.02 / 3);
  spec.textile.outline = {Vec2(0, 0), Vec2(0.3, 0), Vec2(0.3, 0.2), Vec2(0, 0.2)};
  spec.textile.named_points = {NamedPoint{"corner", "corner", Vec2(0, 0.2)}};
  spec.hold = {HoldPoint{"", Vec2(0.128, 0)}};
  RestShapeSettings fast;
  fast.method = RestShapeMethod::kQuasiStatic;
  fast.coarse_spacing = 0.01;
  DrapeScene with_band = buildDrapeScene(spec);
  const RestShapeResult r = findRestShape(with_band, fast);
  ASSERT_TRUE(r.rest_reached) << r.failure;
  EXPECT_EQ(r.method_used, "quasi_static");
  EXPECT_TRUE(r.coarse_level);
  EXPECT_LT(r.relaxation.min_ratio_before, 0.5);
  EXPECT_GE(r.relaxation.min_ratio_after, 0.9 * (1 - 1e-6));
  EXPECT_LE(r.relaxation.max_ratio_after, 1.1 * (1 + 1e-6));
  EXPECT_GT(r.finish_run.steps, 0);
  EXPECT_GT(r.coarse_finish.iterations, 0);
  // Without the coarse Newton finish the prolonged settling state is settled on the fine grid directly.
  fast.coarse_static_finish = false;
  DrapeScene no_finish = buildDrapeScene(spec);
  const RestShapeResult n = findRestShape(no_finish, fast);
  ASSERT_TRUE(n.rest_reached) << n.failure;
  EXPECT_EQ(n.method_used, "quasi_static");
  EXPECT_EQ(n.coarse_finish.iterations, 0);
  EXPECT_GT(n.finish_run.steps, 0);
  fast.coarse_static_finish = true;
  fast.prolonged_min_edge_ratio = 0;  // off
  DrapeScene without = buildDrapeScene(spec);
  const RestShapeResult f = findRestShape(without, fast);
  EXPECT_EQ(f.method_used.rfind("dynamic (quasi-static finish failed: fine dynamic finish diverged", 0), 0u) << f.method_used;
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
  EXPECT_NE(r.text().find(" prolonged_edge_ratios: 0.9"), std::string::npos) << r.text();
  EXPECT_NE(r.text().find(" coarse_static_finish: 1"), std::string::npos) << r.text();
  r.prolonged_max_edge_ratio = 0.99;
  EXPECT_THROW(r.validate(), SimError);
  r.prolonged_max_edge_ratio = 1.1;
  r.prolonged_min_edge_ratio = 1.5;
  EXPECT_THROW(r.validate(), SimError);
  r.prolonged_min_edge_ratio = 0.9;
  r.coarse_spacing = -1;
  EXPECT_THROW(r.validate(), SimError);
}

}  // namespace
}  // namespace textile_handling
