// Per-segment kernels of the yarn-level model: stretch energy, gravity and the configuration-dependent
// segment mass matrix, each a function of one yarn segment between two nodes. Source: the notes on the
// yarn-level model (../shared/reference/yarn-level-woven-cloth.md, eqs. 5-7, with their reconstructed
// derivatives); docs/yarn_model.md.
//
// Every kernel takes a segment's generalised coordinates in the order q = (x0, u0, x1, u1) (8 values):
// the two nodes' positions [m] and the arc-length coordinates [m] of the segment's yarn at them (u for a
// warp, v for a weft), with D = u1 - u0 > 0 the segment's rest length.
#pragma once

#include <Eigen/Core>

#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace yarn {

using SegmentVector = Eigen::Matrix<Real, 8, 1>;  ///< (x0, u0, x1, u1)
using SegmentMatrix = Eigen::Matrix<Real, 8, 8>;

/// One segment's coordinates, packed as q = (x0, u0, x1, u1).
SegmentVector packSegment(const Vec3& x0, Real u0, const Vec3& x1, Real u1);

/// Stretch (notes eq. 7, after Spillmann & Teschner 2007): strain constant along the segment,
///   V = 1/2 k_s D (|w| - 1)^2 = k_s (l - D)^2 / (2 D),  w = (x1 - x0) / D,  l = |x1 - x0|,
/// with k_s = Y pi R^2 [N]. Forces: F_x1 = -F_x0 = -k_s (l / D - 1) t (t = (x1 - x0) / l) and
/// F_u1 = -F_u0 = 1/2 k_s (l^2 / D^2 - 1): a stretched segment pulls yarn material in from its
/// neighbours. Requires D > 0 and l > 0 (a zero-length segment has no direction; the value is still
/// defined).
Real stretchEnergy(const SegmentVector& q, Real k_s);
/// dV/dq.
SegmentVector stretchGradient(const SegmentVector& q, Real k_s);
/// d2V/dq2: with d = x1 - x0 and D,
///   H_dd = k_s / D [t t^T + (1 - D / l)(I - t t^T)],  H_dD = -k_s l / D^2 t,  H_DD = k_s l^2 / D^3,
/// mapped to q by dd/dx1 = -dd/dx0 = I and dD/du1 = -dD/du0 = 1. Indefinite for a compressed segment
/// (l < D: the transverse term is negative).
SegmentMatrix stretchHessian(const SegmentVector& q, Real k_s);
/// stretchHessian() with (1 - D / l) clamped at 0: positive semi-definite (the (l, D) part is rank one
/// because (l - D)^2 / D is a perspective function, jointly convex; notes section 3.1).
SegmentMatrix stretchHessianClamped(const SegmentVector& q, Real k_s);

/// Gravity on a segment (notes eq. 6 with the sign for a downward g, z up):
///   V = -rho D g . (x0 + x1) / 2,
/// rho the yarn's linear density [kg/m] and g the gravity vector [m/s^2] (e.g. (0, 0, -9.81)). Because V
/// depends on D, gravity also pushes the sliding coordinates: F_u1 = -F_u0 = rho g . (x0 + x1) / 2, which
/// summed over a node's two segments moves yarn material into the lower one.
Real gravityEnergy(const SegmentVector& q, Real rho, const Vec3& g);
SegmentVector gravityGradient(const SegmentVector& q, Real rho, const Vec3& g);
/// Constant in q: only the mixed x-u entries, d2V/dx0 du1 = d2V/dx1 du1 = -rho g / 2 and
/// d2V/dx0 du0 = d2V/dx1 du0 = +rho g / 2.
SegmentMatrix gravityHessian(Real rho, const Vec3& g);

using BendVector = Eigen::Matrix<Real, 12, 1>;  ///< (x2, u2, x0, u0, x1, u1)
using BendMatrix = Eigen::Matrix<Real, 12, 12>;

/// One bending stencil's coordinates: the centre node x0 between its neighbours x2 (lower arc length)
/// and x1 along one yarn, packed as q = (x2, u2, x0, u0, x1, u1).
BendVector packBendStencil(const Vec3& x2, Real u2, const Vec3& x0, Real u0, const Vec3& x1, Real u1);

/// Bending at a node along one yarn (notes eq. 8): the discrete curvature 2 theta / (u1 - u2) with theta
/// the angle between the segments a = x0 - x2 and b = x1 - x0, integrated over the two half segments:
///   V = k_b theta^2 / (u1 - u2),  theta = atan2(|a x b|, a . b),  k_b = B pi R^2,
/// zero rest curvature (yarns start straight). u0 does not appear. Sliding forces F_u1 = -F_u2 =
/// k_b theta^2 / (u1 - u2)^2. Smooth through theta = 0: theta^2 is evaluated as F(S, c) with S = |a x b|^2
/// and c = a . b (polynomials of the positions) and F's derivatives by series for small angles, so the
/// Hessian is exact also for a straight yarn. A yarn folded back on itself (theta -> pi) is singular.
Real bendEnergy(const BendVector& q, Real k_b);
BendVector bendGradient(const BendVector& q, Real k_b);
/// The exact Hessian (indefinite in general).
BendMatrix bendHessian(const BendVector& q, Real k_b);
/// The Hessian with the negative eigenvalues of its (a, b, u1 - u2) part (7 x 7) set to zero: positive
/// semi-definite.
BendMatrix bendHessianClamped(const BendVector& q, Real k_b);

/// The segment's generalised mass matrix (notes eqs. 4-5): the kinetic energy of mass rho spread evenly
/// along the segment, whose material point u moves with (eq. 2)
///   xdot(u) = (u1 - u)/D (x0dot - u0dot w) + (u - u0)/D (x1dot - u1dot w),
/// is T = 1/2 qdot^T M qdot with
///   M = rho D / 6 [[2, 1], [1, 2]] (x) P^T P,  P = [I_3, -w]  (3 x 4, per node: (x, u)).
/// Symmetric, rank 6 of 8; its null motion xdot = udot w at both nodes slides the nodes along the yarn
/// without moving material. Depends on q through w and D.
SegmentMatrix segmentMass(const SegmentVector& q, Real rho);

}  // namespace yarn
}  // namespace textile_handling
