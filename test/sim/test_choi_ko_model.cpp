// Tests of the Choi–Ko cloth model (textile_handling/sim/choi_ko_model.h, choi_ko_kernels.h) and of
// the compression scenes (stability_scenes.h).
//
//  * kernels: the sinc inversion against the table of the notes (shared/reference/
//    choi-ko-buckling-hysteresis.md section 7), the limits of g and g', the linear-segment table,
//    derivatives of every scalar law against central differences, the pair kernels' forces against
//    their energies and their Jacobians against their forces;
//  * hysteresis: the discrete model driven through the notes' test vector (slopes of every branch,
//    unloading segments twice as long), the continuous model's curvature rates (K on loading, K/2 on
//    unloading), Masing memory, and the continuous model against a discrete one with many units;
//  * the model: flat sheet, forces against the finite-difference gradient of potentialEnergy() and
//    the exact Jacobian against finite differences of the forces on random tension-active and
//    compressed configurations, the assembled default Jacobian symmetric negative semi-definite,
//    thread-count independence, masses, the KES mapping, the bend sign, internalState round trips;
//  * stability: Choi–Ko without damping at 10 and 20 ms in both compression scenes.
//  * rest: the bench's towel (d = 2 cm, corner) settles to a true equilibrium (residual force check);
//    the 8 s-cap target is a disabled test (docs/choi_ko.md, "Reaching rest").
//
// Finite differences are central with h = 1e-7 m (d = 1 cm). Tolerances: forces within 1e-6 of the
// largest force (+1e-12 N); Jacobian blocks within 1e-5 of their norm plus 1e-7 of the largest block
// (the same scheme as test_particle_model.cpp). Configurations with a term within 1e-4 L of a kink
// of its law (r = L, s = s*, s = s_lo) are redrawn, so the differences never straddle a kink.

// GCC 12 reports a -Wmaybe-uninitialized false positive inside Eigen's SelfAdjointEigenSolver.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include "../test_support.h"
#include "textile_handling/sim/particle_cloth_model.h"
#include "textile_handling/sim/choi_ko_model.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/bench/stability_scan.h"
#include "textile_handling/sim/textile_geometry.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace textile_handling {
namespace {

using test_support::ThreadScope;

using namespace choi_ko;

// ---- kernels ----------------------------------------------------------------------------------------

// Notes section 7: s, theta, kappa L, g, g' (python3, bisection + Newton, residuals <= 1.1e-16).
struct TableRow {
  Real s, theta, kappa_l, g, dg;
};
const TableRow kNotesTable[] = {
    {0.999, 0.0774712903, 0.1549425806, -12.007205, 7.209885},
    {0.99, 0.2453178089, 0.4906356177, -12.072497, 7.299823},
    {0.95, 0.5519109786, 1.1038219572, -12.372806, 7.721847},
    {0.9, 0.7866830720, 1.5733661441, -12.773224, 8.306097},
    {0.75, 1.2756981093, 2.5513962186, -14.177052, 10.553382},
    {0.5, 1.8954942670, 3.7909885341, -17.547251, 17.280966},
    {0.25, 2.4745767874, 4.9491535747, -23.650478, 34.752692},
    {0.1, 2.8523418945, 5.7046837889, -30.746068, 64.816172},
    {0.0, kPi, 2 * kPi, -4 * kPi * kPi, 12 * kPi * kPi},
};

TEST(ChoiKoKernels, SincInversionMatchesNotesTable) {
  for (const TableRow& row : kNotesTable) {
    const Real theta = inverseSinc(row.s);
    EXPECT_NEAR(theta, row.theta, 1e-9) << "s = " << row.s;
    const Real kappa_l = 2 * theta;  // L = 1
    EXPECT_NEAR(kappa_l, row.kappa_l, 2e-9) << "s = " << row.s;
    const BucklingShape b = bucklingShape(1 - row.s);
    EXPECT_NEAR(b.g, row.g, 1e-6 * std::abs(row.g)) << "s = " << row.s;
    EXPECT_NEAR(b.dg, row.dg, 1e-6 * std::abs(row.dg)) << "s = " << row.s;
    // sinc of the result gives s back.
    EXPECT_NEAR(sinc(theta), row.s, 1e-14) << "s = " << row.s;
  }
}

TEST(ChoiKoKernels, SincInversionRoundTripAndLimits) {
  std::mt19937_64 gen(7);
  std::uniform_real_distribution<Real> u(0, 1);
  for (int k = 0; k < 2000; ++k) {
    const Real theta = kPi * u(gen);
    // Round trip through the chord deficit keeps relative accuracy down to tiny angles.
    const Real t2 = theta * std::pow(10.0, -6 * u(gen));
    const Real back = halfAngleFromChordDeficit(oneMinusSinc(t2));
    EXPECT_NEAR(back, t2, 1e-12 * t2 + 1e-300) << "theta = " << t2;
  }
  EXPECT_EQ(halfAngleFromChordDeficit(0.0), 0.0);
  EXPECT_EQ(halfAngleFromChordDeficit(-1.0), 0.0);
  EXPECT_EQ(halfAngleFromChordDeficit(1.0), kPi);
  EXPECT_EQ(inverseSinc(1.5), 0.0);
  // Limits of the notes (section 2.6): g(1-) = -12, g'(1-) = 7.2, g(0) = -4 pi^2, g'(0) = 12 pi^2.
  const BucklingShape near1 = bucklingShape(1e-14);
  EXPECT_NEAR(near1.g, -12.0, 1e-9);
  EXPECT_NEAR(near1.dg, 7.2, 1e-9);
  const BucklingShape at0 = bucklingShape(1.0);
  EXPECT_NEAR(at0.g, -4 * kPi * kPi, 1e-9);
  EXPECT_NEAR(at0.dg, 12 * kPi * kPi, 1e-8);
  // Near s = 1: theta^2 ~ 6 u + 1.8 u^2 and g ~ -12 (1 + theta^2 / 10).
  for (Real uu : {1e-6, 1e-4, 1e-3}) {
    const BucklingShape b = bucklingShape(uu);
    EXPECT_NEAR(b.theta * b.theta, 6 * uu + 1.8 * uu * uu, 1e-2 * uu * uu + 1e-15);
    EXPECT_NEAR(b.g, -12 * (1 + b.theta * b.theta / 10), 1e-3 * b.theta * b.theta);
  }
  // The series (theta < 1) and the direct formulas (theta >= 1) join continuously.
  const Real u1 = oneMinusSinc(1.0);
  const BucklingShape lo = bucklingShape(u1 * (1 - 1e-12)), hi = bucklingShape(u1 * (1 + 1e-12));
  EXPECT_NEAR(lo.g, hi.g, 1e-9);
  EXPECT_NEAR(lo.dg, hi.dg, 1e-9);
  EXPECT_NEAR(lo.k2, hi.k2, 1e-8);
  EXPECT_NEAR(bucklingD(0.999999), std::cos(0.999999) - std::sin(0.999999) / 0.999999, 1e-15);
}

TEST(ChoiKoKernels, ShapeDerivativesMatchFiniteDifferences) {
  // g = 4 theta^2 / D as a function of s; k1 = L^2 dkappa/dr and k2 = L^3 d2kappa/dr2 with L = 1.
  for (Real s = 0.02; s < 0.9995; s += 0.0371) {
    const Real h = 1e-6;
    const BucklingShape b = bucklingShape(1 - s);
    const BucklingShape bp = bucklingShape(1 - (s + h)), bm = bucklingShape(1 - (s - h));
    EXPECT_NEAR(b.dg, (bp.g - bm.g) / (2 * h), 1e-6 * std::abs(b.dg)) << "s = " << s;
    const Real kappa_p = 2 * bp.theta, kappa_m = 2 * bm.theta;
    EXPECT_NEAR(b.k1, (kappa_p - kappa_m) / (2 * h), 1e-6 * std::abs(b.k1)) << "s = " << s;
    EXPECT_NEAR(b.k2, (bp.k1 - bm.k1) / (2 * h), 2e-6 * std::abs(b.k2)) << "s = " << s;
    // The buckling force is the derivative of the bending energy 2 theta^2 (units F0 L).
    EXPECT_NEAR(b.g, (2 * bp.theta * bp.theta - 2 * bm.theta * bm.theta) / (2 * h), 1e-6 * std::abs(b.g));
  }
}

TEST(ChoiKoKernels, LinearSegmentCrossingsMatchNotesTable) {
  // Notes section 7: gamma -> range of s where the buckling curve is used.
  struct Row {
    Real gamma, s_hi, s_lo;
  };
  const Row rows[] = {{35, 0.497, 0.078}, {40, 0.600, 0}, {60, 0.767, 0},   {100, 0.870, 0},
                      {300, 0.959, 0},    {1000, 0.988, 0}, {1e4, 0.9988, 0}};
  for (const Row& row : rows) {
    // Upper crossing by bisection on |g(s)| / (1 - s) = gamma (increasing near s = 1).
    Real lo = 0.3, hi = 1 - 1e-12;
    for (int it = 0; it < 200; ++it) {
      const Real mid = 0.5 * (lo + hi);
      if (-bucklingShape(1 - mid).g / (1 - mid) > row.gamma) hi = mid; else lo = mid;
    }
    const BucklingLaw law = makeBucklingLaw(0.5 * (lo + hi));
    EXPECT_NEAR(law.gamma, row.gamma, 1e-6 * row.gamma);
    EXPECT_NEAR(law.onset, row.s_hi, 1.5e-3) << "gamma " << row.gamma;
    EXPECT_NEAR(law.s_lo, row.s_lo, 1.5e-3) << "gamma " << row.gamma;
    // f* is continuous at the crossings.
    for (Real s : {law.onset, law.s_lo}) {
      if (s <= 0) continue;
      const BucklingResponse a = bucklingResponse(1 - s + 1e-10, law), b = bucklingResponse(1 - s - 1e-10, law);
      EXPECT_NEAR(a.f, b.f, 1e-6 * std::abs(a.f));
    }
  }
  EXPECT_THROW(makeBucklingLaw(1.0), std::invalid_argument);
  EXPECT_THROW(makeBucklingLaw(0.0), std::invalid_argument);
}

TEST(ChoiKoKernels, BucklingLawEnergyDerivativeIsForce) {
  for (Real onset : {0.5, 0.9, 0.999}) {  // 0.5: gamma < 4 pi^2, so the segment returns below s_lo
    const BucklingLaw law = makeBucklingLaw(onset);
    for (Real s = 0.013; s < 0.99999; s += 0.00731) {
      if (std::abs(s - law.onset) < 1e-5 || std::abs(s - law.s_lo) < 1e-5) continue;
      const Real h = 1e-7;
      const BucklingResponse r = bucklingResponse(1 - s, law);
      const BucklingResponse p = bucklingResponse(1 - (s + h), law), m = bucklingResponse(1 - (s - h), law);
      EXPECT_NEAR(r.f, (p.e - m.e) / (2 * h), 1e-6 * std::abs(r.f) + 1e-9) << "onset " << onset << " s " << s;
      EXPECT_NEAR(r.df, (p.f - m.f) / (2 * h), 1e-5 * std::abs(r.df) + 1e-6) << "onset " << onset << " s " << s;
      EXPECT_LT(r.f, 0);
      EXPECT_GT(r.df, 0);
      // f* = max(g, gamma (s - 1)).
      EXPECT_NEAR(r.f, std::max(bucklingShape(1 - s).g, law.gamma * (s - 1)), 1e-12 * std::abs(r.f));
    }
    const BucklingResponse none = bucklingResponse(0.0, law);
    EXPECT_EQ(none.f, 0);
    EXPECT_EQ(none.e, 0);
  }
}

Vec3 randomVec(std::mt19937_64& gen, Real amp) {
  std::uniform_real_distribution<Real> u(-amp, amp);
  return Vec3(u(gen), u(gen), u(gen));
}

// Checks one pair kernel: force = dE/dr along the unit, Jacobian = d f_i / d x_j by differences.
void checkPairKernel(const std::function<bool(const Vec3&, const Vec3&, PairTermResult*)>& kernel,
                     const Vec3& xi, const Vec3& xj, bool check_energy, const std::string& what) {
  PairTermResult r;
  ASSERT_TRUE(kernel(xi, xj, &r)) << what;
  const Real h = 1e-9;
  const Vec3 fi = r.f * r.unit;
  Mat3 jac_fd;
  for (int k = 0; k < 3; ++k) {
    Vec3 e = Vec3::Zero();
    e[k] = h;
    PairTermResult p, m;
    ASSERT_TRUE(kernel(xi, xj + e, &p));
    ASSERT_TRUE(kernel(xi, xj - e, &m));
    jac_fd.col(k) = (p.f * p.unit - m.f * m.unit) / (2 * h);
    if (check_energy) {
      PairTermResult pi, mi;
      ASSERT_TRUE(kernel(xi + e, xj, &pi));
      ASSERT_TRUE(kernel(xi - e, xj, &mi));
      EXPECT_NEAR(fi[k], -(pi.energy - mi.energy) / (2 * h), 1e-6 * fi.norm() + 1e-12) << what;
    }
  }
  EXPECT_LE((jac_fd - r.jac).norm(), 1e-5 * r.jac.norm() + 1e-9) << what << "\nJ =\n" << r.jac << "\nFD =\n" << jac_fd;
}

TEST(ChoiKoKernels, TensionOnlySpringForcesAndJacobians) {
  std::mt19937_64 gen(11);
  const Real rest = 0.01, k = 120;
  int stretched = 0, compressed = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 xi = randomVec(gen, 0.05);
    const Vec3 dir = randomVec(gen, 1).normalized();
    const Real r = rest * (0.5 + std::uniform_real_distribution<Real>(0, 1)(gen));
    if (std::abs(r - rest) < 1e-5 * rest) continue;
    const Vec3 xj = xi + r * dir;
    auto kernel = [&](const Vec3& a, const Vec3& b, PairTermResult* o) { return tensionOnlySpring(a, b, rest, k, true, o); };
    checkPairKernel(kernel, xi, xj, true, "spring");
    PairTermResult res;
    tensionOnlySpring(xi, xj, rest, k, true, &res);
    if (r < rest) {
      ++compressed;
      EXPECT_FALSE(res.active);
      EXPECT_EQ(res.f, 0);
      EXPECT_EQ(res.jac.norm(), 0);
    } else {
      ++stretched;
      EXPECT_NEAR(res.f, k * (r - rest), 1e-12);
      const Eigen::SelfAdjointEigenSolver<Mat3> es(res.jac);
      EXPECT_GE(es.eigenvalues().minCoeff(), -1e-12);  // positive semi-definite in tension
    }
  }
  EXPECT_GT(stretched, 50);
  EXPECT_GT(compressed, 50);
  PairTermResult res;
  EXPECT_FALSE(tensionOnlySpring(Vec3::Zero(), Vec3::Zero(), rest, k, true, &res));
  EXPECT_FALSE(tensionOnlySpring(Vec3::Zero(), Vec3(NAN, 0, 0), rest, k, true, &res));
}

