// The yarn-level model's state and assembled terms over a laid yarn grid (yarn_sheet.h).
#include "textile_handling/sim/yarn_sheet.h"

#include <algorithm>
#include <cmath>

#include "textile_handling/sim/yarn_kernels.h"

namespace textile_handling {

namespace {

// The sliding coordinate of a piece's yarn within a node's five: u (3) for a warp, v (4) for a weft.
int slideOffset(const YarnPiece& p) { return p.warp ? 3 : 4; }

// Calls segment(piece, k) for every segment (k, k + 1) and bend(piece, k) for every interior node k.
template <class Segment, class Bend>
void forEachTerm(const YarnSheet& sheet, Segment segment, Bend bend) {
  for (const YarnPiece& p : sheet.grid.pieces) {
    for (std::size_t k = 0; k + 1 < p.nodes.size(); ++k) segment(p, k);
    for (std::size_t k = 1; k + 1 < p.nodes.size(); ++k) bend(p, k);
  }
}

yarn::SegmentVector segmentCoordinates(const VecX& q, const YarnPiece& p, std::size_t k, int slide) {
  const std::size_t a = kYarnDofsPerNode * p.nodes[k], b = kYarnDofsPerNode * p.nodes[k + 1];
  return yarn::packSegment(q.segment<3>(a), q[a + slide], q.segment<3>(b), q[b + slide]);
}

}  // namespace

YarnSheet buildYarnSheet(YarnGrid grid) {
  YarnSheet s;
  s.grid = std::move(grid);
  s.rest = VecX::Zero(static_cast<Eigen::Index>(s.dofCount()));
  for (std::size_t n = 0; n < s.grid.nodeCount(); ++n) {
    const Vec2 p = s.grid.nodePosition(n);
    s.rest.segment<kYarnDofsPerNode>(kYarnDofsPerNode * n) << p.x(), p.y(), 0, p.x(), p.y();
  }
  // An end's both sliding coordinates are held: its arc length is the yarn's end, the other unused.
  for (std::size_t n = s.grid.crossings.size(); n < s.grid.nodeCount(); ++n) {
    s.held_dofs.push_back(kYarnDofsPerNode * n + 3);
    s.held_dofs.push_back(kYarnDofsPerNode * n + 4);
  }
  return s;
}

Real yarnSheetEnergy(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q, const Vec3& g, VecX* gradient) {
  const Real r2 = fabric.yarn_radius_m * fabric.yarn_radius_m;
  const Real k_s = fabric.young_modulus_pa * M_PI * r2, k_b = fabric.bending_modulus * M_PI * r2;
  const Real rho = fabric.linear_density_kg_per_m;
  if (gradient) *gradient = VecX::Zero(q.size());
  Real energy = 0;
  forEachTerm(
      sheet,
      [&](const YarnPiece& p, std::size_t k) {
        const int slide = slideOffset(p);
        const yarn::SegmentVector s = segmentCoordinates(q, p, k, slide);
        energy += yarn::stretchEnergy(s, k_s) + yarn::gravityEnergy(s, rho, g);
        if (!gradient) return;
        const yarn::SegmentVector gs = yarn::stretchGradient(s, k_s) + yarn::gravityGradient(s, rho, g);
        for (int node = 0; node < 2; ++node) {
          const std::size_t base = kYarnDofsPerNode * p.nodes[k + node];
          gradient->segment<3>(base) += gs.segment<3>(4 * node);
          (*gradient)[base + slide] += gs[4 * node + 3];
        }
      },
      [&](const YarnPiece& p, std::size_t k) {
        const int slide = slideOffset(p);
        const std::size_t n2 = kYarnDofsPerNode * p.nodes[k - 1], n0 = kYarnDofsPerNode * p.nodes[k],
                          n1 = kYarnDofsPerNode * p.nodes[k + 1];
        const yarn::BendVector b = yarn::packBendStencil(q.segment<3>(n2), q[n2 + slide], q.segment<3>(n0), q[n0 + slide],
                                                         q.segment<3>(n1), q[n1 + slide]);
        energy += yarn::bendEnergy(b, k_b);
        if (!gradient) return;
        const yarn::BendVector gb = yarn::bendGradient(b, k_b);
        const std::size_t bases[3] = {n2, n0, n1};
        for (int node = 0; node < 3; ++node) {
          gradient->segment<3>(bases[node]) += gb.segment<3>(4 * node);
          (*gradient)[bases[node] + slide] += gb[4 * node + 3];
        }
      });
  return energy;
}

Eigen::SparseMatrix<Real> yarnSheetHessian(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q, const Vec3& g,
                                           bool clamped) {
  const Real r2 = fabric.yarn_radius_m * fabric.yarn_radius_m;
  const Real k_s = fabric.young_modulus_pa * M_PI * r2, k_b = fabric.bending_modulus * M_PI * r2;
  const Real rho = fabric.linear_density_kg_per_m;
  std::vector<Eigen::Triplet<Real>> t;
  // Scatters a kernel's Hessian over nodes `bases` (4 coordinates each: position and `slide`).
  auto scatter = [&](const auto& h, const std::size_t* bases, int nodes, int slide) {
    for (int r = 0; r < 4 * nodes; ++r)
      for (int c = 0; c < 4 * nodes; ++c) {
        if (h(r, c) == 0) continue;
        const std::size_t dr = bases[r / 4] + (r % 4 == 3 ? static_cast<std::size_t>(slide) : static_cast<std::size_t>(r % 4));
        const std::size_t dc = bases[c / 4] + (c % 4 == 3 ? static_cast<std::size_t>(slide) : static_cast<std::size_t>(c % 4));
        t.emplace_back(static_cast<int>(dr), static_cast<int>(dc), h(r, c));
      }
  };
  const yarn::SegmentMatrix h_gravity = yarn::gravityHessian(rho, g);
  forEachTerm(
      sheet,
      [&](const YarnPiece& p, std::size_t k) {
        const int slide = slideOffset(p);
        const yarn::SegmentVector s = segmentCoordinates(q, p, k, slide);
        const yarn::SegmentMatrix h =
            (clamped ? yarn::stretchHessianClamped(s, k_s) : yarn::stretchHessian(s, k_s)) + h_gravity;
        const std::size_t bases[2] = {kYarnDofsPerNode * p.nodes[k], kYarnDofsPerNode * p.nodes[k + 1]};
        scatter(h, bases, 2, slide);
      },
      [&](const YarnPiece& p, std::size_t k) {
        const int slide = slideOffset(p);
        const std::size_t bases[3] = {kYarnDofsPerNode * p.nodes[k - 1], kYarnDofsPerNode * p.nodes[k],
                                      kYarnDofsPerNode * p.nodes[k + 1]};
        const yarn::BendVector b = yarn::packBendStencil(q.segment<3>(bases[0]), q[bases[0] + slide], q.segment<3>(bases[1]),
                                                         q[bases[1] + slide], q.segment<3>(bases[2]), q[bases[2] + slide]);
        scatter(clamped ? yarn::bendHessianClamped(b, k_b) : yarn::bendHessian(b, k_b), bases, 3, slide);
      });
  Eigen::SparseMatrix<Real> H(static_cast<Eigen::Index>(sheet.dofCount()), static_cast<Eigen::Index>(sheet.dofCount()));
  H.setFromTriplets(t.begin(), t.end());
  return H;
}

Eigen::SparseMatrix<Real> yarnSheetMass(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q) {
  std::vector<Eigen::Triplet<Real>> t;
  std::vector<char> held(sheet.dofCount(), 0);
  for (std::size_t d : sheet.held_dofs) held[d] = 1;
  forEachTerm(
      sheet,
      [&](const YarnPiece& p, std::size_t k) {
        const int slide = slideOffset(p);
        const yarn::SegmentMatrix m = yarn::segmentMass(segmentCoordinates(q, p, k, slide), fabric.linear_density_kg_per_m);
        std::size_t dof[8];
        for (int node = 0; node < 2; ++node) {
          const std::size_t base = kYarnDofsPerNode * p.nodes[k + node];
          for (int c = 0; c < 3; ++c) dof[4 * node + c] = base + c;
          dof[4 * node + 3] = base + slide;
        }
        for (int r = 0; r < 8; ++r)
          for (int c = 0; c < 8; ++c)
            if (!held[dof[r]] && !held[dof[c]] && m(r, c) != 0)
              t.emplace_back(static_cast<int>(dof[r]), static_cast<int>(dof[c]), m(r, c));
      },
      [](const YarnPiece&, std::size_t) {});
  Eigen::SparseMatrix<Real> M(static_cast<Eigen::Index>(sheet.dofCount()), static_cast<Eigen::Index>(sheet.dofCount()));
  M.setFromTriplets(t.begin(), t.end());
  return M;
}

}  // namespace textile_handling
