// Tests of BlockLdlt (src/sim/block_ldlt.h), the coarse level's block LDL^T: solutions against dense
// and scalar sparse (BlockSparseLdlt) references on random and grid patterns for block sizes 1 to 6, the
// analysis reused for new values, indefinite matrices refused without spoiling the next factorisation,
// the two subtrees factorised and solved side by side with the same results on one and two threads,
// and misuse.
#include "../../src/sim/block_ldlt.h"
#include "../../src/sim/sparse_ldlt.h"
#include "textile_handling/sim/sim_errors.h"
#include "../test_support.h"
#include "sim_test_support.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <limits>
#include <random>
#include <utility>
#include <vector>

namespace textile_handling {
namespace {

using Couplings = std::vector<std::pair<Index, Index>>;
using sim_test_support::fillSymmetric;
using sim_test_support::gridCouplings;

Couplings randomCouplings(std::mt19937& gen, Index n, int count) {
  std::uniform_int_distribution<Index> node(0, n - 1);
  Couplings c;
  for (int k = 0; k < count; ++k) c.emplace_back(node(gen), node(gen));
  return c;
}

// A w x h grid system with b x b blocks, analysed.
struct GridSystem {
  GridSystem(Index w, Index h, int b, unsigned seed) : gen(seed), pattern(w * h, b, gridCouplings(w, h)), a(&pattern) {
    ldlt.analyse(pattern);
  }
  // x = A^-1 rhs by the factorisation, with the residual of A x = rhs checked.
  VecX solveChecked(const VecX& rhs) {
    VecX x, ax;
    ldlt.solve(rhs, x);
    a.multiply(x, ax);
    EXPECT_LE((ax - rhs).norm(), 1e-11 * rhs.norm());
    return x;
  }
  std::mt19937 gen;
  BlockPattern pattern;
  BlockSparseMatrix a;
  BlockLdlt ldlt;
};

TEST(BlockLdlt, SolvesRandomDefiniteSystemsLikeADenseFactorisation) {
  for (int b = 1; b <= 6; ++b)
    for (unsigned seed = 0; seed < 8; ++seed) {
      SCOPED_TRACE("block size " + std::to_string(b) + ", seed " + std::to_string(seed));
      std::mt19937 gen(1000 * b + seed);
      const Index n = 1 + static_cast<Index>(gen() % 50);
      const BlockPattern p(n, b, randomCouplings(gen, n, static_cast<int>(gen() % (3 * n + 1))));
      BlockSparseMatrix a(&p);
      fillSymmetric(gen, a, true);
      BlockLdlt ldlt;
      ldlt.analyse(p);
      ASSERT_TRUE(ldlt.factorize(a));
      const VecX rhs = sim_test_support::randomVector(n * b, gen());
      VecX x;
      ldlt.solve(rhs, x);
      const Eigen::MatrixXd dense = sim_test_support::denseMatrix(a);
      const VecX reference = dense.ldlt().solve(rhs);
      ASSERT_EQ(x.size(), rhs.size());
      EXPECT_LE((x - reference).norm(), 1e-11 * reference.norm());
      EXPECT_LE((dense * x - rhs).norm(), 1e-11 * rhs.norm());
    }
}

TEST(BlockLdlt, MatchesTheScalarFactorisationOnAGridAndReusesItsAnalysis) {
  GridSystem g(30, 24, 5, 7);
  BlockSparseLdlt scalar;
  scalar.setPattern(g.pattern);
  // The grid's fill: more blocks in L than the pattern's lower triangle.
  EXPECT_GT(g.ldlt.factorBlocks(), (g.pattern.numBlocks() - g.pattern.numNodes()) / 2);
  VecX first;
  for (int round = 0; round < 3; ++round) {  // new values on the same analysis
    SCOPED_TRACE("round " + std::to_string(round));
    fillSymmetric(g.gen, g.a, true);
    ASSERT_TRUE(g.ldlt.factorize(g.a));
    ASSERT_TRUE(scalar.factorize(g.a, {}));
    const VecX rhs = sim_test_support::randomVector(g.pattern.numNodes() * 5, g.gen());
    const VecX x = g.solveChecked(rhs);
    VecX reference;
    scalar.solve(rhs, reference);
    EXPECT_LE((x - reference).norm(), 1e-11 * reference.norm());
    if (round == 0) first = x;
    else EXPECT_GT((x - first).norm(), 0.1 * first.norm());  // the new values were used
  }
}

// A grid large enough for the parallel path (50 x 50 blocks of 5): the elimination tree splits into
// two groups of subtrees that carry most of the rows, the rest is their ancestors; the factor and the
// solution are bitwise the same on one and two threads and solve the system.
TEST(BlockLdlt, SubtreesRunSideBySideWithTheSameResultsOnOneAndTwoThreads) {
  GridSystem g(50, 50, 5, 13);
  const std::array<Index, 3> parts = g.ldlt.partSizes();
  EXPECT_EQ(parts[0] + parts[1] + parts[2], g.pattern.numNodes());
  EXPECT_GT(parts[0], g.pattern.numNodes() / 4);
  EXPECT_GT(parts[1], g.pattern.numNodes() / 4);
  EXPECT_LT(parts[2], g.pattern.numNodes() / 4);
  fillSymmetric(g.gen, g.a, true);
  const VecX rhs = sim_test_support::randomVector(g.pattern.numNodes() * 5, g.gen());
  auto solveOn = [&](int threads) {
    test_support::ThreadScope scope(threads);
    EXPECT_TRUE(g.ldlt.factorize(g.a));
    return g.solveChecked(rhs);
  };
  const VecX one = solveOn(1), two = solveOn(2);
  EXPECT_TRUE(one == two);
  BlockSparseLdlt scalar;
  scalar.setPattern(g.pattern);
  ASSERT_TRUE(scalar.factorize(g.a, {}));
  VecX reference;
  scalar.solve(rhs, reference);
  EXPECT_LE((two - reference).norm(), 1e-11 * reference.norm());
}

TEST(BlockLdlt, RefusesAnIndefiniteMatrixAndRecoversOnTheNext) {
  GridSystem g(12, 12, 3, 11);
  fillSymmetric(g.gen, g.a, false);
  EXPECT_LT(sim_test_support::denseMatrix(g.a).selfadjointView<Eigen::Lower>().eigenvalues().minCoeff(), 0);
  EXPECT_FALSE(g.ldlt.factorize(g.a));
  VecX x;
  EXPECT_THROW(g.ldlt.solve(sim_test_support::randomVector(g.pattern.numNodes() * 3, g.gen()), x), SimError);
  // A definite matrix afterwards factorises correctly (the failed run's workspace is not reused).
  fillSymmetric(g.gen, g.a, true);
  ASSERT_TRUE(g.ldlt.factorize(g.a));
  g.solveChecked(sim_test_support::randomVector(g.pattern.numNodes() * 3, g.gen()));
  // A non-finite value is refused too.
  g.a.block(g.pattern.diagonal(5))[0] = std::numeric_limits<Real>::quiet_NaN();
  EXPECT_FALSE(g.ldlt.factorize(g.a));
}

TEST(BlockLdlt, RejectsMisuse) {
  const BlockPattern p(4, 3, {{0, 1}, {2, 3}});
  const BlockPattern other(4, 3, {{0, 1}});
  const BlockPattern wide(2, 7, {{0, 1}});
  BlockLdlt ldlt;
  BlockSparseMatrix a(&p), b(&other);
  EXPECT_THROW(ldlt.factorize(a), SimError);  // not analysed
  EXPECT_THROW(ldlt.analyse(wide), SimError);
  ldlt.analyse(p);
  EXPECT_THROW(ldlt.factorize(b), SimError);  // another pattern
  std::mt19937 gen(3);
  fillSymmetric(gen, a, true);
  ASSERT_TRUE(ldlt.factorize(a));
  VecX x;
  EXPECT_THROW(ldlt.solve(VecX::Zero(5), x), SimError);
}

}  // namespace
}  // namespace textile_handling
