// Tests for sim/yarn_sheet.h: the flat sheet at rest, the assembled gradient against finite differences,
// the assembled mass (total mass, symmetry, positive definite on the free DOFs, held DOFs massless).
// GCC 12 reports a -Wmaybe-uninitialized false positive inside Eigen's SelfAdjointEigenSolver
// (tridiagonalisation); silence it for this file only (it must precede the first Eigen include).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include "textile_handling/sim/yarn_sheet.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <random>

namespace textile_handling {
namespace {

// A 4 x 3 mm plain-weave patch at 1 yarn per mm: 4 x 3 crossings, every yarn with two free ends.
YarnSheet smallSheet() {
  const std::vector<Vec2> rect = {Vec2(0, 0), Vec2(4e-3, 0), Vec2(4e-3, 3e-3), Vec2(0, 3e-3)};
  return buildYarnSheet(layYarnGrid(rect, WovenFabric()));
}

Real totalYarnLength(const YarnSheet& s) {
  Real total = 0;
  for (const YarnPiece& p : s.grid.pieces) total += p.arc_length_m.back() - p.arc_length_m.front();
  return total;
}

// The rest state with every position moved by up to 0.1 mm and every crossing slid by up to 0.05 mm.
VecX perturbed(const YarnSheet& s, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<Real> unit(-1, 1);
  VecX q = s.rest;
  for (std::size_t n = 0; n < s.nodeCount(); ++n) {
    for (int c = 0; c < 3; ++c) q[5 * n + c] += 1e-4 * unit(rng);
    if (n < s.grid.crossings.size())
      for (int c = 3; c < 5; ++c) q[5 * n + c] += 5e-5 * unit(rng);
  }
  return q;
}

TEST(YarnSheet, FlatSheetIsAtRestExceptForGravity) {
  const YarnSheet s = smallSheet();
  ASSERT_EQ(s.grid.crossings.size(), 12u);
  ASSERT_EQ(s.nodeCount(), 12u + 14u);
  EXPECT_EQ(s.held_dofs.size(), 28u);
  const WovenFabric f;
  VecX grad;
  EXPECT_NEAR(yarnSheetEnergy(s, f, s.rest, Vec3::Zero(), &grad), 0, 1e-20);
  EXPECT_LT(grad.norm(), 1e-15);
  // With gravity: the position forces add up to the yarns' weight.
  yarnSheetEnergy(s, f, s.rest, Vec3(0, 0, -kGravity), &grad);
  Real fz = 0;
  for (std::size_t n = 0; n < s.nodeCount(); ++n) fz -= grad[5 * n + 2];
  EXPECT_NEAR(fz, -f.linear_density_kg_per_m * totalYarnLength(s) * kGravity, 1e-15);
  EXPECT_NEAR(totalYarnLength(s), 3 * 4e-3 + 4 * 3e-3, 1e-15);
}

TEST(YarnSheet, GradientMatchesFiniteDifferences) {
  const YarnSheet s = smallSheet();
  WovenFabric f;
  f.young_modulus_pa = 1e5;  // a soft yarn keeps stretch and bending of the same order here
  const VecX q = perturbed(s, 37);
  const Vec3 g(0, 0, -kGravity);
  VecX grad;
  yarnSheetEnergy(s, f, q, g, &grad);
  const Real h = 1e-9;
  for (Eigen::Index k = 0; k < q.size(); ++k) {
    VecX a = q, b = q;
    a[k] += h;
    b[k] -= h;
    const Real fd = (yarnSheetEnergy(s, f, a, g) - yarnSheetEnergy(s, f, b, g)) / (2 * h);
    EXPECT_NEAR(grad[k], fd, 1e-5 * grad.cwiseAbs().maxCoeff()) << "dof " << k;
  }
}

TEST(YarnSheet, HessianMatchesFiniteDifferencesAndClampedIsSemiDefinite) {
  const YarnSheet s = smallSheet();
  WovenFabric f;
  f.young_modulus_pa = 1e5;
  const VecX q = perturbed(s, 43);
  const Vec3 g(0, 0, -kGravity);
  const Eigen::MatrixXd H = Eigen::MatrixXd(yarnSheetHessian(s, f, q, g));
  EXPECT_LT((H - H.transpose()).norm(), 1e-12 * H.norm());
  const Real h = 1e-9;
  Eigen::MatrixXd Hn(q.size(), q.size());
  for (Eigen::Index k = 0; k < q.size(); ++k) {
    VecX a = q, b = q, ga, gb;
    a[k] += h;
    b[k] -= h;
    yarnSheetEnergy(s, f, a, g, &ga);
    yarnSheetEnergy(s, f, b, g, &gb);
    Hn.col(k) = (ga - gb) / (2 * h);
  }
  EXPECT_LT((H - Hn).norm(), 1e-5 * H.norm());
  // Without gravity, the clamped Hessian is positive semi-definite; the exact one here is not.
  const Eigen::VectorXd exact = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(yarnSheetHessian(s, f, q, Vec3::Zero())))
                                    .eigenvalues();
  const Eigen::VectorXd clamped =
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(yarnSheetHessian(s, f, q, Vec3::Zero(), true))).eigenvalues();
  EXPECT_LT(exact.minCoeff(), -1e-6 * exact.cwiseAbs().maxCoeff());
  EXPECT_GE(clamped.minCoeff(), -1e-9 * clamped.cwiseAbs().maxCoeff());
}

TEST(YarnSheet, MassHasTheYarnsWeightAndIsPositiveDefiniteOnFreeDofs) {
  const YarnSheet s = smallSheet();
  const WovenFabric f;
  std::mt19937 rng(41);
  std::uniform_real_distribution<Real> unit(-1, 1);
  VecX q = s.rest;
  for (std::size_t n = 0; n < s.nodeCount(); ++n)
    for (int c = 0; c < 3; ++c) q[5 * n + c] += 1e-4 * unit(rng);
  const Eigen::MatrixXd M = Eigen::MatrixXd(yarnSheetMass(s, f, q));
  EXPECT_LT((M - M.transpose()).norm(), 1e-15 * M.norm());
  // A uniform translation (no sliding) has kinetic energy 1/2 m |v|^2 with m the yarns' mass.
  VecX v = VecX::Zero(q.size());
  for (std::size_t n = 0; n < s.nodeCount(); ++n) v.segment<3>(5 * n) = Vec3(1, -2, 0.5);
  EXPECT_NEAR(v.dot(M * v), f.linear_density_kg_per_m * totalYarnLength(s) * Vec3(1, -2, 0.5).squaredNorm(), 1e-15);
  // Held DOFs carry nothing; the rest is positive definite.
  std::vector<char> held(q.size(), 0);
  for (std::size_t d : s.held_dofs) {
    held[d] = 1;
    EXPECT_EQ(M.row(static_cast<Eigen::Index>(d)).norm(), 0.0);
  }
  std::vector<Eigen::Index> free;
  for (Eigen::Index k = 0; k < q.size(); ++k)
    if (!held[k]) free.push_back(k);
  Eigen::MatrixXd Mf(free.size(), free.size());
  for (std::size_t r = 0; r < free.size(); ++r)
    for (std::size_t c = 0; c < free.size(); ++c) Mf(r, c) = M(free[r], free[c]);
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Mf).eigenvalues();
  EXPECT_GT(ev.minCoeff(), 1e-6 * ev.maxCoeff());
}

}  // namespace
}  // namespace textile_handling
