// Dynamics of the yarn_woven model on yarns with free ends (layYarnGrid): energy conservation without
// friction and damping, stick below and slip above the Coulomb limit of a pulled yarn, and a pinched
// hem crossing pulling its yarn through while its neighbours stay put. docs/yarn_model.md, "Tests".
#include "yarn_test_support.h"  // first: see there

#include <gtest/gtest.h>

#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "../test_support.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {
namespace {

using test_support::ThreadScope;

// The yarn_woven model plus constant external forces on chosen DOFs (a pull), everything else forwarded.
class PulledModel : public ClothModel {
 public:
  explicit PulledModel(YarnWovenModel& inner) : inner_(inner) {}
  std::vector<std::pair<Index, Real>> pulls;  ///< (DOF, force [N])
  /// Sliding DOFs held at 0 by a stiff spring (a gripper's jaws on the yarns), and its stiffness [N/m].
  std::vector<Index> gripped;
  Real grip_stiffness = 0;

  std::string name() const override { return inner_.name(); }
  Index numNodes() const override { return inner_.numNodes(); }
  int dofsPerNode() const override { return inner_.dofsPerNode(); }
  const BlockPattern& jacobianPattern() const override { return inner_.jacobianPattern(); }
  ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) override {
    const ForceReport r = inner_.computeForces(x, v, f, jac);
    for (const auto& [dof, force] : pulls) f[dof] += force;
    for (Index dof : gripped) {
      f[dof] -= grip_stiffness * x[dof];
      if (jac) jac->dfdx.block(jacobianPattern().diagonal(dof / 5))[(dof % 5) * 6] -= grip_stiffness;
    }
    return r;
  }
  // The pull is a constant force field, like gravity: its potential is part of both energies (the
  // simulation's energy check compares kinetic + gravitational energy with the initial total).
  Real potentialEnergy(const VecX& x) const override { return inner_.potentialEnergy(x) + pullEnergy(x); }
  Real maxEdgeStretch(const VecX& x) const override { return inner_.maxEdgeStretch(x); }
  void acceptStep(const VecX& x, VecX& v) override { inner_.acceptStep(x, v); }
  bool hasLumpedMass() const override { return false; }
  const VecX& massPerDof() const override { return inner_.massPerDof(); }
  void addMassMatrix(const VecX& x, Real scale, BlockSparseMatrix& a) const override { inner_.addMassMatrix(x, scale, a); }
  void multiplyMass(const VecX& x, const VecX& v, VecX& mv) const override { inner_.multiplyMass(x, v, mv); }
  Real gravitationalEnergy(const VecX& x) const override { return inner_.gravitationalEnergy(x) + pullEnergy(x); }
  Real totalMass() const override { return inner_.totalMass(); }

 private:
  Real pullEnergy(const VecX& x) const {
    Real e = 0;
    for (const auto& [dof, force] : pulls) e -= force * x[dof];
    for (Index dof : gripped) e += 0.5 * grip_stiffness * x[dof] * x[dof];
    return e;
  }
  YarnWovenModel& inner_;
};

// A 6 x 6 mm patch of the default fabric (1 yarn/mm, every yarn simulated) with free yarn ends, flat at
// z = 0.
YarnWovenModel patch(YarnWovenOptions o) {
  const std::vector<Vec2> square = {Vec2(0, 0), Vec2(0.006, 0), Vec2(0.006, 0.006), Vec2(0, 0.006)};
  return YarnWovenModel(buildYarnSheet(layYarnGrid(square, o.fabric)), o.fabric, o);
}

VecX restState(const YarnWovenModel& m) {
  VecX x = VecX::Zero(m.numDofs());
  for (Index i = 0; i < m.numNodes(); ++i) x.segment<3>(5 * i) = m.sheet().rest.segment<3>(5 * i);
  return x;
}

// The warp piece along the middle line and its end node at high x.
const YarnPiece& middleWarp(const YarnWovenModel& m) {
  for (const YarnPiece& p : m.sheet().grid.pieces)
    if (p.warp && p.line == 3) return p;
  throw std::runtime_error("no middle warp");
}

using yarn_test_support::fixedSteps;

