#include "textile_handling/sim/energy_kernels.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace textile_handling {

bool tensionTerm(const Vec3& p0, const Vec3& p1, Real d, Real c0, bool want_hessian,
                 bool clamp_compression, TensionDerivatives* out) {
  const Vec3 diff = p0 - p1;
  const Real r = diff.norm();
  if (!(r > 1e-12 * d) || !std::isfinite(r) || !(d > 0)) return false;
  const Vec3 u = diff / r;
  Real e, de, d2e;
  if (r >= d) {
    const Real s = (r - d) / d;
    const Real s3 = s * s * s;
    e = c0 * s3 * s * s;
    de = 5 * c0 * s3 * s / d;
    d2e = 20 * c0 * s3 / (d * d);
  } else {
    const Real s = (d - r) / d;
    const Real s3 = s * s * s, s4 = s3 * s, s5 = s4 * s;
    e = c0 * s5 * d / r;
    de = -c0 * (5 * s4 / r + s5 * d / (r * r));
    d2e = c0 * (20 * s3 / (d * r) + 10 * s4 / (r * r) + 2 * s5 * d / (r * r * r));
  }
  out->energy = e;
  out->grad0 = de * u;
  if (want_hessian) {
    const Mat3 uu = u * u.transpose();
    out->hess00 = d2e * uu;
    if (!(clamp_compression && de < 0)) out->hess00 += (de / r) * (Mat3::Identity() - uu);
  }
  return true;
}

bool angleGeometry(const Vec3& p0, const Vec3& pa, const Vec3& pb, AngleGeometry* geo) {
  // Check before writing: on degenerate input the outputs stay untouched (header contract).
  const Vec3 k1 = pa - p0, k2 = pb - p0;
  const Real a = k1.norm(), b = k2.norm();
  if (!(a > 0) || !(b > 0) || !std::isfinite(a) || !std::isfinite(b)) return false;
  geo->k1 = k1;
  geo->k2 = k2;
  geo->a = a;
  geo->b = b;
  const Real dot = geo->k1.dot(geo->k2);
  const Real cross = geo->k1.cross(geo->k2).norm();
  const Real ab = geo->a * geo->b;
  geo->phi = std::atan2(cross, dot);
  geo->c = dot / ab;
  geo->s = cross / ab;
  const Real a2 = geo->a * geo->a, b2 = geo->b * geo->b;
  geo->g1 = (geo->k2 - (dot / a2) * geo->k1) / ab;
  geo->g2 = (geo->k1 - (dot / b2) * geo->k2) / ab;
  return true;
}

namespace {

// G_uv = d g_u / d k_v (thesis eqs 171, 176, 181, 186).
void secondDerivativesOfCosine(const AngleGeometry& g, Mat3* G11, Mat3* G12, Mat3* G22) {
  const Vec3& k1 = g.k1;
  const Vec3& k2 = g.k2;
  const Real a = g.a, b = g.b;
  const Real dot = k1.dot(k2);
  const Real a3b = a * a * a * b, ab3 = a * b * b * b;
  const Mat3 k1k2 = k1 * k2.transpose();
  const Mat3 k1k1 = k1 * k1.transpose();
  const Mat3 k2k2 = k2 * k2.transpose();
  const Mat3 I = Mat3::Identity();
  *G11 = -(k1k2 + k1k2.transpose()) / a3b - (dot / a3b) * I + (3 * dot / (a3b * a * a)) * k1k1;
  *G22 = -(k1k2 + k1k2.transpose()) / ab3 - (dot / ab3) * I + (3 * dot / (ab3 * b * b)) * k2k2;
  *G12 = I / (a * b) - k2k2 / ab3 - k1k1 / a3b + (dot / (a3b * b * b)) * k1k2;
}

// sin(t) - t cos(t), accurate for small t (series t^3/3 - t^5/30 + t^7/840).
Real sinMinusTCos(Real t) {
  if (std::abs(t) < 1e-2) {
    const Real t2 = t * t;
    return t * t2 * (1.0 / 3.0 - t2 * (1.0 / 30.0 - t2 / 840.0));
  }
  return std::sin(t) - t * std::cos(t);
}

}  // namespace

