// The yarn-level model's state and assembled terms over a laid yarn grid (yarn_sheet.h).
#include "textile_handling/sim/yarn_sheet.h"

#include <algorithm>
#include <array>
#include <string>
#include <utility>
#include <vector>

#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/yarn_kernels.h"
#include "yarn_stencils.h"

namespace textile_handling {

namespace {

using yarn_stencil::Dofs;
using yarn_stencil::gather;
using yarn_stencil::scatterAdd;

template <int Nodes>
using StencilDofs = Dofs<Nodes>;

// forEachTerm over the sheet, handing each term its DOFs.
template <class Segment, class Bend>
void forEachTerm(const YarnSheet& sheet, Segment segment, Bend bend) {
  yarn_stencil::forEachTerm(
      sheet.grid, [&](const YarnPiece& p, std::size_t k) { segment(yarn_stencil::dofsOf<2>(p, k)); },
      [&](const YarnPiece& p, std::size_t k) { bend(yarn_stencil::dofsOf<3>(p, k)); });
}

// Appends m's non-zero entries as triplets; `keep(dof)` false drops a row or column (held DOFs).
template <int Nodes, class Keep>
void scatterTriplets(const Eigen::Matrix<Real, 4 * Nodes, 4 * Nodes>& m, const StencilDofs<Nodes>& d, Keep keep,
                     std::vector<Eigen::Triplet<Real>>* t) {
  for (int r = 0; r < 4 * Nodes; ++r)
    for (int c = 0; c < 4 * Nodes; ++c)
      if (m(r, c) != 0 && keep(d[r]) && keep(d[c])) t->emplace_back(static_cast<int>(d[r]), static_cast<int>(d[c]), m(r, c));
}

Eigen::SparseMatrix<Real> sparseFrom(const YarnSheet& sheet, const std::vector<Eigen::Triplet<Real>>& t) {
  Eigen::SparseMatrix<Real> M(static_cast<Eigen::Index>(sheet.dofCount()), static_cast<Eigen::Index>(sheet.dofCount()));
  M.setFromTriplets(t.begin(), t.end());
  return M;
}

// Throws SimError unless every piece's arc-length coordinates are its own: a seam runs through end
// nodes only, with a slot (u or v) per node, and no node's u or v serves two pieces.
void checkPieceSlots(const YarnGrid& grid) {
  std::vector<std::size_t> owner(kYarnDofsPerNode * grid.nodeCount(), grid.pieces.size());
  for (std::size_t i = 0; i < grid.pieces.size(); ++i) {
    const YarnPiece& p = grid.pieces[i];
    const std::string name = "yarn sheet: piece " + std::to_string(i);
    if (p.nodes.size() != p.arc_length_m.size()) throw SimError(name + " has not one arc length per node");
    if (p.seam && p.slide_offsets.size() != p.nodes.size()) throw SimError(name + " (a seam) has not one slide offset per node");
    for (std::size_t k = 0; k < p.nodes.size(); ++k) {
      if (p.nodes[k] >= grid.nodeCount()) throw SimError(name + " names node " + std::to_string(p.nodes[k]) + ", beyond the grid");
      if (p.seam && !grid.isEnd(p.nodes[k]))
        throw SimError(name + " (a seam) runs through crossing " + std::to_string(p.nodes[k]) + "; seams join yarn ends only");
      const int off = p.slideOffset(k);
      if (off != 3 && off != 4) throw SimError(name + " has slide offset " + std::to_string(off) + " (3 or 4)");
      std::size_t& o = owner[kYarnDofsPerNode * p.nodes[k] + static_cast<std::size_t>(off)];
      if (o != grid.pieces.size())
        throw SimError(name + " uses the " + (off == 3 ? "u" : "v") + " of node " + std::to_string(p.nodes[k]) +
                       ", which is piece " + std::to_string(o) + "'s");
      o = i;
    }
  }
}

}  // namespace

YarnSheet buildYarnSheet(YarnGrid grid) {
  checkPieceSlots(grid);
  YarnSheet s;
  s.grid = std::move(grid);
  s.rest = VecX::Zero(static_cast<Eigen::Index>(s.dofCount()));
  for (std::size_t n = 0; n < s.grid.nodeCount(); ++n) {
    const Vec2 p = s.grid.nodePosition(n);
    s.rest.segment<kYarnDofsPerNode>(kYarnDofsPerNode * n) << p.x(), p.y(), 0, p.x(), p.y();
  }
  // A seam's arc length (distance along its edge) sits in the slot its end node's own yarn leaves unused.
  for (const YarnPiece& p : s.grid.pieces)
    if (p.seam)
      for (std::size_t k = 0; k < p.nodes.size(); ++k)
        s.rest[static_cast<Eigen::Index>(kYarnDofsPerNode * p.nodes[k] + static_cast<std::size_t>(p.slideOffset(k)))] = p.arc_length_m[k];
  // An end's both sliding coordinates are held: its arc length is the yarn's end, the other unused or
  // a seam's arc length (sewn: the seam does not slide through the end).
  for (std::size_t n = s.grid.crossings.size(); n < s.grid.nodeCount(); ++n) {
    s.held_dofs.push_back(kYarnDofsPerNode * n + 3);
    s.held_dofs.push_back(kYarnDofsPerNode * n + 4);
  }
  // A piece that ends at a crossing (its end stub was dropped, or the grid has no end nodes) keeps
  // that crossing's arc length on it: otherwise material could flow out of the yarn's last segment
  // into yarn that is not simulated.
  for (const YarnPiece& p : s.grid.pieces)
    for (std::size_t k : {std::size_t{0}, p.nodes.size() - 1})
      if (!s.grid.isEnd(p.nodes[k])) s.held_dofs.push_back(kYarnDofsPerNode * p.nodes[k] + static_cast<std::size_t>(p.slideOffset(k)));
  std::sort(s.held_dofs.begin(), s.held_dofs.end());
  s.held_dofs.erase(std::unique(s.held_dofs.begin(), s.held_dofs.end()), s.held_dofs.end());
  return s;
}

Real yarnSheetEnergy(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q, const Vec3& g, VecX* gradient) {
  const Real k_s = fabric.stretchStiffness(), k_b = fabric.bendingStiffness(), rho = fabric.linear_density_kg_per_m;
  if (gradient) *gradient = VecX::Zero(q.size());
  Real energy = 0;
  forEachTerm(
      sheet,
      [&](const StencilDofs<2>& d) {
        const yarn::SegmentVector s = gather<2>(q, d);
        energy += yarn::stretchEnergy(s, k_s) + yarn::gravityEnergy(s, rho, g);
        if (gradient) scatterAdd<2>(yarn::stretchGradient(s, k_s) + yarn::gravityGradient(s, rho, g), d, gradient);
      },
      [&](const StencilDofs<3>& d) {
        const yarn::BendVector b = gather<3>(q, d);
        energy += yarn::bendEnergy(b, k_b);
        if (gradient) scatterAdd<3>(yarn::bendGradient(b, k_b), d, gradient);
      });
  return energy;
}

Eigen::SparseMatrix<Real> yarnSheetHessian(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q, const Vec3& g,
                                           bool clamped) {
  const Real k_s = fabric.stretchStiffness(), k_b = fabric.bendingStiffness();
  const yarn::SegmentMatrix h_gravity = yarn::gravityHessian(fabric.linear_density_kg_per_m, g);
  auto all = [](std::size_t) { return true; };
  std::vector<Eigen::Triplet<Real>> t;
  forEachTerm(
      sheet,
      [&](const StencilDofs<2>& d) {
        const yarn::SegmentVector s = gather<2>(q, d);
        const yarn::SegmentMatrix h = clamped ? yarn::stretchHessianClamped(s, k_s) : yarn::stretchHessian(s, k_s);
        scatterTriplets<2>(h + h_gravity, d, all, &t);
      },
      [&](const StencilDofs<3>& d) {
        const yarn::BendVector b = gather<3>(q, d);
        scatterTriplets<3>(clamped ? yarn::bendHessianClamped(b, k_b) : yarn::bendHessian(b, k_b), d, all, &t);
      });
  return sparseFrom(sheet, t);
}

Eigen::SparseMatrix<Real> yarnSheetMass(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q) {
  std::vector<char> held(sheet.dofCount(), 0);
  for (std::size_t d : sheet.held_dofs) held[d] = 1;
  auto free = [&](std::size_t dof) { return !held[dof]; };
  std::vector<Eigen::Triplet<Real>> t;
  forEachTerm(
      sheet,
      [&](const StencilDofs<2>& d) {
        scatterTriplets<2>(yarn::segmentMass(gather<2>(q, d), fabric.linear_density_kg_per_m), d, free, &t);
      },
      [](const StencilDofs<3>&) {});
  return sparseFrom(sheet, t);
}

}  // namespace textile_handling
