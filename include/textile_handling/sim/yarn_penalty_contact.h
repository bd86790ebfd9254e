// Long-range self-collision of the yarn-level model by penalties on extruded triangles (notes section 4
// after Teschner et al. 2003, and 9.8): every quad of the crossing grid (two neighbouring warps x two
// neighbouring wefts) split into two triangles; each triangle extruded by gamma to both sides into a
// prism; the prisms' boxes in a uniform-grid spatial hash; every crossing queried; a crossing inside a
// prism is pushed out of it by a penalty spring along the triangle's normal, the opposite force going to
// the triangle's nodes by the barycentric weights of the crossing's projection. Source: the notes on the
// yarn-level model (../shared/reference/yarn-level-woven-cloth.md); docs/yarn_model.md, "Collisions".
// ROS-free; only Eigen.
//
// One contact couples a node x with a triangle (a, b, c), packed as p = (x, a, b, c) (12 values).
// Decision: the normal is the triangle's face normal n = (b - a) x (c - a) / |...| (not the notes'
// interpolated vertex normals), for the prism and the force alike. Then the signed distance of x to the
// triangle's plane is d = n^T (x - a) = n^T (x - p) with p the projection, its gradient is exactly
// (n, -w_a n, -w_b n, -w_c n) with w the barycentric weights of p, and the penalty force is the exact
// negative gradient of its energy (conservative, no rotation terms to drop).
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "textile_handling/sim/types.h"
#include "textile_handling/sim/yarn_grid.h"

