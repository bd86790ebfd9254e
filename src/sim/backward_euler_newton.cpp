// Backward Euler with Newton's method and preconditioned conjugate-residual solves (integrators.h,
// docs/simulation.md "Backward Euler with Newton").
//
// Unknown: the end-of-step velocity v; x = x_n + h v. Residual r(v) = M (v - v_n) - h f(x_n + h v, v),
// with M = M(x_n) held over the step. Newton's iterations run on the pair (dx, dv) = (x - x_n, v - v_n)
// from the zero start (0, 0): the first linearisation is at (x_n, v_n), so the first iterate is
// exactly the linearised (semi-implicit) step, (M - h D - h^2 K) dv = h (f + h K v_n); every later one
// is at the current iterate (x_n + h v_k, v_k) and solves A_k delta = -r(v_k). Pinned nodes have their
// velocity prescribed from the start and are removed from every solve.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_triangles.h"  // pinnedMask
#include "textile_handling/sim/conjugate_residual.h"
#include "textile_handling/sim/timing.h"
#include "implicit_euler_base.h"

namespace textile_handling {

namespace {

using Clock = std::chrono::steady_clock;

class BackwardEulerNewton : public ImplicitEulerBase {
 public:
  explicit BackwardEulerNewton(SolverSettings s) : ImplicitEulerBase(s) {}
  IntegratorType type() const override { return IntegratorType::kBackwardEulerNewton; }

  StepOutcome step(ClothModel& model, const PinnedNodes& pins, const VecX& x, const VecX& v, Real t, Real h,
                   VecX& x_new, VecX& v_new) override {
    StepOutcome out;
    auto t_asm = Clock::now();
    if (!assemble(model, x, v, h, &out)) return out;
    const Index dofs = model.numDofs();
    mask_ = pinnedMask(model.numNodes(), pins);
    block_ = model.dofsPerNode();
    const Real limit = solver_.newton_tolerance * residualScale(model, x, v, h);

    // Zero start: A y = h (f + h K v_n) - A dv_p on the free DOFs, dv_p the pins' prescribed change.
    VecX dv = VecX::Zero(dofs);
    pinnedVelocityChange(model, pins, x, v, t, h, dv);
    system_.multiply(dv, ap_);
    b_ = rhs_ - ap_;
    filter(b_);
    VecX vk = v + dv;  // the pinned DOFs keep this value in every iteration
    out.assembly_ms += msSince(t_asm);

    for (int k = 1;; ++k) {
      if (!linearSolve(k, &out)) return out;
      vk += delta_;
      out.newton_iterations = k;
      t_asm = Clock::now();
      const bool finite = residual(model, x, v, vk, h, &out);
      out.assembly_ms += msSince(t_asm);
      if (!finite) {
        out.ok = false;
        out.failure = "non-finite force or residual in Newton iteration " + std::to_string(k);
        return out;
      }
      const Real r_norm = free_residual_.cwiseAbs().maxCoeff();
      if (r_norm <= limit) break;
      if (k >= solver_.newton_max_iterations) {
        std::ostringstream m;
        m << "Newton's method did not converge in " << k << " iterations (free-DOF residual " << r_norm
          << " > tolerance " << limit << ")";
        out.ok = false;
        out.failure = m.str();
        return out;
      }
      // Next linearisation at the iterate; the mass stays at x_n.
      t_asm = Clock::now();
      x_k_ = x + h * vk;
      if (!assembleSystem(model, x_k_, vk, x, h, &out)) {
        out.failure = "non-finite force in Newton iteration " + std::to_string(k + 1);
        return out;
      }
      b_ = -free_residual_;
      out.assembly_ms += msSince(t_asm);
    }
    finish(pins, x, v, t, h, vk - v, model, x_new, v_new, &out);
    return out;
  }

 private:
  // Zeroes the pinned nodes' entries.
  void filter(VecX& y) const {
    const Index n = static_cast<Index>(mask_.size());
    for (Index i = 0; i < n; ++i)
      if (mask_[i]) y.segment(i * block_, block_).setZero();
  }

  Real freeInfNorm(const VecX& y) const {
    Real worst = 0;
    const Index n = static_cast<Index>(mask_.size());
    for (Index i = 0; i < n; ++i)
      if (!mask_[i]) worst = std::max(worst, y.segment(i * block_, block_).cwiseAbs().maxCoeff());
    return worst;
  }

  // max(|M v_n|_inf, h |f(x_n, v_n)|_inf, h g max m) on the free DOFs; f_ holds f(x_n, v_n). The last
  // term, the impulse of the heaviest node's weight over the step, keeps the scale physical for a
  // textile at rest, where the first two vanish and the residual would be asked to beat rounding.
  Real residualScale(const ClothModel& model, const VecX& x, const VecX& v, Real h) {
    model.multiplyMass(x, v, mv_);
    const Real weight = h * kGravity * model.massPerDof().maxCoeff();
    return std::max({freeInfNorm(mv_), h * freeInfNorm(f_), weight, 1e-300});
  }

  // free_residual_ = M(x_n) (v_k - v_n) - h f(x_n + h v_k, v_k) on the free DOFs (zero on pinned ones).
  bool residual(ClothModel& model, const VecX& x, const VecX& v, const VecX& vk, Real h, StepOutcome* out) {
    x_k_ = x + h * vk;
    const ForceReport rep = model.computeForces(x_k_, vk, fk_, nullptr);
    out->degenerate_terms = std::max(out->degenerate_terms, rep.degenerate_terms);
    out->torn_segments = std::max(out->torn_segments, rep.torn_segments);
    model.multiplyMass(x, vk - v, mv_);
    free_residual_ = mv_ - h * fk_;
    filter(free_residual_);
    return free_residual_.allFinite();
  }

  // delta_ from A delta = b_ on the free DOFs (PCR with the configured preconditioner, SolverSettings).
  bool linearSolve(int k, StepOutcome* out) {
    const auto t_solve = Clock::now();
    ConjugateResidualPreconditioner preconditioner;
    preconditioner.kind = solver_.preconditioner;
    preconditioner.smoothing_steps = solver_.smoothing_steps;
    preconditioner.smoothing_weight = solver_.smoothing_weight;
    if (!cr_.setMatrix(system_, mask_, preconditioner)) {
      out->ok = false;
      out->failure = "singular diagonal block in the Newton system (iteration " + std::to_string(k) + ")";
      return false;
    }
    const ConjugateResidualResult r = cr_.solve(b_, delta_, solver_.relative_tolerance, solver_.max_iterations,
                                                solver_.accept_tolerance);
    out->solver_iterations += r.iterations;
    out->solve_ms += msSince(t_solve);
    if (!r.converged) {
      out->ok = false;
      out->failure = "Newton iteration " + std::to_string(k) + ": " + r.failure;
      return false;
    }
    return true;
  }

  std::vector<char> mask_;
  int block_ = 3;
  ConjugateResidualSolver cr_;
  VecX b_, delta_, ap_, mv_, fk_, x_k_, free_residual_;
};

}  // namespace

std::unique_ptr<Integrator> makeBackwardEulerNewton(const SolverSettings& solver) {
  return std::make_unique<BackwardEulerNewton>(solver);
}

}  // namespace textile_handling
