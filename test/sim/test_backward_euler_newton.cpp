// Tests of backward Euler with Newton's method (integrators.h, backward_euler_newton) and of its linear
// solver, preconditioned conjugate residuals (conjugate_residual.h):
//  - PCR against a dense direct solve on random symmetric positive definite block systems (3 and 5
//    DOFs per node, with removed nodes), on a singular consistent semi-definite system and on a
//    symmetric indefinite one; bitwise the same iterates with 1 and 2 OpenMP threads; failures named;
//    the two-level preconditioner on a grid system (same solution, far fewer iterations, a restart
//    with the additive form when the smoothed cycle is not positive definite);
//  - Newton on the particle and Choi-Ko models: the residual of a converged step is below the
//    tolerance (and that of the linearised step is not), one iteration from the zero start is the
//    semi-implicit step, a step too large to converge fails and the adaptive policies halve it, the
//    hanging towel comes to rest on the same shape as with the semi-implicit integrator;
//  - a 5-DOF model with a non-diagonal mass (sliding_particle_model.h): a free sheet's momentum
//    changes by exactly the impulse of gravity.
// GCC 12 reports a -Wmaybe-uninitialized false positive inside Eigen's SelfAdjointEigenSolver
// (tridiagonalisation); silence it for this file only (it must precede the first Eigen include).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "../test_support.h"
#include "sim_test_support.h"
#include "sliding_particle_model.h"
#include "textile_handling/sim/cloth_triangles.h"
#include "textile_handling/sim/conjugate_residual.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/integrators.h"