TEST(YarnWovenDynamics, EnergyIsConservedWithoutFrictionAndDamping) {
  ThreadScope threads(1);
  YarnWovenOptions o;
  o.fabric.damping_mass_per_s = o.fabric.damping_stiffness_s = 0;
  o.crossing.friction = false;
  YarnWovenModel m = patch(o);
  // Hung by one corner crossing, released flat: it falls and swings, exchanging potential and kinetic
  // energy. The quadratic-velocity terms of M(q) are left out (docs/yarn_model.md), so the check is
  // how small the drift stays against the energy exchanged.
  const VecX x0 = restState(m);
  PinnedNodes pins;
  pins.nodes = {0};
  pins.anchors = {x0.segment<3>(0)};
  DrapeSimulation sim(m, pins, fixedSteps(IntegratorType::kRK4, 2e-6, 0.004), x0, VecX::Zero(x0.size()));
  const Real e0 = m.potentialEnergy(x0);
  sim.run();
  const VecX& x = sim.state();
  const Real kinetic = m.kineticEnergy(x, sim.velocities()), potential = m.potentialEnergy(x);
  ASSERT_GT(kinetic, 0.2 * (e0 - potential));  // it moved
  EXPECT_GT(e0 - potential, 1e-9);
  EXPECT_LT(std::abs(kinetic + potential - e0), 0.01 * (e0 - potential));
  // Each yarn's total rest length is constant while it slides.
  for (const YarnPiece& p : m.sheet().grid.pieces) {
    const Index a = static_cast<Index>(p.nodes.front()), b = static_cast<Index>(p.nodes.back());
    const int off = p.warp ? 3 : 4;
    const VecX q = m.kernelCoordinates(x);
    EXPECT_NEAR(q[5 * b + off] - q[5 * a + off], p.arc_length_m.back() - p.arc_length_m.front(), 1e-15);
  }
}

// A free, weightless patch whose middle warp is pulled at its free end along +x with `force` for 2 ms:
// the rest of the sheet can only follow through friction at the warp's crossings. Returns the largest
// slide |u - u_rest| along that warp; `threshold` gets the pull above which some crossing must slip.
Real pullMiddleWarp(Real force_per_threshold, Real* threshold) {
  YarnWovenOptions o;
  o.gravity = false;
  // Without Rayleigh damping (whose stiffness part, beta k_s / L, would slow any slide to micrometres
  // per millisecond): friction alone decides.
  o.fabric.damping_mass_per_s = o.fabric.damping_stiffness_s = 0;
  YarnWovenModel m = patch(o);
  const VecX x0 = restState(m);
  VecX f;
  m.computeForces(x0, VecX::Zero(x0.size()), f, nullptr);  // evaluates the lagged F_n at rest
  const YarnPiece& warp = middleWarp(m);
  // A rigid follow accelerates the whole sheet at a = F / M; crossing c then has to carry the mass
  // of the sheet outside the warp, shared by its crossings, so it sticks while a (M - m_warp) / n_c <=
  // mu F_n(c). The threshold is the smallest such F over the warp's crossings.
  std::size_t crossings = 0;
  Real weakest = std::numeric_limits<Real>::infinity();
  for (std::size_t node : warp.nodes)
    if (!m.sheet().grid.isEnd(node)) {
      ++crossings;
      weakest = std::min(weakest, o.fabric.sliding_friction * m.compression()[node]);
    }
  const Real warp_mass = o.fabric.linear_density_kg_per_m * (warp.arc_length_m.back() - warp.arc_length_m.front());
  *threshold = weakest * static_cast<Real>(crossings) * m.totalMass() / (m.totalMass() - warp_mass);
  PulledModel pulled(m);
  pulled.pulls = {{5 * static_cast<Index>(warp.nodes.back()), force_per_threshold * *threshold}};
  DrapeSimulation sim(pulled, PinnedNodes{}, fixedSteps(IntegratorType::kSemiImplicitEuler, 2e-5, 0.002), x0,
                      VecX::Zero(x0.size()));
  const RunResult r = sim.run();
  EXPECT_FALSE(r.diverged) << r.divergence_reason;
  Real slide = 0;
  for (std::size_t node : warp.nodes)
    if (!m.sheet().grid.isEnd(node)) slide = std::max(slide, std::abs(sim.state()[5 * static_cast<Eigen::Index>(node) + 3]));
  return slide;
}

