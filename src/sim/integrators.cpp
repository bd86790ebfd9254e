#include "textile_handling/sim/integrators.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace textile_handling {

std::string toString(IntegratorType t) {
  switch (t) {
    case IntegratorType::kRK4: return "rk4";
    case IntegratorType::kSemiImplicitEuler: return "semi_implicit";
    case IntegratorType::kBlockDiagonalEuler: return "block_diagonal";
  }
  return "unknown";
}

IntegratorType integratorFromString(const std::string& s) {
  if (s == "rk4") return IntegratorType::kRK4;
  if (s == "semi_implicit") return IntegratorType::kSemiImplicitEuler;
  if (s == "block_diagonal") return IntegratorType::kBlockDiagonalEuler;
  throw std::invalid_argument("unknown integrator '" + s + "' (expected rk4, semi_implicit or block_diagonal)");
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
  constexpr Index kChunks = 64;
  const Index n = a.size();
  Real partial[kChunks];
#pragma omp parallel for schedule(static)
  for (Index c = 0; c < kChunks; ++c) {
    const Index lo = n * c / kChunks, hi = n * (c + 1) / kChunks;
    partial[c] = a.segment(lo, hi - lo).dot(b.segment(lo, hi - lo));
  }
  Real s = 0;
  for (Index c = 0; c < kChunks; ++c) s += partial[c];
  return s;
}

namespace {

bool allFinite(const VecX& v) { return v.allFinite(); }

// Marks the DOFs of pinned nodes.
std::vector<char> pinnedMask(const ClothModel& model, const PinnedNodes& pins) {
  std::vector<char> mask(model.numNodes(), 0);
  for (Index p : pins.nodes) mask[p] = 1;
  return mask;
}

// Shared by both implicit variants: assembles A = M - h D - h^2 K and rhs = h (f + h K v).
class ImplicitEulerBase : public Integrator {
 protected:
  explicit ImplicitEulerBase(SolverSettings s) : solver_(s) {}

  bool assemble(ClothModel& model, const VecX& x, const VecX& v, Real h, StepOutcome* out) {
    if (model_ != &model) {
      jac_ = model.makeJacobians();
      system_ = BlockSparseMatrix(&model.jacobianPattern());
      model_ = &model;
    }
    const ForceReport rep = model.computeForces(x, v, f_, &jac_);
    out->degenerate_terms = rep.degenerate_terms;
    if (!allFinite(f_)) {
      out->ok = false;
      out->failure = "non-finite force";
      return false;
    }
    auto& A = system_.values();
    const auto& K = jac_.dfdx.values();
    const auto& D = jac_.dfdv.values();
    const Real h2 = h * h;
#pragma omp parallel for schedule(static)
    for (Index k = 0; k < static_cast<Index>(A.size()); ++k) A[k] = -h * D[k] - h2 * K[k];
    const BlockPattern& p = model.jacobianPattern();
    const int b = p.blockSize();
    const VecX& m = model.massPerDof();
    for (Index i = 0; i < p.numNodes(); ++i) {
      Real* blk = system_.block(p.diagonal(i));
      for (int r = 0; r < b; ++r) blk[r * b + r] += m[i * b + r];
    }
    jac_.dfdx.multiply(v, kv_);
    rhs_ = h * (f_ + h * kv_);
    return true;
  }

  // Inverts the diagonal block of node i of the system matrix.
  bool invertDiagonal(Index i, Eigen::MatrixXd* inv) const {
    const BlockPattern& p = system_.pattern();
    const int b = p.blockSize();
    Eigen::Map<const Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> blk(
        system_.block(p.diagonal(i)), b, b);
    Eigen::FullPivLU<Eigen::MatrixXd> lu(blk);
    if (!lu.isInvertible()) return false;
    *inv = lu.inverse();
    return true;
  }

  void finish(const PinnedNodes& pins, const VecX& x, const VecX& v, Real t, Real h, const VecX& dv,
              const ClothModel& model, VecX& x_new, VecX& v_new, StepOutcome* out) {
    v_new = v + dv;
    x_new = x + h * v_new;
    const int b = model.dofsPerNode();
    // Pinned nodes land exactly on their prescribed positions.
    for (size_t k = 0; k < pins.nodes.size(); ++k) {
      const Index p = pins.nodes[k];
      x_new.segment<3>(p * b) = pins.position(k, t + h);
    }
    Real worst = 0;
    const auto mask = pinnedMask(model, pins);
    for (Index i = 0; i < model.numNodes(); ++i)
      if (!mask[i]) worst = std::max(worst, dv.segment<3>(i * b).norm());
    out->error_estimate = 0.5 * h * worst;  // |x_backward - x_forward| / 2
    out->error_order = 2;
    if (!allFinite(x_new) || !allFinite(v_new)) {
      out->ok = false;
      out->failure = "non-finite state after step";
    }
  }

  // Prescribed velocity change of pinned nodes so that they reach their target at t + h.
  void pinnedVelocityChange(const ClothModel& model, const PinnedNodes& pins, const VecX& x, const VecX& v,
                            Real t, Real h, VecX& dv) const {
    const int b = model.dofsPerNode();
    for (size_t k = 0; k < pins.nodes.size(); ++k) {
      const Index p = pins.nodes[k];
      const Vec3 target_v = (pins.position(k, t + h) - x.segment<3>(p * b)) / h;
      dv.segment(p * b, b).setZero();
      dv.segment<3>(p * b) = target_v - v.segment<3>(p * b);
    }
  }

