#include "textile_handling/sim/integrators.h"
#include "textile_handling/sim/sim_errors.h"

#include <Eigen/LU>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "textile_handling/sim/collision.h"
#include "textile_handling/sim/timing.h"
#include "block_jacobi.h"
#include "implicit_euler_base.h"
#include "sparse_ldlt.h"
#include "system_preconditioner.h"
#include "parallel_size.h"
#include "parallel_vector_ops.h"

namespace textile_handling {

std::string toString(IntegratorType t) {
  switch (t) {
    case IntegratorType::kRK4: return "rk4";
    case IntegratorType::kSemiImplicitEuler: return "semi_implicit";
    case IntegratorType::kBlockDiagonalEuler: return "block_diagonal";
    case IntegratorType::kBackwardEulerNewton: return "backward_euler_newton";
  }
  return "unknown";
}

IntegratorType integratorFromString(const std::string& s) {
  if (s == "rk4") return IntegratorType::kRK4;
  if (s == "semi_implicit") return IntegratorType::kSemiImplicitEuler;
  if (s == "block_diagonal") return IntegratorType::kBlockDiagonalEuler;
  if (s == "backward_euler_newton") return IntegratorType::kBackwardEulerNewton;
  throw SimError("unknown integrator '" + s +
                 "' (expected rk4, semi_implicit, block_diagonal or backward_euler_newton)");
}

std::string toString(LinearSolverKind k) {
  switch (k) {
    case LinearSolverKind::kCG: return "cg";
    case LinearSolverKind::kDirect: return "direct";
  }
  return "unknown";
}

LinearSolverKind linearSolverFromString(const std::string& s) {
  if (s == "cg") return LinearSolverKind::kCG;
  if (s == "direct") return LinearSolverKind::kDirect;
  throw SimError("unknown linear solver '" + s + "' (expected cg or direct)");
}

std::string toString(PreconditionerKind k) {
  switch (k) {
    case PreconditionerKind::kBlockJacobi: return "block_jacobi";
    case PreconditionerKind::kTwoLevel: return "two_level";
  }
  return "unknown";
}

PreconditionerKind preconditionerFromString(const std::string& s) {
  if (s == "block_jacobi") return PreconditionerKind::kBlockJacobi;
  if (s == "two_level") return PreconditionerKind::kTwoLevel;
  throw SimError("unknown preconditioner '" + s + "' (expected block_jacobi or two_level)");
}

Vec3 PinnedNodes::offset(Real t) const {
  if (waypoint_times.empty()) return Vec3::Zero();
  if (t <= waypoint_times.front()) return waypoint_offsets.front();
  for (size_t k = 1; k < waypoint_times.size(); ++k) {
    if (t < waypoint_times[k]) {
      const Real a = (t - waypoint_times[k - 1]) / (waypoint_times[k] - waypoint_times[k - 1]);
      return (1 - a) * waypoint_offsets[k - 1] + a * waypoint_offsets[k];
    }
  }
  return waypoint_offsets.back();
}

Vec3 PinnedNodes::offsetVelocity(Real t) const {
  for (size_t k = 1; k < waypoint_times.size(); ++k) {
    if (t >= waypoint_times[k - 1] && t < waypoint_times[k])
      return (waypoint_offsets[k] - waypoint_offsets[k - 1]) / (waypoint_times[k] - waypoint_times[k - 1]);
  }
  return Vec3::Zero();
}

Real deterministicDot(const VecX& a, const VecX& b) {
  // Fixed chunks summed in order: the same result for any thread count.
  // Small vectors are summed on one thread (same chunks, same order, same result): a parallel
  // region costs more than the work, and much more when other processes keep the cores busy.
  constexpr Index kChunks = 64;
  const Index n = a.size();
  Real partial[kChunks];
#pragma omp parallel for schedule(static) if (n > (1 << 16))
  for (Index c = 0; c < kChunks; ++c) {
    const Index lo = n * c / kChunks, hi = n * (c + 1) / kChunks;
    partial[c] = a.segment(lo, hi - lo).dot(b.segment(lo, hi - lo));
  }
  Real s = 0;
  for (Index c = 0; c < kChunks; ++c) s += partial[c];
  return s;
}

namespace {

using Clock = std::chrono::steady_clock;

class SemiImplicitEuler : public ImplicitEulerBase {
 public:
  explicit SemiImplicitEuler(SolverSettings s) : ImplicitEulerBase(s) {}
  IntegratorType type() const override { return IntegratorType::kSemiImplicitEuler; }

