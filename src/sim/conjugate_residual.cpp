#include "textile_handling/sim/conjugate_residual.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "textile_handling/sim/integrators.h"  // deterministicDot
#include "parallel_vector_ops.h"
#include "system_preconditioner.h"

namespace textile_handling {

struct ConjugateResidualSolver::Impl {
  const BlockSparseMatrix* a = nullptr;
  std::vector<char> pinned;
  bool any_pinned = false;
  int block = 3;
  SystemPreconditioner preconditioner;
  VecX r, z, p, az, ap, q;

  // Zeroes the pinned nodes' entries.
  void filter(VecX& x) const {
    if (!any_pinned) return;
    const Index n = static_cast<Index>(pinned.size());
    for (Index i = 0; i < n; ++i)
      if (pinned[i]) x.segment(i * block, block).setZero();
  }
  // out = A_ff in (`in` is zero on the pinned DOFs; the pinned rows of `out` are zeroed).
  void applyA(const VecX& in, VecX& out) const { preconditioner.applySystem(in, out); }
  // New search direction from the current residual: z = P r, p = z, Ap = Az; returns rho = z^T A z.
  Real restart() {
    preconditioner.apply(r, z);
    applyA(z, az);
    p = z;
    ap = az;
    return deterministicDot(z, az);
  }
};

ConjugateResidualSolver::ConjugateResidualSolver() : impl_(std::make_unique<Impl>()) {}
ConjugateResidualSolver::~ConjugateResidualSolver() = default;

bool ConjugateResidualSolver::setMatrix(const BlockSparseMatrix& a, const std::vector<char>& node_pinned,
                                        const ConjugateResidualPreconditioner& preconditioner) {
  Impl& s = *impl_;
  const Index n = a.pattern().numNodes();
  s.a = &a;
  s.block = a.pattern().blockSize();
  s.pinned = node_pinned.empty() ? std::vector<char>(n, 0) : node_pinned;
  s.pinned.resize(n, 0);
  s.any_pinned = std::any_of(s.pinned.begin(), s.pinned.end(), [](char c) { return c != 0; });
  return s.preconditioner.update(a, s.pinned, preconditioner.kind, preconditioner.smoothing_steps,
                                 preconditioner.smoothing_weight, BlockJacobi::Inverse::kPositiveDefinite);
}

ConjugateResidualResult ConjugateResidualSolver::solve(const VecX& b, VecX& y, Real relative_tolerance,
                                                       int max_iterations, Real accept_tolerance) {
  Impl& s = *impl_;
  ConjugateResidualResult out;
  const Index dofs = static_cast<Index>(s.pinned.size()) * s.block;
  y.setZero(dofs);
  s.r = b;
  s.filter(s.r);
  out.rhs_norm = std::sqrt(deterministicDot(s.r, s.r));
  out.residual_norm = out.rhs_norm;
  if (!std::isfinite(out.rhs_norm)) {
    out.failure = "conjugate residual: non-finite right-hand side";
    return out;
  }
  const Real stop = relative_tolerance * out.rhs_norm;
  if (out.rhs_norm <= stop || out.rhs_norm == 0) {
    out.converged = true;
    return out;
  }
  out.used_coarse_level = s.preconditioner.usesCoarseLevel();
  // z = P r, p = z, A p = A z; rho = z^T A z (the P-inner product <z, P A z>_P^-1).
  Real rho = s.restart();
  while (out.iterations < max_iterations) {
    s.preconditioner.apply(s.ap, s.q);  // q = P A p
    const Real sigma = deterministicDot(s.ap, s.q);
    if (!(sigma > 0) && s.preconditioner.dropSmoothing()) {
      // The smoothed cycle is not positive definite for this A: continue with the additive form.
      ++out.restarts;
      rho = s.restart();
      continue;
    }
    if (!(sigma > 0) || !std::isfinite(rho) || rho == 0) {
      std::ostringstream m;
      m << "conjugate residual breakdown at iteration " << out.iterations << " (z^T A z = " << rho
        << ", (Ap)^T P Ap = " << sigma << ")";
      out.failure = m.str();
      return out;
    }
    const Real alpha = rho / sigma;
    addScaled(y, alpha, s.p);
    addScaled(s.r, -alpha, s.ap);
    addScaled(s.z, -alpha, s.q);
    ++out.iterations;
    out.residual_norm = std::sqrt(deterministicDot(s.r, s.r));
    if (!std::isfinite(out.residual_norm)) {
      out.failure = "conjugate residual: non-finite residual at iteration " + std::to_string(out.iterations);
      return out;
    }
    if (out.residual_norm <= stop) {
      out.converged = true;
      return out;
    }
    s.applyA(s.z, s.az);
    const Real rho_new = deterministicDot(s.z, s.az);
    const Real beta = rho_new / rho;
    scaleAndAdd(s.p, beta, s.z);  // p = z + beta p
    scaleAndAdd(s.ap, beta, s.az);
    rho = rho_new;
  }
  if (accept_tolerance > 0 && out.residual_norm <= accept_tolerance * out.rhs_norm) {
    out.converged = true;
    return out;
  }
  std::ostringstream m;
  m << "conjugate residual did not converge in " << out.iterations << " iterations (relative residual "
    << out.residual_norm / out.rhs_norm << ")";
  out.failure = m.str();
  return out;
}

}  // namespace textile_handling