  SolverSettings solver_;
  const ClothModel* model_ = nullptr;
  ForceJacobians jac_;
  BlockSparseMatrix system_;
  VecX f_, kv_, rhs_;
};

class SemiImplicitEuler : public ImplicitEulerBase {
 public:
  explicit SemiImplicitEuler(SolverSettings s) : ImplicitEulerBase(s) {}
  IntegratorType type() const override { return IntegratorType::kSemiImplicitEuler; }

  StepOutcome step(ClothModel& model, const PinnedNodes& pins, const VecX& x, const VecX& v, Real t, Real h,
                   VecX& x_new, VecX& v_new) override {
    StepOutcome out;
    if (!assemble(model, x, v, h, &out)) return out;
    const Index n = model.numNodes();
    const int b = model.dofsPerNode();
    const Index dofs = n * b;
    const auto mask = pinnedMask(model, pins);

    // Block-Jacobi preconditioner.
    precond_.resize(n);
    for (Index i = 0; i < n; ++i) {
      if (mask[i]) continue;
      if (!invertDiagonal(i, &precond_[i])) {
        out.ok = false;
        out.failure = "singular diagonal block in implicit system";
        return out;
      }
    }
    auto filter = [&](VecX& y) {
      for (Index p : pins.nodes) y.segment(p * b, b).setZero();
    };
    auto applyPrecond = [&](const VecX& r, VecX& z) {
      z.resize(dofs);
#pragma omp parallel for schedule(static)
      for (Index i = 0; i < n; ++i) {
        if (mask[i]) {
          z.segment(i * b, b).setZero();
        } else {
          z.segment(i * b, b) = precond_[i] * r.segment(i * b, b);
        }
      }
    };

    VecX dv = VecX::Zero(dofs);
    pinnedVelocityChange(model, pins, x, v, t, h, dv);
    VecX r(dofs), z(dofs), p(dofs), Ap(dofs);
    system_.multiply(dv, Ap);
    r = rhs_ - Ap;
    filter(r);
    VecX rhs_free = rhs_;
    filter(rhs_free);
    const Real stop = solver_.relative_tolerance * std::max(std::sqrt(deterministicDot(rhs_free, rhs_free)), 1e-300);
    applyPrecond(r, z);
    p = z;
    Real rz = deterministicDot(r, z);
    int it = 0;
    bool converged = std::sqrt(deterministicDot(r, r)) <= stop;
    while (!converged && it < solver_.max_iterations) {
      system_.multiply(p, Ap);
      filter(Ap);
      const Real pAp = deterministicDot(p, Ap);
      if (!(pAp > 0)) {
        out.ok = false;
        out.failure = "implicit system not positive definite (negative curvature in CG)";
        out.solver_iterations = it;
        return out;
      }
      const Real alpha = rz / pAp;
      dv += alpha * p;
      r -= alpha * Ap;
      ++it;
      if (std::sqrt(deterministicDot(r, r)) <= stop) {
        converged = true;
        break;
      }
      applyPrecond(r, z);
      const Real rz_new = deterministicDot(r, z);
      p = z + (rz_new / rz) * p;
      rz = rz_new;
    }
    out.solver_iterations = it;
    if (!converged) {
      out.ok = false;
      out.failure = "conjugate gradients did not converge in " + std::to_string(it) + " iterations";
      return out;
    }
    finish(pins, x, v, t, h, dv, model, x_new, v_new, &out);
    return out;
  }

 private:
  std::vector<Eigen::MatrixXd> precond_;
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
    const auto mask = pinnedMask(model, pins);
    VecX dv = VecX::Zero(n * b);
    bool singular = false;
    if (b == 3) {
#pragma omp parallel for schedule(static) reduction(|| : singular)
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
    const VecX& m = model.massPerDof();
    auto derivative = [&](VecX& xs, VecX& vs, Real ts, VecX& a) {
      // Pinned nodes sit exactly on their trajectory at every stage.
      for (size_t k = 0; k < pins.nodes.size(); ++k) {
        const Index p = pins.nodes[k];
        xs.segment<3>(p * b) = pins.position(k, ts);
        vs.segment(p * b, b).setZero();
        vs.segment<3>(p * b) = pins.offsetVelocity(ts);
      }
      const ForceReport rep = model.computeForces(xs, vs, a, nullptr);
      out.degenerate_terms += rep.degenerate_terms;
      a.array() /= m.array();
      for (Index p : pins.nodes) a.segment(p * b, b).setZero();
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
    // Embedded estimate: distance to the explicit midpoint rule (second order).
    const VecX x_mid = x1 + h * v2;
    Real worst = 0;
    for (Index i = 0; i < model.numNodes(); ++i)
      worst = std::max(worst, (x_new.segment<3>(i * b) - x_mid.segment<3>(i * b)).norm());
    out.error_estimate = worst;
    out.error_order = 3;
    if (!allFinite(x_new) || !allFinite(v_new)) {
      out.ok = false;
      out.failure = "non-finite state after step";
    }
    return out;
  }
};

}  // namespace

std::unique_ptr<Integrator> makeIntegrator(IntegratorType type, const SolverSettings& solver) {
  switch (type) {
    case IntegratorType::kRK4: return std::make_unique<RungeKutta4>();
    case IntegratorType::kSemiImplicitEuler: return std::make_unique<SemiImplicitEuler>(solver);
    case IntegratorType::kBlockDiagonalEuler: return std::make_unique<BlockDiagonalEuler>(solver);
  }
  throw std::invalid_argument("unknown integrator");
}

}  // namespace textile_handling
