// Crossing-level kernels of the yarn-level model: the angle between a warp and a weft segment at a
// crossing, shear with compression-dependent stiffness and jamming, shear friction, sliding friction
// and the contact between adjacent parallel yarns. Source: the notes on the yarn-level model
// (../shared/reference/yarn-level-woven-cloth.md, sections 3.3-3.8 and 9, eqs. 10-13, with their
// reconstructed forms); docs/yarn_model.md, "Crossing kernels".
//
// The angle kernels take one (warp segment, weft segment) pair at a crossing, positions only (notes
// 3.5, 3.8: shear uses the rest spacing L, so it has no force on the sliding coordinates), packed as
// p = (x0, x1, x3) (9 values): x0 the crossing [m], x1 the other end of the warp segment, x3 the other
// end of the weft segment. The normal compression F_n (yarn_normal_force.h) enters every kernel as a
// constant: it is lagged, evaluated once per step and not differentiated (notes 9.2).
#pragma once

#include <Eigen/Core>

#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace yarn {

using CrossingVector = Eigen::Matrix<Real, 9, 1>;  ///< (x0, x1, x3)
using CrossingMatrix = Eigen::Matrix<Real, 9, 9>;

/// One (warp segment, weft segment) pair's positions, packed as p = (x0, x1, x3).
CrossingVector packCrossingStencil(const Vec3& x0, const Vec3& x1, const Vec3& x3);

// ---- Crossing angle (notes 3.5, Fig. 3D) ---------------------------------------------------------

/// The angle between the warp segment a = x1 - x0 and the weft segment b = x3 - x0 [rad]:
///   phi = atan2(|a x b|, a . b),  in [0, pi];  pi / 2 for an unsheared crossing.
/// Defined for a, b != 0.
Real crossingAngle(const CrossingVector& p);
/// dphi/dp (9). With S = |a x b|^2 (> 0) and c = a . b:
///   dphi/da = (c a / |a|^2 - b) / sqrt(S),  dphi/db = (c b / |b|^2 - a) / sqrt(S),
///   dphi/dx1 = dphi/da,  dphi/dx3 = dphi/db,  dphi/dx0 = -(dphi/da + dphi/db)
/// (the notes' -(b^ - cos phi a^) / (|a| sin phi), written without normalising). Accurate for phi in
/// (0, pi); singular at 0 and pi, where a and b are parallel and the plane of the angle is undefined
/// (|dphi/da| = 1 / |a| for every phi, but its direction jumps). Shear keeps phi near pi / 2 and
/// jamming keeps interlaced pairs above phi_j.
CrossingVector crossingAngleGradient(const CrossingVector& p);
/// crossingAngle() and crossingAngleGradient() from one evaluation of the angle (the same values).
struct AngleWithGradient {
  Real phi = 0;
  CrossingVector g = CrossingVector::Zero();
};
AngleWithGradient crossingAngleWithGradient(const CrossingVector& p);
/// d2phi/dp2 (9 x 9, symmetric), exact: phi = G(S, c) = atan2(sqrt(S), c) with S and c polynomials of
/// (a, b), so d2phi = G_S d2S + G_c d2c + G_SS dS dS^T + G_Sc (dS dc^T + dc dS^T) + G_cc dc dc^T, with
/// s = sqrt(S), r^2 = S + c^2 = |a|^2 |b|^2:
///   G_S = c / (2 s r^2),  G_c = -s / r^2,  G_SS = -c (r^2 + 2 S) / (4 s^3 r^4),
///   G_Sc = (S - c^2) / (2 s r^4),  G_cc = 2 s c / r^4.
/// Grows like 1 / sin phi towards 0 and pi (singular there, as the gradient's direction).
CrossingMatrix crossingAngleHessian(const CrossingVector& p);

// ---- Shear with compression-dependent stiffness and jamming (notes eq. 11, 3.5, 9.5) ------------

/// The compression-dependent shear stiffness k_x(F_n) = k_x (1 + c_n F_n) [N] (notes 9.5: the source
/// gives no functional form; this linear one is our choice). k_x = S R^2 [N], c_n >= 0 [1/N], F_n >= 0
/// the crossing's normal compression [N], lagged (constant within a step).
Real shearStiffness(Real k_x, Real c_n, Real F_n);

/// Parameters of one pair's shear term.
struct ShearParameters {
  Real stiffness = 0;      ///< k = shearStiffness(k_x, c_n, F_n) [N], frozen within a step
  Real rest_spacing = 0;   ///< L [m]: the half-segments at the crossing are integrated with it (notes 3.5)
  Real jamming_angle = 0;  ///< phi_j = 2 asin(R / L) [rad] (WovenFabric::jammingAngle())
  Real jamming_gain = 0;   ///< c_j >= 0: the stiffness at phi = 0 is (1 + c_j) k
  bool interlaced = false; ///< the warp or the weft segment of the pair is interlaced (jamming applies)
};

