// Shared by the yarn-level model's tests. Include it first: the eigenvalue checks trip GCC 12's
// -Wmaybe-uninitialized false positive inside Eigen's self-adjoint eigen solver (as in
// src/sim/yarn_kernels.cpp), and the pragma must precede the first Eigen include of the file.
#pragma once
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <functional>

#include "sim_test_support.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/types.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {
namespace yarn_test_support {

/// Eigenvalues of a symmetric matrix, ascending.
inline Eigen::VectorXd eigenvalues(const Eigen::MatrixXd& m) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m).eigenvalues();
}

/// Central differences (step h) of a scalar function of N values (N = Eigen::Dynamic: of q.size()).
template <int N>
Eigen::Matrix<Real, N, 1> numericGradientN(const std::function<Real(const Eigen::Matrix<Real, N, 1>&)>& f,
                                           const Eigen::Matrix<Real, N, 1>& q, Real h) {
  Eigen::Matrix<Real, N, 1> g = q;
  for (Eigen::Index k = 0; k < q.size(); ++k) {
    Eigen::Matrix<Real, N, 1> a = q, b = q;
    a[k] += h;
    b[k] -= h;
    g[k] = (f(a) - f(b)) / (2 * h);
  }
  return g;
}

/// Central differences (step h) of a vector function of N values, column by column (N = Eigen::Dynamic:
/// of q.size() values).
template <int N>
Eigen::Matrix<Real, N, N> numericJacobianN(const std::function<Eigen::Matrix<Real, N, 1>(const Eigen::Matrix<Real, N, 1>&)>& f,
                                           const Eigen::Matrix<Real, N, 1>& q, Real h) {
  Eigen::Matrix<Real, N, N> J;
  J.resize(q.size(), q.size());
  for (Eigen::Index k = 0; k < q.size(); ++k) {
    Eigen::Matrix<Real, N, 1> a = q, b = q;
    a[k] += h;
    b[k] -= h;
    J.col(k) = (f(a) - f(b)) / (2 * h);
  }
  return J;
}

/// Fixed steps of dt with `integrator` until `until` [s]; the run never stops early at rest.
inline SimulationSettings fixedSteps(IntegratorType integrator, Real dt, Real until) {
  SimulationSettings s;
  s.integrator = integrator;
  s.policy = StepPolicy::kFixed;
  s.dt = dt;
  s.max_time = until;
  s.rest_duration = 1e9;
  return s;
}

/// The model's df/dx and df/dv at (x, v), dense.
struct DenseJacobians {
  Eigen::MatrixXd dfdx, dfdv;
};

/// Checks a yarn model's Jacobians at (x, v) against central differences of its forces (steps hx on x,
/// hv on v): every held DOF's row and column of df/dx and row of df/dv are zero, and its difference
/// columns are left out (perturbing a held DOF is no motion of the model); the rest agrees within
/// x_tolerance and v_tolerance times the largest entry. Returns the analytic Jacobians.
inline DenseJacobians expectJacobiansMatchFiniteDifferences(YarnWovenModel& m, const VecX& x, const VecX& v, Real hx,
                                                            Real hv, Real x_tolerance, Real v_tolerance) {
  ForceJacobians jac = m.makeJacobians();
  VecX f;
  m.computeForces(x, v, f, &jac);  // also evaluates the lagged quantities at x
  DenseJacobians out{sim_test_support::denseMatrix(jac.dfdx), sim_test_support::denseMatrix(jac.dfdv)};
  auto forceAt = [&](const VecX& y, const VecX& w) {
    VecX r;
    m.computeForces(y, w, r, nullptr);
    return r;
  };
  Eigen::MatrixXd fdx = numericJacobianN<Eigen::Dynamic>([&](const VecX& y) { return forceAt(y, v); }, x, hx);
  Eigen::MatrixXd fdv = numericJacobianN<Eigen::Dynamic>([&](const VecX& w) { return forceAt(x, w); }, v, hv);
  for (Index d = 0; d < x.size(); ++d)
    if (m.isHeld(d)) {
      EXPECT_EQ(out.dfdx.row(d).cwiseAbs().maxCoeff(), 0) << d;
      EXPECT_EQ(out.dfdx.col(d).cwiseAbs().maxCoeff(), 0) << d;
      EXPECT_EQ(out.dfdv.row(d).cwiseAbs().maxCoeff(), 0) << d;
      fdx.col(d).setZero();
      fdv.col(d).setZero();
    }
  EXPECT_LT((out.dfdx - fdx).cwiseAbs().maxCoeff(), x_tolerance * out.dfdx.cwiseAbs().maxCoeff());
  EXPECT_LT((out.dfdv - fdv).cwiseAbs().maxCoeff(), v_tolerance * out.dfdv.cwiseAbs().maxCoeff());
  return out;
}

/// The model's mass matrix M(x), dense, after checking that it is symmetric and positive definite.
inline Eigen::MatrixXd expectSymmetricPositiveDefiniteMass(const ClothModel& m, const VecX& x) {
  BlockSparseMatrix a(&m.jacobianPattern());
  a.setZero();
  m.addMassMatrix(x, 1.0, a);
  const Eigen::MatrixXd M = sim_test_support::denseMatrix(a);
  EXPECT_LT((M - M.transpose()).cwiseAbs().maxCoeff(), 1e-20);
  EXPECT_GT(eigenvalues(M).minCoeff(), 0);
  return M;
}

}  // namespace yarn_test_support
}  // namespace textile_handling
