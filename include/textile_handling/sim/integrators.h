// Time integrators shared by all cloth models.
//
//  - kRK4: classical explicit Runge-Kutta, the baseline (four force evaluations per step);
//  - kSemiImplicitEuler: linearised backward Euler of Baraff & Witkin (thesis eq 77),
//      (M - h df/dv - h^2 df/dx) dv = h (f + h df/dx v),
//    with the full sparse system solved by preconditioned conjugate gradients (block-Jacobi, or
//    two-level: block-Jacobi smoothing plus an exact solve on node aggregates) or, optionally, by a
//    sparse LDL^T factorisation every step (SolverSettings);
//  - kBlockDiagonalEuler: the thesis's reduction (section 4.4): the same system with only its
//    diagonal blocks, solved node by node in closed form. The right-hand side keeps the full
//    df/dx v product (thesis open decision 11).
//  - kBackwardEulerNewton: backward Euler solved by Newton's method (yarn-level cloth, section 5.1):
//    the residual r(v) = M (v - v_n) - h f(x_n + h v, v) is driven to zero by at most
//    SolverSettings::newton_max_iterations solves of (M - h df/dv - h^2 df/dx) dv = -r with a
//    preconditioned conjugate-residual solver (conjugate_residual.h); a step that does not converge
//    fails, and the adaptive step policies retry it with h / 2.
// Pinned nodes follow prescribed positions exactly: their velocity change is fixed and moved to the
// right-hand side, and the solve runs on the free DOFs only (constraint filtering).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model.h"

namespace textile_handling {

enum class IntegratorType { kRK4, kSemiImplicitEuler, kBlockDiagonalEuler, kBackwardEulerNewton };
std::string toString(IntegratorType t);
/// Parses "rk4", "semi_implicit", "block_diagonal", "backward_euler_newton"; throws std::invalid_argument
/// otherwise.
IntegratorType integratorFromString(const std::string& s);

/// Nodes held in place; they follow anchor + offset(t), offset piecewise linear in time (lifting).
struct PinnedNodes {
  std::vector<Index> nodes;
  std::vector<Vec3> anchors;                 ///< position of each pinned node at offset 0 [m]
  std::vector<Real> waypoint_times;          ///< increasing [s]; empty = static pins
  std::vector<Vec3> waypoint_offsets;        ///< offset at each waypoint time [m]

