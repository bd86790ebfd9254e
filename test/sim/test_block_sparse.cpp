// Tests of BlockPattern / BlockSparseMatrix (textile_handling/sim/block_sparse.h): pattern
// construction and lookup, and y = A x against a dense reference for block sizes 3 and 5 (the fixed-size
// kernels) and generic sizes (1, 2, 4).
#include "../test_support.h"
#include "textile_handling/sim/block_sparse.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <random>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace textile_handling {
namespace {

using test_support::ThreadScope;

using Couplings = std::vector<std::pair<Index, Index>>;

Couplings randomCouplings(std::mt19937& gen, Index n, int count) {
  std::uniform_int_distribution<Index> node(0, n - 1);
  Couplings c;
  for (int k = 0; k < count; ++k) c.emplace_back(node(gen), node(gen));  // may repeat, may be (i, i)
  return c;
}

// Dense copy of a block-sparse matrix (blocks are stored row-major).
Eigen::MatrixXd toDense(const BlockSparseMatrix& A) {
  const BlockPattern& p = A.pattern();
  const int b = p.blockSize();
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(p.numNodes() * b, p.numNodes() * b);
  for (Index i = 0; i < p.numNodes(); ++i) {
    for (Index k = p.rowStart()[i]; k < p.rowStart()[i + 1]; ++k) {
      const Index j = p.column()[k];
      const Real* blk = A.block(k);
      for (int r = 0; r < b; ++r)
        for (int c = 0; c < b; ++c) D(i * b + r, j * b + c) = blk[r * b + c];
    }
  }
  return D;
}

TEST(BlockPattern, FindDiagonalAndLayout) {
  // 5 nodes, couplings 0-1, 1-3 (twice, once reversed), 4-4 (self), 2-0.
  const BlockPattern p(5, 3, {{0, 1}, {1, 3}, {3, 1}, {4, 4}, {2, 0}});
  EXPECT_EQ(p.numNodes(), 5);
  EXPECT_EQ(p.blockSize(), 3);
  // Rows: 0:{0,1,2} 1:{0,1,3} 2:{0,2} 3:{1,3} 4:{4}
  EXPECT_EQ(p.numBlocks(), 11);
  const std::vector<Index> expected_start = {0, 3, 6, 8, 10, 11};
  EXPECT_EQ(p.rowStart(), expected_start);
  const std::vector<Index> expected_col = {0, 1, 2, 0, 1, 3, 0, 2, 1, 3, 4};
  EXPECT_EQ(p.column(), expected_col);
  const std::set<std::pair<Index, Index>> present = {{0, 0}, {0, 1}, {0, 2}, {1, 0}, {1, 1}, {1, 3},
                                                     {2, 0}, {2, 2}, {3, 1}, {3, 3}, {4, 4}};
  for (Index i = 0; i < 5; ++i) {
    for (Index j = 0; j < 5; ++j) {
      const Index slot = p.find(i, j);
      if (present.count({i, j})) {
        ASSERT_GE(slot, p.rowStart()[i]) << i << "," << j;
        ASSERT_LT(slot, p.rowStart()[i + 1]) << i << "," << j;
        EXPECT_EQ(p.column()[slot], j);
      } else {
        EXPECT_EQ(slot, -1) << i << "," << j;
      }
    }
    EXPECT_EQ(p.diagonal(i), p.find(i, i));
  }
}

TEST(BlockPattern, RandomPatternsAreSymmetricSortedAndComplete) {
  std::mt19937 gen(7);
  for (int trial = 0; trial < 20; ++trial) {
    const Index n = 1 + static_cast<Index>(gen() % 40);
    const Couplings c = randomCouplings(gen, n, static_cast<int>(gen() % (3 * n + 1)));
    const BlockPattern p(n, 1 + static_cast<int>(gen() % 5), c);
    std::set<std::pair<Index, Index>> present;
    for (Index i = 0; i < n; ++i) present.insert({i, i});
    for (const auto& [i, j] : c) {
      present.insert({i, j});
      present.insert({j, i});
    }
    EXPECT_EQ(p.numBlocks(), static_cast<Index>(present.size()));
    ASSERT_EQ(p.rowStart().size(), static_cast<std::size_t>(n + 1));
    EXPECT_EQ(p.rowStart().front(), 0);
    EXPECT_EQ(p.rowStart().back(), p.numBlocks());
    for (Index i = 0; i < n; ++i) {
      // Columns strictly increasing within a row.
      for (Index k = p.rowStart()[i] + 1; k < p.rowStart()[i + 1]; ++k) EXPECT_LT(p.column()[k - 1], p.column()[k]);
      EXPECT_EQ(p.column()[p.diagonal(i)], i);
      for (Index j = 0; j < n; ++j) {
        const Index slot = p.find(i, j);
        EXPECT_EQ(slot >= 0, present.count({i, j}) == 1) << i << "," << j;
        if (slot >= 0) {
          EXPECT_EQ(p.column()[slot], j);
        }
      }
    }
  }
}

TEST(BlockPattern, RejectsBadInput) {
  EXPECT_THROW(BlockPattern(3, 3, {{0, 3}}), std::out_of_range);
  EXPECT_THROW(BlockPattern(3, 3, {{-1, 0}}), std::out_of_range);
  EXPECT_THROW(BlockPattern(3, 0, {}), std::invalid_argument);
  EXPECT_THROW(BlockPattern(-1, 3, {}), std::invalid_argument);
  const BlockPattern empty(0, 3, {});
  EXPECT_EQ(empty.numBlocks(), 0);
}

void checkMultiply(int block, unsigned seed) {
  SCOPED_TRACE("block size " + std::to_string(block) + ", seed " + std::to_string(seed));
  ThreadScope single(1);
  std::mt19937 gen(seed);
  std::uniform_real_distribution<Real> val(-1, 1);
  const Index n = 1 + static_cast<Index>(gen() % 60);
  const BlockPattern p(n, block, randomCouplings(gen, n, static_cast<int>(gen() % (4 * n + 1))));
  BlockSparseMatrix A(&p);
  ASSERT_EQ(A.values().size(), static_cast<std::size_t>(p.numBlocks()) * block * block);
  for (Real& v : A.values()) {
    EXPECT_EQ(v, 0.0);  // fresh matrices are zero
    v = val(gen);
  }
  // Independent dense reference from (i, j, r, c) -> value via find().
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(n * block, n * block);
  for (Index i = 0; i < n; ++i)
    for (Index j = 0; j < n; ++j) {
      const Index slot = p.find(i, j);
      if (slot < 0) continue;
      for (int r = 0; r < block; ++r)
        for (int c = 0; c < block; ++c) D(i * block + r, j * block + c) = A.values()[slot * block * block + r * block + c];
    }
  EXPECT_EQ((toDense(A) - D).norm(), 0.0);
  VecX x(n * block);
  for (Index k = 0; k < x.size(); ++k) x[k] = val(gen);
  VecX y = VecX::Constant(3, 99.0);  // wrong size and content on purpose: multiply() must resize
  A.multiply(x, y);
  ASSERT_EQ(y.size(), n * block);
  const VecX ref = D * x;
  EXPECT_LE((y - ref).norm(), 1e-13 * (ref.norm() + 1)) << "max diff " << (y - ref).cwiseAbs().maxCoeff();

  // Same result (bitwise) with 2 threads (checked on a few of the matrices only).
  if (seed % 5 == 0) {
    ThreadScope two(2);
    VecX y2;
    A.multiply(x, y2);
    EXPECT_TRUE(y == y2);
  }

  // setZero() clears every value.
  A.setZero();
  A.multiply(x, y);
  EXPECT_EQ(y.norm(), 0.0);
}

TEST(BlockSparseMatrix, MultiplyMatchesDenseBlock3) {
  for (unsigned s = 0; s < 15; ++s) checkMultiply(3, 100 + s);
}
TEST(BlockSparseMatrix, MultiplyMatchesDenseBlock5) {
  for (unsigned s = 0; s < 15; ++s) checkMultiply(5, 200 + s);
}
TEST(BlockSparseMatrix, MultiplyMatchesDenseGenericBlocks) {
  for (int b : {1, 2, 4})
    for (unsigned s = 0; s < 10; ++s) checkMultiply(b, 300 + 10 * b + s);
}

TEST(BlockSparseMatrix, Add3WritesRowMajorBlock) {
  const BlockPattern p(3, 3, {{0, 2}});
  BlockSparseMatrix A(&p);
  Mat3 m;
  m << 1, 2, 3, 4, 5, 6, 7, 8, 9;
  const Index slot = p.find(0, 2);
  A.add3(slot, m);
  A.add3(slot, m);
  const Real* blk = A.block(slot);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(blk[3 * r + c], 2 * m(r, c));
  // Only that block changed, and its action on x is the one of 2 m at rows 0..2, columns 6..8.
  VecX x(9);
  x << 0, 0, 0, 0, 0, 0, 1, -2, 0.5;
  VecX y;
  A.multiply(x, y);
  VecX expected = VecX::Zero(9);
  expected.head<3>() = 2 * m * x.tail<3>();
  EXPECT_EQ(y, expected);
}

}  // namespace
}  // namespace textile_handling