/// A potential of the angle with its first two derivatives in phi.
struct AnglePotential {
  Real value = 0;   ///< V(phi) [J]
  Real first = 0;   ///< dV/dphi [J]
  Real second = 0;  ///< d2V/dphi2 [J]
};

/// The shear potential as a function of the angle (notes eq. 11 and the "grows cubically" of 3.5):
///   V(phi) = 1/2 k L (phi - pi/2)^2 + V_jam(phi),
///   V_jam = k L c_j phi_j^2 s^5 / 20  for an interlaced pair with phi < phi_j, else 0,
///   s = (phi_j - phi) / phi_j,
/// so d2V/dphi2 = k L (1 + c_j s^3): the notes' candidate k(phi) = k [1 + c_j s^3] as the curvature of
/// a potential, which keeps the force conservative (the source only says "the stiffness grows
/// cubically"). V_jam and its first four derivatives vanish at phi_j: the potential is C4 there.
/// Shearing either way closes one of the four quadrant angles at a crossing, so the test per pair
/// covers both directions.
AnglePotential shearPotential(Real phi, const ShearParameters& s);
/// V(phi(p)) on the stencil p = (x0, x1, x3).
Real shearEnergy(const CrossingVector& p, const ShearParameters& s);
/// dV/dp = V'(phi) dphi/dp (9). The force on x_i is -V'(phi) dphi/dx_i (notes 3.5).
CrossingVector shearGradient(const CrossingVector& p, const ShearParameters& s);
/// d2V/dp2 = V''(phi) dphi dphi^T + V'(phi) d2phi (9 x 9, exact; indefinite in general).
CrossingMatrix shearHessian(const CrossingVector& p, const ShearParameters& s);
/// The Gauss-Newton part V''(phi) dphi dphi^T (notes 9.2: no d2phi): positive semi-definite, rank one,
/// because V'' = k L (1 + c_j s^3) > 0 for k > 0 and c_j >= 0.
CrossingMatrix shearHessianClamped(const CrossingVector& p, const ShearParameters& s);
/// shearGradient() and shearHessianClamped() from the angle and gradient of p already evaluated (the same
/// values).
CrossingVector shearGradient(const AngleWithGradient& a, const ShearParameters& s);
CrossingMatrix shearHessianClamped(const AngleWithGradient& a, const ShearParameters& s);

// ---- Stick/slip spring (notes 3.4, 3.6) ---------------------------------------------------------

/// A zero-rest-length spring of stiffness k between a coordinate x and its anchor x_bar, whose force
/// is capped at the Coulomb limit (Yamane & Nakamura 2006, as in the notes 3.4).
struct StickSlip {
  Real force = 0;      ///< F: -k (x - x_bar) in stick, -sign(x - x_bar) limit in slip
  Real stiffness = 0;  ///< dF/dx (x_bar and the limit held): -k in stick, 0 in slip
  bool stick = true;   ///< k |x - x_bar| <= limit
};

/// The spring's force at x: stick while k |x - x_bar| <= limit (k > 0, limit >= 0), else slip with
/// a force of constant magnitude `limit` against the displacement. Continuous at the limit.
StickSlip stickSlipSpring(Real x, Real anchor, Real k, Real limit);
/// The anchor after a step that ended at x (notes 3.4, reconstructed): unchanged in stick; in slip it
/// moves to x - sign(x - x_bar) limit / k, so the spring stays at the Coulomb limit (k |x - x_bar| =
/// limit) and reverses into stick as soon as the motion does.
Real stickSlipAnchor(Real x, Real anchor, Real k, Real limit);

// ---- Sliding friction (notes eq. 10, 3.4) -------------------------------------------------------

/// The elastic part of the friction on a sliding coordinate u (warp; the same for v) at a crossing
/// with anchor u_bar (initialised to u):
///   stick (k_f |u - u_bar| <= mu F_n):  F_u = -k_f (u - u_bar),        dF_u/du = -k_f;
///   slip:                               F_u = -sign(u - u_bar) mu F_n, dF_u/du = 0.
/// k_f > 0 [N/m] and mu >= 0 are parameters of the model (the source gives no k_f); F_n is lagged.
StickSlip slidingFriction(Real u, Real anchor, Real k_f, Real mu, Real F_n);
/// The anchor update of stickSlipAnchor() with the limit mu F_n.
Real slidingFrictionAnchor(Real u, Real anchor, Real k_f, Real mu, Real F_n);
/// The viscous part of eq. 10, -d_f u_dot [N] (d_f >= 0 [N s/m]), the same in stick and slip; its
/// derivative in u_dot is -d_f. u_dot is the sliding velocity relative to the crossing.
Real slidingDamping(Real u_dot, Real d_f);

