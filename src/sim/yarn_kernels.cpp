// Per-segment kernels of the yarn-level model (yarn_kernels.h).
#include "textile_handling/sim/yarn_kernels.h"

#include <algorithm>
#include <cmath>

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

}  // namespace

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
