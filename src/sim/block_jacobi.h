// Block-Jacobi preconditioner of an implicit system on a block-sparse matrix: the inverses of the
// diagonal blocks of the free nodes. Shared by the semi-implicit integrator (conjugate gradients) and
// the conjugate-residual solver of backward Euler with Newton. Private to the simulation core.
#pragma once

#include <vector>

#include "textile_handling/sim/block_sparse.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

class BlockJacobi {
 public:
  /// How a diagonal block D_i is inverted.
  enum class Inverse {
    kPlain,             ///< D_i^-1 (LU); fails on a singular block
    /// A symmetric positive definite inverse: D_i^-1 by Cholesky when D_i is positive definite,
    /// otherwise V |Lambda|^-1 V^T from the eigen-decomposition of D_i (the absolute-value
    /// preconditioner of indefinite systems); fails on a (numerically) singular block.
    kPositiveDefinite,
  };

  /// Inverts the diagonal block of every node with node_pinned[i] == 0 (pinned nodes get zero). Keeps a
  /// pointer to `node_pinned`, which must outlive the applications. False if a block is singular or
  /// not finite.
  bool update(const BlockSparseMatrix& A, const std::vector<char>& node_pinned, Inverse kind = Inverse::kPlain);
  /// z = weight * D^-1 r (add = false) or z += weight * D^-1 r (add = true); zero on pinned nodes.
  void apply(const VecX& r, VecX& z, Real weight, bool add) const;

 private:
  int b_ = 3;
  std::vector<Real> inv_;
  const std::vector<char>* pinned_ = nullptr;
};

}  // namespace textile_handling