TEST(YarnWovenDynamics, APulledYarnSticksBelowAndSlipsAboveTheCoulombLimit) {
  ThreadScope threads(1);
  Real threshold = 0;
  const Real below = pullMiddleWarp(0.5, &threshold);
  EXPECT_GT(threshold, 0);  // the flat weave is compressed (eq. 9)
  const Real above = pullMiddleWarp(2.0, &threshold);
  // Below: the sheet follows; the warp gives only its stick springs' stretch (a micrometre or less).
  EXPECT_LT(below, 1e-6);
  // Above: the yarn slides through its crossings, by far more.
  EXPECT_GT(above, 30 * below);
  EXPECT_GT(above, 1e-5);
}

TEST(YarnWovenDynamics, APinchedHemCrossingPullsItsYarnThroughWhileItsNeighboursStayPut) {
  ThreadScope threads(1);
  // A 10 x 10 mm patch held along its top row of crossings; the middle crossing of the bottom (hem)
  // row is pinched (its yarns gripped) and pulled down, out of the sheet along its weft, with five
  // times the Coulomb limits of that weft's crossings.
  YarnWovenOptions o;
  o.gravity = false;
  const std::vector<Vec2> square = {Vec2(0, 0), Vec2(0.01, 0), Vec2(0.01, 0.01), Vec2(0, 0.01)};
  YarnWovenModel m(buildYarnSheet(layYarnGrid(square, o.fabric)), o.fabric, o);
  const VecX x0 = restState(m);
  VecX f;
  m.computeForces(x0, VecX::Zero(x0.size()), f, nullptr);
  const YarnGrid& g = m.sheet().grid;
  std::size_t hem = 0;
  PinnedNodes pins;
  for (std::size_t c = 0; c < g.crossings.size(); ++c)
    if (g.crossings[c].warp == 0 && g.crossings[c].weft == 5) hem = c;
  // Held by the free ends of its warps (material ends: the wefts still slide through every crossing).
  for (const YarnPiece& p : g.pieces)
    if (p.warp)
      for (std::size_t node : {p.nodes.front(), p.nodes.back()})
        if (g.isEnd(node)) {
          pins.nodes.push_back(static_cast<Index>(node));
          pins.anchors.push_back(x0.segment<3>(5 * static_cast<Eigen::Index>(node)));
        }
  Real limit = 0;
  for (std::size_t c = 0; c < g.crossings.size(); ++c)
    if (g.crossings[c].weft == 5) limit += o.fabric.sliding_friction * m.compression()[c];
  PulledModel pulled(m);
  pulled.pulls = {{5 * static_cast<Index>(hem) + 1, -5 * limit}};
  pulled.gripped = {5 * static_cast<Index>(hem) + 4};
  pulled.grip_stiffness = 100 * m.fabric().stretchStiffness() / m.fabric().weftSpacing();
  DrapeSimulation sim(pulled, pins, fixedSteps(IntegratorType::kSemiImplicitEuler, 1e-3, 1.0), x0, VecX::Zero(x0.size()));
  const RunResult r = sim.run();
  ASSERT_FALSE(r.diverged) << r.divergence_reason;
  const VecX& x = sim.state();
  // The pinched crossing came down and its weft slid through the crossings above it (by 40 um in 1 s,
  // observed; the Rayleigh damping's stiffness part makes sliding slow); the neighbouring wefts did not
  // slide above the two hem rows (next to the pinch they slide by about a third of the pulled weft,
  // observed), and no crossing of theirs moved as far as the pinched one (the sheet sags as a whole).
  const Real hem_dy = x[5 * static_cast<Eigen::Index>(hem) + 1] - x0[5 * static_cast<Eigen::Index>(hem) + 1];
  EXPECT_LT(hem_dy, -3e-4);
  Real weft_slide = 0, neighbour_slide = 0, neighbour_move = 0;
  for (std::size_t c = 0; c < g.crossings.size(); ++c) {
    const Eigen::Index k = 5 * static_cast<Eigen::Index>(c);
    if (g.crossings[c].weft == 5 && c != hem) weft_slide = std::max(weft_slide, std::abs(x[k + 4]));
    if (g.crossings[c].weft == 4 || g.crossings[c].weft == 6) {
      if (g.crossings[c].warp >= 2) neighbour_slide = std::max(neighbour_slide, std::abs(x[k + 4]));
      neighbour_move = std::max(neighbour_move, (x.segment<3>(k) - x0.segment<3>(k)).norm());
    }
  }
  EXPECT_GT(weft_slide, 2e-5);
  EXPECT_LT(neighbour_slide, 0.05 * weft_slide);
  EXPECT_LT(neighbour_move, std::abs(hem_dy));
}

}  // namespace
}  // namespace textile_handling
