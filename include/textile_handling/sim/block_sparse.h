// Block-compressed sparse rows (BSR) for Jacobians and implicit systems.
//
// One block per pair of coupled nodes; the block size is the model's DOFs per node (3 for particle
// cloth, 5 for yarn crossings). The pattern is fixed when a model is built, so assembly writes straight
// into precomputed block slots and never allocates.
#pragma once

#include <utility>
#include <vector>

#include "textile_handling/sim/types.h"

namespace textile_handling {

class BlockPattern {
 public:
  BlockPattern() = default;
  /// Pattern over `num_nodes` nodes with square blocks of `block` DOFs. Every diagonal block is present;
  /// each pair (i, j) in `couplings` adds blocks (i, j) and (j, i). Duplicates are fine.
  BlockPattern(Index num_nodes, int block, const std::vector<std::pair<Index, Index>>& couplings);

  Index numNodes() const { return num_nodes_; }
  int blockSize() const { return block_; }
  Index numBlocks() const { return static_cast<Index>(col_.size()); }
  /// Slot of block (i, j) in the value array (in blocks); -1 if not in the pattern. O(log row length).
  Index find(Index i, Index j) const;
  Index diagonal(Index i) const { return diag_[i]; }
  const std::vector<Index>& rowStart() const { return row_start_; }
  const std::vector<Index>& column() const { return col_; }

 private:
  Index num_nodes_ = 0;
  int block_ = 3;
  std::vector<Index> row_start_;  // size num_nodes + 1, in blocks
  std::vector<Index> col_;        // block column of each block
  std::vector<Index> diag_;       // slot of each diagonal block
};

/// Values over a BlockPattern. Blocks are stored row-major, block after block.
class BlockSparseMatrix {
 public:
  BlockSparseMatrix() = default;
  explicit BlockSparseMatrix(const BlockPattern* pattern);

  const BlockPattern& pattern() const { return *pattern_; }
  void setZero();
  Real* block(Index slot) { return values_.data() + static_cast<size_t>(slot) * bb_; }
  const Real* block(Index slot) const { return values_.data() + static_cast<size_t>(slot) * bb_; }
  /// Adds a 3x3 matrix to a block (block size must be 3).
  void add3(Index slot, const Mat3& m) {
    Eigen::Map<Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(block(slot)) += m;
  }
  std::vector<Real>& values() { return values_; }
  const std::vector<Real>& values() const { return values_; }

  /// y = A x (parallel over block rows; the result does not depend on the thread count).
  void multiply(const VecX& x, VecX& y) const;

 private:
  const BlockPattern* pattern_ = nullptr;
  int bb_ = 9;
  std::vector<Real> values_;
};

}  // namespace textile_handling
