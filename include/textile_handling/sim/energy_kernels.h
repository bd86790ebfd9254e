// Small energy kernels of the particle cloth model (thesis, Breen 1994 / Eberhardt 1996).
//
// Every kernel evaluates one term: its energy, its gradient with respect to the nodes it touches, and
// (optionally) its Hessian blocks. Forces are the negative gradient, Jacobians df/dx the negative
// Hessian. Kernels return false on degenerate geometry (zero-length edges, non-finite input) and then
// leave the outputs untouched, so the caller can skip the term and report it.
//
// Notes on sources: formulas follow shared/reference/thesis-hanging-textiles.md sections 3 and 5;
// the SI re-parametrisation of the tension law and the curvature reading of the KES bending curve are
// decisions of this package, documented in docs/simulation.md.
#pragma once

#include "textile_handling/sim/types.h"

namespace textile_handling {

/// Tension term of one edge, quintic Breen-type law in the dimensionless strain of the thesis:
///   r > d:  E = C0 * ((r - d)/d)^5                       (stretch, thesis eq 20, stretch branch)
///   r < d:  E = C0 * ((d - r)/d)^5 * d / r                (compression, thesis eq 20 divided by d^4 so
///                                                           that C0 is an energy in joule)
/// with r = |p0 - p1|. Both branches meet with E = E' = E'' = 0 at r = d (C2 join).
/// Outputs: grad0 = dE/dp0 (dE/dp1 = -grad0); H00 = d2E/dp0^2 (H11 = H00, H01 = H10 = -H00).
/// If `clamp_compression` is set, the transverse term (E'/r)(I - u u^T), which is negative in
/// compression, is dropped from H00 so the Hessian stays positive semi-definite.
struct TensionDerivatives {
  Real energy = 0;
  Vec3 grad0 = Vec3::Zero();
  Mat3 hess00 = Mat3::Zero();
};
bool tensionTerm(const Vec3& p0, const Vec3& p1, Real rest_length, Real c0, bool want_hessian,
                 bool clamp_compression, TensionDerivatives* out);

/// Scalar profile of an angle energy E(theta), where theta is the deviation from the rest angle.
/// `dE` = dE/dtheta, `d2E` = d2E/dtheta2 and `secant` = dE/dtheta / theta (finite at theta = 0, equal
/// to d2E there); the secant lets the bending kernel stay exact on a flat sheet.
struct AngleProfile {
  Real energy = 0;
  Real dE = 0;
  Real d2E = 0;
  Real secant = 0;
};

/// One angle term at p0 spanned by k1 = pa - p0 and k2 = pb - p0, with the angle
///   phi = atan2(|k1 x k2|, k1 . k2)  in [0, pi]   (thesis eq 30, evaluated with atan2 for accuracy)
/// Shear:   theta = phi - pi/2 (rest pi/2, signed);   Bending: theta = pi - phi (rest pi, theta >= 0).
/// With c = cos(phi), s = sin(phi), g_u = dc/dk_u and G_uv = d g_u / d k_v (thesis eqs 171-186):
///   dE/dk_u  = w1 g_u,            w1 = -(dE/dphi)/s
///   d2E/dk_u dk_v = w2 g_u g_v^T + w1 G_uv,   w2 = (d2E/dphi2)/s^2 - (dE/dphi) c / s^3
/// Nodes: dE/dpa = dE/dk1, dE/dpb = dE/dk2, dE/dp0 = -(dE/dk1 + dE/dk2).
/// Near a flat bend (phi -> pi) both g and s vanish; w1 is evaluated as secant * theta/sin(theta)
/// and w2 g g^T -> 0, so the flat starting sheet gives finite, exact derivatives (decision 6).
/// `gauss_newton` keeps only (d2E/dphi2 / s^2) g g^T, which is positive semi-definite for d2E >= 0.
enum class AngleKind { kShear, kBending };

/// Evaluates the profile E(theta) for the current theta; provided by the model (material curves).
/// Must return dE, d2E and secant for the given theta (theta >= 0 for bending, signed for shear).
struct AngleDerivatives {
  Real energy = 0;
  Real theta = 0;
  Vec3 grad[3];      // dE/dp0, dE/dpa, dE/dpb
  Mat3 hess[3][3];   // d2E/dpx dpy, x,y in {0, a, b}
};

/// Geometry of an angle, computed once and reused for energy and derivatives.
struct AngleGeometry {
  Real phi = 0, c = 0, s = 0, a = 0, b = 0;
  Vec3 k1, k2, g1, g2;
};
bool angleGeometry(const Vec3& p0, const Vec3& pa, const Vec3& pb, AngleGeometry* geo);

/// Fills gradient and (optionally) Hessian blocks of one angle term from its geometry and profile.
void angleTermDerivatives(const AngleGeometry& geo, AngleKind kind, const AngleProfile& profile,
                          bool want_hessian, bool gauss_newton, AngleDerivatives* out);

/// Isotropic quadratic fluid drag of one particle (thesis eqs 56-57, 128, sign as in eq 63):
///   R = -1/2 rho c_w A |v| v,   dR/dv = -1/2 rho c_w A (|v| I + v v^T / |v|)   (0 at v = 0)
struct DragDerivatives {
  Vec3 force = Vec3::Zero();
  Mat3 dforce_dv = Mat3::Zero();
};
void dragTerm(const Vec3& v, Real coefficient /* 1/2 rho c_w A [kg/m] */, bool want_jacobian,
              DragDerivatives* out);

}  // namespace textile_handling
