// Yarn tearing in the yarn_woven model (tear_tension_n, docs/yarn_model.md "Tearing"): a strip pulled
// apart tears above and not below its peak tension and its halves separate; one tear per yarn and step
// at the bundle's threshold, cut ends held; forces, Jacobians and mass consistent with torn segments;
// save/resume bitwise with torn segments; the option validated.
#include "yarn_test_support.h"  // first: see there

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "../test_support.h"
#include "sim_test_support.h"
#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/stability_scenes.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {
namespace {

using sim_test_support::denseMatrix;
using test_support::ThreadScope;
using yarn_test_support::numericGradientN;
using yarn_test_support::numericJacobianN;

constexpr Real kStripLength = 0.01, kStripWidth = 0.003, kPull = 0.008, kPullTime = 0.1;
constexpr Real kDt = 1e-4, kEnd = 0.15;

// A weightless 10 x 3 mm strip of the default fabric (every yarn simulated, free yarn ends), the left
// ends of its three warps clamped, their right ends pinned and pulled 8 mm along +x in 0.1 s, then held.
struct PulledStrip {
  explicit PulledStrip(Real tear_tension_n) : model(makeModel(tear_tension_n)) {
    x0 = VecX::Zero(model.numDofs());
    for (Index i = 0; i < model.numNodes(); ++i) x0.segment<3>(5 * i) = model.sheet().rest.segment<3>(5 * i);
    std::vector<Index> left;
    std::vector<Vec3> anchors;
    for (const YarnPiece& p : model.sheet().grid.pieces) {
      if (!p.warp) continue;
      left.push_back(static_cast<Index>(p.nodes.front()));
      anchors.push_back(x0.segment<3>(5 * static_cast<Eigen::Index>(p.nodes.front())));
      pins.nodes.push_back(static_cast<Index>(p.nodes.back()));
      pins.anchors.push_back(x0.segment<3>(5 * static_cast<Eigen::Index>(p.nodes.back())));
    }
    pins.waypoint_times = {0, kPullTime};
    pins.waypoint_offsets = {Vec3::Zero(), Vec3(kPull, 0, 0)};
    // A clamp 100 times as stiff as a segment: it gives way by about 10 um at the peak tension.
    const Real clamp = 100 * model.fabric().stretchStiffness() / model.fabric().warpSpacing();
    clamped = std::make_unique<AnchoredClothModel>(model, left, anchors, clamp);
  }
  static YarnWovenModel makeModel(Real tear_tension_n) {
    YarnWovenOptions o;
    o.gravity = false;
    o.tear_tension_n = tear_tension_n;
    const std::vector<Vec2> strip = {Vec2(0, 0), Vec2(kStripLength, 0), Vec2(kStripLength, kStripWidth),
                                     Vec2(0, kStripWidth)};
    return YarnWovenModel(buildYarnSheet(layYarnGrid(strip, o.fabric)), o.fabric, o);
  }
  DrapeSimulation simulation() const {
    return DrapeSimulation(*clamped, pins, yarn_test_support::fixedSteps(IntegratorType::kSemiImplicitEuler, kDt, kEnd), x0,
                           VecX::Zero(x0.size()));
  }