TEST(ChoiKoKernels, BucklingUnitForcesAndJacobians) {
  std::mt19937_64 gen(12);
  const Real rest = 0.02, f0 = 3e-4;
  for (Real onset : {0.6, 0.999}) {
    const BucklingLaw law = makeBucklingLaw(onset);
    int on_curve = 0, on_segment = 0;
    for (int trial = 0; trial < 300; ++trial) {
      const Vec3 xi = randomVec(gen, 0.05);
      const Vec3 dir = randomVec(gen, 1).normalized();
      // Half uniform in s, half log-uniform in the deficit 1 - s in [1e-5, 1e-1] (near the onset).
      std::uniform_real_distribution<Real> unit01(0, 1);
      const Real s = trial % 2 ? unit01(gen) : 1 - std::pow(10.0, -1 - 4 * unit01(gen));
      if (std::abs(s - law.onset) < 1e-4 || std::abs(s - 1) < 1e-4 || s < 0.02) continue;
      const Vec3 xj = xi + s * rest * dir;
      auto exact = [&](const Vec3& a, const Vec3& b, PairTermResult* o) {
        return bucklingUnit(a, b, rest, f0, law, true, BendingJacobian::kExact, o);
      };
      checkPairKernel(exact, xi, xj, true, "buckling unit, onset " + std::to_string(onset));
      PairTermResult full, dropped, secant;
      bucklingUnit(xi, xj, rest, f0, law, true, BendingJacobian::kExact, &full);
      bucklingUnit(xi, xj, rest, f0, law, true, BendingJacobian::kDropNegative, &dropped);
      bucklingUnit(xi, xj, rest, f0, law, true, BendingJacobian::kSecant, &secant);
      EXPECT_LT(full.f, 0);  // compression resistance: pushes i away from j
      // The seed's Jacobian is the exact one minus the negative transverse term (f/r)(I - u u^T).
      const Mat3 uu = full.unit * full.unit.transpose();
      EXPECT_LE((full.jac - dropped.jac - (full.f / full.r) * (Mat3::Identity() - uu)).norm(), 1e-12 * full.jac.norm());
      // Along the unit, it is exact: u^T J u = d f / d r.
      EXPECT_NEAR(full.unit.dot(dropped.jac * full.unit), full.unit.dot(full.jac * full.unit), 1e-12 * full.jac.norm());
      // Secant: slope max(df, |f| / (L - r)) along u, so the linearised force vanishes at r = L.
      const Real secant_slope = full.unit.dot(secant.jac * full.unit);
      EXPECT_GE(secant_slope, full.unit.dot(dropped.jac * full.unit) * (1 - 1e-12));
      EXPECT_GE(secant_slope * (rest - full.r), -full.f * (1 - 1e-12));
      const BucklingResponse br = bucklingResponse(1 - s, law);
      (br.on_curve ? on_curve : on_segment)++;
    }
    EXPECT_GT(on_curve, 20);
    EXPECT_GT(on_segment, 5);
  }
  // Not compressed: no force at all.
  PairTermResult res;
  ASSERT_TRUE(bucklingUnit(Vec3::Zero(), Vec3(0.021, 0, 0), 0.02, 1.0, makeBucklingLaw(0.99), true,
                           BendingJacobian::kExact, &res));
  EXPECT_FALSE(res.active);
  EXPECT_EQ(res.f, 0);
  EXPECT_EQ(res.energy, 0);
}

