// Preconditioned conjugate residual (PCR) solver for the implicit systems A y = b of the integrators
// (yarn-level cloth, section 5.3), on a block-sparse matrix with pinned nodes removed.
//
// A must be symmetric; it may be indefinite or singular. The preconditioner P must be symmetric positive
// definite: block-Jacobi with a symmetric positive definite inverse of each diagonal block (the Cholesky
// inverse, or V |Lambda|^-1 V^T for an indefinite block; block size = the pattern's block size), or the
// two-level preconditioner of the semi-implicit integrator built on those inverses. The method is CR in
// the P-inner product on P A: every iterate minimises sqrt(r^T P r) over its Krylov space, so the
// residual never grows, and on a consistent positive semi-definite system (b in the range of A) it
// converges to a solution where conjugate gradients can stall. Cost per iteration: one product with A,
// one application of P, five dot products. If the smoothed two-level cycle turns out not to be
// positive definite ((Ap)^T P Ap <= 0), the solve restarts from its current iterate with the additive
// two-level form.
//
// Deterministic: the product is row-parallel with a fixed summation order, dot products use
// deterministicDot and vector updates are element-wise, so the iterates are bitwise the same for any
// OpenMP thread count.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "textile_handling/sim/block_sparse.h"
#include "textile_handling/sim/integrators.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

struct ConjugateResidualResult {
  bool converged = false;
  int iterations = 0;
  Real residual_norm = 0;  ///< |b - A y|_2 on the free DOFs (the recurred residual)
  Real rhs_norm = 0;       ///< |b|_2 on the free DOFs
  std::string failure;     ///< why not converged: breakdown, non-finite values or the iteration cap
  bool used_coarse_level = false;  ///< the two-level preconditioner's coarse level took part
  int restarts = 0;  ///< restarts with the additive two-level form (the smoothed cycle was not positive definite)
};

/// The preconditioner of the conjugate-residual solver (SolverSettings fields of the same names).
struct ConjugateResidualPreconditioner {
  PreconditionerKind kind = PreconditionerKind::kBlockJacobi;
  int smoothing_steps = 1;
  Real smoothing_weight = 0.6;
};

class ConjugateResidualSolver {
 public:
  ConjugateResidualSolver();
  ~ConjugateResidualSolver();
  ConjugateResidualSolver(const ConjugateResidualSolver&) = delete;
  ConjugateResidualSolver& operator=(const ConjugateResidualSolver&) = delete;

  /// Takes A (kept by pointer: it must outlive the solves and not change between setMatrix and
  /// solve) and the nodes to remove (node_pinned[i] != 0: node i's rows and columns are dropped; empty
  /// = none), and builds the preconditioner on the free nodes. False if a diagonal block is singular
  /// or not finite.
  bool setMatrix(const BlockSparseMatrix& a, const std::vector<char>& node_pinned,
                 const ConjugateResidualPreconditioner& preconditioner = {});

  /// Solves A_ff y_f = b_f from y = 0 until |b - A y|_2 <= relative_tolerance |b|_2 (free DOFs) or
  /// max_iterations. At the cap the iterate is still accepted if the residual is at most
  /// accept_tolerance |b|_2 (0 = never). y is zero on the pinned DOFs; b's pinned entries are ignored.
  ConjugateResidualResult solve(const VecX& b, VecX& y, Real relative_tolerance, int max_iterations,
                                Real accept_tolerance = 0);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace textile_handling
