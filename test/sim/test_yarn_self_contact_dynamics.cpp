// Dynamics of the yarn_woven model's penalty self-contact: a strip folded into a U whose two layers
// move towards each other stays two layers with self_contact on, and passes through itself with it off.
// docs/yarn_model.md, "Collisions".
#include "yarn_test_support.h"  // first: see there

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "../test_support.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {
namespace {

// A 14 x 3 mm strip of the default fabric (1 yarn/mm, gamma = 4R = 1 mm) along x, folded at flat x in
// [a, a + pi r] into a half circle of radius r: the lower layer at z = 0, the upper at z = 2r above it.
constexpr Real kLength = 0.014, kWidth = 0.003, kA = 0.0045, kR = 0.0012, kSpeed = 3;  // speed [m/s]

Vec3 folded(const Vec2& flat) {
  const Real s = flat.x();
  if (s <= kA) return Vec3(s, flat.y(), 0);
  const Real arc = kPi * kR;
  if (s <= kA + arc) {
    const Real th = (s - kA) / kR;
    return Vec3(kA + kR * std::sin(th), flat.y(), kR * (1 - std::cos(th)));
  }
  return Vec3(kA - (s - kA - arc), flat.y(), 2 * kR);
}

// The vertical velocity of the fold: +speed on the lower layer, -speed on the upper, cos(theta) between.
Real foldSpeed(const Vec2& flat) {
  const Real s = flat.x();
  if (s <= kA) return kSpeed;
  if (s >= kA + kPi * kR) return -kSpeed;
  return kSpeed * std::cos((s - kA) / kR);
}

struct FoldRun {
  Real min_gap = std::numeric_limits<Real>::infinity();  ///< over time, the smallest layer gap [m]
  Real final_gap = 0;
  bool diverged = false;
};

// The signed gap between the layers: over the upper layer's crossings, the smallest height above the
// nearest (in x, y) crossing of the lower layer (negative once the upper layer is below the lower).
Real layerGap(const YarnGrid& g, const VecX& x) {
  Real gap = std::numeric_limits<Real>::infinity();
  for (std::size_t i = 0; i < g.crossings.size(); ++i) {
    if (g.crossings[i].position.x() < kA + kPi * kR + 0.5e-3) continue;  // not on the upper layer
    const Vec3 xi = x.segment<3>(5 * static_cast<Eigen::Index>(i));
    Real best = std::numeric_limits<Real>::infinity(), dz = 0;
    for (std::size_t j = 0; j < g.crossings.size(); ++j) {
      if (g.crossings[j].position.x() > kA - 0.5e-3) continue;  // not on the lower layer
      const Vec3 xj = x.segment<3>(5 * static_cast<Eigen::Index>(j));
      const Real d = (xi - xj).head<2>().squaredNorm();
      if (d < best) best = d, dz = xi.z() - xj.z();
    }
    if (best < 0.6e-3 * 0.6e-3) gap = std::min(gap, dz);  // a partner close enough below
  }
  return gap;
}

FoldRun runFold(bool self_contact) {
  test_support::ThreadScope threads(1);
  YarnWovenOptions o;
  o.gravity = false;
  // Without Rayleigh damping, whose stiffness part (beta k_s / L) would stop the fold's collapse.
  o.fabric.damping_mass_per_s = o.fabric.damping_stiffness_s = 0;
  o.self_contact.enabled = self_contact;
  const std::vector<Vec2> strip = {Vec2(0, 0), Vec2(kLength, 0), Vec2(kLength, kWidth), Vec2(0, kWidth)};
  YarnWovenModel m(buildYarnSheet(layYarnGrid(strip, o.fabric)), o.fabric, o);
  const YarnGrid& g = m.sheet().grid;
  VecX x0 = VecX::Zero(m.numDofs()), v0 = VecX::Zero(m.numDofs());
  for (std::size_t k = 0; k < g.nodeCount(); ++k) {
    x0.segment<3>(5 * static_cast<Eigen::Index>(k)) = folded(g.nodePosition(k));
    v0[5 * static_cast<Eigen::Index>(k) + 2] = foldSpeed(g.nodePosition(k));
  }
  DrapeSimulation sim(m, PinnedNodes{}, yarn_test_support::fixedSteps(IntegratorType::kSemiImplicitEuler, 2e-5, 0.0016), x0,
                      v0);
  FoldRun r;
  r.min_gap = layerGap(g, x0);
  EXPECT_NEAR(r.min_gap, 2 * kR, 1e-9);
  for (int k = 1; k <= 8 && !r.diverged; ++k) {
    const RunResult run = sim.run(k * 2e-4);
    r.diverged = run.diverged;
    r.final_gap = layerGap(g, sim.state());
    r.min_gap = std::min(r.min_gap, r.final_gap);
  }
  return r;
}

TEST(YarnSelfContactDynamics, FoldedLayersMovingTogetherDoNotPassThroughEachOther) {
  const FoldRun on = runFold(true);
  EXPECT_FALSE(on.diverged);
  // The layers close at 3 m/s each and stop near gamma = 1 mm apart (the penalty's reach).
  EXPECT_GT(on.min_gap, 0.5e-3);
  EXPECT_GT(on.final_gap, 0.5e-3);
  const FoldRun off = runFold(false);
  EXPECT_FALSE(off.diverged);
  EXPECT_LT(off.min_gap, -1e-3);  // without self-contact the layers pass through each other
  std::printf("[          ] layer gap [mm]: self_contact on min %.3f final %.3f, off min %.3f final %.3f\n",
              1e3 * on.min_gap, 1e3 * on.final_gap, 1e3 * off.min_gap, 1e3 * off.final_gap);
}

}  // namespace
}  // namespace textile_handling
