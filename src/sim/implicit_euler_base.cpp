#include "implicit_euler_base.h"

#include <Eigen/LU>
#include <algorithm>

#include "textile_handling/sim/cloth_triangles.h"
#include "parallel_size.h"

namespace textile_handling {

bool ImplicitEulerBase::assembleSystem(ClothModel& model, const VecX& x, const VecX& v, const VecX& x_mass, Real h,
                                       StepOutcome* out) {
  if (model_ != &model) {
    jac_ = model.makeJacobians();
    system_ = BlockSparseMatrix(&model.jacobianPattern());
    model_ = &model;
  }
  const ForceReport rep = model.computeForces(x, v, f_, &jac_);
  out->degenerate_terms = std::max(out->degenerate_terms, rep.degenerate_terms);
  out->torn_segments = std::max(out->torn_segments, rep.torn_segments);
  if (!f_.allFinite()) {
    out->ok = false;
    out->failure = "non-finite force";
    return false;
  }
  auto& A = system_.values();
  const auto& K = jac_.dfdx.values();
  const auto& D = jac_.dfdv.values();
  const Real h2 = h * h;
  const bool parallel = parallelWorthIt(model.numNodes(), model.dofsPerNode());
#pragma omp parallel for schedule(static) if (parallel)
  for (Index k = 0; k < static_cast<Index>(A.size()); ++k) A[k] = -h * D[k] - h2 * K[k];
  model.addMassMatrix(x_mass, 1.0, system_);  // M is held constant over the step
  return true;
}

bool ImplicitEulerBase::assemble(ClothModel& model, const VecX& x, const VecX& v, Real h, StepOutcome* out) {
  if (!assembleSystem(model, x, v, x, h, out)) return false;
  jac_.dfdx.multiply(v, kv_);
  rhs_ = h * (f_ + h * kv_);
  return true;
}

bool ImplicitEulerBase::invertDiagonal(Index i, Eigen::MatrixXd* inv) const {
  const BlockPattern& p = system_.pattern();
  const int b = p.blockSize();
  Eigen::Map<const Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> blk(
      system_.block(p.diagonal(i)), b, b);
  Eigen::FullPivLU<Eigen::MatrixXd> lu(blk);
  if (!lu.isInvertible()) return false;
  *inv = lu.inverse();
  return true;
}

void ImplicitEulerBase::finish(const PinnedNodes& pins, const VecX& x, const VecX& v, Real t, Real h,
                               const VecX& dv, const ClothModel& model, VecX& x_new, VecX& v_new,
                               StepOutcome* out) {
  v_new = v + dv;
  x_new = x + h * v_new;
  const int b = model.dofsPerNode();
  // Pinned nodes land exactly on their prescribed positions.
  for (size_t k = 0; k < pins.nodes.size(); ++k) {
    const Index p = pins.nodes[k];
    x_new.segment<3>(p * b) = pins.position(k, t + h);
  }
  Real worst = 0;
  const auto mask = pinnedMask(model.numNodes(), pins);
  for (Index i = 0; i < model.numNodes(); ++i)
    if (!mask[i]) worst = std::max(worst, dv.segment<3>(i * b).norm());
  out->error_estimate = 0.5 * h * worst;  // |x_backward - x_forward| / 2
  out->error_order = 2;
  if (!x_new.allFinite() || !v_new.allFinite()) {
    out->ok = false;
    out->failure = "non-finite state after step";
  }
}

void ImplicitEulerBase::pinnedVelocityChange(const ClothModel& model, const PinnedNodes& pins, const VecX& x,
                                             const VecX& v, Real t, Real h, VecX& dv) const {
  const int b = model.dofsPerNode();
  for (size_t k = 0; k < pins.nodes.size(); ++k) {
    const Index p = pins.nodes[k];
    const Vec3 target_v = (pins.position(k, t + h) - x.segment<3>(p * b)) / h;
    dv.segment(p * b, b).setZero();
    dv.segment<3>(p * b) = target_v - v.segment<3>(p * b);
  }
}

}  // namespace textile_handling