namespace textile_handling {

/// Options of the yarn_woven model's penalty self-contact (docs/yarn_model.md, "Collisions"), each a
/// factor of the simulated fabric's own quantities so that it keeps its meaning for any yarn or bundle.
struct YarnSelfContactOptions {
  bool enabled = false;         ///< `self_contact`
  /// gamma = factor R (`self_contact_thickness_factor`; the notes' examples use 4R).
  Real thickness_factor = 4;
  /// k_p = factor k_s / L (`self_contact_stiffness_factor`): a penetration resisted like the stretch of
  /// one yarn segment, as stiff as the stiffest spring the sheet already has.
  Real stiffness_factor = 1;
  /// d_p = factor 2 sqrt(k_p m), m the mean crossing mass (`self_contact_damping`): the ratio to the
  /// critical damping of a crossing on the penalty spring.
  Real damping = 1;
  /// mu of the contact friction (`self_contact_friction`); negative: the fabric's sliding friction.
  Real friction = -1;
};
/// "" or the first invalid field, named by its option key.
std::string yarnSelfContactErrors(const YarnSelfContactOptions& o);

namespace yarn {

using PenaltyVector = Eigen::Matrix<Real, 12, 1>;  ///< (x, a, b, c)

/// The geometry of a node against a triangle: face normal, signed distance and barycentric weights of
/// the projection p = x - d n (w_a + w_b + w_c = 1; all in [0, 1] when p is inside the triangle).
struct TriangleProjection {
  Vec3 normal = Vec3::Zero();
  Real distance = 0;                   ///< d = n^T (x - a)
  std::array<Real, 3> weight{{0, 0, 0}};
  bool valid = false;                  ///< false for a degenerate (zero-area) triangle
};
TriangleProjection projectOnTriangle(const PenaltyVector& p);

/// The penalty distance of the notes (section 4): delta = n_s^T (p - x) + gamma = gamma - s d, with
/// n_s = s n the normal turned to the side s (+1 or -1) the node is kept on. delta > 0 while x lies
/// closer than gamma to the plane on side s, and grows past gamma once x has crossed the plane.
Real penaltyDistance(const PenaltyVector& p, int side, Real gamma);

/// The penalty energy V = 1/2 k_p delta^2 for delta > 0, else 0 [J] (k_p [N/m]). C1 at delta = 0.
Real penaltyEnergy(const PenaltyVector& p, int side, Real gamma, Real k_p);
/// dV/dp = -k_p delta s (n, -w_a n, -w_b n, -w_c n) (12): the force on x is k_p delta n_s (the notes'
/// linear penalty force) and the triangle node i gets -w_i times it.
PenaltyVector penaltyGradient(const PenaltyVector& p, int side, Real gamma, Real k_p);

/// The diagonal 3 x 3 blocks of a contact's Jacobian (node, a, b, c).
struct PenaltyBlocks {
  std::array<Mat3, 4> block{{Mat3::Zero(), Mat3::Zero(), Mat3::Zero(), Mat3::Zero()}};
};
/// The diagonal blocks of -d2V/dp2 in the Gauss-Newton form -k_p g_i g_i^T with g = (n, -w n): -k_p n n^T
/// on the node (exact: n does not depend on x), -k_p w_i^2 n n^T on triangle node i (the terms from the
/// normal's rotation and the moving weights, of order delta, are left out). 0 when delta <= 0.
PenaltyBlocks penaltyStiffnessBlocks(const PenaltyVector& p, int side, Real gamma, Real k_p);
/// The damping force of the notes, -d_p n n^T (xdot - pdot) on x with pdot = sum w_i v_i, and w_i times
/// its opposite on triangle node i, while delta > 0 (else 0). d_p [N s/m].
PenaltyVector penaltyDampingForce(const PenaltyVector& p, const PenaltyVector& v, int side, Real gamma, Real d_p);
/// Diagonal blocks of the damping force's velocity Jacobian (exact for those blocks): -d_p n n^T on the
/// node, -d_p w_i^2 n n^T on triangle node i; 0 when delta <= 0.
PenaltyBlocks penaltyDampingBlocks(const PenaltyVector& p, int side, Real gamma, Real d_p);

/// Approximate Coulomb friction by a stick spring (notes section 4: Yamane & Nakamura 2006, the
/// mechanism of the sliding friction, stickSlipSpring()): the tangential offset r = P (x - sum beta_i
/// X_i), P = I - n n^T, of x from an anchor point fixed on the triangle by its barycentric weights beta,
/// pulled back by -k_t r in stick (k_t |r| <= mu k_p delta) and by -mu k_p delta r / |r| in slip; the
/// triangle node i gets -beta_i times it. 0 when delta <= 0.
struct PenaltyFriction {
  PenaltyVector force = PenaltyVector::Zero();
  /// Diagonal blocks of dF/dp, node and triangle nodes: -k_t P and -k_t beta_i^2 P in stick (the
  /// normal's rotation left out), 0 in slip (as the model's slip Jacobians).
  PenaltyBlocks blocks;
  bool stick = true;
};
PenaltyFriction penaltyFriction(const PenaltyVector& p, const std::array<Real, 3>& anchor, int side, Real gamma, Real k_p,
                                Real k_t, Real mu);
/// The anchor after a step that ended at p (stickSlipAnchor() in the tangent plane): unchanged in stick;
/// in slip moved along r so that k_t |r| = mu k_p delta. As barycentric weights of the triangle.
std::array<Real, 3> penaltyFrictionAnchor(const PenaltyVector& p, const std::array<Real, 3>& anchor, int side, Real gamma,
                                          Real k_p, Real k_t, Real mu);

// ---- Triangles and detection ---------------------------------------------------------------------

/// The triangles of a yarn grid: every quad (crossing c, its next crossing along the warp c_u, along the
/// weft c_v, and the crossing d next to both) split along c-d into (c, c_u, d) and (c, d, c_v), both
/// turned like warp x weft. End nodes are in no triangle.
struct YarnTriangles {
  std::vector<std::array<std::size_t, 3>> triangles;
  /// Per node, sorted: itself and its 1-ring (every node that shares a triangle with it). A node is
  /// never tested against a triangle with a vertex in its list (decision, notes 9.8: the own triangles
  /// and those of the 1-ring, i.e. the triangles within two grid steps, which touch it in any smooth
  /// bend and would hold the sheet's own curvature apart).
  std::vector<std::vector<std::size_t>> near;
  bool excluded(std::size_t node, std::size_t triangle) const;
};
YarnTriangles yarnTriangles(const YarnGrid& grid);

/// One node-triangle contact, fixed between accepted steps.
struct PenaltyContact {
  std::size_t node = 0, triangle = 0;
  int side = 1;                               ///< the side of the triangle x is kept on
  std::array<Real, 3> anchor{{0, 0, 0}};      ///< friction anchor, barycentric on the triangle
};

/// Detection options.
struct PenaltyDetection {
  Real gamma = 0;      ///< extrusion [m]
  Real cell = 0;       ///< hash cell edge [m] (> 0)
};

/// The contacts of state x (stride 5: node k's position at x[5k]): every crossing strictly inside the
/// prism of a triangle not excluded for it (|d| < gamma and all weights in [0, 1]). Of the triangles one
/// node is inside, the nearest is kept and every other one that shares a vertex with a kept one is
/// dropped (a node on an edge or at a vertex of one layer is one contact with that layer, not two to
/// six), so two layers squeezing a node are two contacts. The side and the anchor carry over from
/// `previous` when the node was in contact with the same triangle or with one sharing a vertex with it
/// (so a node pushed past a plane within a step is pushed back, not through); else side = sign(d)
/// (+1 for d = 0) and the anchor is the projection. Sorted by (node, triangle); `previous` must be too.
/// `brute_force` tests every pair instead of using the hash (the tests' reference). From 4 096 crossings
/// on, fixed chunks of crossings are detected on all OpenMP threads and joined in order: the same list
/// for every thread count.
std::vector<PenaltyContact> detectPenaltyContacts(const YarnTriangles& tris, std::size_t crossings, const VecX& x,
                                                  const PenaltyDetection& options,
                                                  const std::vector<PenaltyContact>& previous, bool brute_force = false);

/// The 12 coordinates of a contact (node, triangle's nodes) from a vector of stride 5.
PenaltyVector packPenaltyStencil(const VecX& x, std::size_t node, const std::array<std::size_t, 3>& triangle);

}  // namespace yarn
}  // namespace textile_handling
