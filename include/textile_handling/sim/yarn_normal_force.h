// The quasi-static normal compression at every crossing of a yarn sheet (notes eq. 9, section 3.3),
// the Coulomb limit of the crossing's friction and the argument of its shear stiffness k_x(F_n).
// Source: ../shared/reference/yarn-level-woven-cloth.md, sections 1.3, 3.3 and 9.3-9.4;
// docs/yarn_model.md, "Normal force".
//
// F_n is a parameter of the crossing kernels (yarn_crossing_kernels.h), evaluated once per step and
// not differentiated (notes 9.2).
#pragma once

#include <vector>

#include "textile_handling/sim/types.h"
#include "textile_handling/sim/woven_fabric.h"
#include "textile_handling/sim/yarn_sheet.h"

namespace textile_handling {

/// The panel normal N at every crossing of `sheet` at state q (5N): the notes' cheap best-fit plane
/// (9.3),
///   N = normalize((x_warp_next - x_warp_prev) x (x_weft_next - x_weft_prev)),
/// the cross product of the warp chord and the weft chord through the crossing (its neighbours along
/// its warp piece and its weft piece, in the order of increasing arc length; at a piece's last node
/// the node itself stands for the missing neighbour, giving a one-sided chord). Oriented warp x weft:
/// +z for the flat sheet at rest, the side from which the weave flag `warp_on_top` is seen. Zero where
/// the chords are parallel or vanish (|chord_warp x chord_weft| <= 1e-12 |chord_warp| |chord_weft|).
/// One entry per crossing (node k < grid.crossings.size()).
std::vector<Vec3> crossingPanelNormals(const YarnSheet& sheet, const VecX& q);

/// The normal of eq. 9 at every crossing, from the warp towards the weft: n = -s N with s = +1 where
/// the warp is on top and -1 where the weft is (notes 1.3). Zero where N is.
std::vector<Vec3> crossingNormals(const YarnSheet& sheet, const VecX& q);

/// The terms of eq. 9 at every crossing (one entry per crossing).
struct CrossingCompression {
  std::vector<Vec3> normal;  ///< n, from the warp towards the weft (crossingNormals())
  /// n . (F_s(u) + F_b(u)): the warp's stretch and crimped-bending forces at the crossing along n,
  /// positive when they push the warp into the weft [N].
  std::vector<Real> warp_push;
  /// -n . (F_s(v) + F_b(v)): the same for the weft, positive when it is pushed into the warp [N].
  std::vector<Real> weft_push;
  /// F_n = max(0, (warp_push + weft_push) / 2) [N] (eq. 9, clamped: negative means the yarns
  /// separate; no adhesion).
  std::vector<Real> force;
};

/// Eq. 9 at every crossing of `sheet` at state q (5N), with `fabric`'s k_s, k_b and R:
///  * crimp (notes 1.3, 3.3): every crossing's warp point is moved to x + s R N and its weft point to
///    x - s R N (the yarn on top to the top side; i.e. warp x - R n, weft x + R n); yarn ends, and
///    crossings whose N is zero, keep their position;
///  * F_b: the bending force (yarn::bendGradient, zero rest curvature) on the crossing's crimped point
///    from every bending stencil of the crimped yarn that contains it (centred at the previous node,
///    the crossing and the next node: the full force of the crimped yarn on that point; notes 9.4);
///  * F_s: the stretch force (yarn::stretchGradient) on the crossing from its two segments of the
///    uncrimped yarn, as the dynamics see it (the source recomputes only bending on the crimped
///    polylines; crimped chords would be longer than the rest lengths and fake a tension);
/// both with the sliding coordinates of q (u on a warp, v on a weft) as arc lengths. Crossings whose
/// N is zero get F_n = 0. Every value is finite unless a crimped yarn folds back on itself (a bending
/// angle of pi, where bending is singular).
CrossingCompression crossingCompression(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q);

/// crossingCompression(sheet, fabric, q).force: F_n >= 0 per crossing [N].
std::vector<Real> crossingNormalForces(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q);

}  // namespace textile_handling
