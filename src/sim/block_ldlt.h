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
// Two threads: the analysis picks disjoint subtrees of the elimination tree (a frontier found by
// splitting the heaviest subtree at its root while that lowers rest + max(heaviest, frontier / 2), the
// work of a row being 1 + its column count) and deals them to two groups. A group's rows depend only
// on rows of its own subtrees, so the groups are factorised, forward- and back-solved side by side and
// the rest (their ancestors) on one thread. The factor is the plain row order's, bit for bit; the
// forward solve adds a group's updates of the rest's rows from the group's own buffer, in a fixed
// order, so solutions are the same on any thread count.
//
// Shapes: A is n x n blocks of B x B (B = the pattern's block size, 1 to 6); solve() takes and returns
// vectors of n * B entries.
#pragma once

#include <array>
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
  /// Block rows of the two disjoint subtrees of the elimination tree that are factorised and solved
  /// side by side (two threads), and of the rest, which follows on one thread; after analyse().
  std::array<Index, 3> partSizes() const;

 private:
  template <int B>
  bool factorizeFixed(const BlockSparseMatrix& a);
  /// Row k of L and D(k)^-1 (up-looking), with `reach` (n entries) as the row's stack; false if the
  /// pivot block is not positive definite or not finite.
  template <int B>
  bool factorizeRow(const BlockSparseMatrix& a, Index k, std::vector<Index>& reach);
  template <int B>
  void solveFixed(const VecX& b, VecX& x) const;
  /// Chooses the two subtrees (part_, member_) from the tree and the column counts.
  void splitTree(const std::vector<Index>& column_count);
  /// Whether the two subtrees run on two threads (else one after the other: the same arithmetic).
  bool partsInParallel() const;

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
  // Two disjoint subtrees of the elimination tree (parts 0 and 1) and the rest (part 2), each's block
  // rows ascending; member_[k] = the part of row k. A row of a subtree depends only on rows of its own
  // subtree in the factorisation and the forward solve, so the subtrees run side by side; the rest,
  // which holds every ancestor of them, follows.
  std::array<std::vector<Index>, 3> part_;
  std::vector<char> member_;
  // Factorisation workspace: the dense column being solved for, the reach stacks (one per part, the
  // subtrees' running at once) and visit flags (each part touches only its own rows' entries).
  std::vector<Real> column_;
  std::array<std::vector<Index>, 2> reach_;
  std::vector<Index> flag_, l_fill_;
  mutable VecX work_;
  mutable std::array<VecX, 2> outside_;  // the subtrees' forward-solve updates of the rest's rows
};

}  // namespace textile_handling