TEST(ChoiKoKernels, HystereticBendingReducesToLinearLawAndDifferentiates) {
  const Real rest = 0.02, b = 2e-5;
  const BucklingLaw law = makeBucklingLaw(0.999);
  // M = B X: the hysteretic force equals the linear law's (with the same clamp).
  for (Real s = 0.05; s < 0.9999; s += 0.0123) {
    const BucklingShape shape = bucklingShape(1 - s);
    for (Real sign : {-1.0, 1.0}) {
      const Real x = sign * 2 * shape.theta / rest;
      const HystereticBendingScalar h = hystereticBending(shape, 1 - s, sign, b * x, b, rest, b, law);
      const BucklingResponse lin = bucklingResponse(1 - s, law);
      EXPECT_NEAR(h.f, lin.f, 1e-9 * std::abs(lin.f)) << s;
      EXPECT_NEAR(h.df, lin.df, 1e-7 * std::abs(lin.df)) << s;
    }
  }
  // A continuous hysteresis unit with a committed history: d f / d s by differences at fixed state,
  // wherever the clamp is not active.
  HysteresisUnit unit(HysteresisSpec::continuous(0.5 * b, 0.5 * b, 5.0, 60.0));
  for (Real x : {10.0, 80.0, 30.0, 45.0}) unit.drive(x);
  int checked = 0;
  for (Real s = 0.3; s < 0.999; s += 0.0173) {
    auto eval = [&](Real ss) {
      const BucklingShape shape = bucklingShape(1 - ss);
      const Real x = 2 * shape.theta / rest;
      Real t = 0;
      const Real m = unit.moment(x, &t);
      return hystereticBending(shape, 1 - ss, 1.0, m, t, rest, b, law);
    };
    const HystereticBendingScalar c = eval(s);
    const Real h = 1e-7;
    const HystereticBendingScalar p = eval(s + h), m = eval(s - h);
    if (c.clamped || p.clamped || m.clamped) continue;
    // Skip the kinks of the moment curve (x_a, x_b, reversal points) inside the difference interval.
    const Real xs = 2 * bucklingShape(1 - s).theta / rest;
    bool kink = false;
    for (Real k : {5.0, 60.0, 45.0, 30.0, 80.0, 2.5, 30.0 + 10.0, 45.0 - 10.0})
      if (std::abs(xs - k) < 0.05) kink = true;
    if (kink) continue;
    EXPECT_NEAR(c.df, (p.f - m.f) / (2 * h), 1e-5 * std::abs(c.df) + 1e-5) << "s = " << s;
    ++checked;
  }
  EXPECT_GT(checked, 10);
}

// ---- hysteresis ---------------------------------------------------------------------------------------

// Drives a unit along a path in small committed steps and returns (X, M) samples.
std::vector<std::array<Real, 2>> drivePath(HysteresisUnit& unit, Real from, Real to, Real step) {
  std::vector<std::array<Real, 2>> out;
  const int n = static_cast<int>(std::round(std::abs(to - from) / step));
  for (int k = 0; k <= n; ++k) {
    const Real x = from + (to - from) * k / n;
    out.push_back({x, unit.drive(x)});
  }
  return out;
}

// Breakpoints of a piecewise-linear sampled curve and the slopes of its pieces. Runs of equal
// slopes form the pieces; the single interval that straddles a kink (intermediate slope) is dropped
// and the breakpoint is put at its middle, so breakpoints are accurate to half a sample step.
void segments(const std::vector<std::array<Real, 2>>& pts, std::vector<Real>* breaks, std::vector<Real>* slopes) {
  struct Run {
    Real slope, x0, x1;
    int count;
  };
  std::vector<Run> runs;
  for (size_t k = 1; k < pts.size(); ++k) {
    const Real slope = (pts[k][1] - pts[k - 1][1]) / (pts[k][0] - pts[k - 1][0]);
    if (!runs.empty() && std::abs(slope - runs.back().slope) <= 1e-6 * std::abs(runs.back().slope) + 1e-9) {
      runs.back().x1 = pts[k][0];
      ++runs.back().count;
    } else {
      runs.push_back({slope, pts[k - 1][0], pts[k][0], 1});
    }
  }
  std::vector<Run> kept;
  for (const Run& r : runs)
    if (r.count > 2) kept.push_back(r);
  for (size_t i = 0; i < kept.size(); ++i) {
    slopes->push_back(kept[i].slope);
    if (i > 0) breaks->push_back(0.5 * (kept[i - 1].x1 + kept[i].x0));
  }
}

TEST(ChoiKoHysteresis, DiscreteModelFollowsNotesTestVector) {
  // Notes section 4.3: K0 = K1 = K2 = K3 = 1, sigma = (1, 2, 3).
  HysteresisUnit unit(HysteresisSpec::discrete({1, 1, 1, 1}, {1, 2, 3}));
  const Real loading[] = {0, 4, 7, 9, 10};  // at X = 0..4
  for (int x = 0; x <= 4; ++x) EXPECT_NEAR(unit.drive(x), loading[x], 1e-12) << "X = " << x;
  const Real unloading[] = {6, 2, -1, -4, -6, -8, -9, -10};  // at X = 3..-4
  for (int k = 0; k < 8; ++k) EXPECT_NEAR(unit.drive(3 - k), unloading[k], 1e-12) << "X = " << 3 - k;
}

TEST(ChoiKoHysteresis, DiscreteBranchSlopesAndTwiceLongUnloadingSegments) {
  // Four branches with distinct constants so every slope is identifiable: K = (0.5, 3, 2, 1), sigma
  // chosen for yield curvatures sigma_i / K_i = 0.4, 1.0, 1.7.
  const std::vector<Real> k = {0.5, 3, 2, 1};
  const std::vector<Real> sigma = {0.4 * 3, 1.0 * 2, 1.7 * 1};
  HysteresisUnit unit(HysteresisSpec::discrete(k, sigma));
  const Real top = 2.5, step = 1e-3;
  std::vector<Real> lb, ls, ub, us;
  segments(drivePath(unit, 0, top, step), &lb, &ls);
  segments(drivePath(unit, top, -top, step), &ub, &us);
  // Loading slopes: K0+K1+K2+K3, K0+K2+K3, K0+K3, K0 (seed, Fig. 10).
  const std::vector<Real> expect_slopes = {k[0] + k[1] + k[2] + k[3], k[0] + k[2] + k[3], k[0] + k[3], k[0]};
  ASSERT_EQ(ls.size(), 4u);
  ASSERT_EQ(us.size(), 4u);
  ASSERT_EQ(lb.size(), 3u);
  ASSERT_EQ(ub.size(), 3u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(ls[i], expect_slopes[i], 1e-9);
    EXPECT_NEAR(us[i], expect_slopes[i], 1e-9);  // unloading segments parallel to the loading ones
  }
  // Segment lengths: loading from 0, unloading from the top; unloading ones are twice as long.
  const Real load_len[3] = {lb[0], lb[1] - lb[0], lb[2] - lb[1]};
  const Real unload_len[3] = {top - ub[0], ub[0] - ub[1], ub[1] - ub[2]};
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(load_len[i], sigma[i] / k[i + 1] - (i ? sigma[i - 1] / k[i] : 0), 2 * step);
    EXPECT_NEAR(unload_len[i], 2 * load_len[i], 4 * step) << "segment " << i;
  }
}

TEST(ChoiKoHysteresis, ContinuousModelCurvatureRates) {
  const Real k0 = 0.2, ks = 1.5, xa = 0.5, xb = 2.0;
  const Real K = ks / (xb - xa);
  HysteresisUnit unit(HysteresisSpec::continuous(k0, ks, xa, xb));
  const Real top = 3.0, step = 1e-3;
  const auto load = drivePath(unit, 0, top, step);
  const auto unload = drivePath(unit, top, -top, step);
  auto second = [](const std::vector<std::array<Real, 2>>& p, size_t k) {
    const Real h = p[k + 1][0] - p[k][0];
    return (p[k + 1][1] - 2 * p[k][1] + p[k - 1][1]) / (h * h);
  };
  auto slope = [](const std::vector<std::array<Real, 2>>& p, size_t k) {
    return (p[k + 1][1] - p[k][1]) / (p[k + 1][0] - p[k][0]);
  };
  for (size_t k = 1; k + 1 < load.size(); ++k) {
    const Real x = load[k][0];
    if (std::abs(x - xa) < 2 * step || std::abs(x - xb) < 2 * step) continue;
    if (x < xa) {
      EXPECT_NEAR(slope(load, k), k0 + ks, 1e-9);
    }
    if (x > xa && x < xb) { // |F''| = K on loading
      EXPECT_NEAR(second(load, k), -K, 1e-6 * K);
    }
    if (x > xb) {
      EXPECT_NEAR(slope(load, k), k0, 1e-9);
    }
  }
  // Unloading from top: elastic for 2 x_a, then |F''| = K/2 for 2 (x_b - x_a), then slope k0.
  for (size_t k = 1; k + 1 < unload.size(); ++k) {
    const Real travel = top - unload[k][0];
    if (std::abs(travel - 2 * xa) < 2 * step || std::abs(travel - 2 * xb) < 2 * step) continue;
    if (travel < 2 * xa) {
      EXPECT_NEAR(slope(unload, k), k0 + ks, 1e-9);
    }
    if (travel > 2 * xa && travel < 2 * xb) {
      EXPECT_NEAR(second(unload, k), 0.5 * K, 1e-6 * K);
    }
    if (travel > 2 * xb) {
      EXPECT_NEAR(slope(unload, k), k0, 1e-9);
    }
  }
  // At -top the unloading curve meets the (odd) virgin curve.
  EXPECT_NEAR(unload.back()[1], -load.back()[1], 1e-9);
}