  Vec3 offset(Real t) const;
  Vec3 offsetVelocity(Real t) const;  ///< right derivative of offset(t) [m/s]
  Vec3 position(size_t k, Real t) const { return anchors[k] + offset(t); }
};

/// How the semi-implicit integrator solves its sparse system (backward_euler_newton always uses
/// conjugate residuals; it takes the preconditioner, tolerance and iteration caps of this struct).
enum class LinearSolverKind {
  kCG,      ///< preconditioned conjugate gradients ("cg")
  kDirect,  ///< sparse LDL^T factorisation (Eigen, AMD ordering) of the full system every step ("direct");
            ///< exact to rounding, also for an indefinite system, but ~60 ms per step at 3055 particles
};
std::string toString(LinearSolverKind k);
/// Parses "cg", "direct"; throws std::invalid_argument otherwise.
LinearSolverKind linearSolverFromString(const std::string& s);

/// Preconditioner of the CG solver (semi_implicit) and of the conjugate-residual solver
/// (backward_euler_newton).
enum class PreconditionerKind {
  kBlockJacobi,  ///< inverse diagonal blocks ("block_jacobi")
  /// Two-level ("two_level"): damped block-Jacobi smoothing plus an exact (block LDL^T) solve of the
  /// Galerkin coarse system on node aggregates (a node and its pattern neighbours, ~13 nodes; built
  /// once per pattern and pinned set). About 10x fewer iterations than block-Jacobi on the towel.
  /// Falls back to block-Jacobi for a step whose coarse matrix is not positive definite.
  kTwoLevel,
};
std::string toString(PreconditionerKind k);
/// Parses "block_jacobi", "two_level"; throws std::invalid_argument otherwise.
PreconditionerKind preconditionerFromString(const std::string& s);

struct SolverSettings {
  LinearSolverKind kind = LinearSolverKind::kCG;
  PreconditionerKind preconditioner = PreconditionerKind::kTwoLevel;
  /// Two-level only: damped block-Jacobi sweeps before and after the coarse solve (symmetric
  /// V-cycle); 0 = additive (D^-1 + P Ac^-1 P^T, one coarse solve and no extra product per
  /// iteration). The cycle is positive definite if smoothing_weight * lambda_max(D^-1 A) < 2
  /// (lambda_max ~ 2.7 for the particle model); if CG finds it is not, the step continues additively.
  int smoothing_steps = 1;
  Real smoothing_weight = 0.6;
  int max_iterations = 400;        ///< CG (PCR for backward_euler_newton) iteration cap per solve
  Real relative_tolerance = 1e-6;  ///< CG / PCR stop at |r| <= tol |b| (free DOFs, b = right-hand side)
  /// CG starts from the previous step's solution, rescaled to the new step size and then by the
  /// factor that minimises the A-norm error along it (never worse than a zero start). Saves about a
  /// third of the iterations, but makes a step depend on the previous one: a run resumed from a
  /// saved state then matches the uninterrupted run bitwise only if the integrator's solverState()
  /// is saved and restored with it.
  bool warm_start = false;
  /// At the iteration cap, accept the iterate anyway if |r| <= accept_tolerance |b| (0: never).
  Real accept_tolerance = 0;
  /// backward_euler_newton: linear solves per step before the step fails (>= 1).
  int newton_max_iterations = 5;
  /// backward_euler_newton: converged when the residual M (v - v_n) - h f(x_n + h v, v) on the free
  /// DOFs has |r|_inf <= newton_tolerance * max(|M v_n|_inf, h |f(x_n, v_n)|_inf, h g max m) (free
  /// DOFs; m = lumped mass per DOF, g = 9.81 m/s^2).
  Real newton_tolerance = 1e-2;
};

/// What one step did (or why it failed).
struct StepOutcome {
  bool ok = true;
  std::string failure;        ///< non-empty when !ok (solver breakdown, degenerate geometry, NaN)
  int solver_iterations = 0;   ///< linear-solver iterations (all Newton iterations of the step)
  int newton_iterations = 0;   ///< Newton iterations, i.e. linear solves (backward_euler_newton)
  Real error_estimate = 0;    ///< local position error estimate [m] (for error-controlled steps)
  int error_order = 2;        ///< the estimate scales like h^error_order
  Index degenerate_terms = 0;
  Index torn_segments = 0;    ///< the model's ForceReport::torn_segments (largest over the step's evaluations)
  Real assembly_ms = 0;       ///< wall time of forces, Jacobians and system assembly (semi_implicit, Newton)
  Real solve_ms = 0;          ///< wall time of the linear solves, preconditioner set-up included (semi_implicit, Newton)
};

class Integrator {
 public:
  virtual ~Integrator() = default;
  virtual IntegratorType type() const = 0;
  /// Advances (x, v) at time t by h into (x_new, v_new); never modifies the inputs.
  virtual StepOutcome step(ClothModel& model, const PinnedNodes& pins, const VecX& x, const VecX& v,
                           Real t, Real h, VecX& x_new, VecX& v_new) = 0;
  /// Memory carried from one step to the next (the CG warm start), for save/resume; empty if none.
  virtual std::vector<Real> solverState() const { return {}; }
  /// Restores solverState(); returns false (and changes nothing) if it is malformed. A state whose
  /// size does not match the model is ignored at the next step (that step starts cold).
  virtual bool setSolverState(const std::vector<Real>& state) { return state.empty(); }
};

std::unique_ptr<Integrator> makeIntegrator(IntegratorType type, const SolverSettings& solver = {});

/// Dot product whose summation order does not depend on the number of threads.
Real deterministicDot(const VecX& a, const VecX& b);

}  // namespace textile_handling
