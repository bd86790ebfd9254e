// Block LDL^T factorisation of a symmetric positive definite block-sparse (BSR) matrix, for the
// two-level preconditioner's coarse level. Private to the simulation core.
//
// A = P^T L D L^T P with P a fill-reducing permutation of the block rows (AMD on the block graph), L
// unit lower triangular in B x B blocks and D block diagonal (B x B symmetric positive definite blocks).
// The factorisation is the up-looking sparse LDL^T (each row of L from a sparse triangular solve whose
// pattern is the row's reach in the elimination tree), carried out on whole B x B blocks, so every index
// lookup is shared by B^2 values and the arithmetic runs on fixed-size matrices; the scalar simplicial
// LDL^T (BlockSparseLdlt) spends most of its time on per-entry indexing. Only the upper triangle of A
// (in the permuted order) is read; A must be symmetric.
//
// Shapes: A is n x n blocks of B x B (B = the pattern's block size, 1 to 6); solve() takes and returns
// vectors of n * B entries.
#pragma once

#include <vector>

#include "textile_handling/sim/block_sparse.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

class BlockLdlt {
 public:
  /// The ordering, elimination tree and the pattern of L for matrices on `p` (kept by reference until
  /// the next call). Throws SimError for a block size outside 1..6.
  void analyse(const BlockPattern& p);
  /// Factorises `a` (on the analysed pattern). False if a pivot block is not positive definite or
  /// not finite; the factor is then unusable until the next successful call.
  bool factorize(const BlockSparseMatrix& a);
  /// x = A^-1 b with the last successful factorisation (sizes n * B).
  void solve(const VecX& b, VecX& x) const;
  /// Blocks of L below the diagonal (the fill included), after analyse().
  Index factorBlocks() const;

 private:
  template <int B>
  bool factorizeFixed(const BlockSparseMatrix& a);
  template <int B>
  void solveFixed(const VecX& b, VecX& x) const;

  const BlockPattern* pattern_ = nullptr;
  int b_ = 0;
  Index n_ = 0;
  std::vector<Index> order_;      // order_[k] = the original block row at position k
  std::vector<Index> position_;   // inverse of order_
  std::vector<Index> parent_;     // elimination tree of the permuted matrix (-1 = root)
  // Upper triangle of the permuted matrix by column k: rows j < k and the slot of block (order_[k],
  // order_[j]) in the BSR values (the transpose of the wanted block (j, k)).
  std::vector<Index> upper_start_, upper_row_, upper_slot_;
  std::vector<Index> l_start_;    // column starts of L (in blocks)
  std::vector<Index> l_row_;      // row of each block of L
  std::vector<Real> l_values_;    // blocks of L, row-major B x B each
  std::vector<Real> d_inverse_;   // D^-1 blocks, row-major B x B each
  bool factorized_ = false;
  // Factorisation workspace: the dense column being solved for, the reach stack and visit flags.
  std::vector<Real> column_;
  std::vector<Index> reach_, flag_, l_fill_;
  mutable VecX work_;
};

}  // namespace textile_handling