  std::vector<Real> solverState() const override {
    if (!solver_.warm_start || prev_y_.size() == 0) return {};
    std::vector<Real> s(1 + prev_y_.size());
    s[0] = prev_h_;
    std::copy(prev_y_.data(), prev_y_.data() + prev_y_.size(), s.begin() + 1);
    return s;
  }
  bool setSolverState(const std::vector<Real>& state) override {
    if (state.empty()) {
      prev_y_.resize(0);
      prev_h_ = 0;
      return true;
    }
    if (!(state[0] > 0) || !std::all_of(state.begin(), state.end(), [](Real r) { return std::isfinite(r); }))
      return false;
    prev_h_ = state[0];
    prev_y_ = Eigen::Map<const VecX>(state.data() + 1, static_cast<Index>(state.size()) - 1);
    return true;
  }

  StepOutcome step(ClothModel& model, const PinnedNodes& pins, const VecX& x, const VecX& v, Real t, Real h,
                   VecX& x_new, VecX& v_new) override {
    StepOutcome out;
    const auto t_asm = Clock::now();
    const bool new_model = model_ != &model;
    if (!assemble(model, x, v, h, &out)) return out;
    const Index n = model.numNodes();
    const int b = model.dofsPerNode();
    const Index dofs = n * b;
    mask_ = pinnedMask(model.numNodes(), pins);
    if (new_model) {
      if (prev_y_.size() != dofs) prev_y_.resize(0);  // keeps a restored solverState() of the right size
      if (solver_.kind == LinearSolverKind::kDirect) direct_.setPattern(model.jacobianPattern());
    }

    // Prescribed velocity change of the pinned DOFs, moved to the right-hand side:
    // A_ff y = rhs_f - A_fp dv_p, y = 0 on pinned DOFs.
    VecX dv = VecX::Zero(dofs);
    pinnedVelocityChange(model, pins, x, v, t, h, dv);
    system_.multiply(dv, Ap_);
    VecX bf = rhs_ - Ap_;
    filter(bf);
    out.assembly_ms = msSince(t_asm);

    const auto t_solve = Clock::now();
    VecX y = VecX::Zero(dofs);
    if (solver_.kind == LinearSolverKind::kDirect) {
      dof_pinned_.assign(dofs, 0);
      for (Index i = 0; i < n; ++i)
        if (mask_[i])
          for (int r = 0; r < b; ++r) dof_pinned_[i * b + r] = 1;
      if (!direct_.factorize(system_, dof_pinned_)) {
        out.ok = false;
        out.failure = "sparse factorisation of the implicit system failed";
        return out;
      }
      direct_.solve(bf, y);
      filter(y);
      out.solver_iterations = 1;
    } else {
      if (!solvePCG(bf, h, y, &out)) return out;
    }
    out.solve_ms = msSince(t_solve);
    prev_y_ = y;
    prev_h_ = h;
    dv += y;
    finish(pins, x, v, t, h, dv, model, x_new, v_new, &out);
    return out;
  }

