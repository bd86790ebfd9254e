// Tests for sim/yarn_kernels.h: stretch, bending and gravity against finite differences, the forces of
// the notes, the clamped Hessians' definiteness, gravity sliding material down a hanging yarn, and the
// segment mass matrix (symmetry, rank 6 of 8, null motion, kinetic energy, a positive definite crossing).
#include "yarn_test_support.h"  // first: see there

#include "textile_handling/sim/yarn_kernels.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <functional>
#include <random>

namespace textile_handling {
namespace yarn {
namespace {

using yarn_test_support::eigenvalues;

// Random segments of rest length ~1 mm, stretched or compressed by up to 30 %, at random places.
SegmentVector randomSegment(std::mt19937& rng, Real stretch_lo = 0.7, Real stretch_hi = 1.3) {
  std::uniform_real_distribution<Real> unit(-1, 1), st(stretch_lo, stretch_hi), du(0.5e-3, 1.5e-3);
  const Vec3 x0(0.01 * unit(rng), 0.01 * unit(rng), 0.01 * unit(rng));
  const Vec3 dir = Vec3(unit(rng), unit(rng), unit(rng)).normalized();
  const Real D = du(rng), u0 = 0.05 * (unit(rng) + 1);
  return packSegment(x0, u0, x0 + st(rng) * D * dir, u0 + D);
}

using yarn_test_support::numericGradientN;
using yarn_test_support::numericJacobianN;

constexpr Real kKs = 1.963;  // Y pi R^2 of the source's shirt [N]

TEST(YarnStretch, GradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 40; ++trial) {
    const SegmentVector q = randomSegment(rng);
    const SegmentVector g = stretchGradient(q, kKs);
    const SegmentVector gn = numericGradientN<8>([](const SegmentVector& p) { return stretchEnergy(p, kKs); }, q, 1e-8);
    EXPECT_LT((g - gn).norm(), 1e-5 * std::max<Real>(1, g.norm())) << "trial " << trial;
    const SegmentMatrix H = stretchHessian(q, kKs);
    const SegmentMatrix Hn = numericJacobianN<8>([](const SegmentVector& p) { return stretchGradient(p, kKs); }, q, 1e-9);
    EXPECT_LT((H - Hn).norm(), 1e-5 * H.norm()) << "trial " << trial;
    EXPECT_LT((H - H.transpose()).norm(), 1e-12 * H.norm());
    // Moving the whole segment, or sliding both ends equally, changes nothing.
    EXPECT_LT((g.segment<3>(0) + g.segment<3>(4)).norm(), 1e-12 * std::max<Real>(1, g.norm()));
    EXPECT_NEAR(g[3] + g[7], 0, 1e-12 * std::max<Real>(1, g.norm()));
  }
}

TEST(YarnStretch, ForcesOfTheNotesAndRest) {
  // A segment of rest length 1 mm stretched to 1.1 mm along x.
  const SegmentVector q = packSegment(Vec3::Zero(), 0.2, Vec3(1.1e-3, 0, 0), 0.201);
  const SegmentVector f = -stretchGradient(q, kKs);
  EXPECT_NEAR(f[4], -kKs * 0.1, 1e-12);               // F_x1 = -k_s (l / D - 1) t
  EXPECT_NEAR(f[0], kKs * 0.1, 1e-12);
  EXPECT_NEAR(f[7], 0.5 * kKs * (1.21 - 1), 1e-9);     // F_u1 = k_s / 2 (l^2 / D^2 - 1): pulls material in
  EXPECT_NEAR(f[3], -0.5 * kKs * (1.21 - 1), 1e-9);
  EXPECT_NEAR(stretchEnergy(q, kKs), kKs * 1e-8 / 2e-3, 1e-15);
  // At rest length: no energy, no force.
  const SegmentVector rest = packSegment(Vec3(0, 0, 1), 0, Vec3(0, 1e-3, 1), 1e-3);
  EXPECT_NEAR(stretchEnergy(rest, kKs), 0, 1e-18);
  EXPECT_LT(stretchGradient(rest, kKs).norm(), 1e-12);
}

TEST(YarnStretch, ClampedHessianIsPositiveSemiDefinite) {
  std::mt19937 rng(5);
  int indefinite = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const SegmentVector q = randomSegment(rng, 0.6, 0.95);  // compressed
    const Eigen::VectorXd full = eigenvalues(stretchHessian(q, kKs)), clamped = eigenvalues(stretchHessianClamped(q, kKs));
    const Real scale = full.cwiseAbs().maxCoeff();
    indefinite += full.minCoeff() < -1e-6 * scale;
    EXPECT_GE(clamped.minCoeff(), -1e-9 * scale) << "trial " << trial;
  }
  EXPECT_EQ(indefinite, 40);  // a compressed segment's exact Hessian is indefinite
  // Stretched: clamping changes nothing.
  const SegmentVector q = randomSegment(rng, 1.05, 1.3);
  EXPECT_LT((stretchHessian(q, kKs) - stretchHessianClamped(q, kKs)).norm(), 1e-12 * stretchHessian(q, kKs).norm());
}

constexpr Real kKb = 1.96e-9;  // B pi R^2 of the source's shirt [N m^2]

// A bending stencil with segments of ~1 mm bent by `theta` [rad] in a random plane, at a random place.
BendVector bentStencil(std::mt19937& rng, Real theta) {
  std::uniform_real_distribution<Real> unit(-1, 1), len(0.7e-3, 1.3e-3);
  const Vec3 e1 = Vec3(unit(rng), unit(rng), unit(rng)).normalized();
  const Vec3 e2 = e1.cross(Vec3(unit(rng), unit(rng), unit(rng))).normalized();
  const Vec3 x0(0.01 * unit(rng), 0.01 * unit(rng), 0.01 * unit(rng));
  const Real la = len(rng), lb = len(rng), u2 = 0.05 * (unit(rng) + 1);
  const Vec3 x2 = x0 - la * e1, x1 = x0 + lb * (std::cos(theta) * e1 + std::sin(theta) * e2);
  return packBendStencil(x2, u2, x0, u2 + len(rng), x1, u2 + len(rng) + len(rng));
}

TEST(YarnBend, GradientAndHessianMatchFiniteDifferencesFromStraightToSharp) {
  std::mt19937 rng(17);
  // Straight, nearly straight (series branch), at the series threshold, and clearly bent.
  for (Real theta : {0.0, 1e-4, 1e-3, 0.00999, 0.01001, 0.1, 0.5, 1.0, 2.0, 2.8}) {
    for (int trial = 0; trial < 4; ++trial) {
      const BendVector q = bentStencil(rng, theta);
      const BendVector g = bendGradient(q, kKb);
      const BendVector gn = numericGradientN<12>([](const BendVector& p) { return bendEnergy(p, kKb); }, q, 1e-9);
      const Real gscale = std::max<Real>(g.norm(), kKb * 1e3);  // floor: the gradient at theta ~ 1e-3
      EXPECT_LT((g - gn).norm(), 1e-5 * gscale) << "theta " << theta;
      const BendMatrix H = bendHessian(q, kKb);
      const BendMatrix Hn = numericJacobianN<12>([](const BendVector& p) { return bendGradient(p, kKb); }, q, 1e-9);
      EXPECT_LT((H - Hn).norm(), 1e-5 * H.norm()) << "theta " << theta;
      EXPECT_LT((H - H.transpose()).norm(), 1e-12 * H.norm());
      // Moving the stencil changes nothing; u0 does not appear.
      EXPECT_LT((g.segment<3>(0) + g.segment<3>(4) + g.segment<3>(8)).norm(), 1e-12 * gscale);
      EXPECT_EQ(g[7], 0.0);
      EXPECT_EQ(H.row(7).norm(), 0.0);
    }
  }
}

TEST(YarnBend, SeriesAndClosedFormAgreeAtTheirBorder) {
  // The small-angle series takes over below tan(theta) = 1e-2: the Hessian must not jump there.
  for (unsigned seed : {23u, 29u, 31u}) {
    std::mt19937 rng_a(seed), rng_b(seed);
    const Real border = std::atan(1e-2);
    const BendMatrix below = bendHessian(bentStencil(rng_a, border - 1e-12), kKb);
    const BendMatrix above = bendHessian(bentStencil(rng_b, border + 1e-12), kKb);
    EXPECT_LT((below - above).norm(), 1e-9 * below.norm()) << "seed " << seed;
  }
}

TEST(YarnBend, ValueAndSlidingForceOfTheNotes) {
  // A right-angle bend, segments 1 mm, u1 - u2 = 2 mm: V = k_b (pi/2)^2 / 2 mm.
  const BendVector q = packBendStencil(Vec3(-1e-3, 0, 0), 0.1, Vec3::Zero(), 0.101, Vec3(0, 1e-3, 0), 0.102);
  const Real theta = M_PI / 2, D2 = 2e-3;
  EXPECT_NEAR(bendEnergy(q, kKb), kKb * theta * theta / D2, 1e-12 * kKb / D2);
  const BendVector f = -bendGradient(q, kKb);
  EXPECT_NEAR(f[11], kKb * theta * theta / (D2 * D2), 1e-9 * kKb / (D2 * D2));  // F_u1 = k_b theta^2 / D2^2
  EXPECT_NEAR(f[3], -f[11], 1e-18);
  // Straight: no energy, no force, and the Hessian is positive semi-definite (a minimum).
  const BendVector straight = packBendStencil(Vec3(-1e-3, 0, 0), 0.1, Vec3::Zero(), 0.101, Vec3(1e-3, 0, 0), 0.102);
  EXPECT_EQ(bendEnergy(straight, kKb), 0.0);
  EXPECT_LT(bendGradient(straight, kKb).norm(), 1e-30);
  EXPECT_GE(eigenvalues(bendHessian(straight, kKb)).minCoeff(), -1e-12 * bendHessian(straight, kKb).norm());
  // Rotating the stencil rotates the gradient.
  const Mat3 R = Eigen::AngleAxis<Real>(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  BendVector qr = q;
  for (int node : {0, 4, 8}) qr.segment<3>(node) = R * q.segment<3>(node);
  const BendVector gr = bendGradient(qr, kKb), g = bendGradient(q, kKb);
  for (int node : {0, 4, 8}) EXPECT_LT((gr.segment<3>(node) - R * g.segment<3>(node)).norm(), 1e-12 * g.norm());
}

TEST(YarnBend, ClampedHessianIsPositiveSemiDefinite) {
  std::mt19937 rng(19);
  int indefinite = 0;
  for (Real theta : {0.3, 0.8, 1.5, 2.5}) {
    for (int trial = 0; trial < 5; ++trial) {
      const BendVector q = bentStencil(rng, theta);
      const Eigen::VectorXd full = eigenvalues(bendHessian(q, kKb)), clamped = eigenvalues(bendHessianClamped(q, kKb));
      const Real scale = full.cwiseAbs().maxCoeff();
      indefinite += full.minCoeff() < -1e-9 * scale;
      EXPECT_GE(clamped.minCoeff(), -1e-9 * scale);
    }
  }
  EXPECT_GT(indefinite, 0);  // the exact bending Hessian is indefinite for bent yarns
}

// Gently bent yarns (a hanging sheet's stencils) have slightly indefinite Hessians; clamping moves
// them by no more than a small multiple of their most negative eigenvalue.
TEST(YarnBend, ClampedHessianOfAGentleBendStaysCloseToTheExactOne) {
  std::mt19937 rng(23);
  int indefinite = 0;
  for (Real theta : {0.01, 0.03, 0.1, 0.2}) {
    for (int trial = 0; trial < 10; ++trial) {
      const BendVector q = bentStencil(rng, theta);
      const BendMatrix exact = bendHessian(q, kKb), clamped = bendHessianClamped(q, kKb);
      const Eigen::VectorXd full = eigenvalues(exact);
      const Real scale = full.cwiseAbs().maxCoeff(), negative = std::max<Real>(0, -full.minCoeff());
      indefinite += negative > 1e-9 * scale;
      EXPECT_GE(eigenvalues(clamped).minCoeff(), -1e-9 * scale);
      const Real moved = eigenvalues(clamped - exact).cwiseAbs().maxCoeff();
      EXPECT_LE(moved, 10 * negative + 1e-9 * scale) << "theta " << theta << ", most negative " << negative << " of " << scale;
    }
  }
  EXPECT_GT(indefinite, 0);
}

// bendHessianClamped() clamps the bend's frame blocks; that must be the eigenvalue clamp of the
// 7 x 7 Hessian in the reduced variables r = (a, b, D2) = (x0 - x2, x1 - x0, u1 - u2), recovered here
// from the 12 x 12 Hessian through r's Jacobian J (H12 = J^T H7 J, so H7 = J+^T H12 J+).
TEST(YarnBend, ClampedHessianIsTheEigenvalueClampOfTheReducedHessian) {
  Eigen::Matrix<Real, 7, 12> J = Eigen::Matrix<Real, 7, 12>::Zero();
  J.block<3, 3>(0, 0) = -Mat3::Identity();
  J.block<3, 3>(0, 4) = Mat3::Identity();
  J.block<3, 3>(3, 4) = -Mat3::Identity();
  J.block<3, 3>(3, 8) = Mat3::Identity();
  J(6, 3) = -1;
  J(6, 11) = 1;
  const Eigen::Matrix<Real, 12, 7> pinv = J.transpose() * (J * J.transpose()).inverse();
  std::mt19937 rng(29);
  for (Real theta : {0.0, 1e-9, 1e-5, 2e-4, 0.01, 0.3, 1.5, 2.5, 3.0}) {
    for (int trial = 0; trial < 5; ++trial) {
      const BendVector q = bentStencil(rng, theta);
      const Eigen::Matrix<Real, 7, 7> h7 = pinv.transpose() * bendHessian(q, kKb) * pinv;
      ASSERT_LT((J.transpose() * h7 * J - bendHessian(q, kKb)).norm(), 1e-12 * bendHessian(q, kKb).norm());
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<Real, 7, 7>> es(h7);
      const Eigen::Matrix<Real, 7, 7> c7 = es.eigenvectors() * es.eigenvalues().cwiseMax(0).asDiagonal() * es.eigenvectors().transpose();
      const BendMatrix reference = J.transpose() * c7 * J, clamped = bendHessianClamped(q, kKb);
      ASSERT_TRUE(clamped.allFinite()) << "theta " << theta;
      EXPECT_LT((clamped - reference).norm(), 1e-9 * reference.norm()) << "theta " << theta << ", trial " << trial;
    }
  }
}

TEST(YarnGravity, GradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(7);
  const Real rho = 5e-5;
  const Vec3 g(0.3, -0.2, -9.81);
  for (int trial = 0; trial < 20; ++trial) {
    const SegmentVector q = randomSegment(rng);
    const SegmentVector grad = gravityGradient(q, rho, g);
    const SegmentVector gn = numericGradientN<8>([&](const SegmentVector& p) { return gravityEnergy(p, rho, g); }, q, 1e-7);
    EXPECT_LT((grad - gn).norm(), 1e-9 * std::max<Real>(1e-6, grad.norm()) + 1e-15);
    const SegmentMatrix Hn = numericJacobianN<8>([&](const SegmentVector& p) { return gravityGradient(p, rho, g); }, q, 1e-7);
    EXPECT_LT((gravityHessian(rho, g) - Hn).norm(), 1e-9);
  }
  // The position forces are the segment's weight, split between its nodes.
  const SegmentVector q = packSegment(Vec3::Zero(), 0, Vec3(1e-3, 0, 0), 1e-3);
  const SegmentVector f = -gravityGradient(q, rho, Vec3(0, 0, -kGravity));
  EXPECT_NEAR(f[2] + f[6], -rho * 1e-3 * kGravity, 1e-15);
}

TEST(YarnGravity, SlidesMaterialIntoTheLowerSegmentOfAHangingYarn) {
  // A vertical yarn: top (z = 0), middle (z = -L), bottom (z = -2L), straight and at rest length.
  const Real L = 1e-3, rho = 5e-5;
  const Vec3 g(0, 0, -kGravity);
  const SegmentVector upper = packSegment(Vec3::Zero(), 0, Vec3(0, 0, -L), L);
  const SegmentVector lower = packSegment(Vec3(0, 0, -L), L, Vec3(0, 0, -2 * L), 2 * L);
  // The middle node's sliding force: u1 of the upper segment, u0 of the lower one.
  const Real f_u = -(gravityGradient(upper, rho, g)[7] + gravityGradient(lower, rho, g)[3]);
  EXPECT_NEAR(f_u, -rho * kGravity * L, 1e-15);
  // Negative: u of the middle node decreases, so the upper segment's rest length D = u_mid - u_top
  // shrinks and the lower one's grows: material slides down.
  EXPECT_LT(f_u, 0);
}

TEST(YarnSegmentMass, SymmetricRankSixWithSlidingAsNullMotion) {
  std::mt19937 rng(11);
  const Real rho = 5e-5;
  for (int trial = 0; trial < 10; ++trial) {
    const SegmentVector q = randomSegment(rng);
    const SegmentMatrix M = segmentMass(q, rho);
    EXPECT_LT((M - M.transpose()).norm(), 1e-15 * M.norm());
    const Eigen::VectorXd ev = eigenvalues(M);
    const Real top = ev.maxCoeff();
    int positive = 0;
    for (int k = 0; k < 8; ++k) {
      EXPECT_GT(ev[k], -1e-12 * top);
      positive += ev[k] > 1e-9 * top;
    }
    EXPECT_EQ(positive, 6);
    // Null motion: both nodes slide along the yarn (xdot = udot w) without moving material.
    const Real D = q[7] - q[3];
    const Vec3 w = (q.segment<3>(4) - q.segment<3>(0)) / D;
    const SegmentVector slide = packSegment(0.3 * w, 0.3, -0.7 * w, -0.7);
    EXPECT_LT((M * slide).norm(), 1e-12 * top);
  }
}

TEST(YarnSegmentMass, KineticEnergyIsTheIntegralAlongTheSegment) {
  // T = 1/2 qdot^T M qdot against 3-point Gauss quadrature (exact for the quadratic integrand) of
  // 1/2 rho |xdot(u)|^2 over the segment, with xdot(u) from the notes' eq. 2.
  std::mt19937 rng(13);
  std::uniform_real_distribution<Real> unit(-1, 1);
  const Real rho = 5e-5;
  for (int trial = 0; trial < 10; ++trial) {
    const SegmentVector q = randomSegment(rng);
    SegmentVector qdot;
    for (int k = 0; k < 8; ++k) qdot[k] = unit(rng) * (k % 4 == 3 ? 1e-3 : 1.0);
    const Real D = q[7] - q[3];
    const Vec3 w = (q.segment<3>(4) - q.segment<3>(0)) / D;
    const Vec3 a = qdot.segment<3>(0) - qdot[3] * w, b = qdot.segment<3>(4) - qdot[7] * w;
    const Real nodes[3] = {0.5 - std::sqrt(0.15), 0.5, 0.5 + std::sqrt(0.15)}, weights[3] = {5.0 / 18, 8.0 / 18, 5.0 / 18};
    Real T = 0;
    for (int k = 0; k < 3; ++k) T += weights[k] * 0.5 * rho * D * ((1 - nodes[k]) * a + nodes[k] * b).squaredNorm();
    EXPECT_NEAR(0.5 * qdot.dot(segmentMass(q, rho) * qdot), T, 1e-12 * T);
  }
}

TEST(YarnSegmentMass, ACrossingWithAWarpAndAWeftSegmentIsPositiveDefinite) {
  // Crossing node c = (x, u, v) joined to a warp end node (x only) along x and a weft end node along y.
  // DOFs: c.x (0-2), c.u (3), c.v (4), warp end x (5-7), weft end x (8-10).
  const Real rho = 5e-5, L = 1e-3;
  const SegmentMatrix warp = segmentMass(packSegment(Vec3::Zero(), 0.01, Vec3(L, 0, 0), 0.01 + L), rho);
  const SegmentMatrix weft = segmentMass(packSegment(Vec3::Zero(), 0.02, Vec3(0, L, 0), 0.02 + L), rho);
  Eigen::Matrix<Real, 11, 11> M = Eigen::Matrix<Real, 11, 11>::Zero();
  // Each segment's (x0, s0, x1) rows and columns (the end node's sliding coordinate is held: dropped).
  auto add = [&](const SegmentMatrix& m, int slide_dof, int end_dof) {
    const int map[7] = {0, 1, 2, slide_dof, end_dof, end_dof + 1, end_dof + 2};
    for (int r = 0; r < 7; ++r)
      for (int c = 0; c < 7; ++c) M(map[r], map[c]) += m(r, c);
  };
  add(warp, 3, 5);
  add(weft, 4, 8);
  const Eigen::VectorXd ev = eigenvalues(M);
  EXPECT_GT(ev.minCoeff(), 1e-6 * ev.maxCoeff());
  // One segment alone with its free crossing: singular (sliding along that yarn is free).
  Eigen::Matrix<Real, 11, 11> only_warp = Eigen::Matrix<Real, 11, 11>::Zero();
  std::swap(M, only_warp);
  add(warp, 3, 5);
  M(4, 4) = M(8, 8) = M(9, 9) = M(10, 10) = 1;  // the weft's DOFs out of the way
  EXPECT_LT(eigenvalues(M).minCoeff(), 1e-12);
}

}  // namespace
}  // namespace yarn
}  // namespace textile_handling
