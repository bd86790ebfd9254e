// The compact copy of a block-sparse matrix for products (src/sim/compact_block_matrix.h): each 5 x 5
// block is stored as its narrowest DOF subset, and the product equals the full one; subsets widen
// when a value appears outside them; NaN is not dropped; the same bits on any thread count.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "../../src/sim/compact_block_matrix.h"
#include "../test_support.h"
#include "textile_handling/sim/block_sparse.h"

using namespace textile_handling;

namespace {

// A side x side grid of nodes coupled like a yarn sheet: warp neighbours (rows of the grid) at
// distance 1 and 2 through (x, u), weft neighbours (columns) through (x, v), diagonal neighbours
// through x only, the diagonal block full.
struct GridMatrix {
  // Filled with random values in every block's DOFs (fillRandom) from the seed.
  GridMatrix(int n, unsigned seed) : side(n), gen(seed) {
    std::vector<std::pair<Index, Index>> couplings;
    for (int r = 0; r < side; ++r)
      for (int c = 0; c < side; ++c)
        for (const auto& d : {std::pair<int, int>{0, 1}, {0, 2}, {1, 0}, {2, 0}, {1, 1}, {1, -1}})
          if (r + d.first < side && c + d.second >= 0 && c + d.second < side)
            couplings.emplace_back(node(r, c), node(r + d.first, c + d.second));
    pattern = BlockPattern(side * side, 5, couplings);
    matrix = BlockSparseMatrix(&pattern);
    fillRandom();
  }
  Index node(int r, int c) const { return r * side + c; }
  // The DOFs block (i, j) may couple: 0b111 (x), 0b1111 (x, u), 0b10111 (x, v) or all.
  unsigned dofsOf(Index i, Index j) const {
    if (i == j) return 0b11111u;
    const int dr = static_cast<int>(j / side - i / side), dc = static_cast<int>(j % side - i % side);
    if (dr == 0) return 0b01111u;  // along a row: warp
    if (dc == 0) return 0b10111u;  // along a column: weft
    return 0b00111u;
  }
  void fillRandom() {
    std::uniform_real_distribution<Real> value(-1, 1);
    for (Index i = 0; i < pattern.numNodes(); ++i)
      for (Index k = pattern.rowStart()[i]; k < pattern.rowStart()[i + 1]; ++k) {
        const unsigned dofs = dofsOf(i, pattern.column()[k]);
        for (int r = 0; r < 5; ++r)
          for (int c = 0; c < 5; ++c)
            matrix.block(k)[r * 5 + c] = ((dofs >> r) & 1u) && ((dofs >> c) & 1u) ? value(gen) : 0.0;
      }
  }
  std::size_t subsetValues() const {
    std::size_t total = 0;
    for (Index i = 0; i < pattern.numNodes(); ++i)
      for (Index k = pattern.rowStart()[i]; k < pattern.rowStart()[i + 1]; ++k) {
        const unsigned dofs = dofsOf(i, pattern.column()[k]);
        const int s = dofs == 0b11111u ? 5 : dofs == 0b00111u ? 3 : 4;
        total += static_cast<std::size_t>(s * s);
      }
    return total;
  }

