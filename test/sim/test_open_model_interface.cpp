// Tests of the open model interface (cloth_model.h) and the model registry (cloth_model_registry.h)
// with a 5-DOF model whose mass is not diagonal (sliding_particle_model.h): the mass operations, every
// integrator with pins, rest detection, save/resume, scenes with collision passes, and the registry's
// option parsing and fingerprints.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cstdio>
#include <string>
#include <vector>

#include "../test_support.h"
#include "sim_test_support.h"
#include "sliding_particle_model.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/integrators.h"

namespace textile_handling {
namespace {

using testing_models::SlidingParticleModel;
using test_support::ThreadScope;
using test_support::freshTempPath;

DrapeSceneSpec squareSpec(const ClothModelSpec& model) {
  DrapeSceneSpec s = sim_test_support::heldSquareSpec(0.1, 0.02);
  s.model = model;
  return s;
}

ClothModelSpec sliding(Real coupling, Real neighbour_mass) {
  testing_models::registerSlidingParticleModel();
  ClothModelSpec m("test_sliding_particles");
  m.set("coupling", coupling).set("neighbour_mass", neighbour_mass);
  return m;
}

Eigen::MatrixXd denseMass(const ClothModel& model, const VecX& x) {
  BlockSparseMatrix m(&model.jacobianPattern());
  m.setZero();
  model.addMassMatrix(x, 1.0, m);
  return sim_test_support::denseMatrix(m);
}

TEST(OpenModelInterface, FiveDofSceneHasModelSizedStateAndPositionView) {
  const DrapeScene scene = buildDrapeScene(squareSpec(sliding(0.3, 0.02)));
  const Index n = scene.model->numNodes();
  EXPECT_EQ(scene.model->dofsPerNode(), 5);
  EXPECT_EQ(scene.x0.size(), 5 * n);
  EXPECT_EQ(scene.v0.size(), 5 * n);
  const VecX p = scene.model->positionsOf(scene.x0);
  ASSERT_EQ(p.size(), 3 * n);
  for (Index i = 0; i < n; ++i) {
    EXPECT_EQ(p.segment<3>(3 * i), scene.x0.segment<3>(5 * i));
    EXPECT_EQ(scene.x0.segment<2>(5 * i + 3), Vec2::Zero());  // sliding coordinates start at 0
  }
  EXPECT_TRUE(scene.pins.anchors[0].isApprox(Vec3(0, 0, 1)));
  VecX x = scene.x0;
  VecX q = p + VecX::Constant(3 * n, 0.25);
  scene.model->setPositions(q, x);
  EXPECT_EQ(scene.model->positionsOf(x), q);
  for (Index i = 0; i < n; ++i) EXPECT_EQ(x.segment<2>(5 * i + 3), Vec2::Zero());
}

TEST(OpenModelInterface, NonDiagonalMassIsSymmetricPositiveDefiniteAndSolvedOnFreeNodes) {
  const DrapeScene scene = buildDrapeScene(squareSpec(sliding(0.3, 0.02)));
  const ClothModel& m = *scene.model;
  EXPECT_FALSE(m.hasLumpedMass());
  const Eigen::MatrixXd M = denseMass(m, scene.x0);
  EXPECT_LE((M - M.transpose()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(M).info(), Eigen::Success);  // positive definite
  // Off-diagonal entries exist within node blocks and between nodes.
  EXPECT_GT(std::abs(M(0, 3)), 0.0);
  EXPECT_GT(std::abs(M(3, 5 + 3)) + std::abs(M(3, 5 * 6 + 3)), 0.0);
  VecX v = VecX::LinSpaced(m.numDofs(), -1, 1), mv;
  m.multiplyMass(scene.x0, v, mv);
  EXPECT_LE((mv - M * v).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_NEAR(m.kineticEnergy(scene.x0, v), 0.5 * v.dot(M * v), 1e-15);
  // Total mass: the sum of the lumped node masses = areal density x area (the lumping of the particle
  // model, unchanged by the sliding coordinates).
  EXPECT_NEAR(m.totalMass(), Material::cotton().areal_density * 0.1 * 0.1, 1e-9);
  // M_ff a_f = f_f with the pinned node's DOFs held at zero.
  std::vector<char> pinned(m.numNodes(), 0);
  pinned[scene.pins.nodes[0]] = 1;
  VecX f = VecX::LinSpaced(m.numDofs(), 0.5, -0.3), a;
  ASSERT_TRUE(m.solveMass(scene.x0, f, pinned, a));
  const Index p = scene.pins.nodes[0];
  EXPECT_EQ(a.segment<5>(5 * p), (Eigen::Matrix<Real, 5, 1>::Zero()));
  VecX r = M * a - f;
  r.segment<5>(5 * p).setZero();
  EXPECT_LE(r.cwiseAbs().maxCoeff(), 1e-10 * f.cwiseAbs().maxCoeff());
}

TEST(OpenModelInterface, LumpedDefaultsEqualTheFormulasTheIntegratorsUsedBefore) {
  // The 3-DOF models take the lumped fast path: the defaults reproduce the former expressions bitwise.
  const DrapeScene scene = buildDrapeScene(squareSpec(ClothModelSpec("particle_kes")));
  const ClothModel& m = *scene.model;
  ASSERT_TRUE(m.hasLumpedMass());
  const VecX v = VecX::LinSpaced(m.numDofs(), -0.2, 0.3);
  EXPECT_EQ(m.kineticEnergy(scene.x0, v), 0.5 * (m.massPerDof().array() * v.array().square()).sum());
  VecX f = VecX::LinSpaced(m.numDofs(), 0.5, -0.3), a;
  ASSERT_TRUE(m.solveMass(scene.x0, f, {}, a));
  VecX expected = f;
  expected.array() /= m.massPerDof().array();
  EXPECT_EQ(a, expected);
  EXPECT_EQ(m.positionsOf(scene.x0), scene.x0);
}

struct SimRun {
  RunResult result;
  VecX positions, state;
};

SimRun simulate(const DrapeSceneSpec& spec, Real until) {
  DrapeScene scene = buildDrapeScene(spec);
  DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
  sim.setPostStepPass(scene.postStepPass());
  SimRun r;
  r.result = sim.run(until);
  r.positions = sim.positions();
  r.state = sim.state();
  return r;
}

struct IntegratorCase {
  const char* label;
  IntegratorType type;
  LinearSolverKind solver;
  Real dt;
};
const IntegratorCase kIntegrators[] = {
    {"rk4", IntegratorType::kRK4, LinearSolverKind::kCG, 2e-4},
    {"semi_implicit cg", IntegratorType::kSemiImplicitEuler, LinearSolverKind::kCG, 2e-3},
    {"semi_implicit direct", IntegratorType::kSemiImplicitEuler, LinearSolverKind::kDirect, 2e-3},
    {"block_diagonal", IntegratorType::kBlockDiagonalEuler, LinearSolverKind::kCG, 2e-4},
    {"backward_euler_newton", IntegratorType::kBackwardEulerNewton, LinearSolverKind::kCG, 2e-3},
};

DrapeSceneSpec fixedStep(DrapeSceneSpec s, const IntegratorCase& c) {
  s.settings.integrator = c.type;
  s.settings.solver.kind = c.solver;
  s.settings.policy = StepPolicy::kFixed;
  s.settings.dt = c.dt;
  return s;
}

TEST(OpenModelInterface, DecoupledSlidingCoordinatesLeaveThePositionsOfTheParticleModel) {
  // c = eps = 0: positions follow the 3-DOF particle model in every integrator (up to the rounding of
  // sums over longer vectors), and the sliding coordinates stay at 0.
  ThreadScope threads(1);
  const Index held = buildDrapeScene(squareSpec(ClothModelSpec("particle_kes"))).pins.nodes[0];
  for (const auto& c : kIntegrators) {
    const SimRun five = simulate(fixedStep(squareSpec(sliding(0, 0)), c), 0.1);
    const SimRun three = simulate(fixedStep(squareSpec(ClothModelSpec("particle_kes")), c), 0.1);
    ASSERT_FALSE(three.result.diverged) << c.label << ": " << three.result.divergence_reason;
    ASSERT_FALSE(five.result.diverged) << c.label << ": " << five.result.divergence_reason;
    ASSERT_EQ(five.result.steps, three.result.steps) << c.label;
    EXPECT_LE((five.positions - three.positions).cwiseAbs().maxCoeff(), 1e-9) << c.label;
    for (Index i = 0; i < five.state.size() / 5; ++i) EXPECT_EQ(five.state.segment<2>(5 * i + 3), Vec2::Zero()) << c.label;
    // The held corner sits exactly on its pin.
    EXPECT_EQ(five.positions.segment<3>(3 * held), three.positions.segment<3>(3 * held)) << c.label;
  }
}

TEST(OpenModelInterface, CoupledMassReachesTheParticleModelsRestShapeInEveryIntegrator) {
  // An equilibrium does not depend on the mass: with the coupled, non-diagonal mass every integrator
  // comes to rest on the particle model's rest shape, with the sliding coordinates back at 0.
  ThreadScope threads(1);
  DrapeSceneSpec base = squareSpec(ClothModelSpec("particle_kes"));
  base.model.set("settle_damping_per_s", 4.0).set("jacobian", "definite_fix");
  base.settings.max_time = 20;
  const SimRun reference = simulate(fixedStep(base, kIntegrators[1]), 20);
  ASSERT_TRUE(reference.result.rest_reached);
  for (const auto& c : kIntegrators) {
    DrapeSceneSpec s = base;
    s.model = sliding(0.3, 0.02).set("settle_damping_per_s", 4.0).set("jacobian", "definite_fix");
    s = fixedStep(s, c);
    // RK4: stability over 0.3 s, not rest (its step is limited by the stiffest mode, and the coupled
    // mass lowers the effective mass of some modes to m (1 - c): 2e-4 s is stable at c = 0 only).
    if (c.type == IntegratorType::kRK4) {
      s.settings.max_time = 0.3;
      s.settings.dt = 1e-4;
    }
    const SimRun r = simulate(s, s.settings.max_time);
    ASSERT_FALSE(r.result.diverged) << c.label << ": " << r.result.divergence_reason;
    if (c.type == IntegratorType::kRK4) continue;
    EXPECT_TRUE(r.result.rest_reached) << c.label;
    EXPECT_LE((r.positions - reference.positions).cwiseAbs().maxCoeff(), 2e-3) << c.label;
    for (Index i = 0; i < r.state.size() / 5; ++i) EXPECT_LE(r.state.segment<2>(5 * i + 3).norm(), 1e-4) << c.label;
  }
}

TEST(OpenModelInterface, SaveAndResumeOfAFiveDofModelContinuesBitwise) {
  ThreadScope threads(1);
  DrapeSceneSpec s = fixedStep(squareSpec(sliding(0.3, 0.02)), kIntegrators[1]);
  const SimRun whole = simulate(s, 0.2);
  DrapeScene scene = buildDrapeScene(s);
  DrapeSimulation first(*scene.model, scene.pins, s.settings, scene.x0, scene.v0);
  first.run(0.1);
  const std::string path = freshTempPath("five_dof", "state.txt");
  first.save(path);
  DrapeScene scene2 = buildDrapeScene(s);
  DrapeSimulation second(*scene2.model, scene2.pins, s.settings, scene2.x0, scene2.v0);
  second.load(path);
  second.run(0.2);
  EXPECT_EQ(second.state(), whole.state);
  std::remove(path.c_str());
  // A state of the 3-DOF model does not load into the 5-DOF one.
  DrapeScene scene3 = buildDrapeScene(fixedStep(squareSpec(ClothModelSpec("particle_kes")), kIntegrators[1]));
  DrapeSimulation three(*scene3.model, scene3.pins, s.settings, scene3.x0, scene3.v0);
  const std::string path3 = freshTempPath("five_dof", "state3.txt");
  three.save(path3);
  EXPECT_THROW(second.load(path3), std::runtime_error);
  std::remove(path3.c_str());
}

TEST(OpenModelInterface, CollisionPassesRunOnThePositionsOfAFiveDofModel) {
  // Obstacles and self-collision see the node positions (PositionViewPass); a floor stops the cloth.
  ThreadScope threads(1);
  DrapeSceneSpec s = fixedStep(squareSpec(sliding(0.3, 0.02).set("jacobian", "definite_fix")), kIntegrators[1]);
  s.self_collision = true;
  PlaneObstacle floor;
  floor.point = Vec3(0, 0, 0.95);
  s.obstacles.planes.push_back(floor);
  const SimRun r = simulate(s, 0.5);
  ASSERT_FALSE(r.result.diverged) << r.result.divergence_reason;
  EXPECT_GT(r.result.post_step_events, 0);
  for (Index i = 0; i < r.positions.size() / 3; ++i) EXPECT_GE(r.positions[3 * i + 2], 0.95 - 1e-6);
}

TEST(ClothModelRegistryTest, BuiltInModelsOptionsAndErrors) {
  ClothModelRegistry& reg = ClothModelRegistry::instance();
  EXPECT_TRUE(reg.contains("particle_kes"));
  EXPECT_TRUE(reg.contains("choi_ko"));
  try {
    reg.find("yarn_level");
    ADD_FAILURE() << "unknown model accepted";
  } catch (const ClothModelError& e) {
    EXPECT_NE(std::string(e.what()).find("particle_kes"), std::string::npos) << e.what();
  }
  // Each model accepts only its own keys, and each error names the key.
  auto error = [&](const ClothModelSpec& spec) {
    try {
      reg.validate(spec);
    } catch (const ClothModelError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(error(ClothModelSpec("choi_ko", {{"jacobian", "exact"}})).find("model.jacobian"), std::string::npos);
  EXPECT_NE(error(ClothModelSpec("particle_kes", {{"bending_version", "beam"}})).find("model.bending_version"),
            std::string::npos);
  EXPECT_NE(error(ClothModelSpec("particle_kes", {{"settle_damping_per_s", "-1"}})).find("model.settle_damping_per_s"),
            std::string::npos);
  EXPECT_NE(error(ClothModelSpec("choi_ko", {{"buckling_onset", "1.5"}})).find("model.buckling_onset"), std::string::npos);
  EXPECT_NE(error(ClothModelSpec("choi_ko", {{"buckling_onset_curvature_per_m", "0"}})).find("model.buckling_onset_curvature_per_m"),
            std::string::npos);
  EXPECT_NE(error(ClothModelSpec("choi_ko", {{"buckling_onset", "0.99"}, {"buckling_onset_curvature_per_m", "5"}}))
                .find("exclude each other"),
            std::string::npos);
  EXPECT_EQ(error(ClothModelSpec("choi_ko", {{"buckling_onset_curvature_per_m", "5"}})), "");
  EXPECT_NE(error(ClothModelSpec("particle_kes", {{"gravity", "maybe"}})).find("model.gravity"), std::string::npos);
  EXPECT_EQ(error(ClothModelSpec("choi_ko", {{"settle_damping_per_s", "4"}, {"bending_version", "plate"}})), "");
  // Registering a taken name fails.
  ClothModelDescriptor copy = reg.find("particle_kes");
  EXPECT_THROW(reg.add(copy), ClothModelError);
}

TEST(ClothModelRegistryTest, SpecTextRoundTripsAndSettlingSpecFollowsTheModelsKeys) {
  ClothModelSpec s("choi_ko");
  s.set("settle_damping_per_s", 4.0).set("bending_version", "plate");
  EXPECT_EQ(s.text(), "choi_ko bending_version=plate settle_damping_per_s=4");
  EXPECT_EQ(parseClothModelSpecText(s.text()), s);
  EXPECT_THROW(parseClothModelSpecText(""), ClothModelError);
  EXPECT_THROW(parseClothModelSpecText("choi_ko bending_version"), ClothModelError);
  EXPECT_THROW(parseClothModelSpecText("choi_ko a=1 a=2"), ClothModelError);
  EXPECT_EQ(settlingModelSpec("particle_kes", 4.0).options,
            (std::map<std::string, std::string>{{"jacobian", "definite_fix"}, {"settle_damping_per_s", "4"}}));
  EXPECT_EQ(settlingModelSpec("choi_ko", 4.0).options, (std::map<std::string, std::string>{{"settle_damping_per_s", "4"}}));
}

TEST(ClothModelRegistryTest, FingerprintsRecordEveryOptionThatChangesAShape) {
  ClothModelRegistry& reg = ClothModelRegistry::instance();
  const ClothModelFingerprint p = reg.fingerprint(settlingModelSpec("particle_kes", 4.0));
  EXPECT_EQ(p.lines, (std::vector<std::string>{"jacobian: definite_fix", "forces: gravity drag shear bending"}));
  ASSERT_EQ(p.numbers.size(), 1u);
  EXPECT_EQ(p.numbers[0].first, "model_options.settle_damping_per_s");
  const ClothModelFingerprint a = reg.fingerprint(ClothModelSpec("choi_ko", {{"settle_damping_per_s", "4"}}));
  const ClothModelFingerprint b = reg.fingerprint(ClothModelSpec("choi_ko", {{"settle_damping_per_s", "0"}}));
  const ClothModelFingerprint c = reg.fingerprint(ClothModelSpec("choi_ko", {{"bending_version", "plate"}}));
  EXPECT_NE(a.numbers, b.numbers);
  EXPECT_NE(b.lines, c.lines);
  for (const auto& line : a.lines) EXPECT_EQ(line.find("jacobian: definite_fix"), std::string::npos);
}

}  // namespace
}  // namespace textile_handling