TEST(ChoiKoHysteresis, MasingMemoryClosesInnerLoops) {
  for (const HysteresisSpec& spec :
       {HysteresisSpec::continuous(0.3, 1.0, 0.2, 1.5), HysteresisSpec::discrete({0.3, 0.4, 0.3, 0.3}, {0.08, 0.3, 0.45})}) {
    HysteresisUnit a(spec), b(spec);
    a.drive(1.0);
    a.drive(0.4);  // inner loop
    a.drive(0.7);
    a.drive(1.0);  // closes it
    const Real ma = a.drive(1.3);
    b.drive(1.0);
    const Real mb = b.drive(1.3);
    EXPECT_NEAR(ma, mb, 1e-12);
    EXPECT_NEAR(mb, spec.virginMoment(1.3), 1e-12);
  }
  // The trial moment does not change the state.
  HysteresisUnit u(HysteresisSpec::continuous(0.3, 1.0, 0.2, 1.5));
  u.drive(1.0);
  const HysteresisState before = u.state();
  Real t1 = 0;
  u.moment(-0.5, &t1);
  u.moment(2.0);
  EXPECT_EQ(u.state().x, before.x);
  EXPECT_EQ(u.state().reversals.size(), before.reversals.size());
}

TEST(ChoiKoHysteresis, ContinuousModelIsTheLimitOfTheDiscreteModel) {
  // n slip units with equal springs k_sum / n and yield curvatures at the midpoints of n equal
  // sub-intervals of [x_a, x_b] approach the continuous model with error O(k_sum (x_b - x_a) / n).
  const Real k0 = 0.25, ks = 1.2, xa = 0.3, xb = 1.8;
  const int n = 2000;
  std::vector<Real> k(n + 1, ks / n), sigma(n);
  k[0] = k0;
  for (int i = 0; i < n; ++i) sigma[i] = (ks / n) * (xa + (xb - xa) * (i + 0.5) / n);
  HysteresisUnit disc(HysteresisSpec::discrete(k, sigma)), cont(HysteresisSpec::continuous(k0, ks, xa, xb));
  std::mt19937_64 gen(5);
  std::uniform_real_distribution<Real> u(-2.5, 2.5);
  Real worst = 0;
  for (int step = 0; step < 300; ++step) {
    // Random walk with occasional large jumps (several loops closed in one step).
    const Real x = step % 17 == 0 ? u(gen) : std::clamp(cont.state().x + 0.3 * u(gen), -2.5, 2.5);
    Real td = 0, tc = 0;
    const Real trial_d = disc.moment(x, &td), trial_c = cont.moment(x, &tc);
    worst = std::max(worst, std::abs(trial_d - trial_c));
    EXPECT_NEAR(disc.drive(x), cont.drive(x), 2 * ks * (xb - xa) / n);
    EXPECT_NEAR(trial_d, trial_c, 2 * ks * (xb - xa) / n);
  }
  EXPECT_LT(worst, 2 * ks * (xb - xa) / n);
}

TEST(ChoiKoHysteresis, SpecValidation) {
  std::string err;
  EXPECT_TRUE(HysteresisSpec::none().valid(&err));
  EXPECT_FALSE(HysteresisSpec::discrete({1, 1}, {}).valid(&err));
  EXPECT_FALSE(HysteresisSpec::discrete({1, 1}, {1, 2}).valid(&err));
  EXPECT_FALSE(HysteresisSpec::discrete({1, 0}, {1}).valid(&err));
  EXPECT_FALSE(HysteresisSpec::continuous(1, 1, 2, 1).valid(&err));
  EXPECT_FALSE(HysteresisSpec::continuous(1, 0, 0, 1).valid(&err));
  EXPECT_TRUE(HysteresisSpec::continuous(1, 1, 0, 1).valid(&err)) << err;
  const HysteresisSpec kes = HysteresisSpec::continuousFromKes(2e-5, 1e-3, 10, 40);
  EXPECT_NEAR(kes.k0, 2e-5, 1e-20);
  // Beyond x_b every unit slides: the loop's moment width there is 2HB.
  // Loading beyond x_b: M = k0 X + HB; unloading after a reversal travel beyond 2 x_b: k0 X - HB.
  EXPECT_NEAR(kes.virginMoment(100) - 100 * kes.k0, 0.5e-3, 1e-15);
  HysteresisUnit u(kes);
  u.drive(100);
  u.drive(99);
  const Real x = 100 - 2 * 40 - 1e-6;
  EXPECT_NEAR(u.drive(x), kes.k0 * x - 0.5e-3, 1e-15);
  EXPECT_THROW(HysteresisUnit(HysteresisSpec::discrete({1}, {1})), std::invalid_argument);
}

// ---- the model ----------------------------------------------------------------------------------------

TextileOutline rectangle(Real w, Real h) {
  TextileOutline t;
  t.name = "rect";
  t.outline = {Vec2(0, 0), Vec2(w, 0), Vec2(w, h), Vec2(0, h)};
  return t;
}

ParticleTopology topologyOf(const TextileOutline& outline, Real spacing) {
  std::string err;
  const ParticleGrid grid = ParticleGrid::rasterize(outline, spacing, &err);
  EXPECT_FALSE(grid.empty()) << err;
  return ParticleTopology::fromGrid(grid);
}

VecX flatState(const ParticleTopology& topo, Real z0 = 0) {
  VecX x(3 * topo.size());
  for (Index r = 0; r < topo.size(); ++r)
    node3(x, r) = Vec3(topo.grid[r][1] * topo.spacing, topo.grid[r][0] * topo.spacing, z0);
  return x;
}

// Flat sheet scaled in-plane by (sx, sy), plus noise (in units of d): in-plane and out-of-plane.
VecX scaledNoisyState(const ParticleTopology& topo, Real sx, Real sy, Real in_plane, Real out_of_plane,
                      std::mt19937_64& gen) {
  std::uniform_real_distribution<Real> u(-1, 1);
  const Real d = topo.spacing;
  VecX x = flatState(topo, 0.3);
  for (Index r = 0; r < topo.size(); ++r) {
    x[3 * r] = sx * x[3 * r] + in_plane * d * u(gen);
    x[3 * r + 1] = sy * x[3 * r + 1] + in_plane * d * u(gen);
    x[3 * r + 2] += out_of_plane * d * u(gen);
  }
  return x;
}

// True when no term of the model is within `margin` (relative) of a kink of its law.
bool awayFromKinks(const ChoiKoClothModel& m, const VecX& x, Real margin) {
  for (const auto& s : m.springs()) {
    const Real r = (node3(x, s.j) - node3(x, s.i)).norm();
    if (std::abs(r - s.rest) < margin * s.rest) return false;
  }
  const BucklingLaw& law = m.parameters().law;
  for (const auto& b : m.bendingUnits()) {
    const Real s = (node3(x, b.j) - node3(x, b.i)).norm() / b.rest;
    if (std::abs(s - 1) < margin || std::abs(s - law.onset) < margin || (law.s_lo > 0 && std::abs(s - law.s_lo) < margin))
      return false;
  }
  return true;
}

Eigen::MatrixXd dense(const BlockSparseMatrix& a) {
  const BlockPattern& p = a.pattern();
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(3 * p.numNodes(), 3 * p.numNodes());
  for (Index i = 0; i < p.numNodes(); ++i)
    for (Index s = p.rowStart()[i]; s < p.rowStart()[i + 1]; ++s) {
      const Index j = p.column()[s];
      m.block<3, 3>(3 * i, 3 * j) = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(a.block(s));
    }
  return m;
}

struct ModelCase {
  std::string name;
  ChoiKoOptions options;
};

