// What the implicit integrators share (semi_implicit, block_diagonal, backward_euler_newton): the
// assembled system A = M - h df/dv - h^2 df/dx with the linearised right-hand side h (f + h df/dx v),
// pinned nodes by constraint filtering (their velocity change is prescribed so that they land exactly
// on their targets) and the end of a step with its error estimate. Private to the simulation core.
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>

#include "textile_handling/sim/integrators.h"

namespace textile_handling {

class ImplicitEulerBase : public Integrator {
 protected:
  explicit ImplicitEulerBase(SolverSettings s) : solver_(s) {}

  /// Forces and Jacobians at (x, v) into f_ and jac_, and system_ = M(x) - h D - h^2 K, then
  /// rhs_ = h (f + h K v). False (with out->failure) on a non-finite force.
  bool assemble(ClothModel& model, const VecX& x, const VecX& v, Real h, StepOutcome* out);
  /// The same without the right-hand side, with the mass taken at `x_mass` (held over a step):
  /// system_ = M(x_mass) - h D(x, v) - h^2 K(x, v). out->degenerate_terms keeps the largest count.
  bool assembleSystem(ClothModel& model, const VecX& x, const VecX& v, const VecX& x_mass, Real h,
                      StepOutcome* out);
  /// Inverts the diagonal block of node i of the system matrix.
  bool invertDiagonal(Index i, Eigen::MatrixXd* inv) const;
  /// v_new = v + dv, x_new = x + h v_new, pinned nodes exactly on their targets at t + h; the local
  /// error estimate 1/2 h max |dv| over the free nodes' positions; failure on a non-finite state.
  void finish(const PinnedNodes& pins, const VecX& x, const VecX& v, Real t, Real h, const VecX& dv,
              const ClothModel& model, VecX& x_new, VecX& v_new, StepOutcome* out);
  /// Prescribed velocity change of pinned nodes so that they reach their target at t + h (the node's
  /// other DOFs keep their velocity); the free DOFs of dv are left as they are.
  void pinnedVelocityChange(const ClothModel& model, const PinnedNodes& pins, const VecX& x, const VecX& v,
                            Real t, Real h, VecX& dv) const;

  SolverSettings solver_;
  const ClothModel* model_ = nullptr;
  ForceJacobians jac_;
  BlockSparseMatrix system_;
  VecX f_, kv_, rhs_;
};

/// Backward Euler with Newton's method and PCR solves (backward_euler_newton.cpp).
std::unique_ptr<Integrator> makeBackwardEulerNewton(const SolverSettings& solver);

}  // namespace textile_handling
