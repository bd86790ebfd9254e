// Time integrators shared by all cloth models.
//
//  - kRK4: classical explicit Runge-Kutta, the baseline (four force evaluations per step);
//  - kSemiImplicitEuler: linearised backward Euler of Baraff & Witkin (thesis eq 77),
//      (M - h df/dv - h^2 df/dx) dv = h (f + h df/dx v),
//    with the full sparse system solved by block-Jacobi preconditioned conjugate gradients;
//  - kBlockDiagonalEuler: the thesis's reduction (section 4.4): the same system with only its
//    diagonal blocks, solved node by node in closed form. The right-hand side keeps the full
//    df/dx v product (thesis open decision 11).
// Pinned nodes follow prescribed positions exactly: their velocity change is fixed and moved to the
// right-hand side, and the solve runs on the free DOFs only (constraint filtering).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model.h"

namespace textile_handling {

enum class IntegratorType { kRK4, kSemiImplicitEuler, kBlockDiagonalEuler };
std::string toString(IntegratorType t);
/// Parses "rk4", "semi_implicit", "block_diagonal"; throws std::invalid_argument otherwise.
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

struct SolverSettings {
  int max_iterations = 400;
  Real relative_tolerance = 1e-6;
};

/// What one step did (or why it failed).
struct StepOutcome {
  bool ok = true;
  std::string failure;        ///< non-empty when !ok (solver breakdown, degenerate geometry, NaN)
  int solver_iterations = 0;
  Real error_estimate = 0;    ///< local position error estimate [m] (for error-controlled steps)
  int error_order = 2;        ///< the estimate scales like h^error_order
  Index degenerate_terms = 0;
};

class Integrator {
 public:
  virtual ~Integrator() = default;
  virtual IntegratorType type() const = 0;
  /// Advances (x, v) at time t by h into (x_new, v_new); never modifies the inputs.
  virtual StepOutcome step(ClothModel& model, const PinnedNodes& pins, const VecX& x, const VecX& v,
                           Real t, Real h, VecX& x_new, VecX& v_new) = 0;
};

std::unique_ptr<Integrator> makeIntegrator(IntegratorType type, const SolverSettings& solver = {});

/// Dot product whose summation order does not depend on the number of threads.
Real deterministicDot(const VecX& a, const VecX& b);

}  // namespace textile_handling