std::vector<ModelCase> modelCases() {
  std::vector<ModelCase> cases;
  for (ChoiKoBending version : {ChoiKoBending::kBeam, ChoiKoBending::kPlate}) {
    const std::string v = toString(version);
    ChoiKoOptions all;
    all.bending_version = version;
    all.drag = true;
    cases.push_back({v + "/all", all});
    ChoiKoOptions springs = all;
    springs.bending = false;
    springs.gravity = false;
    springs.drag = false;
    cases.push_back({v + "/springs", springs});
    ChoiKoOptions bending = all;
    bending.stretch = bending.shear = false;
    bending.gravity = false;
    bending.drag = false;
    cases.push_back({v + "/bending", bending});
    ChoiKoOptions segment = bending;  // a longer linear segment: more units on it
    segment.buckling_onset = 0.9;
    cases.push_back({v + "/bending_onset_0.9", segment});
  }
  return cases;
}

VecX forcesAt(ClothModel& m, const VecX& x, const VecX& v) {
  VecX f;
  m.computeForces(x, v, f, nullptr);
  return f;
}

// Forces against -grad E and (with the exact bending Jacobian) df/dx, df/dv against differences.
void checkModelDerivatives(const ModelCase& mc, const VecX& x, const VecX& v, const std::string& config) {
  const ParticleTopology topo = topologyOf(rectangle(0.07, 0.05), 0.01);
  ChoiKoOptions opt = mc.options;
  opt.bending_jacobian = BendingJacobian::kExact;
  auto model = std::make_unique<ChoiKoClothModel>(topo, Material::cotton(), opt);
  ForceJacobians jac = model->makeJacobians();
  VecX f;
  const ForceReport rep = model->computeForces(x, v, f, &jac);
  EXPECT_EQ(rep.degenerate_terms, 0);
  const std::string what = mc.name + " / " + config;
  const Real h = 1e-7;
  const Real fmax = f.cwiseAbs().maxCoeff();
  // Forces vs energy: only when nothing depends on velocity.
  if (!opt.drag) {
    for (Index k = 0; k < x.size(); ++k) {
      VecX xp = x, xm = x;
      xp[k] += h;
      xm[k] -= h;
      const Real grad = (model->potentialEnergy(xp) - model->potentialEnergy(xm)) / (2 * h);
      ASSERT_NEAR(f[k], -grad, 1e-6 * fmax + 1e-12) << what << " DOF " << k;
    }
  }
  // Jacobians.
  const Eigen::MatrixXd K = dense(jac.dfdx), D = dense(jac.dfdv);
  Eigen::MatrixXd Kfd(x.size(), x.size()), Dfd(x.size(), x.size());
  for (Index k = 0; k < x.size(); ++k) {
    VecX xp = x, xm = x, vp = v, vm = v;
    xp[k] += h;
    xm[k] -= h;
    Kfd.col(k) = (forcesAt(*model, xp, v) - forcesAt(*model, xm, v)) / (2 * h);
    const Real hv = 1e-6;
    vp[k] += hv;
    vm[k] -= hv;
    Dfd.col(k) = (forcesAt(*model, x, vp) - forcesAt(*model, x, vm)) / (2 * hv);
  }
  const Index n = topo.size();
  for (const auto& pair : {std::make_pair(&K, &Kfd), std::make_pair(&D, &Dfd)}) {
    Real bmax = 0;
    for (Index i = 0; i < n; ++i)
      for (Index j = 0; j < n; ++j) bmax = std::max(bmax, pair.first->block<3, 3>(3 * i, 3 * j).norm());
    for (Index i = 0; i < n; ++i)
      for (Index j = 0; j < n; ++j) {
        const Eigen::Matrix3d a = pair.first->block<3, 3>(3 * i, 3 * j), b = pair.second->block<3, 3>(3 * i, 3 * j);
        ASSERT_LE((a - b).norm(), 1e-5 * a.norm() + 1e-7 * bmax + 1e-12)
            << what << (pair.first == &K ? " dfdx" : " dfdv") << " block (" << i << "," << j << ")\nJ=\n" << a << "\nFD=\n" << b;
      }
  }
}

TEST(ChoiKoModel, ForcesAndExactJacobiansMatchFiniteDifferences) {
  ThreadScope threads(1);
  const ParticleTopology topo = topologyOf(rectangle(0.07, 0.05), 0.01);
  std::mt19937_64 gen(21);
  std::uniform_real_distribution<Real> u(-1, 1);
  for (const ModelCase& mc : modelCases()) {
    ChoiKoOptions o = mc.options;
    const ChoiKoClothModel probe(topo, Material::cotton(), o);
    for (int config = 0; config < 2; ++config) {
      // config 0: stretched (tension-active); config 1: compressed and wrinkled (buckling units on
      // the curve and on the linear segment).
      VecX x;
      for (int attempt = 0; attempt < 200; ++attempt) {
        x = config == 0 ? scaledNoisyState(topo, 1.04, 1.03, 0.05, 0.2, gen)
                        : scaledNoisyState(topo, 0.85, 0.9, 0.05, 0.5, gen);
        if (awayFromKinks(probe, x, 1e-4)) break;
      }
      ASSERT_TRUE(awayFromKinks(probe, x, 1e-4));
      // The configuration really exercises what it is meant to.
      int active_springs = 0, compressed_units = 0;
      for (const auto& s : probe.springs()) active_springs += (node3(x, s.j) - node3(x, s.i)).norm() >= s.rest;
      for (const auto& b : probe.bendingUnits()) compressed_units += (node3(x, b.j) - node3(x, b.i)).norm() < b.rest;
      if (config == 0 && !probe.springs().empty()) {
        EXPECT_GT(active_springs, static_cast<int>(probe.springs().size()) / 2);
      }
      if (config == 1 && !probe.bendingUnits().empty()) {
        EXPECT_GT(compressed_units, static_cast<int>(probe.bendingUnits().size()) / 2);
      }
      VecX v(x.size());
      for (Index k = 0; k < v.size(); ++k) v[k] = 0.5 * u(gen);
      checkModelDerivatives(mc, x, v, config == 0 ? "stretched" : "compressed");
    }
  }
}

TEST(ChoiKoModel, DefaultJacobianIsSymmetricNegativeSemidefinite) {
  ThreadScope threads(1);
  const ParticleTopology topo = topologyOf(rectangle(0.07, 0.05), 0.01);
  std::mt19937_64 gen(22);
  for (ChoiKoBending version : {ChoiKoBending::kBeam, ChoiKoBending::kPlate}) {
    for (BendingJacobian mode : {BendingJacobian::kSecant, BendingJacobian::kDropNegative, BendingJacobian::kExact}) {
      ChoiKoOptions o;
      o.bending_version = version;
      o.bending_jacobian = mode;
      auto model = std::make_unique<ChoiKoClothModel>(topo, Material::cotton(), o);
      ForceJacobians jac = model->makeJacobians();
      Real worst_positive = -1e300;
      for (int config = 0; config < 4; ++config) {
        const VecX x = config % 2 ? scaledNoisyState(topo, 0.8, 0.85, 0.05, 0.5, gen)
                                  : scaledNoisyState(topo, 1.02, 0.97, 0.1, 0.3, gen);
        VecX f;
        model->computeForces(x, VecX::Zero(x.size()), f, &jac);
        const Eigen::MatrixXd K = dense(jac.dfdx);
        const Real scale = K.norm();
        EXPECT_LE((K - K.transpose()).norm(), 1e-13 * scale);
        const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (K + K.transpose()));
        worst_positive = std::max(worst_positive, es.eigenvalues().maxCoeff() / scale);
      }
      if (mode == BendingJacobian::kExact) {
        // The exact Jacobian of compressed units is indefinite: the reason the term is dropped.
        EXPECT_GT(worst_positive, 1e-10) << toString(version);
      } else {
        EXPECT_LE(worst_positive, 1e-12) << toString(version) << " " << toString(mode);
      }
    }
  }
}

TEST(ChoiKoModel, FlatSheetIsFiniteAndForceFree) {
  ThreadScope threads(2);
  const ParticleTopology topo = topologyOf(rectangle(0.3, 0.2), 0.01);
  for (ChoiKoBending version : {ChoiKoBending::kBeam, ChoiKoBending::kPlate}) {
    for (bool hysteresis : {false, true}) {
      ChoiKoOptions o;
      o.bending_version = version;
      if (hysteresis) o.hysteresis = HysteresisSpec::continuous(1e-5, 2e-5, 5, 50);
      auto model = std::make_unique<ChoiKoClothModel>(topo, Material::cotton(), o);
      const VecX x = flatState(topo, 1.0);
      ForceJacobians jac = model->makeJacobians();
      VecX f;
      const ForceReport rep = model->computeForces(x, VecX::Zero(x.size()), f, &jac);
      EXPECT_EQ(rep.degenerate_terms, 0);
      ASSERT_TRUE(f.allFinite());
      for (const Real& val : jac.dfdx.values()) ASSERT_TRUE(std::isfinite(val));
      for (const Real& val : jac.dfdv.values()) ASSERT_TRUE(std::isfinite(val));
      // Only gravity acts on the flat sheet at rest length.
      for (Index r = 0; r < topo.size(); ++r) {
        // (springs at r = L up to rounding: k * 1e-16 m)
        EXPECT_NEAR(f[3 * r], 0, 1e-12);
        EXPECT_NEAR(f[3 * r + 1], 0, 1e-12);
        EXPECT_NEAR(f[3 * r + 2], -model->massPerDof()[3 * r] * kGravity, 1e-12);
      }
      Real mgz = 0;
      for (Index r = 0; r < topo.size(); ++r) mgz += model->massPerDof()[3 * r] * kGravity * x[3 * r + 2];
      EXPECT_NEAR(model->potentialEnergy(x), mgz, 1e-14 * std::abs(mgz));
      VecX at_rest = VecX::Zero(x.size());
      model->acceptStep(x, at_rest);
      EXPECT_TRUE(std::isfinite(model->maxEdgeStretch(x)));
      EXPECT_NEAR(model->maxEdgeStretch(x), 1.0, 1e-12);
    }
  }
}

