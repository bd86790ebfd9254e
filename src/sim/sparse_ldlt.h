// Sparse LDL^T factorisation of a block-sparse (BSR) matrix, shared by the semi-implicit integrator
// (its direct solver and the two-level preconditioner's coarse level) and the static equilibrium
// solver. Private to the simulation core.
#pragma once

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <cstddef>
#include <vector>

#include "textile_handling/sim/block_sparse.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

/// LDL^T (Eigen's SimplicialLDLT, AMD ordering) of a BSR matrix. DOFs marked in `dof_pinned` get
/// identity rows and columns, so the scalar pattern (and the fill-reducing ordering, computed once)
/// never changes.
class BlockSparseLdlt {
 public:
  using SpMat = Eigen::SparseMatrix<Real, Eigen::ColMajor, int>;

  /// Builds the lower-triangular scalar pattern of `p` and the map to the BSR values.
  void setPattern(const BlockPattern& p);
  /// Copies the values of `a` (on the pattern given to setPattern; DOFs flagged in `dof_pinned`
  /// decoupled, empty = none) and factorises. False if the factorisation failed or is not finite.
  bool factorize(const BlockSparseMatrix& a, const std::vector<char>& dof_pinned);
  /// Non-positive pivots of the last factorisation (0 = the matrix is positive definite).
  Index negativePivots() const { return negative_pivots_; }
  /// x = A^-1 b with the last factorisation (size: DOFs of the pattern).
  void solve(const VecX& b, VecX& x) const { x = ldlt_.solve(b); }

 private:
  SpMat lower_;
  std::vector<std::size_t> map_;
  std::vector<Index> row_of_, col_of_;
  Eigen::SimplicialLDLT<SpMat, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt_;
  bool analysed_ = false;
  Index negative_pivots_ = 0;
};

}  // namespace textile_handling
