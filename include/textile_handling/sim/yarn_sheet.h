// The yarn-level model's state over a laid yarn grid: five coordinates per node and the sheet's
// energy (stretch, bending, gravity), its gradient and its configuration-dependent mass matrix,
// assembled from the per-segment kernels (yarn_kernels.h). docs/yarn_model.md, "Sheet".
#pragma once

#include <Eigen/SparseCore>
#include <cstddef>
#include <vector>

#include "textile_handling/sim/types.h"
#include "textile_handling/sim/woven_fabric.h"
#include "textile_handling/sim/yarn_grid.h"

namespace textile_handling {

/// Coordinates per node: position (3), warp arc length u, weft arc length v.
constexpr int kYarnDofsPerNode = 5;

/// Every node of a YarnGrid with 5 coordinates (x, y, z, u, v), node k at [5k, 5k + 5). A crossing's u
/// and v are its warp's and weft's arc lengths. An end node belongs to one yarn: its arc length on that
/// yarn is fixed at the yarn's end (notes 2.1) and its other sliding coordinate is unused; both are held
/// (`held_dofs`), so an end is a 3-DOF node padded to 5 (notes 9.6). A piece that ends at a crossing
/// (no end node) holds its sliding coordinate at that crossing, so no yarn material leaves the sheet.
/// A seam piece's arc length at an end is the end's otherwise unused coordinate (YarnPiece::slideOffset),
/// held like it: the seam is sewn, it does not slide through its nodes.
struct YarnSheet {
  YarnGrid grid;
  VecX rest;                          ///< 5N: the flat sheet at z = 0 in the outline frame
  std::vector<std::size_t> held_dofs; ///< sliding DOFs that never move, ascending

  std::size_t nodeCount() const { return grid.nodeCount(); }
  std::size_t dofCount() const { return kYarnDofsPerNode * nodeCount(); }
};

/// The sheet of `grid`: flat rest state (a seam's slot holding its arc length) and held sliding DOFs.
/// Throws SimError naming the piece if a seam runs through a crossing or lacks a slide offset per node,
/// a node index is out of range, or one node's u or v is the arc length of two pieces.
YarnSheet buildYarnSheet(YarnGrid grid);

/// The sheet's conservative terms at state q (5N): stretch (k_s = Y pi R^2) and gravity on every
/// segment, bending (k_b = B pi R^2) at every node between two segments of a yarn piece. Returns the
/// energy [J]; adds dV/dq into *gradient if not null (resized and zeroed first). `g`: gravity [m/s^2].
Real yarnSheetEnergy(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q, const Vec3& g,
                     VecX* gradient = nullptr);

/// d2V/dq2 of yarnSheetEnergy() (5N x 5N, symmetric), assembled from the kernels' Hessians: exact, or
/// with `clamped` each term's clamped Hessian (stretch: transverse factor held at >= 0; bending:
/// negative eigenvalues dropped), which makes the sum positive semi-definite (gravity's Hessian is
/// added as is: it is indefinite but small, rho g D against k_s / D).
Eigen::SparseMatrix<Real> yarnSheetHessian(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q, const Vec3& g,
                                           bool clamped = false);

/// The generalised mass matrix M(q) (5N x 5N, symmetric): every segment's mass (notes eq. 5) with the
/// linear density rho, on its nodes' positions and its yarn's sliding coordinate. Positive definite on
/// the free DOFs of a sheet whose crossings all have a warp and a weft segment; held DOFs get no mass.
Eigen::SparseMatrix<Real> yarnSheetMass(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q);

}  // namespace textile_handling
