// Shared by the yarn-level model's tests. Include it first: the eigenvalue checks trip GCC 12's
// -Wmaybe-uninitialized false positive inside Eigen's self-adjoint eigen solver (as in
// src/sim/yarn_kernels.cpp), and the pragma must precede the first Eigen include of the file.
#pragma once
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include <Eigen/Eigenvalues>
#include <functional>

#include "textile_handling/sim/types.h"

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

}  // namespace yarn_test_support
}  // namespace textile_handling