void angleTermDerivatives(const AngleGeometry& geo, AngleKind kind, const AngleProfile& p,
                          bool want_hessian, bool gauss_newton, AngleDerivatives* out) {
  out->energy = p.energy;
  Real w1, w2;      // exact weights of g and g g^T / G (see header)
  Real w_gn;        // Gauss-Newton weight of g g^T
  bool flat = false;
  if (kind == AngleKind::kShear) {
    out->theta = geo.phi - kPi / 2;
    const Real s = geo.s;
    w1 = -p.dE / s;
    w2 = (p.d2E * s - p.dE * geo.c) / (s * s * s);
    w_gn = std::max(p.d2E, Real(0)) / (s * s);  // clamp: a falling curve must not break definiteness
  } else {
    const Real theta = kPi - geo.phi;
    out->theta = theta;
    const Real s = geo.s;  // = sin(theta)
    // Only a nearly straight bend is "flat"; a fully folded one (theta -> pi) is a genuine
    // singularity and yields a non-finite gradient that the model reports as degenerate.
    flat = !(s > 1e-12) && theta < kPi / 2;
    const Real theta_over_sin = theta < 1e-4 ? 1 + theta * theta / 6 : theta / s;
    w1 = p.secant * theta_over_sin;
    if (flat) {
      w2 = 0;  // g vanishes like theta, so w2 g g^T -> 0 on a flat bend
      w_gn = 0;
    } else {
      w2 = ((p.d2E - p.secant) * s + p.secant * sinMinusTCos(theta)) / (s * s * s);
      w_gn = std::max(p.d2E, Real(0)) / (s * s);
    }
  }
  const Vec3 ga = w1 * geo.g1;
  const Vec3 gb = w1 * geo.g2;
  out->grad[1] = ga;
  out->grad[2] = gb;
  out->grad[0] = -(ga + gb);
  if (!want_hessian) return;

  Mat3 H11, H12, H22;
  if (gauss_newton && !(kind == AngleKind::kBending && flat)) {
    // Positive semi-definite part only: d2E/dphi2 * grad(phi) grad(phi)^T.
    H11 = w_gn * geo.g1 * geo.g1.transpose();
    H12 = w_gn * geo.g1 * geo.g2.transpose();
    H22 = w_gn * geo.g2 * geo.g2.transpose();
  } else {
    Mat3 G11, G12, G22;
    secondDerivativesOfCosine(geo, &G11, &G12, &G22);
    H11 = w2 * geo.g1 * geo.g1.transpose() + w1 * G11;
    H12 = w2 * geo.g1 * geo.g2.transpose() + w1 * G12;
    H22 = w2 * geo.g2 * geo.g2.transpose() + w1 * G22;
  }
  // Chain rule to nodes: k1 = pa - p0, k2 = pb - p0.
  const Mat3 H21 = H12.transpose();
  out->hess[1][1] = H11;
  out->hess[1][2] = H12;
  out->hess[2][1] = H21;
  out->hess[2][2] = H22;
  out->hess[0][1] = -(H11 + H21);
  out->hess[0][2] = -(H12 + H22);
  out->hess[1][0] = out->hess[0][1].transpose();
  out->hess[2][0] = out->hess[0][2].transpose();
  out->hess[0][0] = H11 + H12 + H21 + H22;
}

void dragTerm(const Vec3& v, Real coefficient, bool want_jacobian, DragDerivatives* out) {
  const Real speed = v.norm();
  out->force = -coefficient * speed * v;
  if (want_jacobian) {
    if (speed > 0) {
      out->dforce_dv = -coefficient * (speed * Mat3::Identity() + v * v.transpose() / speed);
    } else {
      out->dforce_dv.setZero();
    }
  }
}

}  // namespace textile_handling
