// Tests for sim/yarn_crossing_kernels.h and sim/yarn_normal_force.h: the crossing angle, shear with
// jamming and shear friction against finite differences, their clamped Hessians' definiteness and
// invariances; the stick/slip spring, its anchor update and sliding friction; the parallel-yarn
// contact; the normal compression of flat, floating, curved and stretched sheets.
#include "yarn_test_support.h"  // first: see there

#include "textile_handling/sim/yarn_crossing_kernels.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "textile_handling/sim/yarn_kernels.h"
#include "textile_handling/sim/yarn_normal_force.h"

namespace textile_handling {
namespace yarn {
namespace {

using yarn_test_support::eigenvalues;

using yarn_test_support::numericGradientN;
using yarn_test_support::numericJacobianN;

// A crossing stencil with segments of ~1 mm at the angle `phi` [rad] in a random plane, at a random place.
CrossingVector stencilAt(std::mt19937& rng, Real phi) {
  std::uniform_real_distribution<Real> unit(-1, 1), len(0.7e-3, 1.3e-3);
  const Vec3 e1 = Vec3(unit(rng), unit(rng), unit(rng)).normalized();
  const Vec3 e2 = e1.cross(Vec3(unit(rng), unit(rng), unit(rng))).normalized();
  const Vec3 x0(0.01 * unit(rng), 0.01 * unit(rng), 0.01 * unit(rng));
  return packCrossingStencil(x0, x0 + len(rng) * e1, x0 + len(rng) * (std::cos(phi) * e1 + std::sin(phi) * e2));
}

CrossingVector rotated(const CrossingVector& p, const Mat3& R, const Vec3& shift) {
  CrossingVector r;
  for (int node : {0, 3, 6}) r.segment<3>(node) = R * p.segment<3>(node) + shift;
  return r;
}

const Real kPhiJ = 2 * std::asin(0.25);  // R / L = 0.25: the source's shirt
constexpr Real kL = 1e-3;

ShearParameters shearParameters(bool interlaced, Real gain = 100) {
  ShearParameters s;
  s.stiffness = shearStiffness(6.25e-4, 20, 0.01);  // k_x = S R^2 of the shirt, raised by F_n = 10 mN
  s.rest_spacing = kL;
  s.jamming_angle = kPhiJ;
  s.jamming_gain = gain;
  s.interlaced = interlaced;
  return s;
}

TEST(YarnCrossingAngle, ValueGradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(101);
  for (Real phi : {0.05, 0.3, 0.505, 1.0, kPi / 2, 2.0, 2.8, 3.09}) {
    for (int trial = 0; trial < 5; ++trial) {
      const CrossingVector p = stencilAt(rng, phi);
      EXPECT_NEAR(crossingAngle(p), phi, 1e-12) << "phi " << phi;
      const CrossingVector g = crossingAngleGradient(p);
      const CrossingVector gn = numericGradientN<9>([](const CrossingVector& x) { return crossingAngle(x); }, p, 1e-9);
      EXPECT_LT((g - gn).norm(), 1e-6 * g.norm()) << "phi " << phi;
      const CrossingMatrix H = crossingAngleHessian(p);
      const CrossingMatrix Hn = numericJacobianN<9>([](const CrossingVector& x) { return crossingAngleGradient(x); }, p, 1e-9);
      EXPECT_LT((H - Hn).norm(), 1e-6 * H.norm()) << "phi " << phi;
      EXPECT_LT((H - H.transpose()).norm(), 1e-12 * H.norm());
    }
  }
}

TEST(YarnCrossingAngle, InvariantUnderTranslationRotationAndScale) {
  std::mt19937 rng(103);
  const Mat3 R = Eigen::AngleAxis<Real>(1.1, Vec3(-2, 1, 3).normalized()).toRotationMatrix();
  const Vec3 shift(0.3, -0.2, 0.05);
  for (Real phi : {0.4, 1.3, kPi / 2, 2.2}) {
    const CrossingVector p = stencilAt(rng, phi);
    const CrossingVector g = crossingAngleGradient(p);
    const CrossingMatrix H = crossingAngleHessian(p);
    // Translation: the node gradients sum to zero, and so do the Hessian's node blocks along a row.
    EXPECT_LT((g.segment<3>(0) + g.segment<3>(3) + g.segment<3>(6)).norm(), 1e-12 * g.norm());
    EXPECT_LT((H.leftCols<3>() + H.middleCols<3>(3) + H.rightCols<3>()).norm(), 1e-10 * H.norm());
    // Scale: phi is homogeneous of degree 0, so sum_i dphi/dx_i . (x_i - x0) = 0.
    const Real euler = g.segment<3>(3).dot(p.segment<3>(3) - p.segment<3>(0)) + g.segment<3>(6).dot(p.segment<3>(6) - p.segment<3>(0));
    EXPECT_NEAR(euler, 0, 1e-12);
    EXPECT_NEAR(crossingAngle(CrossingVector(3.7 * p)), phi, 1e-12);
    // Rotation: same angle, rotated gradient.
    const CrossingVector pr = rotated(p, R, shift);
    EXPECT_NEAR(crossingAngle(pr), phi, 1e-12);
    const CrossingVector gr = crossingAngleGradient(pr);
    for (int node : {0, 3, 6}) EXPECT_LT((gr.segment<3>(node) - R * g.segment<3>(node)).norm(), 1e-9 * g.norm());
    // |dphi/dx1| = 1 / |a| and |dphi/dx3| = 1 / |b| at every angle.
    EXPECT_NEAR(g.segment<3>(3).norm() * (p.segment<3>(3) - p.segment<3>(0)).norm(), 1, 1e-12);
    EXPECT_NEAR(g.segment<3>(6).norm() * (p.segment<3>(6) - p.segment<3>(0)).norm(), 1, 1e-12);
  }
}

TEST(YarnCrossingAngle, RightAngleClosesWhenTheWarpEndMovesTowardsTheWeft) {
  const CrossingVector p = packCrossingStencil(Vec3::Zero(), Vec3(kL, 0, 0), Vec3(0, kL, 0));
  EXPECT_NEAR(crossingAngle(p), kPi / 2, 1e-15);
  const CrossingVector g = crossingAngleGradient(p);
  EXPECT_LT((g.segment<3>(3) - Vec3(0, -1 / kL, 0)).norm(), 1e-9);  // x1 towards +y closes the angle
  EXPECT_LT((g.segment<3>(6) - Vec3(-1 / kL, 0, 0)).norm(), 1e-9);  // x3 towards +x closes it
  EXPECT_LT((g.segment<3>(0) - Vec3(1 / kL, 1 / kL, 0)).norm(), 1e-9);
}

TEST(YarnShear, GradientAndHessianMatchFiniteDifferencesOnBothSidesOfJamming) {
  std::mt19937 rng(107);
  // Below, at and above phi_j, within a finite-difference step of it, at rest and sheared the other way.
  const std::vector<Real> phis = {0.2, 0.35, kPhiJ - 0.02, kPhiJ - 5e-7, kPhiJ, kPhiJ + 5e-7, kPhiJ + 0.05,
                                  1.2, kPi / 2, 2.0, 2.6};
  for (bool interlaced : {true, false}) {
    const ShearParameters s = shearParameters(interlaced);
    for (Real phi : phis) {
      for (int trial = 0; trial < 3; ++trial) {
        const CrossingVector p = stencilAt(rng, phi);
        const CrossingVector g = shearGradient(p, s);
        const CrossingVector gn = numericGradientN<9>([&](const CrossingVector& x) { return shearEnergy(x, s); }, p, 1e-9);
        const Real gscale = std::max<Real>(g.norm(), s.stiffness * 1e-3);  // floor: the gradient 1 mrad from rest
        EXPECT_LT((g - gn).norm(), 1e-6 * gscale) << "phi " << phi << " interlaced " << interlaced;
        const CrossingMatrix H = shearHessian(p, s);
        const CrossingMatrix Hn = numericJacobianN<9>([&](const CrossingVector& x) { return shearGradient(x, s); }, p, 1e-9);
        EXPECT_LT((H - Hn).norm(), 1e-6 * H.norm()) << "phi " << phi << " interlaced " << interlaced;
        EXPECT_LT((H - H.transpose()).norm(), 1e-12 * H.norm());
        // Translation and rotation.
        EXPECT_LT((g.segment<3>(0) + g.segment<3>(3) + g.segment<3>(6)).norm(), 1e-12 * gscale);
        const Mat3 R = Eigen::AngleAxis<Real>(0.8, Vec3(1, 1, -2).normalized()).toRotationMatrix();
        const CrossingVector gr = shearGradient(rotated(p, R, Vec3(0.1, 0.2, 0.3)), s);
        for (int node : {0, 3, 6}) EXPECT_LT((gr.segment<3>(node) - R * g.segment<3>(node)).norm(), 1e-9 * gscale);
      }
    }
  }
}

TEST(YarnShear, PotentialIsSmoothAcrossTheJammingAngle) {
  const ShearParameters s = shearParameters(true);
  const Real h = 1e-6;
  for (Real phi : {0.2, kPhiJ - 1e-3, kPhiJ, kPhiJ + 1e-3, 1.0}) {
    const AnglePotential v = shearPotential(phi, s);
    const Real d1 = (shearPotential(phi + h, s).value - shearPotential(phi - h, s).value) / (2 * h);
    const Real d2 = (shearPotential(phi + h, s).first - shearPotential(phi - h, s).first) / (2 * h);
    EXPECT_NEAR(v.first, d1, 1e-6 * std::abs(v.first) + 1e-18) << "phi " << phi;
    EXPECT_NEAR(v.second, d2, 1e-6 * v.second) << "phi " << phi;
  }
  // C2 at phi_j: value, slope and curvature agree from both sides.
  const AnglePotential below = shearPotential(kPhiJ - 1e-9, s), above = shearPotential(kPhiJ + 1e-9, s);
  EXPECT_NEAR(below.second, above.second, 1e-6 * above.second);
  EXPECT_NEAR(below.first, above.first, 1e-6 * std::abs(above.first));
}

TEST(YarnShear, JammingStiffensSharplyBelowTheJammingAngle) {
  const Real gain = 1000;
  const ShearParameters jam = shearParameters(true, gain), free = shearParameters(false, gain);
  const Real kL_ = jam.stiffness * kL;
  // Curvature measured by finite differences of the potential (not read from AnglePotential::second).
  auto curvature = [](Real phi, const ShearParameters& s) {
    const Real h = 1e-5;
    return (shearPotential(phi + h, s).value - 2 * shearPotential(phi, s).value + shearPotential(phi - h, s).value) / (h * h);
  };
  const Real below = curvature(kPhiJ - 0.1, jam), above = curvature(kPhiJ + 0.1, jam);
  EXPECT_NEAR(above, kL_, 1e-5 * kL_);
  const Real t = 0.1 / kPhiJ;
  EXPECT_NEAR(below / above, 1 + gain * t * t * t, 1e-4 * below / above);
  EXPECT_GT(below / above, 5);
  // Deeper into jamming the stiffness keeps growing, cubically.
  EXPECT_GT(curvature(kPhiJ - 0.3, jam), 10 * below);
  // A floating pair does not jam.
  EXPECT_NEAR(curvature(kPhiJ - 0.1, free), kL_, 1e-5 * kL_);
  // The jamming force opens the angle: a step against the gradient increases phi, more than without jamming.
  std::mt19937 rng(109);
  const CrossingVector p = stencilAt(rng, kPhiJ - 0.1);
  const Real step = 1e-6 / jam.stiffness;  // moves the nodes by ~1 um
  const Real opened = crossingAngle(CrossingVector(p - step * shearGradient(p, jam)));
  const Real opened_free = crossingAngle(CrossingVector(p - step * shearGradient(p, free)));
  EXPECT_GT(opened_free, kPhiJ - 0.1);
  EXPECT_GT(opened - (kPhiJ - 0.1), 1.1 * (opened_free - (kPhiJ - 0.1)));
}

TEST(YarnShear, ValueOfTheNotesAndRest) {
  EXPECT_EQ(shearStiffness(6.25e-4, 0, 0.5), 6.25e-4);
  EXPECT_NEAR(shearStiffness(6.25e-4, 2, 0.5), 2 * 6.25e-4, 1e-18);
  const ShearParameters s = shearParameters(true, 50);
  const Real kL_ = s.stiffness * kL;
  std::mt19937 rng(113);
  // At rest: no energy, no force, and a positive semi-definite Hessian.
  const CrossingVector rest = stencilAt(rng, kPi / 2);
  EXPECT_NEAR(shearEnergy(rest, s), 0, 1e-30);
  EXPECT_LT(shearGradient(rest, s).norm(), 1e-15);
  EXPECT_GE(eigenvalues(shearHessian(rest, s)).minCoeff(), -1e-12 * shearHessian(rest, s).norm());
  // Sheared above phi_j: eq. 11 with the rest spacing; below: plus k L c_j phi_j^2 s^5 / 20.
  EXPECT_NEAR(shearEnergy(stencilAt(rng, 1.2), s), 0.5 * kL_ * std::pow(1.2 - kPi / 2, 2), 1e-12 * kL_);
  const Real phi = kPhiJ - 0.2, t = 0.2 / kPhiJ;
  EXPECT_NEAR(shearEnergy(stencilAt(rng, phi), s),
              0.5 * kL_ * std::pow(phi - kPi / 2, 2) + kL_ * 50 * kPhiJ * kPhiJ * std::pow(t, 5) / 20, 1e-12 * kL_);
}

TEST(YarnShear, ClampedHessianIsPositiveSemiDefinite) {
  std::mt19937 rng(127);
  int indefinite = 0;
  for (bool interlaced : {true, false}) {
    const ShearParameters s = shearParameters(interlaced);
    for (Real phi : {0.3, kPhiJ - 0.05, 0.9, 1.4, 1.8, 2.5}) {
      for (int trial = 0; trial < 3; ++trial) {
        const CrossingVector p = stencilAt(rng, phi);
        const Eigen::VectorXd exact = eigenvalues(shearHessian(p, s)), clamped = eigenvalues(shearHessianClamped(p, s));
        const Real scale = exact.cwiseAbs().maxCoeff();
        indefinite += exact.minCoeff() < -1e-9 * scale;
        EXPECT_GE(clamped.minCoeff(), -1e-12 * scale) << "phi " << phi;
        // Rank one, along the angle's gradient.
        EXPECT_LT(clamped[7], 1e-12 * scale);
        EXPECT_NEAR(clamped[8], shearPotential(phi, s).second * crossingAngleGradient(p).squaredNorm(), 1e-9 * clamped[8]);
      }
    }
  }
  EXPECT_GT(indefinite, 0);  // the exact shear Hessian is indefinite away from rest
}

TEST(YarnStickSlip, StickBelowAndSlipAboveTheCoulombLimit) {
  const Real k = 2e3, limit = 0.3 * 0.01;  // k_f [N/m], mu F_n [N]
  const Real x_limit = limit / k;
  for (Real sign : {1.0, -1.0}) {
    const StickSlip below = stickSlipSpring(0.7 + sign * 0.5 * x_limit, 0.7, k, limit);
    EXPECT_TRUE(below.stick);
    EXPECT_NEAR(below.force, -sign * 0.5 * limit, 1e-9 * limit);
    EXPECT_EQ(below.stiffness, -k);
    const StickSlip above = stickSlipSpring(0.7 + sign * 3 * x_limit, 0.7, k, limit);
    EXPECT_FALSE(above.stick);
    EXPECT_EQ(above.force, -sign * limit);
    EXPECT_EQ(above.stiffness, 0.0);
    // Continuous at the limit.
    const StickSlip in = stickSlipSpring(0.7 + sign * x_limit * (1 - 1e-9), 0.7, k, limit);
    const StickSlip out = stickSlipSpring(0.7 + sign * x_limit * (1 + 1e-9), 0.7, k, limit);
    EXPECT_TRUE(in.stick);
    EXPECT_FALSE(out.stick);
    EXPECT_NEAR(in.force, out.force, 1e-8 * limit);
  }
  // dF/dx against central differences in either mode.
  for (Real x : {0.7 + 0.3 * x_limit, 0.7 - 0.6 * x_limit, 0.7 + 5 * x_limit, 0.7 - 5 * x_limit}) {
    const Real h = 1e-3 * x_limit;
    const Real fd = (stickSlipSpring(x + h, 0.7, k, limit).force - stickSlipSpring(x - h, 0.7, k, limit).force) / (2 * h);
    EXPECT_NEAR(stickSlipSpring(x, 0.7, k, limit).stiffness, fd, 1e-6 * k);
  }
  // Without compression there is no friction at all.
  const StickSlip none = stickSlipSpring(0.3, 0.2, k, 0);
  EXPECT_FALSE(none.stick);
  EXPECT_EQ(none.force, 0.0);
}

TEST(YarnStickSlip, AnchorUpdateKeepsTheSpringAtTheLimitAndGivesHysteresis) {
  const Real k = 2e3, limit = 3e-3;
  std::mt19937 rng(131);
  std::uniform_real_distribution<Real> unit(-1, 1);
  for (int trial = 0; trial < 50; ++trial) {
    const Real anchor = 0.1 * unit(rng), x = anchor + 4 * limit / k * unit(rng);
    const StickSlip before = stickSlipSpring(x, anchor, k, limit);
    const Real moved = stickSlipAnchor(x, anchor, k, limit);
    const StickSlip after = stickSlipSpring(x, moved, k, limit);
    EXPECT_NEAR(after.force, before.force, 1e-9 * limit);  // the update does not change the force
    if (before.stick) {
      EXPECT_EQ(moved, anchor);
    } else {
      EXPECT_NEAR(k * std::abs(x - moved), limit, 1e-9 * limit);
      // Any motion back towards the anchor sticks at once.
      EXPECT_TRUE(stickSlipSpring(x - 1e-3 * (x - moved), moved, k, limit).stick);
    }
  }
  // Pull a coordinate forward in steps, then back: the force saturates at -limit, and on reversal
  // sticks and falls linearly through zero before slipping the other way (a hysteresis loop).
  Real x = 0, anchor = 0;
  const Real dx = 0.25 * limit / k;
  std::vector<Real> forces;
  for (int step = 0; step < 24; ++step) {
    x += step < 12 ? dx : -dx;
    forces.push_back(stickSlipSpring(x, anchor, k, limit).force);
    anchor = stickSlipAnchor(x, anchor, k, limit);
  }
  EXPECT_NEAR(forces[3], -limit, 1e-12);   // 4 steps of a quarter: at the limit
  EXPECT_NEAR(forces[11], -limit, 1e-12);  // saturated
  EXPECT_NEAR(forces[12], -0.75 * limit, 1e-12);  // first step back: stick, the spring relaxes
  EXPECT_NEAR(forces[15], 0, 1e-12);
  EXPECT_NEAR(forces[19], limit, 1e-12);
  EXPECT_NEAR(forces[23], limit, 1e-12);
}

TEST(YarnSlidingFriction, CoulombLimitFromTheNormalForceAndDamping) {
  const Real k_f = 1e3, mu = 0.3, F_n = 0.02;
  // The Coulomb limit mu F_n = 6 mN: 6 um of spring.
  const StickSlip stick = slidingFriction(0.1 + 5e-6, 0.1, k_f, mu, F_n);  // k_f |du| = 5 mN
  EXPECT_TRUE(stick.stick);
  EXPECT_NEAR(stick.force, -5e-3, 1e-12);
  EXPECT_EQ(stick.stiffness, -k_f);
  const StickSlip slip = slidingFriction(0.1 - 1e-5, 0.1, k_f, mu, F_n);  // 10 mN of spring
  EXPECT_FALSE(slip.stick);
  EXPECT_NEAR(slip.force, mu * F_n, 1e-15);
  EXPECT_EQ(slip.stiffness, 0.0);
  EXPECT_NEAR(slidingFrictionAnchor(0.1 - 1e-5, 0.1, k_f, mu, F_n), 0.1 - 1e-5 + mu * F_n / k_f, 1e-15);
  EXPECT_EQ(slidingFrictionAnchor(0.1 + 5e-6, 0.1, k_f, mu, F_n), 0.1);
  // More compression, a higher limit: the same displacement sticks.
  EXPECT_TRUE(slidingFriction(0.1 - 1e-5, 0.1, k_f, mu, 0.05).stick);
  EXPECT_NEAR(slidingDamping(2e-3, 0.05), -1e-4, 1e-18);
}

TEST(YarnShearFriction, StickGradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(137);
  const Real k_fphi = 1e-4;
  int indefinite = 0;
  for (Real phi : {0.6, 1.2, kPi / 2, 1.9}) {
    for (int trial = 0; trial < 4; ++trial) {
      const CrossingVector p = stencilAt(rng, phi);
      const Real anchor = phi + 0.2 * (trial - 1.5);
      EXPECT_NEAR(shearFrictionStickEnergy(p, anchor, k_fphi), 0.5 * k_fphi * (phi - anchor) * (phi - anchor), 1e-15);
      const CrossingVector g = shearFrictionStickGradient(p, anchor, k_fphi);
      const CrossingVector gn =
          numericGradientN<9>([&](const CrossingVector& x) { return shearFrictionStickEnergy(x, anchor, k_fphi); }, p, 1e-9);
      EXPECT_LT((g - gn).norm(), 1e-6 * g.norm());
      const CrossingMatrix H = shearFrictionStickHessian(p, anchor, k_fphi);
      const CrossingMatrix Hn =
          numericJacobianN<9>([&](const CrossingVector& x) { return shearFrictionStickGradient(x, anchor, k_fphi); }, p, 1e-9);
      EXPECT_LT((H - Hn).norm(), 1e-6 * H.norm());
      const Eigen::VectorXd exact = eigenvalues(H), clamped = eigenvalues(shearFrictionStickHessianClamped(p, anchor, k_fphi));
      indefinite += exact.minCoeff() < -1e-9 * exact.cwiseAbs().maxCoeff();
      EXPECT_GE(clamped.minCoeff(), -1e-12 * exact.cwiseAbs().maxCoeff());
    }
  }
  EXPECT_GT(indefinite, 0);
}

TEST(YarnShearFriction, StickSpringBelowAndConstantMomentAboveTheLimit) {
  std::mt19937 rng(139);
  const Real k_fphi = 1e-4, mu_phi = 0.3 * kL, F_n = 0.02;  // limit mu_phi F_n = 6e-6 N m: 0.06 rad of spring
  const Real phi = 1.3;
  const CrossingVector p = stencilAt(rng, phi);
  const CrossingVector dphi = crossingAngleGradient(p);
  // Stick: the spring's force, with the exact Hessian as (minus) its Jacobian.
  const Real near_anchor = phi - 0.03;
  const ShearFriction stick = shearFriction(p, near_anchor, k_fphi, mu_phi, F_n, false);
  EXPECT_TRUE(stick.stick);
  EXPECT_LT((stick.force + shearFrictionStickGradient(p, near_anchor, k_fphi)).norm(), 1e-12 * stick.force.norm());
  EXPECT_LT((stick.jacobian + shearFrictionStickHessian(p, near_anchor, k_fphi)).norm(), 1e-9 * stick.jacobian.norm());
  EXPECT_LT((shearFriction(p, near_anchor, k_fphi, mu_phi, F_n, true).jacobian +
             shearFrictionStickHessianClamped(p, near_anchor, k_fphi)).norm(), 1e-12 * stick.jacobian.norm());
  // Slip: the constant moment mu_phi F_n against the displacement, whatever the distance.
  for (Real far_anchor : {phi - 0.1, phi - 0.5, phi + 0.2}) {
    const ShearFriction slip = shearFriction(p, far_anchor, k_fphi, mu_phi, F_n, false);
    EXPECT_FALSE(slip.stick);
    const Real sign = phi > far_anchor ? 1 : -1;
    EXPECT_LT((slip.force + sign * mu_phi * F_n * dphi).norm(), 1e-12 * slip.force.norm());
    EXPECT_LT((slip.force - shearFrictionSlipForce(p, far_anchor, mu_phi, F_n)).norm(), 1e-15);
    // Its exact Jacobian against finite differences of the force; the clamped one is zero.
    const CrossingMatrix Jn = numericJacobianN<9>(
        [&](const CrossingVector& x) { return CrossingVector(shearFriction(x, far_anchor, k_fphi, mu_phi, F_n, false).force); }, p,
        1e-9);
    EXPECT_LT((slip.jacobian - Jn).norm(), 1e-6 * slip.jacobian.norm());
    EXPECT_EQ(shearFriction(p, far_anchor, k_fphi, mu_phi, F_n, true).jacobian.norm(), 0.0);
    // The anchor follows to the limit angle.
    const Real moved = shearFrictionAnchor(phi, far_anchor, k_fphi, mu_phi, F_n);
    EXPECT_NEAR(k_fphi * std::abs(phi - moved), mu_phi * F_n, 1e-9 * mu_phi * F_n);
    EXPECT_LT((shearFriction(p, moved, k_fphi, mu_phi, F_n, false).force - slip.force).norm(), 1e-9 * slip.force.norm());
  }
  // The slip force has no resultant: it only turns the two segments towards each other.
  const CrossingVector f = shearFrictionSlipForce(p, phi - 0.5, mu_phi, F_n);
  EXPECT_LT((f.segment<3>(0) + f.segment<3>(3) + f.segment<3>(6)).norm(), 1e-12 * f.norm());
}

TEST(YarnShearFriction, OneAngleEvaluationGivesTheSeparateKernelsValues) {
  // The model's clamped crossing pass evaluates the angle once per pair and derives shear and friction
  // from it: the same bits as crossingAngle(), crossingAngleGradient() and shearFriction(clamped).
  std::mt19937 rng(141);
  const Real k_fphi = 1e-4, mu_phi = 0.3 * kL, F_n = 0.02;
  for (Real phi : {0.4, 1.3, kPi / 2, 2.5}) {
    const CrossingVector p = stencilAt(rng, phi);
    const AngleWithGradient a = crossingAngleWithGradient(p);
    EXPECT_EQ(a.phi, crossingAngle(p));
    EXPECT_TRUE((a.g.array() == crossingAngleGradient(p).array()).all());
    for (Real anchor : {phi - 0.03, phi + 0.5}) {  // stick, slip
      const ShearFriction separate = shearFriction(p, anchor, k_fphi, mu_phi, F_n, true);
      const ShearFriction shared = shearFrictionClamped(a, anchor, k_fphi, mu_phi, F_n);
      EXPECT_EQ(shared.stick, separate.stick);
      EXPECT_TRUE((shared.force.array() == separate.force.array()).all());
      EXPECT_TRUE((shared.jacobian.array() == separate.jacobian.array()).all());
    }
    const ShearParameters s = shearParameters(true);
    const AnglePotential v = shearPotential(a.phi, s);
    EXPECT_TRUE(((v.second * a.g * a.g.transpose()).array() == shearHessianClamped(p, s).array()).all());
    EXPECT_TRUE(((v.first * a.g).array() == shearGradient(p, s).array()).all());
  }
}

TEST(YarnParallelContact, ZeroAboveTheDistanceAndPushingApartBelow) {
  const Real R = 0.25e-3, k_c = 1.963 / kL;  // k_c ~ k_s / L
  EXPECT_NEAR(parallelContactDistance(R, true), 1e-3, 1e-18);
  EXPECT_NEAR(parallelContactDistance(R, false), 0.5e-3, 1e-18);
  for (bool interlaced : {true, false}) {
    const Real d = parallelContactDistance(R, interlaced);
    for (Real gap : {d, 1.01 * d, 3 * d}) {
      EXPECT_EQ(parallelContactEnergy(0, gap, k_c, kL, d), 0.0);
      EXPECT_EQ(parallelContactGradient(0, gap, k_c, kL, d).norm(), 0.0);
      EXPECT_EQ(parallelContactHessian(0, gap, k_c, kL, d).norm(), 0.0);
    }
    for (Real gap : {0.99 * d, 0.7 * d, 0.2 * d, -0.1 * d}) {
      const Real u0 = 0.2, u1 = 0.2 + gap;
      EXPECT_NEAR(parallelContactEnergy(u0, u1, k_c, kL, d), 0.5 * k_c * kL * (gap - d) * (gap - d), 1e-15);
      const ContactVector force = -parallelContactGradient(u0, u1, k_c, kL, d);
      EXPECT_LT(force[0], 0);  // the lower crossing is pushed back
      EXPECT_GT(force[1], 0);  // the upper one forward
      EXPECT_NEAR(force[0], k_c * kL * (gap - d), 1e-12);
      const ContactVector q(u0, u1);
      const ContactVector gn = numericGradientN<2>(
          [&](const ContactVector& x) { return parallelContactEnergy(x[0], x[1], k_c, kL, d); }, q, 1e-9);
      EXPECT_LT((parallelContactGradient(u0, u1, k_c, kL, d) - gn).norm(), 1e-6 * force.norm());
      const ContactMatrix Hn = numericJacobianN<2>(
          [&](const ContactVector& x) { return parallelContactGradient(x[0], x[1], k_c, kL, d); }, q, 1e-9);
      const ContactMatrix H = parallelContactHessian(u0, u1, k_c, kL, d);
      EXPECT_LT((H - Hn).norm(), 1e-6 * H.norm());
      EXPECT_GE(eigenvalues(H).minCoeff(), -1e-12 * H.norm());
    }
  }
}

}  // namespace
}  // namespace yarn

namespace {

// ---- Normal force ----------------------------------------------------------------------------

// A flat square sheet at 1 yarn per mm, 8 x 8 mm by default (64 crossings, every yarn with two free ends).
YarnSheet patch(const WovenFabric& fabric, Real size = 8e-3) {
  const std::vector<Vec2> rect = {Vec2(0, 0), Vec2(size, 0), Vec2(size, size), Vec2(0, size)};
  return buildYarnSheet(layYarnGrid(rect, fabric));
}

WovenFabric fabricWith(const std::string& weave) {
  WovenFabric f;
  f.weave = namedWeave(weave);
  return f;
}

// A crossing is interior when it has two crossings on each side along both of its yarns: every
// bending stencil through it is made of crossings.
std::vector<bool> interiorCrossings(const YarnSheet& s) {
  std::vector<int> warp_depth(s.grid.crossings.size(), 0), weft_depth(s.grid.crossings.size(), 0);
  for (const YarnPiece& p : s.grid.pieces) {
    std::vector<std::size_t> cs;
    for (std::size_t n : p.nodes)
      if (!s.grid.isEnd(n)) cs.push_back(n);
    for (std::size_t k = 0; k < cs.size(); ++k)
      (p.warp ? warp_depth : weft_depth)[cs[k]] = static_cast<int>(std::min(k, cs.size() - 1 - k));
  }
  std::vector<bool> interior(s.grid.crossings.size());
  for (std::size_t c = 0; c < interior.size(); ++c) interior[c] = warp_depth[c] >= 2 && weft_depth[c] >= 2;
  return interior;
}

Real mean(const std::vector<Real>& v) {
  Real sum = 0;
  for (Real x : v) sum += x;
  return sum / static_cast<Real>(v.size());
}

TEST(YarnNormalForce, FlatPlainWeaveAtRestIsCompressedAtInteriorCrossings) {
  const WovenFabric f = fabricWith("plain");
  const YarnSheet s = patch(f);
  ASSERT_EQ(s.grid.crossings.size(), 64u);
  const CrossingCompression cc = crossingCompression(s, f, s.rest);
  ASSERT_EQ(cc.force.size(), 64u);
  const std::vector<bool> interior = interiorCrossings(s);
  int interior_count = 0;
  for (std::size_t c = 0; c < cc.force.size(); ++c) {
    // n from the warp to the weft: down where the warp is on top.
    const Vec3 expected(0, 0, s.grid.crossings[c].warp_on_top ? -1 : 1);
    EXPECT_LT((cc.normal[c] - expected).norm(), 1e-15) << "crossing " << c;
    EXPECT_TRUE(std::isfinite(cc.force[c]));
    EXPECT_GE(cc.force[c], 0);
    if (interior[c]) {
      ++interior_count;
      EXPECT_GT(cc.force[c], 0) << "crossing " << c;
      // Both yarns are pressed into each other by their crimp, equally by symmetry.
      EXPECT_GT(cc.warp_push[c], 0);
      EXPECT_NEAR(cc.warp_push[c], cc.weft_push[c], 1e-9 * cc.warp_push[c]);
    }
  }
  EXPECT_EQ(interior_count, 16);
  // All interior crossings of a plain weave are alike.
  const std::size_t first = static_cast<std::size_t>(std::find(interior.begin(), interior.end(), true) - interior.begin());
  for (std::size_t c = 0; c < cc.force.size(); ++c) {
    if (!interior[c]) continue;
    EXPECT_NEAR(cc.force[c], cc.force[first], 1e-9 * cc.force[first]);
  }
  EXPECT_EQ(crossingNormalForces(s, f, s.rest), cc.force);
}

TEST(YarnNormalForce, CrimpedBendingMatchesFiniteDifferencesOfTheCrimpedYarns) {
  // An interior crossing of the flat plain weave: no stretch force, so warp_push is minus the
  // derivative along n of the crimped bending energy of the warp's stencil centred at the crossing (the
  // stencils centred at its neighbours do not count; docs/yarn_model.md, "Normal force").
  const WovenFabric f = fabricWith("plain");
  const YarnSheet s = patch(f);
  const CrossingCompression cc = crossingCompression(s, f, s.rest);
  const std::vector<bool> interior = interiorCrossings(s);
  const Real R = f.yarn_radius_m, k_b = f.bendingStiffness();
  for (std::size_t c = 0; c < s.grid.crossings.size(); ++c) {
    if (!interior[c]) continue;
    for (const YarnPiece& p : s.grid.pieces) {
      const auto it = std::find(p.nodes.begin(), p.nodes.end(), c);
      if (it == p.nodes.end()) continue;
      const std::size_t at = static_cast<std::size_t>(it - p.nodes.begin());
      // The crimped yarn: a crossing's own yarn sits R above the sheet where it is on top, else below.
      auto energy = [&](Real h) {
        std::vector<Vec3> y;
        for (std::size_t n : p.nodes) {
          Vec3 x = s.rest.segment<3>(5 * n);
          if (!s.grid.isEnd(n)) x.z() += (s.grid.crossings[n].warp_on_top == p.warp ? R : -R);
          y.push_back(x);
        }
        y[at] += h * cc.normal[c];
        const std::size_t k = at;
        return yarn::bendEnergy(yarn::packBendStencil(y[k - 1], s.rest[5 * p.nodes[k - 1] + (p.warp ? 3 : 4)], y[k], 0,
                                                      y[k + 1], s.rest[5 * p.nodes[k + 1] + (p.warp ? 3 : 4)]),
                                k_b);
      };
      const Real h = 1e-8, along_n = -(energy(h) - energy(-h)) / (2 * h);
      if (p.warp) {
        EXPECT_NEAR(cc.warp_push[c], along_n, 1e-6 * std::abs(along_n)) << "crossing " << c;
      } else {
        EXPECT_NEAR(cc.weft_push[c], -along_n, 1e-6 * std::abs(along_n)) << "crossing " << c;
      }
    }
  }
}

TEST(YarnNormalForce, FloatsCompressLessThanAPlainWeave) {
  std::vector<Real> means;
  for (const char* weave : {"plain", "twill_2_2", "satin_5"}) {
    const WovenFabric f = fabricWith(weave);
    const YarnSheet s = patch(f, 20e-3);
    const std::vector<Real> fn = crossingNormalForces(s, f, s.rest);
    const std::vector<bool> interior = interiorCrossings(s);
    std::vector<Real> inside;
    for (std::size_t c = 0; c < fn.size(); ++c) {
      EXPECT_TRUE(std::isfinite(fn[c]));
      EXPECT_GE(fn[c], 0);
      if (interior[c]) inside.push_back(fn[c]);
    }
    means.push_back(mean(inside));
  }
  EXPECT_GT(means[2], 0);
  EXPECT_LT(means[1], means[0]);  // twill below plain
  EXPECT_LT(means[2], means[1]);  // satin below twill: more floats, less crimp
  EXPECT_LT(means[2], 0.8 * means[0]);
}

// The flat rest state wrapped around a cylinder along the warp (axis along y, radius `radius`, centre
// below the sheet for radius > 0, above for radius < 0) with the warp stretched by `stretch`.
VecX wrapped(const YarnSheet& s, Real radius, Real stretch) {
  VecX q = s.rest;
  for (std::size_t n = 0; n < s.nodeCount(); ++n) {
    const Real x = stretch * (s.rest[5 * n] - 4e-3), angle = x / radius;
    q[5 * n] = 4e-3 + radius * std::sin(angle);
    q[5 * n + 2] = radius * (std::cos(angle) - 1);
  }
  return q;
}

TEST(YarnNormalForce, TensionOverACurvedSheetPressesTheYarnOnTop) {
  const WovenFabric f = fabricWith("plain");
  const YarnSheet s = patch(f);
  const std::vector<bool> interior = interiorCrossings(s);
  const std::vector<Real> flat = crossingNormalForces(s, f, s.rest);
  // Stretched by 2 % but flat: the tension has no normal component (only the crimp angles change a little).
  VecX stretched = s.rest;
  for (std::size_t n = 0; n < s.nodeCount(); ++n) stretched[5 * n] = 4e-3 + 1.02 * (s.rest[5 * n] - 4e-3);
  const std::vector<Real> flat_stretched = crossingNormalForces(s, f, stretched);
  // Wrapped with the centre below (the warp bends away from the +z side) and stretched by 2 %: the
  // warp's tension presses it down, into the weft where the warp is on top and away from it where it
  // is below; wrapped the other way, the reverse.
  const Real radius = 10e-3, stretch = 1.02;
  for (Real side : {1.0, -1.0}) {
    const VecX q = wrapped(s, side * radius, stretch);
    const CrossingCompression cc = crossingCompression(s, f, q);
    for (std::size_t c = 0; c < flat.size(); ++c) {
      EXPECT_TRUE(std::isfinite(cc.force[c]));
      EXPECT_GE(cc.force[c], 0);
      if (!interior[c]) continue;
      const bool pressed = s.grid.crossings[c].warp_on_top == (side > 0);
      // The tension's normal component: T times the turning angle of the chords, T = k_s (l / D - 1).
      const Real l = 2 * std::abs(radius) * std::sin(stretch * 1e-3 / (2 * radius)), T = f.stretchStiffness() * (l / 1e-3 - 1);
      // Two segments each turned by half the angle between chords, half of it in F_n (eq. 9).
      const Real expected = 0.5 * 2 * T * std::sin(stretch * 1e-3 / (2 * radius));
      EXPECT_LT(std::abs(flat_stretched[c] - flat[c]), 0.1 * expected) << "crossing " << c;
      if (pressed) {
        EXPECT_GT(cc.force[c], flat[c] + 0.5 * expected) << "crossing " << c;
        EXPECT_NEAR(cc.force[c] - flat[c], expected, 0.2 * expected) << "crossing " << c;
      } else {
        EXPECT_LT(cc.force[c], flat[c]) << "crossing " << c;
      }
    }
  }
}

TEST(YarnNormalForce, InvariantUnderRigidMotionAndAMirroredWeave) {
  const WovenFabric f = fabricWith("twill_2_2");
  const YarnSheet s = patch(f);
  std::mt19937 rng(149);
  std::uniform_real_distribution<Real> unit(-1, 1);
  VecX q = wrapped(s, 15e-3, 1.01);
  for (std::size_t n = 0; n < s.nodeCount(); ++n) q.segment<3>(5 * n) += 2e-5 * Vec3(unit(rng), unit(rng), unit(rng));
  const CrossingCompression cc = crossingCompression(s, f, q);
  const Mat3 R = Eigen::AngleAxis<Real>(2.1, Vec3(1, -3, 2).normalized()).toRotationMatrix();
  VecX moved = q;
  for (std::size_t n = 0; n < s.nodeCount(); ++n) moved.segment<3>(5 * n) = R * q.segment<3>(5 * n) + Vec3(0.4, -1, 0.2);
  const CrossingCompression cm = crossingCompression(s, f, moved);
  Real scale = 0;
  for (Real x : cc.force) scale = std::max(scale, x);
  ASSERT_GT(scale, 0);
  for (std::size_t c = 0; c < cc.force.size(); ++c) {
    EXPECT_NEAR(cm.force[c], cc.force[c], 1e-8 * scale);
    EXPECT_LT((cm.normal[c] - R * cc.normal[c]).norm(), 1e-9);
  }
  // Swapping every weave flag mirrors the flat sheet through its plane: the same compression, the
  // normals flipped.
  WovenFabric mirrored = f;
  mirrored.weave = customWeave({{0, 0, 1, 1}, {0, 1, 1, 0}, {1, 1, 0, 0}, {1, 0, 0, 1}});
  const YarnSheet ms = patch(mirrored);
  for (std::size_t c = 0; c < s.grid.crossings.size(); ++c)
    ASSERT_NE(ms.grid.crossings[c].warp_on_top, s.grid.crossings[c].warp_on_top);
  const CrossingCompression a = crossingCompression(s, f, s.rest), b = crossingCompression(ms, mirrored, ms.rest);
  for (std::size_t c = 0; c < a.force.size(); ++c) {
    EXPECT_NEAR(a.force[c], b.force[c], 1e-12 * scale);
    EXPECT_LT((a.normal[c] + b.normal[c]).norm(), 1e-15);
  }
}

}  // namespace
}  // namespace textile_handling
