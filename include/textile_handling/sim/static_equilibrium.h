// Quasi-static finish of a drape: the static equilibrium f(x) = 0 (gravity and elastic forces, pinned
// nodes fixed) reached from a starting state by damped Newton iterations on the potential energy.
//
// Each iteration solves the regularised Newton system
//     (M / h^2 - K(x)) dx = f(x),    K = df/dx at v = 0 (the model's Jacobian, free DOFs only),
// by a sparse LDL^T factorisation and moves x by alpha dx, alpha from a backtracking (Armijo) line
// search on the model's potential energy. h is a pseudo time step: M / h^2 keeps the system positive
// definite and the step short while the start is far from equilibrium (for h -> infinity it is Newton's
// method; one iteration at finite h is one backward-Euler step of a system that starts at rest every
// step). h grows 4x after a full step and shrinks 4x after a shortened one (Levenberg-Marquardt style).
// Because every accepted step lowers the energy, the iteration ends in a local minimum near the start:
// the caller chooses the basin (a dynamic run that has nearly settled), this solver only finishes it.
//
// With the definite-fix Jacobian of the particle model (-K positive semi-definite), M / h^2 - K is
// positive definite for every h; with an exact, indefinite Jacobian a factorisation with negative
// pivots shrinks h and retries. Convergence: every free node's residual force is at most
// `force_tolerance` times its weight (m_i g). See docs/simulation.md, "Quasi-static finish".
#pragma once

#include <string>

#include "textile_handling/sim/integrators.h"

namespace textile_handling {

struct StaticEquilibriumSettings {
  int max_iterations = 60;          ///< Newton iterations (each one factorisation)
  Real force_tolerance = 1e-3;      ///< converged: |f_i| <= tol * m_i g at every free node
  Real initial_time_scale = 0.05;   ///< h of the first iteration [s]
  Real max_time_scale = 1e4;        ///< h cap [s]
  Real min_time_scale = 1e-6;       ///< below this the solve gives up [s]
  int max_backtracks = 10;          ///< line-search halvings per iteration
  /// A full step that lowers the energy is doubled while the energy keeps falling, up to this factor
  /// (1 = never): Newton's step on a quintic tension term covers only a fifth of the way.
  Real max_extrapolation = 16;
};

struct StaticEquilibriumResult {
  bool converged = false;
  std::string failure;              ///< why not (empty when converged)
  int iterations = 0;               ///< Newton iterations (factorised systems)
  int rejected = 0;                 ///< systems rejected (not positive definite, no descent)
  Real residual_ratio = 0;          ///< max over free nodes of |f_i| / (m_i g) at the end
  Real max_move = 0;                ///< largest node displacement from the start [m]
  Real energy_drop = 0;             ///< potential energy at the start minus at the end [J]
  Real time_scale = 0;              ///< h at the end [s]
  double assembly_ms = 0;           ///< forces, Jacobians, energies, system values
  double solve_ms = 0;              ///< factorisations and solves
  double wall_ms = 0;
};

/// Moves `x` (the model's full state, numDofs()) to the static equilibrium near it, the pinned nodes
/// held at pins.position(k, t) (their whole DOF block fixed). On failure `x` holds the last accepted
/// iterate (never a worse one than the start). Throws SimError if `x` has the wrong size or is not
/// finite, or the settings are out of range (field named).
StaticEquilibriumResult solveStaticEquilibrium(ClothModel& model, const PinnedNodes& pins, Real t, VecX& x,
                                               const StaticEquilibriumSettings& settings = {});

/// max over free nodes of |f_i| / (m_i g) for forces `f` (size numDofs(); position part of each node).
Real staticResidualRatio(const ClothModel& model, const VecX& f, const std::vector<char>& node_pinned);

}  // namespace textile_handling
