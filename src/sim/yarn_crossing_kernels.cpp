// Crossing-level kernels of the yarn-level model (yarn_crossing_kernels.h).
#include "textile_handling/sim/yarn_crossing_kernels.h"

#include "yarn_angle_polynomials.h"

#include <Eigen/Geometry>
#include <cmath>

namespace textile_handling {
namespace yarn {

namespace {

using Vec6 = Eigen::Matrix<Real, 6, 1>;
using Mat6 = Eigen::Matrix<Real, 6, 6>;

// The angle and its derivatives in the stencil's reduced variables r = (a, b) = (x1 - x0, x3 - x0).
struct ReducedAngle {
  Real phi = 0;
  Vec6 g = Vec6::Zero();  // dphi/dr
  Mat6 H = Mat6::Zero();  // d2phi/dr2 (only if asked for)
};

ReducedAngle reducedAngle(const CrossingVector& p, bool hessian) {
  const detail::AnglePolynomials P =
      detail::anglePolynomials(p.segment<3>(3) - p.segment<3>(0), p.segment<3>(6) - p.segment<3>(0));
  const Real S = P.S, c = P.c, s = std::sqrt(S);
  ReducedAngle r;
  r.phi = std::atan2(s, c);
  r.g << (c / P.aa * P.a - P.b) / s, (c / P.bb * P.b - P.a) / s;
  if (!hessian) return r;
  // phi = G(S, c) = atan2(sqrt(S), c): chain rule through the polynomials S(a, b) and c(a, b).
  const Real r2 = S + c * c;
  r.H = detail::chainHessian(P, c / (2 * s * r2), -s / r2, -c * (r2 + 2 * S) / (4 * S * s * r2 * r2),
                             (S - c * c) / (2 * s * r2 * r2), 2 * s * c / (r2 * r2));
  return r;
}

// d r / d p for r = (a, b) and p = (x0, x1, x3).
Eigen::Matrix<Real, 6, 9> angleReductionJacobian() {
  Eigen::Matrix<Real, 6, 9> J = Eigen::Matrix<Real, 6, 9>::Zero();
  J.block<3, 3>(0, 0) = -Mat3::Identity();  // a = x1 - x0
  J.block<3, 3>(0, 3) = Mat3::Identity();
  J.block<3, 3>(3, 0) = -Mat3::Identity();  // b = x3 - x0
  J.block<3, 3>(3, 6) = Mat3::Identity();
  return J;
}

// The angle with its gradient and (if asked for) Hessian on the stencil.
struct StencilAngle {
  Real phi = 0;
  CrossingVector g = CrossingVector::Zero();
  CrossingMatrix H = CrossingMatrix::Zero();
};

StencilAngle stencilAngle(const CrossingVector& p, bool hessian) {
  const ReducedAngle r = reducedAngle(p, hessian);
  const Eigen::Matrix<Real, 6, 9> J = angleReductionJacobian();
  StencilAngle a;
  a.phi = r.phi;
  a.g = J.transpose() * r.g;
  if (hessian) a.H = J.transpose() * r.H * J;
  return a;
}

// The Hessian of V(phi(p)): V'' dphi dphi^T, plus V' d2phi unless `gauss_newton`.
CrossingMatrix composedHessian(const CrossingVector& p, Real first, Real second, bool gauss_newton) {
  const StencilAngle a = stencilAngle(p, !gauss_newton);
  CrossingMatrix H = second * a.g * a.g.transpose();
  if (!gauss_newton) H += first * a.H;
  return H;
}

Real sign(Real x) { return static_cast<Real>((x > 0) - (x < 0)); }

}  // namespace

CrossingVector packCrossingStencil(const Vec3& x0, const Vec3& x1, const Vec3& x3) {
  CrossingVector p;
  p << x0, x1, x3;
  return p;
}

Real crossingAngle(const CrossingVector& p) { return reducedAngle(p, false).phi; }

CrossingVector crossingAngleGradient(const CrossingVector& p) { return stencilAngle(p, false).g; }

AngleWithGradient crossingAngleWithGradient(const CrossingVector& p) {
  const StencilAngle a = stencilAngle(p, false);
  return {a.phi, a.g};
}

CrossingMatrix crossingAngleHessian(const CrossingVector& p) { return stencilAngle(p, true).H; }

Real shearStiffness(Real k_x, Real c_n, Real F_n) { return k_x * (1 + c_n * F_n); }

AnglePotential shearPotential(Real phi, const ShearParameters& s) {
  const Real kL = s.stiffness * s.rest_spacing, d = phi - kPi / 2;
  AnglePotential v;
  v.value = 0.5 * kL * d * d;
  v.first = kL * d;
  v.second = kL;
  if (s.interlaced && phi < s.jamming_angle) {
    const Real pj = s.jamming_angle, t = (pj - phi) / pj, t3 = t * t * t;
    v.value += kL * s.jamming_gain * pj * pj * t3 * t * t / 20;
    v.first -= kL * s.jamming_gain * pj * t3 * t / 4;
    v.second += kL * s.jamming_gain * t3;
  }
  return v;
}

Real shearEnergy(const CrossingVector& p, const ShearParameters& s) { return shearPotential(crossingAngle(p), s).value; }

CrossingVector shearGradient(const CrossingVector& p, const ShearParameters& s) {
  return shearGradient(crossingAngleWithGradient(p), s);
}

CrossingVector shearGradient(const AngleWithGradient& a, const ShearParameters& s) {
  return shearPotential(a.phi, s).first * a.g;
}

CrossingMatrix shearHessian(const CrossingVector& p, const ShearParameters& s) {
  const AnglePotential v = shearPotential(crossingAngle(p), s);
  return composedHessian(p, v.first, v.second, false);
}

CrossingMatrix shearHessianClamped(const CrossingVector& p, const ShearParameters& s) {
  return shearHessianClamped(crossingAngleWithGradient(p), s);  // one evaluation of the angle for phi and dphi
}

CrossingMatrix shearHessianClamped(const AngleWithGradient& a, const ShearParameters& s) {
  return shearPotential(a.phi, s).second * a.g * a.g.transpose();
}

StickSlip stickSlipSpring(Real x, Real anchor, Real k, Real limit) {
  const Real d = x - anchor;
  StickSlip f;
  f.stick = k * std::abs(d) <= limit;
  f.force = f.stick ? -k * d : -sign(d) * limit;
  f.stiffness = f.stick ? -k : 0;
  return f;
}

Real stickSlipAnchor(Real x, Real anchor, Real k, Real limit) {
  const Real d = x - anchor;
  if (k * std::abs(d) <= limit) return anchor;
  return x - sign(d) * limit / k;
}

StickSlip slidingFriction(Real u, Real anchor, Real k_f, Real mu, Real F_n) {
  return stickSlipSpring(u, anchor, k_f, mu * F_n);
}

Real slidingFrictionAnchor(Real u, Real anchor, Real k_f, Real mu, Real F_n) {
  return stickSlipAnchor(u, anchor, k_f, mu * F_n);
}

Real slidingDamping(Real u_dot, Real d_f) { return -d_f * u_dot; }

Real shearFrictionStickEnergy(const CrossingVector& p, Real anchor, Real k_fphi) {
  const Real d = crossingAngle(p) - anchor;
  return 0.5 * k_fphi * d * d;
}

CrossingVector shearFrictionStickGradient(const CrossingVector& p, Real anchor, Real k_fphi) {
  const StencilAngle a = stencilAngle(p, false);
  return k_fphi * (a.phi - anchor) * a.g;
}

CrossingMatrix shearFrictionStickHessian(const CrossingVector& p, Real anchor, Real k_fphi) {
  return composedHessian(p, k_fphi * (crossingAngle(p) - anchor), k_fphi, false);
}

CrossingMatrix shearFrictionStickHessianClamped(const CrossingVector& p, Real anchor, Real k_fphi) {
  return composedHessian(p, 0, k_fphi, true);
}

CrossingVector shearFrictionSlipForce(const CrossingVector& p, Real anchor, Real mu_phi, Real F_n) {
  const StencilAngle a = stencilAngle(p, false);
  return -sign(a.phi - anchor) * mu_phi * F_n * a.g;
}

ShearFriction shearFrictionClamped(const AngleWithGradient& a, Real anchor, Real k_fphi, Real mu_phi, Real F_n) {
  const StickSlip s = stickSlipSpring(a.phi, anchor, k_fphi, mu_phi * F_n);
  ShearFriction f;
  f.stick = s.stick;
  f.force = s.force * a.g;
  f.jacobian = s.stiffness * a.g * a.g.transpose();
  return f;
}

ShearFriction shearFriction(const CrossingVector& p, Real anchor, Real k_fphi, Real mu_phi, Real F_n, bool clamped) {
  if (clamped) return shearFrictionClamped(crossingAngleWithGradient(p), anchor, k_fphi, mu_phi, F_n);
  const StencilAngle a = stencilAngle(p, true);
  ShearFriction f = shearFrictionClamped({a.phi, a.g}, anchor, k_fphi, mu_phi, F_n);
  // d(F_phi dphi)/dp = F_phi' dphi dphi^T + F_phi d2phi, F_phi' = -k_fphi (stick) or 0 (slip).
  f.jacobian += stickSlipSpring(a.phi, anchor, k_fphi, mu_phi * F_n).force * a.H;
  return f;
}

Real shearFrictionAnchor(Real phi, Real anchor, Real k_fphi, Real mu_phi, Real F_n) {
  return stickSlipAnchor(phi, anchor, k_fphi, mu_phi * F_n);
}

Real parallelContactDistance(Real R, bool interlaced) { return (interlaced ? 4 : 2) * R; }

Real parallelContactEnergy(Real u0, Real u1, Real k_c, Real L, Real d) {
  const Real gap = u1 - u0 - d;
  return gap < 0 ? 0.5 * k_c * L * gap * gap : 0;
}

ContactVector parallelContactGradient(Real u0, Real u1, Real k_c, Real L, Real d) {
  const Real gap = u1 - u0 - d;
  if (gap >= 0) return ContactVector::Zero();
  return k_c * L * gap * ContactVector(-1, 1);
}

ContactMatrix parallelContactHessian(Real u0, Real u1, Real k_c, Real L, Real d) {
  if (u1 - u0 >= d) return ContactMatrix::Zero();
  ContactMatrix H;
  H << 1, -1, -1, 1;
  return k_c * L * H;
}

}  // namespace yarn
}  // namespace textile_handling