 private:
  void filter(VecX& y) const {
    const int b = system_.pattern().blockSize();
    const Index n = static_cast<Index>(mask_.size());
    for (Index i = 0; i < n; ++i)
      if (mask_[i]) y.segment(i * b, b).setZero();
  }
  // out = A_ff in (pinned rows zeroed; `in` is zero on pinned DOFs).
  void applyA(const VecX& in, VecX& out) const { preconditioner_.applySystem(in, out); }
  bool solvePCG(const VecX& bf, Real h, VecX& y, StepOutcome* out) {
    const Index dofs = bf.size();
    // The coarse level needs a positive definite Galerkin matrix; when it is not (possible with an
    // indefinite exact Jacobian), this step falls back to block-Jacobi, and CG decides.
    if (!preconditioner_.update(system_, mask_, solver_.preconditioner, solver_.smoothing_steps,
                                solver_.smoothing_weight, BlockJacobi::Inverse::kPlain)) {
      out->ok = false;
      out->failure = "singular diagonal block in implicit system";
      return false;
    }
    const Real bnorm = std::sqrt(deterministicDot(bf, bf));
    const Real stop = solver_.relative_tolerance * std::max(bnorm, 1e-300);
    VecX r = bf;
    y.setZero(dofs);
    if (solver_.warm_start && prev_y_.size() == dofs && prev_h_ > 0) {
      // Guess g = previous solution scaled by h / h_prev, then by the A-norm optimal factor.
      VecX g = prev_y_ * (h / prev_h_);
      filter(g);
      applyA(g, Ap_);
      const Real gAg = deterministicDot(g, Ap_);
      if (gAg > 0) {
        const Real s = deterministicDot(g, bf) / gAg;
        y = s * g;
        r = bf - s * Ap_;
      }
    }
    int it = 0;
    Real rnorm = std::sqrt(deterministicDot(r, r));
    bool converged = rnorm <= stop;
    if (!converged) {
      preconditioner_.apply(r, z_);
      p_ = z_;
      Real rz = deterministicDot(r, z_);
      while (it < solver_.max_iterations) {
        if (!(rz > 0) && preconditioner_.dropSmoothing()) {
          // The smoothed cycle is positive definite only if smoothing_weight * lambda_max(D^-1 A) < 2;
          // if it is not, restart the search directions with the additive two-level preconditioner.
          preconditioner_.apply(r, z_);
          p_ = z_;
          rz = deterministicDot(r, z_);
        }
        applyA(p_, Ap_);
        const Real pAp = deterministicDot(p_, Ap_);
        if (!(pAp > 0) || !(rz > 0)) {
          out->ok = false;
          out->failure = "implicit system not positive definite (negative curvature in CG)";
          out->solver_iterations = it;
          return false;
        }
        const Real alpha = rz / pAp;
        addScaled(y, alpha, p_);
        addScaled(r, -alpha, Ap_);
        ++it;
        rnorm = std::sqrt(deterministicDot(r, r));
        if (rnorm <= stop) {
          converged = true;
          break;
        }
        preconditioner_.apply(r, z_);
        const Real rz_new = deterministicDot(r, z_);
        scaleAndAdd(p_, rz_new / rz, z_);  // p = z + (rz_new / rz) p
        rz = rz_new;
      }
    }
    out->solver_iterations = it;
    if (!converged && !(solver_.accept_tolerance > 0 && rnorm <= solver_.accept_tolerance * bnorm)) {
      out->ok = false;
      out->failure = "conjugate gradients did not converge in " + std::to_string(it) + " iterations";
      return false;
    }
    return true;
  }

  std::vector<char> mask_;
  SystemPreconditioner preconditioner_;
  BlockSparseLdlt direct_;
  std::vector<char> dof_pinned_;
  VecX Ap_, z_, p_, prev_y_;
  Real prev_h_ = 0;
};

class BlockDiagonalEuler : public ImplicitEulerBase {
 public:
  explicit BlockDiagonalEuler(SolverSettings s) : ImplicitEulerBase(s) {}
  IntegratorType type() const override { return IntegratorType::kBlockDiagonalEuler; }

  StepOutcome step(ClothModel& model, const PinnedNodes& pins, const VecX& x, const VecX& v, Real t, Real h,
                   VecX& x_new, VecX& v_new) override {
    StepOutcome out;
    if (!assemble(model, x, v, h, &out)) return out;
    const Index n = model.numNodes();
    const int b = model.dofsPerNode();
    const auto mask = pinnedMask(model.numNodes(), pins);
    VecX dv = VecX::Zero(n * b);
    bool singular = false;
    if (b == 3) {
#pragma omp parallel for schedule(static) reduction(|| : singular) if (parallelWorthIt(n, b))
      for (Index i = 0; i < n; ++i) {
        if (mask[i]) continue;
        // Closed-form 3x3 inverse (adjugate / determinant), as in the thesis.
        const Mat3 A = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(
            system_.block(system_.pattern().diagonal(i)));
        const Real det = A.determinant();
        if (!(std::abs(det) > 1e-300)) {
          singular = true;
          continue;
        }
        dv.segment<3>(3 * i) = A.inverse() * rhs_.segment<3>(3 * i);
      }
    } else {
      for (Index i = 0; i < n && !singular; ++i) {
        if (mask[i]) continue;
        Eigen::MatrixXd inv;
        if (!invertDiagonal(i, &inv)) {
          singular = true;
          break;
        }
        dv.segment(i * b, b) = inv * rhs_.segment(i * b, b);
      }
    }
    if (singular) {
      out.ok = false;
      out.failure = "singular diagonal block in block-diagonal system";
      return out;
    }
    pinnedVelocityChange(model, pins, x, v, t, h, dv);
    finish(pins, x, v, t, h, dv, model, x_new, v_new, &out);
    return out;
  }
};

class RungeKutta4 : public Integrator {
 public:
  IntegratorType type() const override { return IntegratorType::kRK4; }

