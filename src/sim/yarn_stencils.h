// Internal to sim_core: how a yarn kernel's coordinates map to the sheet's DOFs, shared by the sheet's
// assembly (yarn_sheet.cpp) and the yarn_woven model (yarn_woven_model.cpp).
//
// A kernel over n nodes of one yarn piece sees 4 n coordinates: per node its position and its yarn's
// sliding coordinate, u (node offset 3) for a warp, v (4) for a weft, and for a seam the per-node slot
// holding its arc length (YarnPiece::slideOffset) (yarn_kernels.h: (x0, u0, x1, u1) for a segment,
// (x2, u2, x0, u0, x1, u1) for a bending stencil).
#pragma once

#include <array>
#include <cstddef>

#include "textile_handling/sim/types.h"
#include "textile_handling/sim/yarn_grid.h"
#include "textile_handling/sim/yarn_sheet.h"

namespace textile_handling {
namespace yarn_stencil {

template <int Nodes>
using Dofs = std::array<std::size_t, 4 * Nodes>;

/// The DOFs of the `Nodes` consecutive nodes of piece `p` starting at its node `first`.
template <int Nodes>
Dofs<Nodes> dofsOf(const YarnPiece& p, std::size_t first) {
  Dofs<Nodes> d;
  for (int n = 0; n < Nodes; ++n) {
    const std::size_t k = first + static_cast<std::size_t>(n), base = kYarnDofsPerNode * p.nodes[k];
    for (int c = 0; c < 3; ++c) d[4 * n + c] = base + static_cast<std::size_t>(c);
    d[4 * n + 3] = base + static_cast<std::size_t>(p.slideOffset(k));
  }
  return d;
}

/// Calls segment(piece, k) for every segment (nodes k, k + 1) of every yarn piece and bend(piece, k)
/// for every bending stencil (nodes k, k + 1, k + 2: centre k + 1).
template <class Segment, class Bend>
void forEachTerm(const YarnGrid& grid, Segment segment, Bend bend) {
  for (const YarnPiece& p : grid.pieces) {
    for (std::size_t k = 0; k + 1 < p.nodes.size(); ++k) segment(p, k);
    for (std::size_t k = 0; k + 2 < p.nodes.size(); ++k) bend(p, k);
  }
}

template <int Nodes>
Eigen::Matrix<Real, 4 * Nodes, 1> gather(const VecX& q, const Dofs<Nodes>& d) {
  Eigen::Matrix<Real, 4 * Nodes, 1> v;
  for (int i = 0; i < 4 * Nodes; ++i) v[i] = q[static_cast<Eigen::Index>(d[i])];
  return v;
}

template <int Nodes>
void scatterAdd(const Eigen::Matrix<Real, 4 * Nodes, 1>& v, const Dofs<Nodes>& d, VecX* out) {
  for (int i = 0; i < 4 * Nodes; ++i) (*out)[static_cast<Eigen::Index>(d[i])] += v[i];
}

}  // namespace yarn_stencil
}  // namespace textile_handling
