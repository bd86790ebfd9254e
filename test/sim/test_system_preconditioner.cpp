// Tests of SystemPreconditioner (src/sim/system_preconditioner.h): the two-level V(nu, nu) cycle against
// a dense evaluation of its formula (block-Jacobi smoothing, Galerkin coarse correction on the node
// aggregates), with pinned nodes and for block sizes 3, 4 and 5, and the symmetry CG relies on.
#include "../../src/sim/system_preconditioner.h"
#include "sim_test_support.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace textile_handling {
namespace {

struct Case {
  int block;
  int smoothing_steps;
};

// The V(nu, nu) cycle of system_preconditioner.h written out densely: A_f is A with the pinned rows and
// columns zeroed, D^-1 the inverses of A's free diagonal blocks (zero on pinned nodes), P the
// piecewise-constant prolongator of `aggregate`, Ac = P^T A P; nu = 0 is the additive form D^-1 + P Ac^-1 P^T.
VecX denseVCycle(const Eigen::MatrixXd& a_full, const std::vector<char>& pinned, const std::vector<Index>& aggregate,
                 int b, int nu, Real w, const VecX& r) {
  const Index n = static_cast<Index>(pinned.size());
  Eigen::MatrixXd a = a_full;
  for (Index i = 0; i < n; ++i)
    if (pinned[static_cast<std::size_t>(i)]) {
      a.middleRows(i * b, b).setZero();
      a.middleCols(i * b, b).setZero();
    }
  Eigen::MatrixXd d_inv = Eigen::MatrixXd::Zero(n * b, n * b);
  for (Index i = 0; i < n; ++i)
    if (!pinned[static_cast<std::size_t>(i)]) d_inv.block(i * b, i * b, b, b) = a.block(i * b, i * b, b, b).inverse();
  Index na = 0;
  for (Index g : aggregate) na = std::max(na, g + 1);
  Eigen::MatrixXd p = Eigen::MatrixXd::Zero(n * b, na * b);
  for (Index i = 0; i < n; ++i)
    if (aggregate[static_cast<std::size_t>(i)] >= 0)
      p.block(i * b, aggregate[static_cast<std::size_t>(i)] * b, b, b).setIdentity();
  const Eigen::MatrixXd ac = p.transpose() * a * p;
  if (nu == 0) return d_inv * r + p * ac.ldlt().solve(p.transpose() * r);  // the additive form
  VecX z = w * d_inv * r;
  for (int s = 1; s < nu; ++s) z += w * d_inv * (r - a * z);
  z += p * ac.ldlt().solve(p.transpose() * (r - a * z));
  for (int s = 0; s < nu; ++s) z += w * d_inv * (r - a * z);
  return z;
}

TEST(SystemPreconditioner, TwoLevelCycleMatchesItsDenseFormulaWithPinnedNodes) {
  for (const Case c : {Case{3, 1}, Case{5, 1}, Case{4, 1}, Case{5, 2}, Case{3, 0}}) {
    SCOPED_TRACE("block " + std::to_string(c.block) + ", smoothing steps " + std::to_string(c.smoothing_steps));
    std::mt19937 gen(static_cast<unsigned>(17 * c.block + c.smoothing_steps));
    const Index w = 13, h = 9, n = w * h;
    const BlockPattern pattern(n, c.block, sim_test_support::gridCouplings(w, h));
    BlockSparseMatrix a(&pattern);
    sim_test_support::fillSymmetric(gen, a, true);
    std::vector<char> pinned(static_cast<std::size_t>(n), 0);
    pinned[0] = pinned[static_cast<std::size_t>(w - 1)] = pinned[static_cast<std::size_t>(n / 2)] = 1;
    const Real weight = 0.7;
    SystemPreconditioner m;
    ASSERT_TRUE(m.update(a, pinned, PreconditionerKind::kTwoLevel, c.smoothing_steps, weight,
                         BlockJacobi::Inverse::kPlain));
    ASSERT_TRUE(m.usesCoarseLevel());
    const std::vector<Index> aggregate = m.aggregateOfNode();
    ASSERT_EQ(aggregate.size(), pinned.size());
    Index aggregates = 0;
    for (Index i = 0; i < n; ++i) {
      EXPECT_EQ(aggregate[static_cast<std::size_t>(i)] < 0, pinned[static_cast<std::size_t>(i)] != 0) << "node " << i;
      aggregates = std::max(aggregates, aggregate[static_cast<std::size_t>(i)] + 1);
    }
    EXPECT_LT(3 * aggregates, n);  // a coarse level: several nodes per aggregate
    const Eigen::MatrixXd dense = sim_test_support::denseMatrix(a);
    VecX r1 = sim_test_support::randomVector(n * c.block, 3), r2 = sim_test_support::randomVector(n * c.block, 4);
    for (Index i = 0; i < n; ++i)
      if (pinned[static_cast<std::size_t>(i)]) {
        r1.segment(i * c.block, c.block).setZero();
        r2.segment(i * c.block, c.block).setZero();
      }
    VecX z1, z2;
    m.apply(r1, z1);
    m.apply(r2, z2);
    const VecX reference = denseVCycle(dense, pinned, aggregate, c.block, c.smoothing_steps, weight, r1);
    ASSERT_EQ(z1.size(), reference.size());
    EXPECT_LE((z1 - reference).norm(), 1e-12 * reference.norm());
    for (Index i = 0; i < n; ++i) {
      if (pinned[static_cast<std::size_t>(i)]) {
        EXPECT_EQ(z1.segment(i * c.block, c.block).norm(), 0.0) << "node " << i;
      }
    }
    // Symmetric: r2^T M r1 = r1^T M r2 (CG needs a symmetric preconditioner).
    EXPECT_NEAR(r2.dot(z1), r1.dot(z2), 1e-12 * std::abs(r1.dot(z2)));
  }
}

}  // namespace
}  // namespace textile_handling