  int side;
  std::mt19937 gen;
  BlockPattern pattern;
  BlockSparseMatrix matrix;
};

VecX randomVector(std::mt19937& gen, Index size) {
  std::uniform_real_distribution<Real> value(-1, 1);
  VecX x(size);
  for (Index k = 0; k < size; ++k) x[k] = value(gen);
  return x;
}

// The largest difference between the compact and the full product at a random x, relative to the
// full product's largest entry.
Real relativeProductDifference(GridMatrix& g, const CompactBlockMatrix& compact) {
  const VecX x = randomVector(g.gen, g.pattern.numNodes() * 5);
  VecX full, y;
  g.matrix.multiply(x, full);
  compact.multiply(x, y);
  if (y.size() != full.size()) return std::numeric_limits<Real>::infinity();
  return (y - full).cwiseAbs().maxCoeff() / full.cwiseAbs().maxCoeff();
}

TEST(CompactBlockMatrix, StoresEachBlockAsItsNarrowestSubsetAndMultipliesLikeTheFullMatrix) {
  GridMatrix g(12, 7);
  CompactBlockMatrix compact;
  compact.assign(g.matrix);
  EXPECT_EQ(compact.storedValues(), g.subsetValues());
  EXPECT_LT(compact.storedValues(), g.matrix.values().size() * 2 / 3);
  EXPECT_LE(relativeProductDifference(g, compact), 1e-13);
}

TEST(CompactBlockMatrix, WidensABlockWhenAValueAppearsOutsideItsSubset) {
  GridMatrix g(6, 8);
  CompactBlockMatrix compact;
  compact.assign(g.matrix);
  const std::size_t before = compact.storedValues();
  // A diagonal neighbour's block (x only so far) gets a v-u coupling; a warp block a v row.
  const Index diag_slot = g.pattern.find(g.node(2, 2), g.node(3, 3));
  const Index warp_slot = g.pattern.find(g.node(2, 2), g.node(2, 3));
  g.matrix.block(diag_slot)[4 * 5 + 3] = 0.75;
  g.matrix.block(warp_slot)[4 * 5 + 0] = -2.5;
  compact.assign(g.matrix);
  EXPECT_EQ(compact.storedValues(), before + (25 - 9) + (25 - 16));
  EXPECT_LE(relativeProductDifference(g, compact), 1e-13);
  // Subsets never narrow again: the values going back to zero keep the wider blocks.
  g.matrix.block(diag_slot)[4 * 5 + 3] = 0;
  compact.assign(g.matrix);
  EXPECT_EQ(compact.storedValues(), before + (25 - 9) + (25 - 16));
}

TEST(CompactBlockMatrix, ANaNOutsideEverySubsetReachesTheProduct) {
  GridMatrix g(5, 9);
  CompactBlockMatrix compact;
  compact.assign(g.matrix);
  const Index slot = g.pattern.find(g.node(1, 1), g.node(2, 2));  // x only
  g.matrix.block(slot)[3 * 5 + 4] = std::nan("");
  compact.assign(g.matrix);
  VecX y;
  compact.multiply(randomVector(g.gen, 5 * 5 * 5), y);
  EXPECT_TRUE(std::isnan(y[g.node(1, 1) * 5 + 3]));
  EXPECT_TRUE(std::isfinite(y[g.node(1, 1) * 5 + 0]));
}

TEST(CompactBlockMatrix, SameBitsOnOneTwoAndThreeThreads) {
  GridMatrix g(60, 10);  // 3600 nodes x 5 DOFs: above the size at which the loops go parallel
  const VecX x = randomVector(g.gen, 60 * 60 * 5);
  std::vector<VecX> results;
  for (int threads : {1, 2, 3}) {
    test_support::ThreadScope scope(threads);
    CompactBlockMatrix compact;
    compact.assign(g.matrix);
    VecX y;
    compact.multiply(x, y);
    results.push_back(y);
  }
  for (std::size_t t = 1; t < results.size(); ++t) EXPECT_TRUE((results[t].array() == results[0].array()).all());
}

TEST(CompactBlockMatrix, OtherBlockSizesUseTheFullMatrix) {
  std::mt19937 gen(11);
  const BlockPattern pattern(30, 3, {{0, 1}, {1, 2}, {5, 20}, {29, 3}});
  BlockSparseMatrix a(&pattern);
  std::uniform_real_distribution<Real> value(-1, 1);
  for (Real& v : a.values()) v = value(gen);
  CompactBlockMatrix compact;
  compact.assign(a);
  EXPECT_EQ(compact.storedValues(), a.values().size());
  const VecX x = randomVector(gen, 90);
  VecX full, y;
  a.multiply(x, full);
  compact.multiply(x, y);
  EXPECT_TRUE((y.array() == full.array()).all());
}

}  // namespace
