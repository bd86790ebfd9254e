// Preconditioners of the implicit systems A y = b (A on a block-sparse pattern, pinned nodes removed),
// shared by the semi-implicit integrator (conjugate gradients) and backward Euler with Newton
// (conjugate residuals). Private to the simulation core.
//
// block_jacobi: z = D^-1 r with D the diagonal blocks. two_level: damped block-Jacobi smoothing plus
// an exact (block LDL^T, block_ldlt.h) solve of the Galerkin coarse system P^T A P on node aggregates (P piecewise
// constant), as the symmetric V(nu, nu) cycle, or additively (D^-1 + P Ac^-1 P^T) for nu = 0 or after
// dropSmoothing(). Every application is deterministic across OpenMP thread counts.
#pragma once

#include <memory>
#include <vector>

#include "textile_handling/sim/block_sparse.h"
#include "textile_handling/sim/integrators.h"
#include "textile_handling/sim/types.h"
#include "block_jacobi.h"
#include "block_ldlt.h"
#include "compact_block_matrix.h"

namespace textile_handling {

class CoarseLevel;

class SystemPreconditioner {
 public:
  SystemPreconditioner();
  ~SystemPreconditioner();
  SystemPreconditioner(const SystemPreconditioner&) = delete;
  SystemPreconditioner& operator=(const SystemPreconditioner&) = delete;

  /// Prepares z = M^-1 r and the products with A (kept by pointer, and not to be changed, until the
  /// next update) without the nodes flagged in node_pinned (copied). `kind`, `smoothing_steps` and `smoothing_weight` as in SolverSettings;
  /// `inverse` says how the diagonal blocks are inverted. The coarse level is used only when its
  /// Galerkin matrix is positive definite (usesCoarseLevel()). False if a diagonal block is singular
  /// or not finite.
  bool update(const BlockSparseMatrix& a, const std::vector<char>& node_pinned, PreconditionerKind kind,
              int smoothing_steps, Real smoothing_weight, BlockJacobi::Inverse inverse);
  /// z = M^-1 r (size: the DOFs of A; zero on pinned nodes; r must be zero on pinned nodes).
  void apply(const VecX& r, VecX& z);
  /// out = A_ff in for the solvers, from the copy of A made by update() (compact_block_matrix.h); `in`
  /// must be zero on pinned nodes, whose rows of `out` are zeroed.
  void applySystem(const VecX& in, VecX& out) const;
  /// Switches the V-cycle to the additive form (always positive definite when the diagonal-block
  /// inverses and the coarse matrix are) until the next update. False if there was nothing to drop.
  bool dropSmoothing();
  bool usesCoarseLevel() const { return use_coarse_; }
  /// The coarse level's aggregate of every node (-1 for pinned nodes); empty without a coarse level.
  /// For tests and diagnostics: P maps aggregate a's coarse DOFs onto every member node's DOFs.
  std::vector<Index> aggregateOfNode() const;

 private:
  std::vector<char> pinned_;
  int block_ = 3;
  int smoothing_steps_ = 0;
  Real smoothing_weight_ = 1;
  bool use_coarse_ = false;
  CompactBlockMatrix system_copy_;
  BlockJacobi jacobi_;
  std::unique_ptr<CoarseLevel> coarse_;
  VecX t_;
};

}  // namespace textile_handling
