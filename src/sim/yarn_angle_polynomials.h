// Internal to sim_core: the polynomials S = |a x b|^2 and c = a . b of two edge vectors, with their
// first and second derivatives in (a, b), shared by the bending kernel (theta^2 = F(S, c)) and the
// crossing-angle kernel (phi = G(S, c)). Writing an angle function through S and c keeps its
// derivatives exact and smooth where the edges are parallel (yarn_kernels.h, yarn_crossing_kernels.h).
#pragma once

#include <Eigen/Core>

#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace yarn {
namespace detail {

using Vec6 = Eigen::Matrix<Real, 6, 1>;
using Mat6 = Eigen::Matrix<Real, 6, 6>;

struct AnglePolynomials {
  Vec3 a, b;
  Real aa = 0, bb = 0;  ///< |a|^2, |b|^2
  Real S = 0, c = 0;    ///< |a x b|^2 (computed as such: no cancellation near 0 and pi), a . b
  Vec6 dS, dc;          ///< dS/d(a, b), dc/d(a, b)
};

inline AnglePolynomials anglePolynomials(const Vec3& a, const Vec3& b) {
  AnglePolynomials p;
  p.a = a, p.b = b;
  p.aa = a.squaredNorm(), p.bb = b.squaredNorm(), p.c = a.dot(b);
  p.S = a.cross(b).squaredNorm();
  p.dS << 2 * p.bb * a - 2 * p.c * b, 2 * p.aa * b - 2 * p.c * a;
  p.dc << b, a;
  return p;
}

/// d2F/d(a, b)^2 of a function F(S, c) from its partial derivatives:
///   F_S d2S + F_c d2c + F_SS dS dS^T + F_Sc (dS dc^T + dc dS^T) + F_cc dc dc^T.
inline Mat6 chainHessian(const AnglePolynomials& p, Real F_S, Real F_c, Real F_SS, Real F_Sc, Real F_cc) {
  const Mat3 I = Mat3::Identity();
  const Vec3 &a = p.a, &b = p.b;
  Mat6 HS, Hc = Mat6::Zero();
  HS.topLeftCorner<3, 3>() = 2 * p.bb * I - 2 * b * b.transpose();
  HS.topRightCorner<3, 3>() = 4 * a * b.transpose() - 2 * b * a.transpose() - 2 * p.c * I;
  HS.bottomLeftCorner<3, 3>() = HS.topRightCorner<3, 3>().transpose();
  HS.bottomRightCorner<3, 3>() = 2 * p.aa * I - 2 * a * a.transpose();
  Hc.topRightCorner<3, 3>() = I;
  Hc.bottomLeftCorner<3, 3>() = I;
  return F_S * HS + F_c * Hc + F_SS * p.dS * p.dS.transpose() + F_Sc * (p.dS * p.dc.transpose() + p.dc * p.dS.transpose()) +
         F_cc * p.dc * p.dc.transpose();
}

}  // namespace detail
}  // namespace yarn
}  // namespace textile_handling