namespace textile_handling {
namespace {

using test_support::ThreadScope;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// ---- random block systems ------------------------------------------------------------------------

struct BlockSystem {
  std::unique_ptr<BlockPattern> pattern;
  BlockSparseMatrix a;
  Index dofs() const { return pattern->numNodes() * pattern->blockSize(); }
};

// A block "spring network": a chain through all nodes plus random couplings; each coupling (i, j)
// adds a random symmetric positive definite block W (scale log-uniform in [1e-2, 1e2]) to the blocks
// (i, i) and (j, j) and -W to (i, j) and (j, i). That sum is symmetric positive semi-definite and
// singular (every node moved alike is in its null space); `mass` adds m_i I to the diagonal blocks, m_i
// log-uniform in [mass / 10, 10 mass] (mass = 0: none, the singular network itself).
BlockSystem randomSystem(Index nodes, int b, unsigned seed, Real mass) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<Real> unit(-1.0, 1.0);
  std::vector<std::pair<Index, Index>> couplings;
  for (Index i = 0; i + 1 < nodes; ++i) couplings.emplace_back(i, i + 1);
  std::uniform_int_distribution<Index> node(0, nodes - 1);
  for (Index k = 0; k < nodes; ++k) {
    const Index i = node(rng), j = node(rng);
    if (i != j) couplings.emplace_back(i, j);
  }
  BlockSystem s;
  s.pattern = std::make_unique<BlockPattern>(nodes, b, couplings);
  s.a = BlockSparseMatrix(s.pattern.get());
  s.a.setZero();
  using Block = Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  auto add = [&](Index i, Index j, const Block& w) {
    Eigen::Map<Block>(s.a.block(s.pattern->find(i, j)), b, b) += w;
  };
  // Unique couplings only: duplicates would add twice, which is fine but makes scales less varied.
  std::sort(couplings.begin(), couplings.end());
  couplings.erase(std::unique(couplings.begin(), couplings.end()), couplings.end());
  for (const auto& [i, j] : couplings) {
    Block r(b, b);
    for (int e = 0; e < b * b; ++e) r.data()[e] = unit(rng);
    const Real scale = std::pow(10.0, 2 * unit(rng));
    const Block w = scale * (r * r.transpose() + 0.1 * Block::Identity(b, b));
    add(i, i, w);
    add(j, j, w);
    add(i, j, -w);
    add(j, i, -w);
  }
  if (mass > 0)
    for (Index i = 0; i < nodes; ++i) add(i, i, mass * std::pow(10.0, unit(rng)) * Block::Identity(b, b));
  return s;
}

using sim_test_support::randomVector;

// Indices of the free DOFs.
std::vector<Index> freeDofs(const std::vector<char>& pinned, int b) {
  std::vector<Index> out;
  for (Index i = 0; i < static_cast<Index>(pinned.size()); ++i)
    if (!pinned[i])
      for (int r = 0; r < b; ++r) out.push_back(i * b + r);
  return out;
}

// b - A y on the free DOFs, computed afresh (not PCR's recurrence).
VecX trueResidual(const BlockSparseMatrix& a, const VecX& b, const VecX& y, const std::vector<char>& pinned) {
  VecX ay;
  a.multiply(y, ay);
  VecX r = b - ay;
  const int bs = a.pattern().blockSize();
  for (Index i = 0; i < static_cast<Index>(pinned.size()); ++i)
    if (pinned[i]) r.segment(i * bs, bs).setZero();
  return r;
}

TEST(ConjugateResidual, MatchesADirectSolveOnRandomPositiveDefiniteBlockSystems) {
  ThreadScope threads(1);
  for (int b : {3, 5}) {
    SCOPED_TRACE("block " + std::to_string(b));
    const Index nodes = 60;
    const BlockSystem s = randomSystem(nodes, b, 11 + b, 1.0);
    std::vector<char> pinned(nodes, 0);
    for (Index p : {0, 7, 31}) pinned[p] = 1;
    const VecX rhs = randomVector(s.dofs(), 3 + b);
    ConjugateResidualSolver cr;
    ASSERT_TRUE(cr.setMatrix(s.a, pinned));
    VecX y;
    const ConjugateResidualResult r = cr.solve(rhs, y, 1e-12, 1000);
    ASSERT_TRUE(r.converged) << r.failure;
    EXPECT_TRUE(r.failure.empty());
    // Reference: the free-DOF system solved densely.
    const std::vector<Index> f = freeDofs(pinned, b);
    const Eigen::MatrixXd full = sim_test_support::denseMatrix(s.a);
    Eigen::MatrixXd aff(f.size(), f.size());
    VecX bf(f.size());
    for (size_t i = 0; i < f.size(); ++i) {
      bf[i] = rhs[f[i]];
      for (size_t j = 0; j < f.size(); ++j) aff(i, j) = full(f[i], f[j]);
    }
    const VecX want = aff.ldlt().solve(bf);
    Real worst = 0;
    for (size_t i = 0; i < f.size(); ++i) worst = std::max(worst, std::abs(y[f[i]] - want[i]));
    EXPECT_LE(worst, 1e-8 * want.cwiseAbs().maxCoeff());
    for (Index p : {0, 7, 31}) EXPECT_EQ(y.segment(p * b, b), VecX::Zero(b)) << "pinned node " << p;
    EXPECT_LE(trueResidual(s.a, rhs, y, pinned).norm(), 1e-10 * r.rhs_norm);
    EXPECT_GT(r.iterations, 1);
    EXPECT_LT(r.iterations, static_cast<int>(f.size()));
    // Empty pinned list = nothing removed: the whole system.
    ConjugateResidualSolver whole;
    ASSERT_TRUE(whole.setMatrix(s.a, {}));
    VecX y_all;
    ASSERT_TRUE(whole.solve(rhs, y_all, 1e-12, 1000).converged);
    EXPECT_LE((full * y_all - rhs).norm(), 1e-10 * rhs.norm());
    std::cout << "[ measured ] block " << b << ": " << r.iterations << " PCR iterations to 1e-12 for "
              << f.size() << " free DOFs\n";
  }
}

TEST(ConjugateResidual, SolvesASingularConsistentSemidefiniteSystem) {
  ThreadScope threads(1);
  for (int b : {3, 5}) {
    SCOPED_TRACE("block " + std::to_string(b));
    const Index nodes = 50;
    const BlockSystem s = randomSystem(nodes, b, 5 + b, 0.0);  // no mass: singular, null space = translations
    const Eigen::MatrixXd full = sim_test_support::denseMatrix(s.a);
    // Semi-definite and singular: the smallest eigenvalue is 0 to rounding, b of them.
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(full);
    const Real top = eig.eigenvalues().maxCoeff();
    EXPECT_LE(std::abs(eig.eigenvalues()[b - 1]), 1e-12 * top);
    EXPECT_GT(eig.eigenvalues()[b], 1e-8 * top);
    // A consistent right-hand side (in the range of A).
    const VecX x_true = randomVector(s.dofs(), 9);
    const VecX rhs = full * x_true;
    ConjugateResidualSolver cr;
    ASSERT_TRUE(cr.setMatrix(s.a, {}));
    VecX y;
    const ConjugateResidualResult r = cr.solve(rhs, y, 1e-12, 2000);
    ASSERT_TRUE(r.converged) << r.failure;
    EXPECT_LE((full * y - rhs).norm(), 1e-10 * rhs.norm());
    // The solution differs from x_true by a null-space vector: the same translation of every node.
    const VecX diff = y - x_true;
    for (Index i = 1; i < nodes; ++i)
      EXPECT_LE((diff.segment(i * b, b) - diff.segment(0, b)).norm(), 1e-6 * x_true.norm()) << "node " << i;
    std::cout << "[ measured ] block " << b << ": singular system solved to " << (full * y - rhs).norm() / rhs.norm()
              << " in " << r.iterations << " iterations\n";
  }
}

TEST(ConjugateResidual, ConvergesOnASymmetricIndefiniteSystemWithIndefiniteDiagonalBlocks) {
  // A negative shift on some nodes makes the system, and some of its diagonal blocks, indefinite (as
  // an exact Jacobian of compressed edges can at a large step). The preconditioner then uses
  // V |Lambda|^-1 V^T for those blocks and stays positive definite, so PCR still converges.
  ThreadScope threads(1);
  const int b = 3;
  const Index nodes = 40;
  BlockSystem s = randomSystem(nodes, b, 21, 1.0);
  int indefinite_blocks = 0;
  for (Index i = 0; i < nodes; i += 5) {
    Real* blk = s.a.block(s.pattern->diagonal(i));
    Eigen::Map<Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>> d(blk);
    const Real top = Eigen::SelfAdjointEigenSolver<Mat3>(Mat3(d)).eigenvalues().maxCoeff();
    d -= 0.6 * top * Mat3::Identity();
    const auto ev = Eigen::SelfAdjointEigenSolver<Mat3>(Mat3(d)).eigenvalues();
    indefinite_blocks += ev.minCoeff() < 0 && ev.maxCoeff() > 0;
  }
  ASSERT_GT(indefinite_blocks, 0);
  const Eigen::MatrixXd full = sim_test_support::denseMatrix(s.a);
  const auto ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(full).eigenvalues();
  ASSERT_LT(ev.minCoeff(), 0);
  ASSERT_GT(ev.maxCoeff(), 0);
  const VecX rhs = randomVector(s.dofs(), 4);
  ConjugateResidualSolver cr;
  ASSERT_TRUE(cr.setMatrix(s.a, {}));
  VecX y;
  const ConjugateResidualResult r = cr.solve(rhs, y, 1e-11, 2000);
  ASSERT_TRUE(r.converged) << r.failure;
  const VecX want = full.fullPivLu().solve(rhs);
  EXPECT_LE((y - want).cwiseAbs().maxCoeff(), 1e-7 * want.cwiseAbs().maxCoeff());
}

// A block "membrane" on a side x side grid: every node coupled to its 4 grid neighbours by a random
// symmetric positive definite block (scale 1) and a small mass (1e-3) on the diagonal blocks - the
// structure of a cloth system, where block-Jacobi is slow and a coarse level pays.
BlockSystem gridSystem(Index side, int b, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<Real> unit(-1.0, 1.0);
  std::vector<std::pair<Index, Index>> couplings;
  for (Index r = 0; r < side; ++r)
    for (Index c = 0; c < side; ++c) {
      if (c + 1 < side) couplings.emplace_back(r * side + c, r * side + c + 1);
      if (r + 1 < side) couplings.emplace_back(r * side + c, (r + 1) * side + c);
    }
  const Index nodes = side * side;
  BlockSystem s;
  s.pattern = std::make_unique<BlockPattern>(nodes, b, couplings);
  s.a = BlockSparseMatrix(s.pattern.get());
  s.a.setZero();
  using Block = Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  auto add = [&](Index i, Index j, const Block& w) { Eigen::Map<Block>(s.a.block(s.pattern->find(i, j)), b, b) += w; };
  for (const auto& [i, j] : couplings) {
    Block r(b, b);
    for (int e = 0; e < b * b; ++e) r.data()[e] = unit(rng);
    const Block w = r * r.transpose() / b + 0.5 * Block::Identity(b, b);
    add(i, i, w);
    add(j, j, w);
    add(i, j, -w);
    add(j, i, -w);
  }
  for (Index i = 0; i < nodes; ++i) add(i, i, 1e-3 * Block::Identity(b, b));
  return s;
}

TEST(ConjugateResidual, TwoLevelPreconditionerSolvesTheSameSystemInFarFewerIterations) {
  ThreadScope threads(1);
  for (int b : {3, 5}) {
    SCOPED_TRACE("block " + std::to_string(b));
    const Index side = 40;
    const BlockSystem s = gridSystem(side, b, 21 + b);
    std::vector<char> pinned(side * side, 0);
    pinned[0] = pinned[side - 1] = 1;  // two held corners
    const VecX rhs = randomVector(s.dofs(), 4 + b);
    auto solve = [&](PreconditionerKind kind, int smoothing, Real weight, ConjugateResidualResult* r) {
      ConjugateResidualPreconditioner p;
      p.kind = kind;
      p.smoothing_steps = smoothing;
      p.smoothing_weight = weight;
      ConjugateResidualSolver cr;
      EXPECT_TRUE(cr.setMatrix(s.a, pinned, p));
      VecX y;
      *r = cr.solve(rhs, y, 1e-10, 5000);
      EXPECT_TRUE(r->converged) << r->failure;
      EXPECT_LE(trueResidual(s.a, rhs, y, pinned).norm(), 1e-8 * r->rhs_norm);
      return y;
    };
    ConjugateResidualResult jacobi, cycle, additive, too_strong;
    const VecX y_jacobi = solve(PreconditionerKind::kBlockJacobi, 1, 0.6, &jacobi);
    const VecX y_cycle = solve(PreconditionerKind::kTwoLevel, 1, 0.6, &cycle);
    const VecX y_additive = solve(PreconditionerKind::kTwoLevel, 0, 0.6, &additive);
    // Smoothing weight 1.9: omega lambda_max(D^-1 A) is about 3.8 > 2, so the smoothed cycle is not
    // positive definite; the solve restarts with the additive form and still converges.
    const VecX y_strong = solve(PreconditionerKind::kTwoLevel, 1, 1.9, &too_strong);
    EXPECT_FALSE(jacobi.used_coarse_level);
    EXPECT_TRUE(cycle.used_coarse_level);
    EXPECT_EQ(cycle.restarts, 0);
    EXPECT_EQ(additive.restarts, 0);
    EXPECT_GE(too_strong.restarts, 1);
    const Real scale = y_jacobi.cwiseAbs().maxCoeff();
    for (const VecX* y : {&y_cycle, &y_additive, &y_strong}) EXPECT_LE((*y - y_jacobi).cwiseAbs().maxCoeff(), 1e-6 * scale);
    EXPECT_LT(3 * cycle.iterations, jacobi.iterations);
    EXPECT_LT(additive.iterations, jacobi.iterations);
    std::cout << "[ measured ] block " << b << ", " << side << " x " << side << " grid: PCR iterations to 1e-10: block-Jacobi "
              << jacobi.iterations << ", two-level V(1,1) " << cycle.iterations << ", additive " << additive.iterations
              << ", weight 1.9 " << too_strong.iterations << " (" << too_strong.restarts << " restart)\n";
  }
}

TEST(ConjugateResidual, IteratesAreBitwiseTheSameWithOneAndTwoThreads) {
#ifndef _OPENMP
  GTEST_SKIP() << "built without OpenMP";
#else
  // Large enough (> 65536 DOFs) that the dot products run in parallel too.
  for (int b : {3, 5}) {
    SCOPED_TRACE("block " + std::to_string(b));
    const Index nodes = b == 3 ? 25000 : 14000;
    const BlockSystem s = randomSystem(nodes, b, 77, 1.0);
    std::vector<char> pinned(nodes, 0);
    pinned[nodes / 2] = 1;
    const VecX rhs = randomVector(s.dofs(), 78);
    auto solve = [&](int threads, ConjugateResidualResult* r) {
      ThreadScope scope(threads);
      EXPECT_EQ(omp_get_max_threads(), threads);
      ConjugateResidualSolver cr;
      EXPECT_TRUE(cr.setMatrix(s.a, pinned));
      VecX y;
      *r = cr.solve(rhs, y, 1e-10, 3000);
      return y;
    };
    ConjugateResidualResult r1, r2;
    const VecX y1 = solve(1, &r1);
    const VecX y2 = solve(2, &r2);
    ASSERT_TRUE(r1.converged) << r1.failure;
    EXPECT_EQ(r1.iterations, r2.iterations);
    EXPECT_EQ(r1.residual_norm, r2.residual_norm);
    EXPECT_TRUE(y1 == y2) << "max difference " << (y1 - y2).cwiseAbs().maxCoeff();
    std::cout << "[ measured ] block " << b << ", " << s.dofs() << " DOFs: " << r1.iterations << " iterations\n";
  }
#endif
}

TEST(ConjugateResidual, FailuresAreReportedWithTheirReason) {
  ThreadScope threads(1);
  const BlockSystem s = randomSystem(30, 3, 2, 1.0);
  const VecX rhs = randomVector(s.dofs(), 1);
  ConjugateResidualSolver cr;
  ASSERT_TRUE(cr.setMatrix(s.a, {}));
  VecX y;
  // The iteration cap.
  const ConjugateResidualResult capped = cr.solve(rhs, y, 1e-14, 2);
  EXPECT_FALSE(capped.converged);
  EXPECT_EQ(capped.iterations, 2);
  EXPECT_TRUE(contains(capped.failure, "did not converge in 2 iterations")) << capped.failure;
  // ... unless the iterate meets the accept tolerance.
  const ConjugateResidualResult accepted = cr.solve(rhs, y, 1e-14, 2, 0.999 * capped.residual_norm / capped.rhs_norm);
  EXPECT_FALSE(accepted.converged);
  const ConjugateResidualResult loose = cr.solve(rhs, y, 1e-14, 2, 1.001 * capped.residual_norm / capped.rhs_norm);
  EXPECT_TRUE(loose.converged);
  // A zero right-hand side is solved by y = 0 without iterating.
  const ConjugateResidualResult zero = cr.solve(VecX::Zero(s.dofs()), y, 1e-12, 100);
  EXPECT_TRUE(zero.converged);
  EXPECT_EQ(zero.iterations, 0);
  EXPECT_EQ(y, VecX::Zero(s.dofs()));
  // A non-finite right-hand side.
  VecX bad = rhs;
  bad[4] = std::nan("");
  const ConjugateResidualResult nan = cr.solve(bad, y, 1e-12, 100);
  EXPECT_FALSE(nan.converged);
  EXPECT_TRUE(contains(nan.failure, "non-finite")) << nan.failure;
  // A singular diagonal block of a free node: no preconditioner.
  BlockSystem singular = randomSystem(30, 3, 2, 1.0);
  std::fill(singular.a.block(singular.pattern->diagonal(3)), singular.a.block(singular.pattern->diagonal(3)) + 9, 0.0);
  EXPECT_FALSE(cr.setMatrix(singular.a, {}));
  std::vector<char> pinned(30, 0);
  pinned[3] = 1;
  EXPECT_TRUE(cr.setMatrix(singular.a, pinned)) << "a pinned node's block is not used";
}

// ---- Newton on the cloth models ------------------------------------------------------------------

// A towel (64 x 46 cm, d = 4 cm, 204 particles) held at a corner, some time into its fall.
struct MovingTowel {
  DrapeSceneSpec spec;
  DrapeScene scene;
  VecX x, v;
  Real t = 0;
};

MovingTowel fallingTowel(const std::string& model, Real until);

// Runs `check` on the particle and the Choi-Ko towel 0.1 s into their fall, one thread.
void forEachFallingTowel(const std::function<void(const std::string&, MovingTowel&)>& check) {
  ThreadScope threads(1);
  for (const char* model : {"particle_kes", "choi_ko"}) {
    SCOPED_TRACE(model);
    MovingTowel m = fallingTowel(model, 0.1);
    check(model, m);
  }
}

MovingTowel fallingTowel(const std::string& model, Real until) {
  MovingTowel m;
  m.spec = benchmarkTowelSpec(0.04, "corner_ul", model);
  m.scene = buildDrapeScene(m.spec);
  SimulationSettings s = m.spec.settings;
  s.integrator = IntegratorType::kSemiImplicitEuler;
  s.policy = StepPolicy::kFixed;
  s.dt = 1e-3;
  DrapeSimulation sim(*m.scene.model, m.scene.pins, s, m.scene.x0, m.scene.v0);
  const RunResult r = sim.run(until);
  EXPECT_FALSE(r.diverged) << r.divergence_reason;
  m.x = sim.state();
  m.v = sim.velocities();
  m.t = sim.time();
  return m;
}

// The backward Euler residual M(x) (v_new - v) - h f(x + h v_new, v_new) on the free nodes, and the
// scale the integrator measures it against: max(|M v|, h |f(x, v)|, h g max m) on the free nodes.
struct Residual {
  Real norm = 0;
  Real scale = 0;
};

Residual backwardEulerResidual(ClothModel& model, const PinnedNodes& pins, const VecX& x, const VecX& v, Real h,
                               const VecX& v_new) {
  const std::vector<char> pinned = pinnedMask(model.numNodes(), pins);
  const int b = model.dofsPerNode();
  auto freeMax = [&](const VecX& y) {
    Real worst = 0;
    for (Index i = 0; i < model.numNodes(); ++i)
      if (!pinned[i]) worst = std::max(worst, y.segment(i * b, b).cwiseAbs().maxCoeff());
    return worst;
  };
  VecX f, mv, f0, m0;
  model.computeForces(x + h * v_new, v_new, f, nullptr);
  model.multiplyMass(x, v_new - v, mv);
  model.computeForces(x, v, f0, nullptr);
  model.multiplyMass(x, v, m0);
  Residual r;
  r.norm = freeMax(mv - h * f);
  r.scale = std::max({freeMax(m0), h * freeMax(f0), h * kGravity * model.massPerDof().maxCoeff()});
  return r;
}

TEST(BackwardEulerNewton, ConvergedStepLeavesAResidualBelowTheTolerance) {
  forEachFallingTowel([](const std::string& model, MovingTowel& m) {
    ClothModel& cm = *m.scene.model;
    const Real h = 0.005;
    SolverSettings solver;
    solver.newton_max_iterations = 10;  // the particle model needs 6 here (measured)
    auto newton = makeIntegrator(IntegratorType::kBackwardEulerNewton, solver);
    VecX x_new, v_new;
    const StepOutcome out = newton->step(cm, m.scene.pins, m.x, m.v, m.t, h, x_new, v_new);
    ASSERT_TRUE(out.ok) << out.failure;
    EXPECT_GE(out.newton_iterations, 2);
    EXPECT_LE(out.newton_iterations, solver.newton_max_iterations);
    EXPECT_GE(out.solver_iterations, out.newton_iterations);
    EXPECT_GT(out.solve_ms, 0.0);
    EXPECT_GT(out.assembly_ms, 0.0);
    const Residual r = backwardEulerResidual(cm, m.scene.pins, m.x, m.v, h, v_new);
    EXPECT_LE(r.norm, solver.newton_tolerance * r.scale);
    // The end state is x + h v_new, the pins exactly on their targets.
    for (size_t k = 0; k < m.scene.pins.nodes.size(); ++k)
      EXPECT_TRUE(x_new.segment<3>(3 * m.scene.pins.nodes[k]) == m.scene.pins.position(k, m.t + h));
    // The linearised (semi-implicit) step from the same state does not meet the tolerance: the check
    // sees the difference, and the further iterations were needed.
    auto semi = makeIntegrator(IntegratorType::kSemiImplicitEuler, solver);
    VecX xs, vs;
    ASSERT_TRUE(semi->step(cm, m.scene.pins, m.x, m.v, m.t, h, xs, vs).ok);
    const Residual rs = backwardEulerResidual(cm, m.scene.pins, m.x, m.v, h, vs);
    EXPECT_GT(rs.norm, 10 * solver.newton_tolerance * rs.scale);
    // A tighter tolerance is met too, with more iterations.
    SolverSettings tight = solver;
    tight.newton_tolerance = 1e-5;
    tight.newton_max_iterations = 30;
    auto precise = makeIntegrator(IntegratorType::kBackwardEulerNewton, tight);
    VecX xt, vt;
    const StepOutcome ot = precise->step(cm, m.scene.pins, m.x, m.v, m.t, h, xt, vt);
    ASSERT_TRUE(ot.ok) << ot.failure;
    EXPECT_GT(ot.newton_iterations, out.newton_iterations);
    EXPECT_LE(backwardEulerResidual(cm, m.scene.pins, m.x, m.v, h, vt).norm, tight.newton_tolerance * r.scale);
    std::cout << "[ measured ] " << model << ", h = 5 ms: residual / scale " << r.norm / r.scale << " after "
              << out.newton_iterations << " Newton iterations (" << out.solver_iterations
              << " PCR iterations), semi-implicit step " << rs.norm / rs.scale << "; tolerance 1e-5 after "
              << ot.newton_iterations << "\n";
  });
}

TEST(BackwardEulerNewton, OneIterationFromTheZeroStartIsTheSemiImplicitStep) {
  forEachFallingTowel([](const std::string& model, MovingTowel& m) {
    ClothModel& cm = *m.scene.model;
    const Real h = 0.005;
    SolverSettings solver;
    solver.relative_tolerance = 1e-12;
    solver.max_iterations = 5000;
    solver.preconditioner = PreconditionerKind::kBlockJacobi;
    SolverSettings one = solver;
    one.newton_max_iterations = 1;
    one.newton_tolerance = 1e30;  // accept the first iterate
    VecX xn, vn, xs, vs;
    const StepOutcome on = makeIntegrator(IntegratorType::kBackwardEulerNewton, one)->step(cm, m.scene.pins, m.x, m.v, m.t, h, xn, vn);
    const StepOutcome os = makeIntegrator(IntegratorType::kSemiImplicitEuler, solver)->step(cm, m.scene.pins, m.x, m.v, m.t, h, xs, vs);
    ASSERT_TRUE(on.ok) << on.failure;
    ASSERT_TRUE(os.ok) << os.failure;
    EXPECT_EQ(on.newton_iterations, 1);
    const Real dv = (vs - m.v).cwiseAbs().maxCoeff();
    ASSERT_GT(dv, 1e-3) << "the cloth should be accelerating";
    EXPECT_LE((vn - vs).cwiseAbs().maxCoeff(), 1e-8 * dv);
    EXPECT_LE((xn - xs).cwiseAbs().maxCoeff(), 1e-8 * h * dv);
    EXPECT_NEAR(on.error_estimate, os.error_estimate, 1e-8 * os.error_estimate);
    // Converged Newton (default tolerance) moves away from the linearised step by far more.
    SolverSettings converged = solver;
    converged.newton_max_iterations = 20;
    VecX xc, vc;
    const StepOutcome oc = makeIntegrator(IntegratorType::kBackwardEulerNewton, converged)->step(cm, m.scene.pins, m.x, m.v, m.t, h, xc, vc);
    ASSERT_TRUE(oc.ok) << oc.failure;
    EXPECT_GE(oc.newton_iterations, 2);
    EXPECT_GT((vc - vs).cwiseAbs().maxCoeff(), 1e-4 * dv);
    std::cout << "[ measured ] " << model << ": |v(1 iteration) - v(semi-implicit)| / |dv| = "
              << (vn - vs).cwiseAbs().maxCoeff() / dv << ", converged Newton differs by "
              << (vc - vs).cwiseAbs().maxCoeff() / dv << "\n";
  });
}

TEST(BackwardEulerNewton, StepThatCannotConvergeFailsAndTheAdaptivePoliciesHalveIt) {
  ThreadScope threads(1);
  const Real h = 0.04;
  DrapeSceneSpec spec = benchmarkTowelSpec(0.04, "corner_ul");
  spec.settings.integrator = IntegratorType::kBackwardEulerNewton;
  DrapeScene scene = buildDrapeScene(spec);
  {
    // From the released flat towel, 40 ms is too large for 5 iterations.
    VecX x_new, v_new;
    const StepOutcome out = makeIntegrator(IntegratorType::kBackwardEulerNewton, spec.settings.solver)
                                ->step(*scene.model, scene.pins, scene.x0, scene.v0, 0.0, h, x_new, v_new);
    EXPECT_FALSE(out.ok);
    EXPECT_EQ(out.newton_iterations, 5);
    EXPECT_TRUE(contains(out.failure, "Newton's method did not converge in 5 iterations")) << out.failure;
    std::cout << "[ measured ] 40 ms step: " << out.failure << "\n";
  }
  // The fixed policy reports it as the divergence.
  {
    DrapeSceneSpec s = spec;
    s.settings.policy = StepPolicy::kFixed;
    s.settings.dt = h;
    DrapeSimulation sim(*scene.model, scene.pins, s.settings, scene.x0, scene.v0);
    const RunResult r = sim.run(0.5);
    EXPECT_TRUE(r.diverged);
    EXPECT_EQ(r.steps, 0);
    EXPECT_TRUE(contains(r.divergence_reason, "Newton's method did not converge")) << r.divergence_reason;
  }
  // The adaptive policies halve the step until Newton converges, then go on.
  for (StepPolicy policy : {StepPolicy::kThesis, StepPolicy::kErrorControlled}) {
    SCOPED_TRACE(toString(policy));
    DrapeSceneSpec s = spec;
    s.settings.policy = policy;
    s.settings.dt = h;
    s.settings.dt_max = h;
    s.settings.error_tolerance = 1.0;  // only Newton's failures reject steps here
    DrapeSimulation sim(*scene.model, scene.pins, s.settings, scene.x0, scene.v0);
    const RunResult first = sim.run(1e-9);  // one accepted step
    ASSERT_FALSE(first.diverged) << first.divergence_reason;
    EXPECT_EQ(first.steps, 1);
    ASSERT_GE(first.rejected_steps, 1);
    EXPECT_EQ(sim.time(), h / std::pow(2.0, static_cast<Real>(first.rejected_steps)));
    const Real first_dt = sim.time();
    const RunResult r = sim.run(0.5);
    EXPECT_FALSE(r.diverged) << r.divergence_reason;
    EXPECT_GE(r.sim_time, 0.5 - 1e-12);
    EXPECT_LT(scene.model->maxEdgeStretch(sim.positions()), 1.05);
    std::cout << "[ measured ] " << toString(policy) << ": first step accepted at " << first_dt << " s after "
              << first.rejected_steps << " halvings; 0.5 s in " << r.steps << " steps, " << r.rejected_steps
              << " rejected\n";
  }
}

// Largest residual force of the free particles at rest, in units of their weight.
Real worstRestResidual(ClothModel& model, const PinnedNodes& pins, const VecX& x) {
  VecX f;
  model.computeForces(x, VecX::Zero(x.size()), f, nullptr);
  const std::vector<char> pinned = pinnedMask(model.numNodes(), pins);
  Real worst = 0;
  for (Index i = 0; i < model.numNodes(); ++i)
    if (!pinned[i]) worst = std::max(worst, f.segment<3>(3 * i).norm() / (model.massPerDof()[3 * i] * kGravity));
  return worst;
}

TEST(BackwardEulerNewton, HangingTowelComesToRestOnTheSemiImplicitRestShape) {
  ThreadScope threads(1);
  struct Rest {
    RunResult result;
    VecX x;
    Real depth = 0, residual = 0;
  };
  auto run = [](IntegratorType integrator) {
    DrapeSceneSpec spec = benchmarkTowelSpec(0.04, "corner_ul");
    spec.settings.integrator = integrator;
    DrapeScene scene = buildDrapeScene(spec);
    DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
    Rest r;
    r.result = sim.run();
    r.x = sim.positions();
    r.depth = hangingDepth(scene, r.x);
    r.residual = worstRestResidual(*scene.model, scene.pins, r.x);
    return r;
  };
  const Rest semi = run(IntegratorType::kSemiImplicitEuler);
  const Rest newton = run(IntegratorType::kBackwardEulerNewton);
  ASSERT_TRUE(semi.result.rest_reached);
  EXPECT_FALSE(newton.result.diverged) << newton.result.divergence_reason;
  EXPECT_TRUE(newton.result.rest_reached) << "t = " << newton.result.sim_time;
  // The same equilibrium: the hanging depth within 1 %, every particle within 3 cm (the towel is
  // 64 cm long), and a true equilibrium (residual forces a small fraction of a particle's weight).
  EXPECT_NEAR(newton.depth, semi.depth, 0.01 * semi.depth);
  EXPECT_LE((newton.x - semi.x).cwiseAbs().maxCoeff(), 0.03);
  EXPECT_LT(newton.residual, 0.05);
  std::cout << "[ measured ] rest at t = " << newton.result.sim_time << " s (semi-implicit " << semi.result.sim_time
            << " s), depth " << newton.depth << " m (" << semi.depth << " m), max distance "
            << (newton.x - semi.x).cwiseAbs().maxCoeff() << " m, residual " << newton.residual << " (" << semi.residual
            << ") of a weight, " << newton.result.steps << " steps, " << newton.result.rejected_steps
            << " rejected, wall " << newton.result.wall_time << " s (" << semi.result.wall_time << " s)\n";
}

// ---- a model with a non-diagonal mass ------------------------------------------------------------

// Generalised momentum of the rigid translations, T^T M(x) v (T: 1 on every node's position DOFs).
Vec3 translationMomentum(const ClothModel& model, const VecX& x, const VecX& v) {
  VecX mv;
  model.multiplyMass(x, v, mv);
  Vec3 p = Vec3::Zero();
  for (Index i = 0; i < model.numNodes(); ++i) p += mv.segment<3>(i * model.dofsPerNode());
  return p;
}

TEST(BackwardEulerNewton, FreeSheetWithANonDiagonalMassGainsExactlyTheImpulseOfGravity) {
  // No pins, no drag, no damping: every force but gravity is internal and translation invariant, so
  // backward Euler changes T^T M v by exactly -h g M_total e_z per step, whatever the elastic forces
  // do, if the mass of the system matrix and of the residual is the same M(x_n). The sliding model's
  // mass couples positions with sliding coordinates and neighbouring nodes.
  ThreadScope threads(1);
  testing_models::registerSlidingParticleModel();
  for (const char* name : {"test_sliding_particles", "particle_kes"}) {
    SCOPED_TRACE(name);
    DrapeSceneSpec spec = sim_test_support::heldSquareSpec(0.1, 0.02);
    spec.model = ClothModelSpec(name);
    spec.model.set("drag", false).set("settle_damping_per_s", 0.0);
    DrapeScene scene = buildDrapeScene(spec);
    ClothModel& model = *scene.model;
    EXPECT_EQ(model.hasLumpedMass(), std::string(name) == "particle_kes");
    const int b = model.dofsPerNode();
    // Stretched by 1 % (elastic forces), swirling, with displaced sliding coordinates.
    VecX x = scene.x0, v = randomVector(model.numDofs(), 5) * 0.1;
    for (Index i = 0; i < model.numNodes(); ++i) {
      x.segment<2>(i * b) *= 1.01;
      if (b == 5) x.segment<2>(i * b + 3) = 0.01 * randomVector(2, static_cast<unsigned>(i));
    }
    SolverSettings solver;
    solver.relative_tolerance = 1e-13;
    solver.max_iterations = 5000;
    auto newton = makeIntegrator(IntegratorType::kBackwardEulerNewton, solver);
    const Real h = 1e-3, total = model.totalMass();
    const Vec3 impulse(0, 0, -h * kGravity * total);
    VecX x_new, v_new;
    Real worst = 0, moved = 0;
    int iterations = 0;
    for (int step = 0; step < 20; ++step) {
      const StepOutcome out = newton->step(model, PinnedNodes{}, x, v, step * h, h, x_new, v_new);
      ASSERT_TRUE(out.ok) << out.failure;
      iterations += out.newton_iterations;
      const Vec3 change = translationMomentum(model, x, v_new) - translationMomentum(model, x, v);
      worst = std::max(worst, (change - impulse).norm());
      moved = std::max(moved, (x_new - x).cwiseAbs().maxCoeff());
      x.swap(x_new);
      v.swap(v_new);
    }
    EXPECT_GT(iterations, 20) << "the elastic forces should need Newton iterations";
    EXPECT_GT(moved, 1e-4);
    EXPECT_LE(worst, 1e-9 * impulse.norm());
    std::cout << "[ measured ] " << name << ": worst momentum balance error " << worst / impulse.norm()
              << " of the step's impulse, " << iterations << " Newton iterations in 20 steps\n";
  }
}

TEST(BackwardEulerNewton, FiveDofModelWithCoupledMassHangsWithExactPins) {
  ThreadScope threads(1);
  testing_models::registerSlidingParticleModel();
  DrapeSceneSpec spec = sim_test_support::heldSquareSpec(0.1, 0.02);
  spec.model = ClothModelSpec("test_sliding_particles");
  spec.model.set("coupling", 0.3).set("neighbour_mass", 0.02).set("settle_damping_per_s", 4.0);
  spec.settings.integrator = IntegratorType::kBackwardEulerNewton;
  spec.settings.max_time = 0.3;
  DrapeScene scene = buildDrapeScene(spec);
  ASSERT_EQ(scene.model->dofsPerNode(), 5);
  DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
  const RunResult r = sim.run();
  ASSERT_FALSE(r.diverged) << r.divergence_reason;
  EXPECT_GE(r.sim_time, 0.3 - 1e-12);
  EXPECT_GT(r.solver_iterations, r.steps);
  EXPECT_GT(hangingDepth(scene, sim.positions()), 0.08);
  for (size_t k = 0; k < scene.pins.nodes.size(); ++k)
    EXPECT_TRUE(sim.positions().segment<3>(3 * scene.pins.nodes[k]) == scene.pins.position(k, sim.time()));
}

// ---- names and settings --------------------------------------------------------------------------

TEST(BackwardEulerNewton, NameSettingsAndSceneKeys) {
  EXPECT_EQ(toString(IntegratorType::kBackwardEulerNewton), "backward_euler_newton");
  EXPECT_EQ(integratorFromString("backward_euler_newton"), IntegratorType::kBackwardEulerNewton);
  EXPECT_EQ(makeIntegrator(IntegratorType::kBackwardEulerNewton)->type(), IntegratorType::kBackwardEulerNewton);
  const SolverSettings defaults;
  EXPECT_EQ(defaults.newton_max_iterations, 5);
  const std::string base = "textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {points: [corner_ul]}\n";
  const DrapeSceneSpec s = parseDrapeSceneYaml(
      base + "simulation: {integrator: backward_euler_newton, newton_max_iterations: 8, newton_tolerance: 0.001}\n");
  EXPECT_EQ(s.settings.integrator, IntegratorType::kBackwardEulerNewton);
  EXPECT_EQ(s.settings.solver.newton_max_iterations, 8);
  EXPECT_DOUBLE_EQ(s.settings.solver.newton_tolerance, 0.001);
  for (const char* bad : {"newton_max_iterations: 0", "newton_tolerance: -1", "newton_tolerance: .nan"}) {
    try {
      parseDrapeSceneYaml(base + "simulation: {" + bad + "}\n");
      ADD_FAILURE() << bad << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_TRUE(contains(e.what(), std::string("simulation.") + std::string(bad).substr(0, std::string(bad).find(':'))))
          << e.what();
    }
  }
  // DrapeSimulation checks the settings it is given in code.
  DrapeScene scene = buildDrapeScene(s);
  SimulationSettings bad = s.settings;
  bad.solver.newton_max_iterations = 0;
  bad.solver.newton_tolerance = 0;
  try {
    DrapeSimulation sim(*scene.model, scene.pins, bad, scene.x0, scene.v0);
    ADD_FAILURE() << "accepted";
  } catch (const SimError& e) {
    EXPECT_TRUE(contains(e.what(), "newton_max_iterations")) << e.what();
    EXPECT_TRUE(contains(e.what(), "newton_tolerance")) << e.what();
  }
}

}  // namespace
}  // namespace textile_handling