  YarnWovenModel model;
  std::unique_ptr<AnchoredClothModel> clamped;
  PinnedNodes pins;
  VecX x0;
};

struct Pull {
  std::vector<Real> tension;  ///< largest tension of an intact segment after each step [N]
  long first_tear = 0;        ///< the step (1-based) after which a segment was first torn, 0 = none
  RunResult result;
  VecX x;  ///< the final state
};

// Runs the strip's pull step by step to kEnd.
Pull pull(PulledStrip& strip) {
  DrapeSimulation sim = strip.simulation();
  Pull p;
  const long steps = std::lround(kEnd / kDt);
  for (long k = 1; k <= steps && !p.result.diverged; ++k) {
    p.result = sim.run(static_cast<Real>(k) * kDt);
    p.tension.push_back(strip.model.maxSegmentTension(sim.state()));
    if (p.first_tear == 0 && strip.model.tornSegmentCount() > 0) p.first_tear = k;
  }
  p.x = sim.state();
  return p;
}

TEST(YarnWovenTearing, APulledStripTearsAboveAndNotBelowItsPeakTensionAndItsHalvesSeparate) {
  ThreadScope threads(1);
  PulledStrip untorn_strip(0);
  const Pull untorn = pull(untorn_strip);
  ASSERT_FALSE(untorn.result.diverged) << untorn.result.divergence_reason;
  ASSERT_EQ(untorn.tension.size(), static_cast<std::size_t>(std::lround(kEnd / kDt)));
  const Real peak = *std::max_element(untorn.tension.begin(), untorn.tension.end());
  // The warps end at 1.8 times their length: T = 0.8 k_s (observed peak 1.569 N, k_s = 1.963 N).
  const Real k_s = untorn_strip.model.fabric().stretchStiffness();
  EXPECT_NEAR(peak, 0.8 * k_s, 0.02 * k_s);
  EXPECT_EQ(untorn_strip.model.tornSegmentCount(), 0u);

  // A threshold above the peak: the same pull tears nothing and runs exactly the same steps.
  PulledStrip strong_strip(1.05 * peak);
  const Pull strong = pull(strong_strip);
  EXPECT_EQ(strong_strip.model.tornSegmentCount(), 0u);
  EXPECT_EQ(strong.result.torn_segments, 0);
  EXPECT_EQ(strong.x, untorn.x);

  // Half the peak: the first tear comes after the first step whose tension exceeds the threshold.
  const Real threshold = 0.5 * peak;
  PulledStrip weak_strip(threshold);
  const Pull weak = pull(weak_strip);
  ASSERT_FALSE(weak.result.diverged) << weak.result.divergence_reason;
  ASSERT_GT(weak.first_tear, 1);
  EXPECT_GT(untorn.tension[static_cast<std::size_t>(weak.first_tear - 1)], threshold);
  EXPECT_LE(untorn.tension[static_cast<std::size_t>(weak.first_tear - 2)], threshold);
  // Each warp broke once (observed: all three at their pinned end segment, after 0.051 s), and the
  // run reports it.
  const YarnWovenModel& m = weak_strip.model;
  EXPECT_EQ(m.tornSegmentCount(), 3u);
  EXPECT_EQ(weak.result.torn_segments, 3);
  // The halves separate: the pins went on pulling, so the two ends of each torn segment are now far
  // more than its length apart (observed 8.0 mm against 0.5 mm) ...
  for (const auto& nodes : m.tornSegmentNodes()) {
    const Real length = (m.sheet().rest.segment<3>(5 * nodes[0]) - m.sheet().rest.segment<3>(5 * nodes[1])).norm();
    const Real gap = (weak.x.segment<3>(5 * nodes[0]) - weak.x.segment<3>(5 * nodes[1])).norm();
    EXPECT_GT(gap, 10 * length);
  }
  // ... and nothing holds the clamped half any more: its tension decays (observed 0.11 N at 0.15 s).
  EXPECT_LT(weak.tension.back(), 0.3 * threshold);
}

// A weightless 8 x 6 mm patch of the default fabric in bundles of n = 2 yarns (2 mm spacing), free ends.
YarnWovenModel bundlePatch(Real tear_tension_n) {
  const WovenFabric real;
  const Real spacing = 0.002;
  YarnWovenOptions o;
  o.gravity = false;
  o.tear_tension_n = tear_tension_n;
  o.bundle_size = yarnBundleSize(real, spacing);
  o.fabric = yarnBundleFabric(real, spacing);
  const std::vector<Vec2> patch = {Vec2(0, 0), Vec2(0.008, 0), Vec2(0.008, 0.006), Vec2(0, 0.006)};
  return YarnWovenModel(buildYarnSheet(layYarnGrid(patch, o.fabric)), o.fabric, o);
}

// The patch's flat positions scaled by `factor` about the origin: every segment stretched alike.
VecX scaledRest(const YarnWovenModel& m, Real factor) {
  VecX x = VecX::Zero(m.numDofs());
  for (Index i = 0; i < m.numNodes(); ++i) x.segment<3>(5 * i) = factor * m.sheet().rest.segment<3>(5 * i);
  return x;
}

// The sliding DOF that a torn segment between `a` and `b` holds at node `a`: u for a warp (along x).
Index cutEnd(const YarnWovenModel& m, Index a, Index b) {
  const bool warp = m.sheet().rest[5 * a + 1] == m.sheet().rest[5 * b + 1];
  return 5 * a + (warp ? 3 : 4);
}

TEST(YarnWovenTearing, EachYarnTearsOnceAStepAboveItsBundlesThresholdAndItsCutEndsStop) {
  const Real n = 2;
  YarnWovenModel probe = bundlePatch(0);
  ASSERT_NEAR(probe.fabric().stretchStiffness(), n * WovenFabric().stretchStiffness(), 1e-12);
  const VecX stretched = scaledRest(probe, 1.1);
  const Real bundle_tension = probe.maxSegmentTension(stretched);
  EXPECT_NEAR(bundle_tension, 0.1 * probe.fabric().stretchStiffness(), 1e-9);
  const VecX moving = VecX::Ones(stretched.size());

  // A real yarn's threshold just above 1 / n of the bundle's tension: nothing tears.
  YarnWovenModel strong = bundlePatch(1.01 * bundle_tension / n);
  VecX v = moving;
  strong.acceptStep(stretched, v);
  EXPECT_EQ(strong.tornSegmentCount(), 0u);
  EXPECT_EQ(v, moving);

  // Just below: each yarn tears at one of its equally stretched segments, not at all of them.
  YarnWovenModel weak = bundlePatch(0.99 * bundle_tension / n);
  const std::size_t yarns = weak.sheet().grid.pieces.size();
  weak.acceptStep(stretched, v);
  ASSERT_EQ(weak.tornSegmentCount(), yarns);
  // The sheet's pieces are split there: two per yarn, one where the tear cut off an end node.
  std::size_t end_tears = 0;
  for (const auto& nodes : weak.tornSegmentNodes())
    for (const Index node : nodes) end_tears += weak.sheet().grid.isEnd(static_cast<std::size_t>(node)) ? 1 : 0;
  EXPECT_EQ(weak.sheet().grid.pieces.size(), 2 * yarns - end_tears);
  // Both cut ends of every torn segment are held and have stopped sliding; no other speed changed.
  std::set<Index> cut;
  for (const auto& nodes : weak.tornSegmentNodes())
    for (const Index end : {cutEnd(weak, nodes[0], nodes[1]), cutEnd(weak, nodes[1], nodes[0])}) {
      EXPECT_TRUE(weak.isHeld(end)) << end;
      EXPECT_EQ(v[end], 0) << end;
      cut.insert(end);
    }
  EXPECT_EQ(static_cast<std::size_t>((v.array() == 0).count()), cut.size());
  // Tearing is irreversible: back at rest nothing heals, and every force evaluation reports the count.
  VecX rest_v = VecX::Zero(v.size());
  weak.acceptStep(scaledRest(weak, 1.0), rest_v);
  EXPECT_EQ(weak.tornSegmentCount(), yarns);
  VecX f;
  EXPECT_EQ(weak.computeForces(scaledRest(weak, 1.0), rest_v, f, nullptr).torn_segments, static_cast<Index>(yarns));
  // The next step at the same stretch tears each remaining run of intact segments (each piece of the
  // split sheet) once more.
  const std::size_t runs = weak.sheet().grid.pieces.size();
  weak.acceptStep(stretched, v);
  EXPECT_EQ(weak.tornSegmentCount(), yarns + runs);
}

// The index of segment k of the (intact) piece of `warp` line `line`, in the model's segment order:
// pieces in sheet order, segments along each.
std::size_t segmentIndex(const YarnSheet& sheet, bool warp, std::size_t line, std::size_t k) {
  std::size_t first = 0;
  for (const YarnPiece& p : sheet.grid.pieces) {
    if (p.warp == warp && p.line == line) return first + k;
    first += p.nodes.size() - 1;
  }
  throw std::runtime_error("no such piece");
}

// A 5 x 4 mm patch at 1 yarn/mm with free ends, torn (through its internal state) at an interior warp
// segment, the weft segment beside it at the same crossing (whose two sliding DOFs are then both held),
// and a warp's end segment (whose end node is then loose).
YarnWovenModel tornPatch(const YarnWovenOptions& o) {
  const std::vector<Vec2> patch = {Vec2(0, 0), Vec2(0.005, 0), Vec2(0.005, 0.004), Vec2(0, 0.004)};
  YarnWovenModel m(buildYarnSheet(layYarnGrid(patch, o.fabric)), o.fabric, o);
  std::vector<std::size_t> torn = {segmentIndex(m.sheet(), true, 1, 2), segmentIndex(m.sheet(), false, 2, 2),
                                   segmentIndex(m.sheet(), true, 3, 0)};
  std::sort(torn.begin(), torn.end());
  std::vector<Real> state = m.internalState();
  for (std::size_t k : torn) state.push_back(static_cast<Real>(k));
  state.push_back(static_cast<Real>(torn.size()));
  if (!m.setInternalState(state)) throw std::runtime_error("torn state refused");
  return m;
}

// A state away from rest: positions moved by up to 80 um, free sliding DOFs by up to 60 um.
VecX perturbed(const YarnWovenModel& m, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<Real> u(-1, 1);
  VecX x = VecX::Zero(m.numDofs());
  for (Index i = 0; i < m.numNodes(); ++i) x.segment<3>(5 * i) = m.sheet().rest.segment<3>(5 * i);
  for (Index d = 0; d < x.size(); ++d)
    if (!m.isHeld(d)) x[d] += (d % 5 < 3 ? 8e-5 : 6e-5) * u(rng);
  return x;
}

TEST(YarnWovenTearing, ForcesAreMinusTheEnergyGradientWithTornSegments) {
  YarnWovenOptions o;  // with gravity: the torn segments' halves keep their weight
  o.fabric.damping_mass_per_s = o.fabric.damping_stiffness_s = o.fabric.sliding_friction = 0;
  YarnWovenModel m = tornPatch(o);
  ASSERT_EQ(m.tornSegmentCount(), 3u);
  const VecX x = perturbed(m, 3);
  VecX f;
  m.computeForces(x, VecX::Zero(x.size()), f, nullptr);
  const VecX fd = -numericGradientN<Eigen::Dynamic>([&](const VecX& y) { return m.potentialEnergy(y); }, x, 1e-8);
  Real worst = 0, scale = 0;
  for (Index d = 0; d < x.size(); ++d) {
    if (m.isHeld(d)) {
      EXPECT_EQ(f[d], 0) << "held DOF " << d;
      continue;
    }
    worst = std::max(worst, std::abs(fd[d] - f[d]));
    scale = std::max(scale, std::abs(f[d]));
  }
  EXPECT_GT(scale, 1e-3);
  EXPECT_LT(worst, 1e-6 * scale);
  // The end node cut off a warp is loose: lifting it costs only the weight of its half of the torn
  // segment.
  int loose = 0;
  for (const auto& nodes : m.tornSegmentNodes())
    for (const Index node : nodes) {
      if (!m.sheet().grid.isEnd(static_cast<std::size_t>(node))) continue;
      ++loose;
      const Real length = (m.sheet().rest.segment<3>(5 * nodes[0]) - m.sheet().rest.segment<3>(5 * nodes[1])).norm();
      const Real work = 0.5 * o.fabric.linear_density_kg_per_m * length * kGravity * 1e-3;
      VecX lifted = x;
      lifted[5 * node + 2] += 1e-3;
      EXPECT_NEAR(m.potentialEnergy(lifted) - m.potentialEnergy(x), work, 1e-6 * work);
    }
  EXPECT_EQ(loose, 1);
}

TEST(YarnWovenTearing, JacobiansMatchFiniteDifferencesWithTornSegments) {
  YarnWovenOptions o;
  o.exact_hessian = true;
  YarnWovenModel m = tornPatch(o);
  const VecX x = perturbed(m, 7), v = VecX::Zero(x.size());
  const Eigen::MatrixXd dfdx = yarn_test_support::expectJacobiansMatchFiniteDifferences(m, x, v, 1e-8, 1e-3, 1e-5, 1e-7).dfdx;
  EXPECT_LT((dfdx - dfdx.transpose()).cwiseAbs().maxCoeff(), 1e-9 * dfdx.cwiseAbs().maxCoeff());
}

TEST(YarnWovenTearing, TheMassStaysPositiveDefiniteWithLooseHalves) {
  const YarnWovenOptions o;
  YarnWovenModel m = tornPatch(o);
  const VecX x = perturbed(m, 5);
  const Eigen::MatrixXd M = yarn_test_support::expectSymmetricPositiveDefiniteMass(m, x);
  std::mt19937 rng(2);
  std::normal_distribution<Real> normal(0, 1);
  VecX v(x.size()), mv;
  for (Index d = 0; d < v.size(); ++d) v[d] = normal(rng);
  m.multiplyMass(x, v, mv);
  EXPECT_LT((mv - M * v).cwiseAbs().maxCoeff(), 1e-12 * (M * v).cwiseAbs().maxCoeff());
  // No material is lost: a uniform velocity carries the whole mass.
  VecX up = VecX::Zero(x.size());
  for (Index i = 0; i < m.numNodes(); ++i) up[5 * i + 2] = 1;
  EXPECT_NEAR(m.kineticEnergy(x, up), 0.5 * m.totalMass(), 1e-12 * m.totalMass());
  // The halves are loose: no mass couples the two nodes of a torn segment, and the end node cut off a
  // warp carries half of its end segment's mass, on its position alone.
  int loose = 0;
  for (const auto& nodes : m.tornSegmentNodes()) {
    EXPECT_EQ((M.block<3, 3>(5 * nodes[0], 5 * nodes[1]).cwiseAbs().maxCoeff()), 0);
    for (const Index node : nodes) {
      if (!m.sheet().grid.isEnd(static_cast<std::size_t>(node))) continue;
      ++loose;
      const Real length = (m.sheet().rest.segment<3>(5 * nodes[0]) - m.sheet().rest.segment<3>(5 * nodes[1])).norm();
      const Eigen::Matrix3d expected = 0.5 * o.fabric.linear_density_kg_per_m * length * Eigen::Matrix3d::Identity();
      EXPECT_LT((M.block<3, 3>(5 * node, 5 * node) - expected).cwiseAbs().maxCoeff(), 1e-15 * expected(0, 0));
    }
  }
  EXPECT_EQ(loose, 1);
}

TEST(YarnWovenTearing, SaveAndResumeWithTornSegmentsIsBitwise) {
  ThreadScope threads(1);
  const Real threshold = 0.8;  // tears after about 0.051 s of the pull (the peak is 1.57 N)
  PulledStrip whole_strip(threshold);
  DrapeSimulation whole = whole_strip.simulation();
  whole.run(kEnd);
  ASSERT_EQ(whole_strip.model.tornSegmentCount(), 3u);
  PulledStrip first_strip(threshold);
  DrapeSimulation first = first_strip.simulation();
  first.run(0.08);
  ASSERT_EQ(first_strip.model.tornSegmentCount(), 3u);
  const std::vector<Real> torn_state = first_strip.model.internalState();
  const std::string path = test_support::freshTempPath("yarn_woven_tearing", "state.txt");
  first.save(path);
  PulledStrip second_strip(threshold);
  DrapeSimulation second = second_strip.simulation();
  second.load(path);
  std::remove(path.c_str());
  EXPECT_EQ(second_strip.model.internalState(), torn_state);
  EXPECT_EQ(second_strip.model.sheet().held_dofs, first_strip.model.sheet().held_dofs);
  second.run(kEnd);
  EXPECT_EQ(second.state(), whole.state());
  EXPECT_EQ(second.velocities(), whole.velocities());

  // A state without torn segments (also any written before tearing existed) restores the laid sheet.
  YarnWovenModel& m = second_strip.model;
  PulledStrip fresh(threshold);
  ASSERT_TRUE(m.setInternalState(fresh.model.internalState()));
  EXPECT_EQ(m.tornSegmentCount(), 0u);
  EXPECT_EQ(m.sheet().held_dofs, fresh.model.sheet().held_dofs);
  EXPECT_EQ(m.sheet().grid.pieces.size(), fresh.model.sheet().grid.pieces.size());
  VecX f_restored, f_fresh;
  m.computeForces(whole.state(), whole.velocities(), f_restored, nullptr);
  fresh.model.computeForces(whole.state(), whole.velocities(), f_fresh, nullptr);
  EXPECT_EQ(f_restored, f_fresh);

  // Malformed torn lists are refused and change nothing.
  ASSERT_TRUE(m.setInternalState(torn_state));
  const std::size_t base = torn_state.size() - 4;  // three indices and their count
  auto refused = [&](std::size_t at, Real value) {
    std::vector<Real> bad = torn_state;
    bad[at] = value;
    const bool accepted = m.setInternalState(bad);
    EXPECT_EQ(m.internalState(), torn_state);
    return !accepted;
  };
  EXPECT_TRUE(refused(base + 3, 2));                     // count does not match the list
  EXPECT_TRUE(refused(base + 1, torn_state[base]));      // repeated index
  EXPECT_TRUE(refused(base, torn_state[base + 2] + 1));  // not ascending
  EXPECT_TRUE(refused(base + 2, 1e6));                   // no such segment
  EXPECT_TRUE(refused(base + 1, torn_state[base + 1] + 0.5));
  EXPECT_TRUE(refused(base + 2, std::nan("")));
  std::vector<Real> no_count(torn_state.begin(), torn_state.end() - 1);
  EXPECT_FALSE(m.setInternalState(no_count));
  EXPECT_EQ(m.internalState(), torn_state);
}

TEST(YarnWovenTearing, TheThresholdOptionIsValidated) {
  const ClothModelRegistry& r = ClothModelRegistry::instance();
  auto message = [&](const std::string& value) {
    try {
      r.validate(ClothModelSpec("yarn_woven", {{"tear_tension_n", value}}));
    } catch (const ClothModelError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message("3.5"), "accepted");
  EXPECT_EQ(message("0"), "accepted");
  EXPECT_NE(message("-1").find("'model.tear_tension_n' must be >= 0"), std::string::npos) << message("-1");
  EXPECT_NE(message("nan").find("'model.tear_tension_n' must be a finite number"), std::string::npos) << message("nan");
  EXPECT_NE(message("inf").find("'model.tear_tension_n'"), std::string::npos);
  // Part of a database build's parameters.
  const std::any parsed = r.parseOptions(ClothModelSpec("yarn_woven", {{"tear_tension_n", "3.5"}}));
  const ClothModelFingerprint fp = r.find("yarn_woven").fingerprint(parsed);
  const std::pair<std::string, double> number("model_options.tear_tension_n", 3.5);
  EXPECT_NE(std::find(fp.numbers.begin(), fp.numbers.end(), number), fp.numbers.end());
  // The C++ API refuses the same values, naming the option.
  for (const Real bad : {-1.0, std::nan("")}) {
    YarnWovenOptions o;
    o.tear_tension_n = bad;
    const std::vector<Vec2> square = {Vec2(0, 0), Vec2(0.003, 0), Vec2(0.003, 0.003), Vec2(0, 0.003)};
    try {
      YarnWovenModel m(buildYarnSheet(layYarnGrid(square, o.fabric)), o.fabric, o);
      ADD_FAILURE() << "accepted " << bad;
    } catch (const SimError& e) {
      EXPECT_NE(std::string(e.what()).find("tear_tension_n"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace textile_handling
