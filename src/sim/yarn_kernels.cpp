// Per-segment kernels of the yarn-level model (yarn_kernels.h).
// GCC 12 reports a -Wmaybe-uninitialized false positive inside Eigen's SelfAdjointEigenSolver
// (tridiagonalisation); silence it for this file only (it must precede the first Eigen include).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include "textile_handling/sim/yarn_kernels.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "yarn_angle_polynomials.h"

namespace textile_handling {
namespace yarn {

namespace {

using Mat4 = Eigen::Matrix<Real, 4, 4>;

struct SegmentGeometry {
  Vec3 d;    // x1 - x0
  Real l;    // |d|
  Vec3 t;    // d / l (zero if l = 0)
  Real D;    // u1 - u0
};

SegmentGeometry geometry(const SegmentVector& q) {
  SegmentGeometry s;
  s.d = q.segment<3>(4) - q.segment<3>(0);
  s.l = s.d.norm();
  s.t = s.l > 0 ? Vec3(s.d / s.l) : Vec3::Zero();
  s.D = q[7] - q[3];
  return s;
}

// A Hessian in (d, D) (4 x 4) mapped to q = (x0, u0, x1, u1): d and D are differences node 1 - node 0.
SegmentMatrix fromDifferenceHessian(const Mat4& h) {
  SegmentMatrix H;
  H << h, -h, -h, h;
  return H;
}

SegmentMatrix stretchHessianImpl(const SegmentVector& q, Real k_s, bool clamp) {
  const SegmentGeometry s = geometry(q);
  Real transverse = s.l > 0 ? 1 - s.D / s.l : 0;
  if (clamp) transverse = std::max<Real>(0, transverse);
  const Mat3 tt = s.t * s.t.transpose();
  Mat4 h;
  h.topLeftCorner<3, 3>() = k_s / s.D * (tt + transverse * (Mat3::Identity() - tt));
  h.topRightCorner<3, 1>() = -k_s * s.l / (s.D * s.D) * s.t;
  h.bottomLeftCorner<1, 3>() = h.topRightCorner<3, 1>().transpose();
  h(3, 3) = k_s * s.l * s.l / (s.D * s.D * s.D);
  return fromDifferenceHessian(h);
}

using Vec6 = Eigen::Matrix<Real, 6, 1>;
using Mat6 = Eigen::Matrix<Real, 6, 6>;
using Vec7 = Eigen::Matrix<Real, 7, 1>;
using Mat7 = Eigen::Matrix<Real, 7, 7>;

// theta^2 = F(S, c) for theta = atan2(sqrt(S), c), and F's first and second derivatives. With s = sqrt(S),
// r^2 = S + c^2, A = theta / s and B = (1 - A c) / S:
//   F_S = A c / r^2,  F_c = -2 A S / r^2,  F_SS = (c^2 B - 3 A c) / (2 r^4),
//   F_Sc = (A S - c - A c^2) / r^4,  F_cc = (2 S + 4 A S c) / r^4,
// (from theta_s = c / r^2, theta_c = -s / r^2 and dS = 2 s ds). For small angles (x = s / c < 1e-2, c > 0)
// A and B come from the series of atan(x) / x, so nothing cancels: A = (1 - x^2/3 + x^4/5 - x^6/7) / c,
// B = (1 - 3x^2/5 + 3x^4/7 - x^6/3) / (3 c^2). As S -> 0: F_S -> 1 / c^2, F_SS -> -4 / (3 c^4).
struct AngleSquared {
  Real F, F_S, F_c, F_SS, F_Sc, F_cc;
};

AngleSquared angleSquared(Real S, Real c) {
  S = std::max<Real>(S, 0);
  const Real s = std::sqrt(S), r2 = S + c * c, theta = std::atan2(s, c);
  Real A, B;
  if (c > 0 && s < 1e-2 * c) {
    const Real x2 = S / (c * c);
    A = (1 - x2 / 3 + x2 * x2 / 5 - x2 * x2 * x2 / 7) / c;
    B = (1 - 3 * x2 / 5 + 3 * x2 * x2 / 7 - x2 * x2 * x2 / 3) / (3 * c * c);
  } else {
    A = theta / s;  // s = 0 here only for a yarn folded back on itself: singular (inf / nan)
    B = (1 - A * c) / S;
  }
  AngleSquared f;
  f.F = theta * theta;
  f.F_S = A * c / r2;
  f.F_c = -2 * A * S / r2;
  f.F_SS = (c * c * B - 3 * A * c) / (2 * r2 * r2);
  f.F_Sc = (A * S - c - A * c * c) / (r2 * r2);
  f.F_cc = (2 * S + 4 * A * S * c) / (r2 * r2);
  return f;
}

// Bending energy in the stencil's reduced variables r = (a, b, D2) = (x0 - x2, x1 - x0, u1 - u2): value,
// gradient and (if `H` is not null) Hessian.
Real bendReduced(const BendVector& q, Real k_b, Vec7* g, Mat7* H) {
  const detail::AnglePolynomials P = detail::anglePolynomials(q.segment<3>(4) - q.segment<3>(0), q.segment<3>(8) - q.segment<3>(4));
  const Real D2 = q[11] - q[3];
  const AngleSquared f = angleSquared(P.S, P.c);  // S computed as |a x b|^2: no cancellation for a straight yarn
  const Vec6 df = f.F_S * P.dS + f.F_c * P.dc;
  const Real V = k_b * f.F / D2;
  if (g) {
    g->head<6>() = k_b / D2 * df;
    (*g)[6] = -k_b * f.F / (D2 * D2);
  }
  if (H) {
    H->topLeftCorner<6, 6>() = k_b / D2 * detail::chainHessian(P, f.F_S, f.F_c, f.F_SS, f.F_Sc, f.F_cc);
    H->topRightCorner<6, 1>() = -k_b / (D2 * D2) * df;
    H->bottomLeftCorner<1, 6>() = H->topRightCorner<6, 1>().transpose();
    (*H)(6, 6) = 2 * k_b * f.F / (D2 * D2 * D2);
  }
  return V;
}

// d r / d q for r = (a, b, D2) and q = (x2, u2, x0, u0, x1, u1).
Eigen::Matrix<Real, 7, 12> bendReductionJacobian() {
  Eigen::Matrix<Real, 7, 12> J = Eigen::Matrix<Real, 7, 12>::Zero();
  J.block<3, 3>(0, 0) = -Mat3::Identity();  // a = x0 - x2
  J.block<3, 3>(0, 4) = Mat3::Identity();
  J.block<3, 3>(3, 4) = -Mat3::Identity();  // b = x1 - x0
  J.block<3, 3>(3, 8) = Mat3::Identity();
  J(6, 3) = -1;                             // D2 = u1 - u2
  J(6, 11) = 1;
  return J;
}

// J^T h J for J = bendReductionJacobian(): each stencil coordinate is +-1 times one or two reduced
// ones, so the product is a signed sum of h's entries (cheaper than Eigen's general product kernel,
// which these sizes would reach).
BendMatrix fromReducedHessian(const Mat7& h) {
  // Per stencil coordinate: up to two (reduced coordinate, sign) pairs; -1 = none.
  static constexpr int kR[12][2] = {{0, -1}, {1, -1}, {2, -1}, {6, -1}, {0, 3}, {1, 4}, {2, 5}, {-1, -1},
                                    {3, -1}, {4, -1}, {5, -1}, {6, -1}};
  static constexpr Real kS[12][2] = {{-1, 0}, {-1, 0}, {-1, 0}, {-1, 0}, {1, -1}, {1, -1}, {1, -1}, {0, 0},
                                     {1, 0},  {1, 0},  {1, 0},  {1, 0}};
  Eigen::Matrix<Real, 7, 12> hj;  // h J
  for (int j = 0; j < 12; ++j) {
    hj.col(j).setZero();
    for (int k = 0; k < 2; ++k)
      if (kR[j][k] >= 0) hj.col(j) += kS[j][k] * h.col(kR[j][k]);
  }
  BendMatrix out;
  for (int i = 0; i < 12; ++i) {
    out.row(i).setZero();
    for (int k = 0; k < 2; ++k)
      if (kR[i][k] >= 0) out.row(i) += kS[i][k] * hj.row(kR[i][k]);
  }
  return out;
}

}  // namespace

BendVector packBendStencil(const Vec3& x2, Real u2, const Vec3& x0, Real u0, const Vec3& x1, Real u1) {
  BendVector q;
  q << x2, u2, x0, u0, x1, u1;
  return q;
}

Real bendEnergy(const BendVector& q, Real k_b) { return bendReduced(q, k_b, nullptr, nullptr); }

BendVector bendGradient(const BendVector& q, Real k_b) {
  Vec7 g;
  bendReduced(q, k_b, &g, nullptr);
  return bendReductionJacobian().transpose() * g;
}

BendMatrix bendHessian(const BendVector& q, Real k_b) {
  Mat7 H;
  bendReduced(q, k_b, nullptr, &H);
  return fromReducedHessian(H);
}

// The clamped Hessian in the bend's own frame. With a = x0 - x2, b = x1 - x0 (lengths l_a, l_b, unit
// vectors a^, b^), n the unit normal of their plane (any normal of a straight yarn), t_a = n x a^ and
// t_b = b^ x n, the Hessian of V = k theta^2 / D2 in the orthonormal basis (a^, t_a, b^, t_b, D2)
// of the plane and (n on a, n on b) out of it is block diagonal (reflection through the plane leaves
// theta unchanged). With grad theta = -t_a / l_a on a and -t_b / l_b on b, and theta's second
// derivatives d2/da^ dt_a = 1 / l_a^2, d2/db^ dt_b = 1 / l_b^2, d2/dn_a^2 = cot theta / l_a^2,
// d2/dn_b^2 = cot theta / l_b^2, d2/dn_a dn_b = -1 / (l_a l_b sin theta) (all others 0):
//   in the plane (5 x 5): (2k / D2) w w^T + p (e1 e2^T + e2 e1^T) + r (e3 e4^T + e4 e3^T),
//     w = (0, -1/l_a, 0, -1/l_b, -theta/D2),  p = 2k theta / (D2 l_a^2),  r = 2k theta / (D2 l_b^2);
//   out of the plane (2 x 2): (2k / D2) (theta / sin theta) [[cos theta / l_a^2, -1 / (l_a l_b)],
//                                                          [-1 / (l_a l_b), cos theta / l_b^2]].
// The eigenvalues of a block-diagonal matrix are its blocks' eigenvalues, so clamping the two blocks
// (a 5 x 5 eigen solve and a closed-form 2 x 2) is the same as clamping the 7 x 7 reduced Hessian in
// (a, b, D2) (up to rounding; test_yarn_kernels checks it against that), at less cost.
BendMatrix bendHessianClamped(const BendVector& q, Real k_b) {
  using Mat5 = Eigen::Matrix<Real, 5, 5>;
  using Mat2 = Eigen::Matrix<Real, 2, 2>;
  const Vec3 a = q.segment<3>(4) - q.segment<3>(0), b = q.segment<3>(8) - q.segment<3>(4);
  const Real D2 = q[11] - q[3], la = a.norm(), lb = b.norm();
  const Vec3 ah = a / la, bh = b / lb, cross = ah.cross(bh);
  const Real sin_t = cross.norm(), theta = std::atan2(sin_t, ah.dot(bh));
  Vec3 n = sin_t > 1e-12 ? Vec3(cross / sin_t) : ah.unitOrthogonal();
  n = (n - n.dot(ah) * ah).normalized();
  const Vec3 ta = n.cross(ah), tb = bh.cross(n);
  const Real c1 = 2 * k_b / D2, c2 = c1 * theta;
  const Real theta_over_sin = theta < 1e-4 ? 1 + theta * theta / 6 : theta / sin_t;

  Eigen::Matrix<Real, 5, 1> w;
  w << 0, -1 / la, 0, -1 / lb, -theta / D2;
  Mat5 h5 = c1 * w * w.transpose();
  h5(0, 1) = h5(1, 0) = c2 / (la * la);
  h5(2, 3) = h5(3, 2) = c2 / (lb * lb);
  const Eigen::SelfAdjointEigenSolver<Mat5> es(h5);
  const Mat5 c5 = es.eigenvectors() * es.eigenvalues().cwiseMax(0).asDiagonal() * es.eigenvectors().transpose();

  Mat2 h2;
  const Real g = c1 * theta_over_sin;
  h2 << g * std::cos(theta) / (la * la), -g / (la * lb), -g / (la * lb), g * std::cos(theta) / (lb * lb);
  // Closed form: eigenvalues m +- d of [[x, y], [y, z]], m = (x + z) / 2, d = sqrt(((x - z) / 2)^2 + y^2).
  const Real m = 0.5 * (h2(0, 0) + h2(1, 1)), d = std::hypot(0.5 * (h2(0, 0) - h2(1, 1)), h2(0, 1));
  Mat2 c2x2 = Mat2::Zero();
  if (m - d >= 0) {
    c2x2 = h2;
  } else if (m + d > 0) {  // keep the positive eigenvalue's part: (m + d) v v^T
    Eigen::Matrix<Real, 2, 1> v(h2(0, 1), m + d - h2(0, 0));  // (H - (m+d) I) v = 0
    if (v.squaredNorm() < 1e-30 * (h2.squaredNorm() + 1e-300)) v = Eigen::Matrix<Real, 2, 1>(m + d - h2(1, 1), h2(0, 1));
    if (v.squaredNorm() > 0) c2x2 = (m + d) * v * v.transpose() / v.squaredNorm();
  }

  // The basis vectors in the reduced coordinates r = (a, b, D2), then to the stencil's.
  Eigen::Matrix<Real, 7, 5> q5 = Eigen::Matrix<Real, 7, 5>::Zero();
  Eigen::Matrix<Real, 7, 2> q2 = Eigen::Matrix<Real, 7, 2>::Zero();
  q5.block<3, 1>(0, 0) = ah;
  q5.block<3, 1>(0, 1) = ta;
  q5.block<3, 1>(3, 2) = bh;
  q5.block<3, 1>(3, 3) = tb;
  q5(6, 4) = 1;
  q2.block<3, 1>(0, 0) = n;
  q2.block<3, 1>(3, 1) = n;
  const Eigen::Matrix<Real, 7, 5> q5c5 = q5 * c5;
  const Eigen::Matrix<Real, 7, 2> q2c2 = q2 * c2x2;
  const Mat7 c7 = q5c5.lazyProduct(q5.transpose()) + q2c2.lazyProduct(q2.transpose());
  return fromReducedHessian(c7);
}

SegmentVector packSegment(const Vec3& x0, Real u0, const Vec3& x1, Real u1) {
  SegmentVector q;
  q << x0, u0, x1, u1;
  return q;
}

Real stretchEnergy(const SegmentVector& q, Real k_s) {
  const SegmentGeometry s = geometry(q);
  return k_s * (s.l - s.D) * (s.l - s.D) / (2 * s.D);
}

SegmentVector stretchGradient(const SegmentVector& q, Real k_s) {
  const SegmentGeometry s = geometry(q);
  const Vec3 gd = k_s * (s.l / s.D - 1) * s.t;                   // dV/dd
  const Real gD = -0.5 * k_s * (s.l * s.l / (s.D * s.D) - 1);   // dV/dD
  return packSegment(-gd, -gD, gd, gD);
}

SegmentMatrix stretchHessian(const SegmentVector& q, Real k_s) { return stretchHessianImpl(q, k_s, false); }

SegmentMatrix stretchHessianClamped(const SegmentVector& q, Real k_s) { return stretchHessianImpl(q, k_s, true); }

Real gravityEnergy(const SegmentVector& q, Real rho, const Vec3& g) {
  const Real D = q[7] - q[3];
  return -rho * D * g.dot(0.5 * (q.segment<3>(0) + q.segment<3>(4)));
}

SegmentVector gravityGradient(const SegmentVector& q, Real rho, const Vec3& g) {
  const Real D = q[7] - q[3];
  const Real height = g.dot(0.5 * (q.segment<3>(0) + q.segment<3>(4)));
  const Vec3 gx = -0.5 * rho * D * g;
  return packSegment(gx, rho * height, gx, -rho * height);
}

SegmentMatrix gravityHessian(Real rho, const Vec3& g) {
  SegmentMatrix H = SegmentMatrix::Zero();
  const Vec3 c = 0.5 * rho * g;
  for (int node : {0, 4}) {
    H.block<3, 1>(node, 3) = c;    // d2V / dx du0
    H.block<3, 1>(node, 7) = -c;   // d2V / dx du1
    H.block<1, 3>(3, node) = c.transpose();
    H.block<1, 3>(7, node) = -c.transpose();
  }
  return H;
}

SegmentMatrix segmentMass(const SegmentVector& q, Real rho) {
  const SegmentGeometry s = geometry(q);
  const Vec3 w = s.d / s.D;
  Mat4 ptp;  // P^T P, P = [I, -w]
  ptp.topLeftCorner<3, 3>() = Mat3::Identity();
  ptp.topRightCorner<3, 1>() = -w;
  ptp.bottomLeftCorner<1, 3>() = -w.transpose();
  ptp(3, 3) = w.squaredNorm();
  SegmentMatrix M;
  M << 2 * ptp, ptp, ptp, 2 * ptp;
  return rho * s.D / 6 * M;
}

}  // namespace yarn
}  // namespace textile_handling