  StepOutcome step(ClothModel& model, const PinnedNodes& pins, const VecX& x, const VecX& v, Real t, Real h,
                   VecX& x_new, VecX& v_new) override {
    StepOutcome out;
    const int b = model.dofsPerNode();
    const std::vector<char> mask = pinnedMask(model.numNodes(), pins);
    bool mass_ok = true;
    auto derivative = [&](VecX& xs, VecX& vs, Real ts, VecX& a) {
      // Pinned nodes sit exactly on their trajectory at every stage.
      for (size_t k = 0; k < pins.nodes.size(); ++k) {
        const Index p = pins.nodes[k];
        xs.segment<3>(p * b) = pins.position(k, ts);
        vs.segment(p * b, b).setZero();
        vs.segment<3>(p * b) = pins.offsetVelocity(ts);
      }
      const ForceReport rep = model.computeForces(xs, vs, force_, nullptr);
      out.degenerate_terms += rep.degenerate_terms;
      out.torn_segments = std::max(out.torn_segments, rep.torn_segments);
      // a = M^-1 f on the free nodes; pinned nodes do not accelerate (their offsets are piecewise linear).
      if (!model.solveMass(xs, force_, mask, a)) mass_ok = false;
    };
    VecX x1 = x, v1 = v, a1, a2, a3, a4;
    derivative(x1, v1, t, a1);
    VecX x2 = x1 + 0.5 * h * v1, v2 = v1 + 0.5 * h * a1;
    derivative(x2, v2, t + 0.5 * h, a2);
    VecX x3 = x1 + 0.5 * h * v2, v3 = v1 + 0.5 * h * a2;
    derivative(x3, v3, t + 0.5 * h, a3);
    VecX x4 = x1 + h * v3, v4 = v1 + h * a3;
    derivative(x4, v4, t + h, a4);
    x_new = x1 + (h / 6) * (v1 + 2 * v2 + 2 * v3 + v4);
    v_new = v1 + (h / 6) * (a1 + 2 * a2 + 2 * a3 + a4);
    for (size_t k = 0; k < pins.nodes.size(); ++k) {
      const Index p = pins.nodes[k];
      x_new.segment<3>(p * b) = pins.position(k, t + h);
      v_new.segment(p * b, b).setZero();
      v_new.segment<3>(p * b) = pins.offsetVelocity(t + h);
    }
    // Embedded estimate: distance to the explicit midpoint rule (second order), in position and in
    // velocity times h. The velocity term matters: a stiff mode near RK4's stability limit shows in
    // the velocities (jitter) long before the positions move, and at rest detection's scale.
    const VecX x_mid = x1 + h * v2;
    const VecX v_mid = v1 + h * a2;
    Real worst = 0;
    for (Index i = 0; i < model.numNodes(); ++i)
      worst = std::max({worst, (x_new.segment<3>(i * b) - x_mid.segment<3>(i * b)).norm(),
                        h * (v_new.segment<3>(i * b) - v_mid.segment<3>(i * b)).norm()});
    out.error_estimate = worst;
    out.error_order = 3;
    if (!mass_ok) {
      out.ok = false;
      out.failure = "mass matrix solve failed";
    } else if (!x_new.allFinite() || !v_new.allFinite()) {
      out.ok = false;
      out.failure = "non-finite state after step";
    }
    return out;
  }

 private:
  VecX force_;
};

}  // namespace

std::unique_ptr<Integrator> makeIntegrator(IntegratorType type, const SolverSettings& solver) {
  switch (type) {
    case IntegratorType::kRK4: return std::make_unique<RungeKutta4>();
    case IntegratorType::kSemiImplicitEuler: return std::make_unique<SemiImplicitEuler>(solver);
    case IntegratorType::kBlockDiagonalEuler: return std::make_unique<BlockDiagonalEuler>(solver);
    case IntegratorType::kBackwardEulerNewton: return makeBackwardEulerNewton(solver);
  }
  throw SimError("unknown integrator");
}

}  // namespace textile_handling