TEST(ChoiKoModel, ResultsDoNotDependOnThreadCount) {
  const ParticleTopology topo = topologyOf(rectangle(0.3, 0.2), 0.01);
  std::mt19937_64 gen(23);
  const VecX x = scaledNoisyState(topo, 0.9, 0.95, 0.05, 0.3, gen);
  VecX v = VecX::Random(x.size());
  ChoiKoOptions o;
  o.hysteresis = HysteresisSpec::discrete({1e-5, 1e-5, 1e-5}, {2e-4, 5e-4});
  auto model = std::make_unique<ChoiKoClothModel>(topo, Material::cotton(), o);
  ForceJacobians j1 = model->makeJacobians(), j2 = model->makeJacobians();
  VecX f1, f2;
  {
    ThreadScope t(1);
    model->computeForces(x, v, f1, &j1);
  }
  {
    ThreadScope t(2);
    model->computeForces(x, v, f2, &j2);
  }
  EXPECT_EQ((f1 - f2).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(j1.dfdx.values(), j2.dfdx.values());
  EXPECT_EQ(j1.dfdv.values(), j2.dfdv.values());
}

TEST(ChoiKoModel, MassesAndDragMatchTheParticleModel) {
  const ParticleTopology topo = topologyOf(rectangle(0.2, 0.13), 0.01);
  const Material cotton = Material::cotton();
  auto ck = std::make_unique<ChoiKoClothModel>(topo, cotton);
  auto pm = std::make_unique<ParticleClothModel>(topo, cotton);
  EXPECT_EQ(ck->massPerDof(), pm->massPerDof());
  EXPECT_NEAR(ck->massPerDof().sum() / 3, cotton.areal_density * 0.2 * 0.13, 1e-12);
  EXPECT_EQ(ck->name(), "choi_ko");
  EXPECT_EQ(ck->numNodes(), topo.size());
  // Drag only (springs and bending see a flat sheet): the same quadratic drag as the particle model.
  ChoiKoOptions o;
  o.gravity = false;
  ParticleModelOptions po;
  po.gravity = false;
  auto ck2 = std::make_unique<ChoiKoClothModel>(topo, cotton, o);
  auto pm2 = std::make_unique<ParticleClothModel>(topo, cotton, po);
  const VecX x = flatState(topo);
  const VecX v = VecX::Random(x.size());
  EXPECT_LE((forcesAt(*ck2, x, v) - forcesAt(*pm2, x, v)).cwiseAbs().maxCoeff(), 1e-12);
  // settle damping is a mass-proportional force.
  o.settle_damping = 3.0;
  auto ck3 = std::make_unique<ChoiKoClothModel>(topo, cotton, o);
  const VecX diff = forcesAt(*ck3, x, v) - forcesAt(*ck2, x, v);
  EXPECT_LE((diff + 3.0 * ck3->massPerDof().cwiseProduct(v)).cwiseAbs().maxCoeff(), 1e-12);
  o.settle_damping = -1;
  EXPECT_THROW(ChoiKoClothModel(topo, cotton, o), std::invalid_argument);
}

TEST(ChoiKoModel, ParametersFromKesData) {
  // A linear-elastic material: both slope rules give back the inputs.
  const Material lin = Material::linearElastic("lin", 0.2, 0.8, 3e-5, 5e7);
  for (KesSlopeRule rule : {KesSlopeRule::kKesStandard, KesSlopeRule::kInitial}) {
    ChoiKoOptions o;
    o.slope_rule = rule;
    const ChoiKoParameters p = choiKoParameters(lin, o);
    EXPECT_NEAR(p.bending_rigidity[0], 3e-5, 1e-15);
    EXPECT_NEAR(p.bending_rigidity[1], 3e-5, 1e-15);
    EXPECT_NEAR(p.shear_stiffness, 0.8, 1e-12);
    EXPECT_NEAR(p.diagonal_spring, 1.6, 1e-12);
    EXPECT_NEAR(p.tensile_stiffness, 5e7 * 1e-6, 1e-9);  // secant of the quintic law at 1 %
    EXPECT_EQ(p.areal_density, 0.2);
  }
  // Cotton: the KES-standard B is the mean slope over 0.5..1.5 1/cm, so it lies between the curve's
  // slopes at the ends of that range; the initial rule gives the slope at 0.
  const Material cotton = Material::cotton();
  ChoiKoOptions o;
  const ChoiKoParameters kes = choiKoParameters(cotton, o);
  for (int dir = 0; dir < 2; ++dir) {
    const Real a = cotton.bendSlopeSI(dir, 50), b = cotton.bendSlopeSI(dir, 150 - 1e-9);
    EXPECT_GE(kes.bending_rigidity[dir], std::min(a, b) * (1 - 1e-12));
    EXPECT_LE(kes.bending_rigidity[dir], std::max(a, b) * (1 + 1e-12));
  }
  o.slope_rule = KesSlopeRule::kInitial;
  const ChoiKoParameters init = choiKoParameters(cotton, o);
  EXPECT_NEAR(init.bending_rigidity[0], cotton.bendSlopeSI(0, 0), 1e-15);
  EXPECT_NEAR(init.shear_stiffness, 0.5 * (cotton.shearSlopeSI(0, 0) + cotton.shearSlopeSI(1, 0)), 1e-12);
  // Explicit values win.
  o.tensile_stiffness = 250;
  o.bending_rigidity_warp = 1e-5;
  const ChoiKoParameters given = choiKoParameters(cotton, o);
  EXPECT_EQ(given.tensile_stiffness, 250);
  EXPECT_EQ(given.bending_rigidity[0], 1e-5);
  EXPECT_EQ(toString(ChoiKoBending::kPlate), "plate");
  EXPECT_EQ(choiKoBendingFromString("beam"), ChoiKoBending::kBeam);
  EXPECT_THROW(choiKoBendingFromString("shell"), std::invalid_argument);
  EXPECT_EQ(kesSlopeRuleFromString("initial"), KesSlopeRule::kInitial);
  EXPECT_EQ(bendingJacobianFromString("secant"), BendingJacobian::kSecant);
  EXPECT_THROW(bendingJacobianFromString("full"), std::invalid_argument);
}

// A sheet rolled isometrically onto a cylinder of radius R about the y axis has curvature 1/R along x.
VecX rolledState(const ParticleTopology& topo, Real radius) {
  VecX x(3 * topo.size());
  for (Index r = 0; r < topo.size(); ++r) {
    const Real X = topo.grid[r][1] * topo.spacing, Y = topo.grid[r][0] * topo.spacing;
    node3(x, r) = Vec3(radius * std::sin(X / radius), Y, radius * (1 - std::cos(X / radius)));
  }
  return x;
}

TEST(ChoiKoModel, CylindricalBendingEnergyMatchesTheRigidity) {
  // Continuum: E = 1/2 B kappa^2 per area. The onset is put very close to 1 so that the energy the
  // linear segment leaves out (about 6 (1 - s*) F0 L per unit) is negligible.
  //  * beam version: a warp beam spans an exact circular arc of length 2d on the cylinder, so every
  //    warp beam has kappa = 1/R; the beams cover the sheet but for half a cell at each end of a
  //    row: E = 1/2 B kappa^2 A (n - 1)/n for n cells along x;
  //  * plate version: hinge families (1,1), (2,-1), (-1,2) see the normal curvatures cos^2(alpha)/R
  //    with cos^2 = 1/2, 4/5, 1/5; with the 1/0.93 calibration and only interior hinges present,
  //    E = 1/2 B kappa^2 d^2 (n_11/4 + n_21 16/25 + n_12/25) / 0.93 (to O(theta^2)).
  const Real d = 0.01;
  const int nx = 30, ny = 20;
  const ParticleTopology topo = topologyOf(rectangle(nx * d, ny * d), d);
  ChoiKoOptions o;
  o.gravity = false;
  o.stretch = o.shear = false;
  o.buckling_onset = 1 - 1e-9;
  const Real area = nx * ny * d * d;
  {
    const Real radius = 6 * d;
    auto beam = std::make_unique<ChoiKoClothModel>(topo, Material::cotton(), o);
    const Real b = beam->parameters().bending_rigidity[0];
    const Real expect = 0.5 * b * area * (nx - 1.0) / nx / (radius * radius);
    EXPECT_NEAR(beam->potentialEnergy(rolledState(topo, radius)), expect, 1e-6 * expect);
  }
  {
    const Real radius = 12 * d;
    o.bending_version = ChoiKoBending::kPlate;
    auto plate = std::make_unique<ChoiKoClothModel>(topo, Material::cotton(), o);
    const Real b = 0.5 * (plate->parameters().bending_rigidity[0] + plate->parameters().bending_rigidity[1]);
    const Real census = nx * ny / 4.0 + (nx - 1.0) * ny * 16.0 / 25.0 + nx * (ny - 1.0) / 25.0;
    const Real expect = 0.5 * b * d * d * census / 0.93 / (radius * radius);
    EXPECT_EQ(plate->bendingUnits().size(), static_cast<size_t>(nx * ny + (nx - 1) * ny + nx * (ny - 1)));
    EXPECT_NEAR(plate->potentialEnergy(rolledState(topo, radius)), expect, 3e-3 * expect);
    // ... which is within a few percent of the continuum value.
    EXPECT_NEAR(expect / (0.5 * b * area / (radius * radius)), 1.0, 0.05);
  }
}

TEST(ChoiKoModel, AnOnsetCurvatureKeepsGentleBendsOnTheBucklingCurveAtFineSpacings) {
  // A sheet rolled to kappa = 20 1/m (0.2 1/cm, a drape's gentle bend) at d = 2 mm. With the default chord
  // onset s* = 0.999 the beams reach the buckling curve only above kappa* = 0.155 / d = 77 1/m, and below
  // it the linear segment stores energy growing like kappa^4: far less than 1/2 B kappa^2. An onset
  // curvature of 5 1/m puts the onset below the bend: the energy is the rigidity's but for the part the
  // segment leaves out, (kappa* / kappa)^2 / 2 = 3 %.
  const Real d = 0.002, kappa = 20;
  const int nx = 30, ny = 10;
  const ParticleTopology topo = topologyOf(rectangle(nx * d, ny * d), d);
  ChoiKoOptions o;
  o.gravity = false;
  o.stretch = o.shear = false;
  const Real area = nx * ny * d * d;
  auto energyRatio = [&](const ChoiKoOptions& options) {
    ChoiKoClothModel m(topo, Material::cotton(), options);
    const Real expect = 0.5 * m.parameters().bending_rigidity[0] * area * (nx - 1.0) / nx * kappa * kappa;
    return m.potentialEnergy(rolledState(topo, 1 / kappa)) / expect;
  };
  const Real fixed = energyRatio(o);
  o.buckling_onset_curvature = 5;
  const Real by_curvature = energyRatio(o);
  EXPECT_LT(fixed, 0.2) << "default onset";
  EXPECT_NEAR(by_curvature, 1 - 0.5 * (5.0 / 20) * (5.0 / 20), 0.02) << "onset at 5 1/m";
  // An onset curvature the grid cannot bend to (kappa* d >= 1) is refused naming it.
  o.buckling_onset_curvature = 600;
  try {
    ChoiKoClothModel bad(topo, Material::cotton(), o);
    ADD_FAILURE() << "accepted kappa* d = 1.2";
  } catch (const SimError& e) {
    EXPECT_NE(std::string(e.what()).find("buckling_onset_curvature"), std::string::npos) << e.what();
  }
}

TEST(ChoiKoModel, BendSignFollowsTheGeometry) {
  const ParticleTopology topo = topologyOf(rectangle(0.1, 0.04), 0.01);
  ChoiKoOptions o;
  o.hysteresis = HysteresisSpec::continuous(1e-5, 1e-5, 5, 50);
  for (ChoiKoBending version : {ChoiKoBending::kBeam, ChoiKoBending::kPlate}) {
    o.bending_version = version;
    auto model = std::make_unique<ChoiKoClothModel>(topo, Material::cotton(), o);
    // Rolled towards +z (the cloth normal is warp x weft = +z): the middle of every bent unit lies
    // below its chord, i.e. on the -normal side: negative curvature; rolled the other way: positive.
    const VecX down = rolledState(topo, 0.05);
    VecX up = down;
    for (Index r = 0; r < topo.size(); ++r) up[3 * r + 2] = -up[3 * r + 2];
    int bent = 0;
    for (Index k = 0; k < static_cast<Index>(model->bendingUnits().size()); ++k) {
      const Real a = model->signedCurvature(k, down), b = model->signedCurvature(k, up);
      if (std::abs(a) < 1e-3) continue;  // straight units (rounding may leave a tiny deficit)
      ++bent;
      EXPECT_LT(a, 0) << toString(version) << " unit " << k;
      EXPECT_NEAR(b, -a, 1e-9 * std::abs(a));
    }
    EXPECT_GT(bent, 10);
    // In-plane compression gives no geometric sign: the committed sign is kept.
    const VecX squeezed = [&] {
      VecX x = flatState(topo);
      for (Index r = 0; r < topo.size(); ++r) x[3 * r] *= 0.9;
      return x;
    }();
    VecX at_rest = VecX::Zero(up.size());
    model->acceptStep(up, at_rest);
    for (Index k = 0; k < static_cast<Index>(model->bendingUnits().size()); ++k) {
      if (std::abs(model->signedCurvature(k, up)) < 1e-3) continue;
      EXPECT_EQ(model->committedSign(k), 1.0);
      if (std::abs(model->signedCurvature(k, squeezed)) > 1e-3) {
        EXPECT_GT(model->signedCurvature(k, squeezed), 0);
      }
    }
    model->acceptStep(down, at_rest);
    for (Index k = 0; k < static_cast<Index>(model->bendingUnits().size()); ++k) {
      if (std::abs(model->signedCurvature(k, down)) < 1e-3) continue;
      EXPECT_EQ(model->committedSign(k), -1.0);
      if (std::abs(model->signedCurvature(k, squeezed)) > 1e-3) {
        EXPECT_LT(model->signedCurvature(k, squeezed), 0);
      }
    }
  }
}

TEST(ChoiKoModel, HysteresisStateIsCommittedOnlyInAcceptStepAndRoundTrips) {
  ThreadScope threads(1);
  const ParticleTopology topo = topologyOf(rectangle(0.1, 0.06), 0.01);
  for (const HysteresisSpec& spec :
       {HysteresisSpec::continuous(0.5e-5, 2e-5, 5, 40), HysteresisSpec::discrete({0.5e-5, 1e-5, 1e-5}, {1e-4, 3e-4})}) {
    ChoiKoOptions o;
    o.hysteresis = spec;
    auto model = std::make_unique<ChoiKoClothModel>(topo, Material::cotton(), o);
    const std::vector<Real> fresh = model->internalState();
    ASSERT_FALSE(fresh.empty());
    // Forces do not change the state.
    const VecX bent = rolledState(topo, 0.03), less = rolledState(topo, 0.07), other = rolledState(topo, -0.05);
    VecX f0, f1;
    model->computeForces(less, VecX::Zero(bent.size()), f0, nullptr);
    model->computeForces(other, VecX::Zero(bent.size()), f1, nullptr);
    EXPECT_EQ(model->internalState(), fresh);
    // A history: bend, unbend part-way, bend the other way, come back.
    VecX at_rest = VecX::Zero(bent.size());
    for (const VecX* x : {&bent, &less, &other, &less}) model->acceptStep(*x, at_rest);
    const std::vector<Real> state = model->internalState();
    EXPECT_NE(state, fresh);
    // Hysteresis: the force at `less` now differs from the virgin one (it is reached from the other
    // side of the loop).
    VecX f_after;
    model->computeForces(less, VecX::Zero(bent.size()), f_after, nullptr);
    EXPECT_GT((f_after - f0).cwiseAbs().maxCoeff(), 1e-3 * f0.cwiseAbs().maxCoeff());
    // Round trip into a fresh model: identical state and forces.
    auto copy = std::make_unique<ChoiKoClothModel>(topo, Material::cotton(), o);
    ASSERT_TRUE(copy->setInternalState(state));
    EXPECT_EQ(copy->internalState(), state);
    VecX fc;
    copy->computeForces(less, VecX::Zero(bent.size()), fc, nullptr);
    EXPECT_EQ((fc - f_after).cwiseAbs().maxCoeff(), 0.0);
    // Malformed states are rejected and leave the model unchanged.
    std::vector<Real> bad = state;
    bad.pop_back();
    EXPECT_FALSE(copy->setInternalState(bad));
    bad = state;
    bad[3] = 0.5;  // the first unit's sign
    EXPECT_FALSE(copy->setInternalState(bad));
    bad = state;
    bad.back() = NAN;
    EXPECT_FALSE(copy->setInternalState(bad));
    EXPECT_FALSE(copy->setInternalState({}));
    EXPECT_EQ(copy->internalState(), state);
  }
  // Without hysteresis the model is stateless.
  auto plain = std::make_unique<ChoiKoClothModel>(topo, Material::cotton());
  EXPECT_TRUE(plain->internalState().empty());
  EXPECT_TRUE(plain->setInternalState({}));
  EXPECT_FALSE(plain->setInternalState({1.0}));
}

TEST(ChoiKoModel, AnchoredModelAddsLinearSprings) {
  const ParticleTopology topo = topologyOf(rectangle(0.05, 0.03), 0.01);
  auto inner = std::make_unique<ChoiKoClothModel>(topo, Material::cotton());
  AnchoredClothModel anchored(*inner, {0, 3}, {Vec3(0, 0, 0.01), Vec3(0.02, 0.01, 0)}, 50.0);
  std::mt19937_64 gen(3);
  const VecX x = scaledNoisyState(topo, 1.01, 1.0, 0.05, 0.1, gen);
  const VecX v = VecX::Zero(x.size());
  ForceJacobians ji = inner->makeJacobians(), ja = anchored.makeJacobians();
  VecX fi, fa;
  inner->computeForces(x, v, fi, &ji);
  anchored.computeForces(x, v, fa, &ja);
  const VecX diff = fa - fi;
  EXPECT_LE((diff.segment<3>(0) + 50.0 * (node3(x, 0) - Vec3(0, 0, 0.01))).norm(), 1e-12);
  EXPECT_LE((diff.segment<3>(9) + 50.0 * (node3(x, 3) - Vec3(0.02, 0.01, 0))).norm(), 1e-12);
  EXPECT_NEAR(anchored.potentialEnergy(x) - inner->potentialEnergy(x),
              25.0 * ((node3(x, 0) - Vec3(0, 0, 0.01)).squaredNorm() + (node3(x, 3) - Vec3(0.02, 0.01, 0)).squaredNorm()),
              1e-15);
  const Eigen::MatrixXd dk = dense(ja.dfdx) - dense(ji.dfdx);
  EXPECT_NEAR(dk.trace(), -6 * 50.0, 1e-9);
  EXPECT_NEAR(dk.norm(), std::sqrt(6.0) * 50.0, 1e-9);
  EXPECT_EQ(anchored.name(), "choi_ko");
}

// ---- stability under compression --------------------------------------------------------------------

TEST(ChoiKoStability, StableWithoutDampingAtTenAndTwentyMilliseconds) {
  ThreadScope threads(1);  // one thread: fast on a loaded machine; results do not depend on it
  // The requirement: Choi-Ko stays stable at dt >= 10 ms without added damping (settle
  // damping 0; the physical air drag stays on), in both compression scenes. Measured margins
  // (docs/choi_ko.md): at d = 2 cm both scenes are stable up to 50 ms.
  for (CompressionScene s : {CompressionScene::kPushedEdges, CompressionScene::kLoweredOntoTable}) {
    for (Real dt : {0.01, 0.02}) {
      CompressionSceneSpec scene;
      scene.scene = s;
      StabilityRunSpec run;
      run.model = ClothModelSpec("choi_ko");
      run.dt = dt;
      run.damping = false;
      const StabilityResult r = runCompressionScene(scene, run);
      EXPECT_TRUE(r.stable) << toString(s) << " dt " << dt << ": " << r.reason;
      EXPECT_GE(r.sim_time, r.end_time - 1e-9);
      // It did compress: scene (a) leaves the plane, scene (b) lies on the table.
      EXPECT_LT(r.peak_edge_stretch, 2.0);
      if (s == CompressionScene::kLoweredOntoTable) {
        EXPECT_GT(r.obstacle_events, 0);
        EXPECT_GE(r.final_min_z, 0.0);
      }
    }
  }
}

TEST(ChoiKoStability, StableAtTenMillisecondsAtOneCentimetreResolution) {
  ThreadScope threads(1);  // one thread: fast on a loaded machine; results do not depend on it
  for (CompressionScene s : {CompressionScene::kPushedEdges, CompressionScene::kLoweredOntoTable}) {
    CompressionSceneSpec scene;
    scene.scene = s;
    scene.spacing = 0.01;
    StabilityRunSpec run;
    run.dt = 0.01;
    const StabilityResult r = runCompressionScene(scene, run);
    EXPECT_TRUE(r.stable) << toString(s) << ": " << r.reason;
  }
}

// ---- reaching rest (docs/choi_ko.md, "Reaching rest") -------------------------------------------------

// The benchmark's towel scene (benchmarkTowelSpec + useFastSolverSettings, as drape_bench's Choi-Ko rows)
// with the Choi-Ko model's default options: settle damping 4/s, semi-implicit Euler with the
// error-controlled step, default rest thresholds.
DrapeSceneSpec benchTowel(Real spacing, const std::string& hold, Real max_time) {
  DrapeSceneSpec s = benchmarkTowelSpec(spacing, hold, "choi_ko");
  useFastSolverSettings(s.settings);
  s.settings.integrator = IntegratorType::kSemiImplicitEuler;
  s.settings.policy = StepPolicy::kErrorControlled;
  s.settings.max_time = max_time;
  return s;
}

struct TowelRun {
  RunResult result;
  Real depth = 0;
  Real worst_residual = 0;  ///< max over free particles of |f_i| / (m_i g) at the end, v = 0
};

TowelRun runBenchTowel(const DrapeSceneSpec& spec) {
  DrapeScene scene = buildDrapeScene(spec);
  DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
  TowelRun run;
  run.result = sim.run();
  run.depth = hangingDepth(scene, sim.positions());
  VecX f;
  scene.model->computeForces(sim.positions(), VecX::Zero(sim.positions().size()), f, nullptr);
  const VecX& m = scene.model->massPerDof();
  for (Index i = 0; i < scene.model->numNodes(); ++i) {
    if (std::count(scene.pins.nodes.begin(), scene.pins.nodes.end(), i)) continue;
    run.worst_residual = std::max(run.worst_residual, node3(f, i).norm() / (m[3 * i] * kGravity));
  }
  return run;
}

TEST(ChoiKoRest, TowelHeldAtACornerSettlesToATrueEquilibrium) {
  ThreadScope threads(1);  // results do not depend on it
  // Characterisation of the slow settling (docs/choi_ko.md, "Reaching rest"): at d = 2 cm the towel
  // held at a corner comes to rest only after about 22 s of simulated time (measured), far beyond the
  // bench's 8 s cap, and the rest it reaches is a real equilibrium (the largest residual force is about
  // 1 % of a particle's weight), not a crawl held up by the linearised step. Default rest thresholds.
  const DrapeSceneSpec spec = benchTowel(0.02, "corner_ul", 30.0);
  const SimulationSettings defaults;
  ASSERT_EQ(spec.settings.rest_speed, defaults.rest_speed);
  ASSERT_EQ(spec.settings.rest_mean_speed, defaults.rest_mean_speed);
  ASSERT_EQ(spec.settings.rest_duration, defaults.rest_duration);
  const TowelRun run = runBenchTowel(spec);
  EXPECT_FALSE(run.result.diverged) << run.result.divergence_reason;
  EXPECT_TRUE(run.result.rest_reached) << "t = " << run.result.sim_time << " s";
  EXPECT_LT(run.worst_residual, 0.05);
  EXPECT_GT(run.depth, 0.5);
}

TEST(ChoiKoStability, ParticleModelWithExactJacobianFailsAtTenMilliseconds) {
  ThreadScope threads(1);  // one thread: fast on a loaded machine; results do not depend on it
  // Observed (docs/choi_ko.md): the particle model with its exact (indefinite) Jacobian breaks down in
  // the first steps of both scenes at 10 ms (CG meets negative curvature), without and with damping.
  for (CompressionScene s : {CompressionScene::kPushedEdges, CompressionScene::kLoweredOntoTable}) {
    CompressionSceneSpec scene;
    scene.scene = s;
    StabilityRunSpec run;
    run.model = ClothModelSpec("particle_kes");
    run.dt = 0.01;
    const StabilityResult r = runCompressionScene(scene, run);
    EXPECT_FALSE(r.stable) << toString(s);
    EXPECT_LT(r.sim_time, 0.5 * r.end_time) << toString(s);
  }
}

TEST(ChoiKoStability, ScanAndCsv) {
  ThreadScope threads(1);  // one thread: fast on a loaded machine; results do not depend on it
  CompressionSceneSpec scene;
  scene.hold_time = 0.1;
  scene.push_time = 0.2;
  StabilityRunSpec run;
  const std::vector<StabilityRow> rows = scanStability(scene, run, {0.05, 0.01}, "choi_ko");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].scene, "pushed_edges");
  EXPECT_EQ(rows[1].dt, 0.01);
  std::ostringstream os;
  writeStabilityCsv(os, rows);
  const std::string csv = os.str();
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "model,scene,dt_s,damping,stable,reason,sim_time_s,steps,peak_rms_speed_m_s,peak_edge_stretch,wall_s");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 3);
  EXPECT_EQ(largestStableDt(rows), rows[0].result.stable ? 0.05 : (rows[1].result.stable ? 0.01 : 0.0));
  EXPECT_EQ(compressionSceneFromString("lowered_onto_table"), CompressionScene::kLoweredOntoTable);
  EXPECT_THROW(compressionSceneFromString("table"), std::invalid_argument);
  StabilityRunSpec bad = run;
  bad.model = ClothModelSpec("cloth");
  EXPECT_THROW(runCompressionScene(scene, bad), std::invalid_argument);
}

}  // namespace
}  // namespace textile_handling
