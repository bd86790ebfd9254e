#include "textile_handling/sim/static_equilibrium.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "sparse_ldlt.h"
#include "textile_handling/sim/cloth_triangles.h"
#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/timing.h"

namespace textile_handling {

namespace {

using Clock = std::chrono::steady_clock;

void checkSettings(const StaticEquilibriumSettings& s) {
  auto positive = [](Real v, const char* field) {
    if (!(v > 0) || !std::isfinite(v)) throw SimError(std::string("static equilibrium: ") + field + " must be finite and > 0");
  };
  if (s.max_iterations < 1) throw SimError("static equilibrium: max_iterations must be >= 1");
  if (s.max_backtracks < 0) throw SimError("static equilibrium: max_backtracks must be >= 0");
  if (!(s.max_extrapolation >= 1) || !std::isfinite(s.max_extrapolation))
    throw SimError("static equilibrium: max_extrapolation must be finite and >= 1");
  positive(s.force_tolerance, "force_tolerance");
  positive(s.initial_time_scale, "initial_time_scale");
  positive(s.max_time_scale, "max_time_scale");
  positive(s.min_time_scale, "min_time_scale");
  if (!(s.min_time_scale <= s.initial_time_scale && s.initial_time_scale <= s.max_time_scale))
    throw SimError("static equilibrium: need min_time_scale <= initial_time_scale <= max_time_scale");
}

}  // namespace

Real staticResidualRatio(const ClothModel& model, const VecX& f, const std::vector<char>& node_pinned) {
  const int b = model.dofsPerNode();
  const VecX& m = model.massPerDof();
  Real worst = 0;
  for (Index i = 0; i < model.numNodes(); ++i) {
    if (!node_pinned.empty() && node_pinned[i]) continue;
    const Real r = f.segment(i * b, b).norm() / (m[i * b] * kGravity);
    if (!(r <= worst)) worst = std::isfinite(r) ? std::max(worst, r) : r;
  }
  return worst;
}

StaticEquilibriumResult solveStaticEquilibrium(ClothModel& model, const PinnedNodes& pins, Real t, VecX& x,
                                               const StaticEquilibriumSettings& s) {
  checkSettings(s);
  if (x.size() != model.numDofs()) throw SimError("static equilibrium: state has the wrong size");
  if (!x.allFinite()) throw SimError("static equilibrium: state is not finite");
  const auto t_start = Clock::now();
  StaticEquilibriumResult res;
  const Index n = model.numNodes();
  const int b = model.dofsPerNode();
  const std::vector<char> mask = pinnedMask(n, pins);
  std::vector<char> dof_pinned(static_cast<std::size_t>(n) * b, 0);
  for (Index i = 0; i < n; ++i)
    if (mask[i]) std::fill(dof_pinned.begin() + i * b, dof_pinned.begin() + (i + 1) * b, 1);
  for (std::size_t k = 0; k < pins.nodes.size(); ++k) x.segment<3>(pins.nodes[k] * b) = pins.position(k, t);
  auto filter = [&](VecX& y) {
    for (Index i = 0; i < n; ++i)
      if (mask[i]) y.segment(i * b, b).setZero();
  };

  const VecX x_start = x;
  const VecX v0 = VecX::Zero(x.size());
  ForceJacobians jac = model.makeJacobians();
  BlockSparseMatrix system(&model.jacobianPattern());
  BlockSparseLdlt ldlt;
  ldlt.setPattern(model.jacobianPattern());
  VecX f, dx, x_try, x_stretch;
  // Energies that differ by less than this are equal to rounding (M g times a metre, times 1e-12).
  const Real energy_noise = 1e-12 * model.totalMass() * kGravity + 1e-300;

  auto a0 = Clock::now();
  Real energy = model.potentialEnergy(x);
  const Real energy_start = energy;
  res.assembly_ms += msSince(a0);
  Real h = s.initial_time_scale;
  bool forces_current = false;
  while (true) {
    if (!forces_current) {
      a0 = Clock::now();
      model.computeForces(x, v0, f, &jac);
      filter(f);
      res.assembly_ms += msSince(a0);
      forces_current = true;
      if (!f.allFinite()) {
        res.failure = "non-finite force";
        break;
      }
      res.residual_ratio = staticResidualRatio(model, f, mask);
      if (res.residual_ratio <= s.force_tolerance) {
        res.converged = true;
        break;
      }
    }
    if (res.iterations >= s.max_iterations) {
      res.failure = "no equilibrium within " + std::to_string(s.max_iterations) + " iterations (residual " +
                    std::to_string(res.residual_ratio) + " of a node's weight)";
      break;
    }
    if (h < s.min_time_scale) {
      res.failure = "pseudo time step fell below min_time_scale (no descent direction)";
      break;
    }
    // Regularised Newton system: M / h^2 - K.
    a0 = Clock::now();
    {
      auto& A = system.values();
      const auto& K = jac.dfdx.values();
      for (std::size_t k = 0; k < A.size(); ++k) A[k] = -K[k];
    }
    model.addMassMatrix(x, 1.0 / (h * h), system);
    res.assembly_ms += msSince(a0);
    const auto s0 = Clock::now();
    ++res.iterations;
    const bool factorised = ldlt.factorize(system, dof_pinned) && ldlt.negativePivots() == 0;
    if (factorised) {
      ldlt.solve(f, dx);
      filter(dx);
    }
    res.solve_ms += msSince(s0);
    const Real slope = factorised ? f.dot(dx) : 0;  // -dE/dalpha at alpha = 0
    if (!factorised || !(slope > 0) || !dx.allFinite()) {
      ++res.rejected;
      h /= 4;
      continue;
    }
    // Backtracking line search on the potential energy (Armijo, c = 1e-4).
    a0 = Clock::now();
    Real alpha = 1;
    bool accepted = false;
    for (int k = 0; k <= s.max_backtracks; ++k, alpha *= 0.5) {
      x_try = x + alpha * dx;
      const Real e = model.potentialEnergy(x_try);
      if (std::isfinite(e) && (e <= energy - 1e-4 * alpha * slope || (k == 0 && e <= energy + energy_noise))) {
        accepted = true;
        energy = e;
        break;
      }
    }
    // A full step that lowered the energy is stretched while it keeps lowering it (alpha 2, 4, ...):
    // along the stiffening (quintic) tension terms Newton's full step covers only a fraction of the way.
    if (accepted && alpha == 1) {
      for (Real stretch = 2; stretch <= s.max_extrapolation; stretch *= 2) {
        x_stretch = x + stretch * dx;
        const Real e = model.potentialEnergy(x_stretch);
        if (!std::isfinite(e) || !(e < energy)) break;
        energy = e;
        alpha = stretch;
        x_try.swap(x_stretch);
      }
    }
    res.assembly_ms += msSince(a0);
    if (!accepted) {
      ++res.rejected;
      h /= 4;
      continue;
    }
    x.swap(x_try);
    forces_current = false;
    h = alpha >= 1 ? std::min(4 * h, s.max_time_scale) : h / 4;
  }
  res.time_scale = h;
  res.energy_drop = energy_start - energy;
  for (Index i = 0; i < n; ++i)
    res.max_move = std::max(res.max_move, (x.segment<3>(i * b) - x_start.segment<3>(i * b)).norm());
  res.wall_ms = msSince(t_start);
  return res;
}

}  // namespace textile_handling
