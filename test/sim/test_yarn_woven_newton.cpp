// Tests of the yarn_woven model under backward Euler with Newton's method (the source's time stepping):
//  - the Rayleigh damping -(alpha M + beta K) v uses the M and K of the step's start state, held until
//    the next accepted step, so that it is linear in v and independent of x within a step and df/dv is
//    its exact derivative;
//  - a sheet of single yarns at 1 yarn/mm hung from two corners converges in at most three Newton
//    iterations per 1 ms step with either preconditioner of the conjugate-residual solver (the
//    two-level one in fewer PCR iterations), and lands where the semi-implicit (linearised) step does
//    to within a small fraction of the motion;
//  - a Newton run saved between steps resumes bitwise.
#include "yarn_test_support.h"  // first: see there

#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <string>

#include "../test_support.h"
#include "sim_test_support.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {
namespace {

using test_support::ThreadScope;

using sim_test_support::randomVector;

// The part of the force that is linear in v at x: f(x, v) - f(x, 0).
VecX velocityForce(ClothModel& m, const VecX& x, const VecX& v) {
  VecX with_v, without;
  m.computeForces(x, v, with_v, nullptr);
  m.computeForces(x, VecX::Zero(v.size()), without, nullptr);
  return with_v - without;
}

TEST(YarnWovenNewton, RayleighDampingIsHeldAtTheStepStartState) {
  DrapeSceneSpec s = sim_test_support::heldSquareSpec(0.02, 0.005);
  s.model = ClothModelSpec("yarn_woven");
  DrapeScene scene = buildDrapeScene(s);
  auto& m = dynamic_cast<YarnWovenModel&>(*scene.model);
  VecX x0 = scene.x0, x1 = scene.x0;
  const VecX dx0 = randomVector(x0.size(), 3, 3e-4), dx1 = randomVector(x0.size(), 4, 3e-4);
  for (Index d = 0; d < x0.size(); ++d)
    if (!m.isHeld(d)) {
      x0[d] += dx0[d];
      x1[d] += dx1[d];
    }
  VecX v = randomVector(x0.size(), 5, 0.05);
  for (Index d = 0; d < v.size(); ++d)
    if (m.isHeld(d)) v[d] = 0;

  // The first evaluation fixes the damping at x0; evaluations at x1 within the same step keep it.
  const VecX at_x0 = velocityForce(m, x0, v);
  const VecX at_x1 = velocityForce(m, x1, v);
  EXPECT_GT(at_x0.cwiseAbs().maxCoeff(), 0);
  EXPECT_LE((at_x1 - at_x0).cwiseAbs().maxCoeff(), 1e-12 * at_x0.cwiseAbs().maxCoeff());

  // After an accepted step at x1 the damping is x1's, and df/dv is its exact derivative.
  VecX v_step = VecX::Zero(v.size());
  m.acceptStep(x1, v_step);
  ForceJacobians jac = m.makeJacobians();
  VecX f;
  m.computeForces(x1, v, f, &jac);
  const VecX after = velocityForce(m, x1, v);
  VecX jv;
  jac.dfdv.multiply(v, jv);
  EXPECT_LE((after - jv).cwiseAbs().maxCoeff(), 1e-9 * after.cwiseAbs().maxCoeff());
  EXPECT_GT((after - at_x0).cwiseAbs().maxCoeff(), 1e-6 * at_x0.cwiseAbs().maxCoeff()) << "K(x1) differs from K(x0)";
}

// side x side crossings of single yarns at 1 mm, hung from its two upper corners, released flat.
DrapeSceneSpec yarnSheet(int side, IntegratorType integrator, Real dt, Real until) {
  const Real L = 1e-3, w = (side - 1) * L;
  DrapeSceneSpec s = sim_test_support::heldSquareSpec(w, L);
  s.hold = {HoldPoint{"", Vec2(0, w)}, HoldPoint{"", Vec2(w, w)}};
  s.model = ClothModelSpec("yarn_woven");
  s.settings = yarn_test_support::fixedSteps(integrator, dt, until);
  return s;
}

TEST(YarnWovenNewton, HangingSheetConvergesInFewNewtonIterationsWithEitherPreconditioner) {
  ThreadScope threads(1);
  const int steps = 20;
  const Real dt = 1e-3, until = (steps - 0.5) * dt;
  auto run = [&](IntegratorType integrator, PreconditionerKind preconditioner, RunResult* r) {
    DrapeSceneSpec s = yarnSheet(20, integrator, dt, until);
    s.settings.solver.preconditioner = preconditioner;
    s.settings.solver.max_iterations = 5000;  // block-Jacobi needs hundreds of PCR iterations at 1e-6
    DrapeScene scene = buildDrapeScene(s);
    DrapeSimulation sim(*scene.model, scene.pins, s.settings, scene.x0, scene.v0);
    *r = sim.run();
    EXPECT_FALSE(r->diverged) << r->divergence_reason;
    EXPECT_EQ(r->steps, steps);
    return std::make_pair(scene.x0, sim.positions());
  };
  RunResult two_level, jacobi, linearised;
  const auto [x0, x_newton] = run(IntegratorType::kBackwardEulerNewton, PreconditionerKind::kTwoLevel, &two_level);
  const auto x_jacobi = run(IntegratorType::kBackwardEulerNewton, PreconditionerKind::kBlockJacobi, &jacobi).second;
  const auto x_linear = run(IntegratorType::kSemiImplicitEuler, PreconditionerKind::kTwoLevel, &linearised).second;
  EXPECT_LE(two_level.newton_iterations, 3 * steps);
  EXPECT_LE(jacobi.newton_iterations, 3 * steps);
  EXPECT_GT(two_level.newton_iterations, steps) << "the stretch nonlinearity should need a second iteration";
  EXPECT_LT(2 * two_level.solver_iterations, jacobi.solver_iterations);
  // Both preconditioners solve the same Newton systems (to the default 1e-6); the converged step and
  // the linearised one differ by far less than the motion.
  Real motion = 0;
  for (Index i = 0; i < x0.size() / 5; ++i) motion = std::max(motion, (x_newton.segment<3>(3 * i) - x0.segment<3>(5 * i)).norm());
  const Real preconditioners = (x_newton - x_jacobi).cwiseAbs().maxCoeff();
  const Real methods = (x_newton - x_linear).cwiseAbs().maxCoeff();
  EXPECT_GT(motion, 1e-4);
  EXPECT_LE(preconditioners, 1e-4 * motion);
  EXPECT_LE(methods, 0.05 * motion);
  std::cout << "[ measured ] 20 x 20 sheet, 20 steps of 1 ms: Newton iterations " << two_level.newton_iterations
            << " (two-level) / " << jacobi.newton_iterations << " (block-Jacobi); PCR iterations "
            << two_level.solver_iterations << " / " << jacobi.solver_iterations << "; motion " << motion
            << " m, preconditioners differ by " << preconditioners / motion << ", semi-implicit by " << methods / motion
            << " of it\n";
}

TEST(YarnWovenNewton, ASavedNewtonRunResumesBitwise) {
  // The held damping is derived from the state a step starts from, so a run saved between steps and
  // resumed in a fresh model continues exactly as the uninterrupted one.
  ThreadScope threads(1);
  const DrapeSceneSpec s = yarnSheet(12, IntegratorType::kBackwardEulerNewton, 1e-3, 1.0);
  DrapeScene whole_scene = buildDrapeScene(s);
  DrapeSimulation whole(*whole_scene.model, whole_scene.pins, s.settings, whole_scene.x0, whole_scene.v0);
  const RunResult all = whole.run(0.0195);
  ASSERT_FALSE(all.diverged) << all.divergence_reason;
  EXPECT_EQ(all.steps, 20);
  EXPECT_GT(all.newton_iterations, all.steps);
  DrapeScene scene = buildDrapeScene(s);
  DrapeSimulation first(*scene.model, scene.pins, s.settings, scene.x0, scene.v0);
  first.run(0.0095);
  const std::string path = test_support::freshTempPath("yarn_woven_newton", "state.txt");
  first.save(path);
  DrapeScene scene2 = buildDrapeScene(s);
  DrapeSimulation second(*scene2.model, scene2.pins, s.settings, scene2.x0, scene2.v0);
  // A force evaluation at the start state before the load must not leave its damping behind.
  VecX f;
  scene2.model->computeForces(scene2.x0, scene2.v0, f, nullptr);
  second.load(path);
  second.run(0.0195);
  EXPECT_TRUE(second.state() == whole.state());
  std::remove(path.c_str());
}

}  // namespace
}  // namespace textile_handling