// ---- Shear friction (notes eq. 12, 3.6) ---------------------------------------------------------

/// The stick spring of a pair: V = 1/2 k_fphi (phi - phi_bar)^2 on the stencil p, with the pair's
/// anchor angle phi_bar and k_fphi > 0 [N m].
Real shearFrictionStickEnergy(const CrossingVector& p, Real anchor, Real k_fphi);
/// dV/dp = k_fphi (phi - phi_bar) dphi/dp (the stick force of eq. 12 is its negative).
CrossingVector shearFrictionStickGradient(const CrossingVector& p, Real anchor, Real k_fphi);
/// d2V/dp2 = k_fphi dphi dphi^T + k_fphi (phi - phi_bar) d2phi (exact).
CrossingMatrix shearFrictionStickHessian(const CrossingVector& p, Real anchor, Real k_fphi);
/// The Gauss-Newton part k_fphi dphi dphi^T: positive semi-definite.
CrossingMatrix shearFrictionStickHessianClamped(const CrossingVector& p, Real anchor, Real k_fphi);
/// The slip force of eq. 12: F = -sign(phi - phi_bar) mu_phi F_n dphi/dp (9). mu_phi carries a length
/// (dphi/dp is in 1/m, so mu_phi F_n is a moment [N m]; notes 3.6 propose mu_phi = mu L).
CrossingVector shearFrictionSlipForce(const CrossingVector& p, Real anchor, Real mu_phi, Real F_n);

/// The force of eq. 12 in the mode the stick test picks, with its Jacobian dF/dp (anchor and F_n
/// held): the scalar stickSlipSpring(phi, phi_bar, k_fphi, mu_phi F_n) times dphi/dp.
struct ShearFriction {
  CrossingVector force = CrossingVector::Zero();
  /// dF/dp. Exact: stick -(k_fphi dphi dphi^T + k_fphi (phi - phi_bar) d2phi), slip F_phi d2phi with
  /// F_phi = -sign(phi - phi_bar) mu_phi F_n. Clamped: stick -k_fphi dphi dphi^T (negative
  /// semi-definite), slip 0 (notes 9.2: slip-mode friction Jacobians set to zero).
  CrossingMatrix jacobian = CrossingMatrix::Zero();
  bool stick = true;
};
ShearFriction shearFriction(const CrossingVector& p, Real anchor, Real k_fphi, Real mu_phi, Real F_n, bool clamped);
/// shearFriction(p, ..., clamped = true) from the angle and gradient of p already evaluated.
ShearFriction shearFrictionClamped(const AngleWithGradient& a, Real anchor, Real k_fphi, Real mu_phi, Real F_n);
/// The anchor update of stickSlipAnchor() for the angle phi with the limit mu_phi F_n.
Real shearFrictionAnchor(Real phi, Real anchor, Real k_fphi, Real mu_phi, Real F_n);

// ---- Contact between adjacent parallel yarns (notes eq. 13, 3.7) --------------------------------

using ContactVector = Eigen::Matrix<Real, 2, 1>;  ///< (u0, u1)
using ContactMatrix = Eigen::Matrix<Real, 2, 2>;

/// The contact distance d between two crossings neighbouring along one yarn: 4 R if the yarn between
/// them is interlaced (it changes side, so the two crossing yarns lie on opposite sides of it), 2 R if
/// it floats.
Real parallelContactDistance(Real R, bool interlaced);
/// The penalty on the arc-length difference of two crossings along one yarn (u0 < u1; v for a weft),
/// which approximates the distance between the two yarns crossing it there:
///   V = 1/2 k_c L (u1 - u0 - d)^2  if u1 - u0 < d,  else 0,
/// k_c > 0 [N/m^2] a parameter of the model (notes 9.1 propose k_c ~ k_s / L), L the rest spacing.
/// C1 at u1 - u0 = d (the Hessian jumps there).
Real parallelContactEnergy(Real u0, Real u1, Real k_c, Real L, Real d);
/// dV/d(u0, u1) = k_c L (u1 - u0 - d) (-1, 1) when active: the forces F_u0 = -F_u1 = k_c L (u1 - u0 - d)
/// push the two crossings apart.
ContactVector parallelContactGradient(Real u0, Real u1, Real k_c, Real L, Real d);
/// k_c L [[1, -1], [-1, 1]] when active, else 0: positive semi-definite.
ContactMatrix parallelContactHessian(Real u0, Real u1, Real k_c, Real L, Real d);

}  // namespace yarn
}  // namespace textile_handling
