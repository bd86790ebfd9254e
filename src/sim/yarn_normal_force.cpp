// The normal compression at the crossings of a yarn sheet (yarn_normal_force.h).
#include "textile_handling/sim/yarn_normal_force.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

#include "textile_handling/sim/yarn_kernels.h"
#include "parallel_size.h"

namespace textile_handling {

namespace {

constexpr std::size_t kNoPiece = std::numeric_limits<std::size_t>::max();

// Where a crossing sits on one of its yarns: the piece and the node's index along it.
struct YarnSlot {
  std::size_t piece = kNoPiece;
  std::size_t index = 0;
};

struct CrossingSlots {
  std::vector<YarnSlot> warp, weft;  // per crossing
};

CrossingSlots crossingSlots(const YarnGrid& grid) {
  CrossingSlots s;
  s.warp.resize(grid.crossings.size());
  s.weft.resize(grid.crossings.size());
  for (std::size_t p = 0; p < grid.pieces.size(); ++p) {
    const YarnPiece& piece = grid.pieces[p];
    for (std::size_t k = 0; k < piece.nodes.size(); ++k) {
      if (grid.isEnd(piece.nodes[k])) continue;
      (piece.warp ? s.warp : s.weft)[piece.nodes[k]] = YarnSlot{p, k};
    }
  }
  return s;
}

Vec3 position(const VecX& q, std::size_t node) {
  return q.segment<3>(static_cast<Eigen::Index>(kYarnDofsPerNode * node));
}

Real slide(const VecX& q, std::size_t node, bool warp) {
  return q[static_cast<Eigen::Index>(kYarnDofsPerNode * node + (warp ? 3 : 4))];
}

// The chord through a piece's node k: next node minus previous node, the node itself standing in for
// a missing neighbour. Zero for a crossing that is not on such a piece.
Vec3 chord(const YarnGrid& grid, const VecX& q, const YarnSlot& slot) {
  if (slot.piece == kNoPiece) return Vec3::Zero();
  const std::vector<std::size_t>& nodes = grid.pieces[slot.piece].nodes;
  const std::size_t prev = slot.index > 0 ? slot.index - 1 : slot.index;
  const std::size_t next = slot.index + 1 < nodes.size() ? slot.index + 1 : slot.index;
  return position(q, nodes[next]) - position(q, nodes[prev]);
}

// +1 where the warp is on top at the crossing, -1 where the weft is.
Real warpSide(const YarnGrid& grid, std::size_t crossing) { return grid.crossings[crossing].warp_on_top ? 1 : -1; }

// For every crossing on `piece`, n . F of the piece's stretch force (uncrimped) and the bending force of
// the crimped stencil centred at it, as (crossing, value) in the piece's order; the caller adds them and
// flips the sign for a weft.
std::vector<std::pair<std::size_t, Real>> pieceNormalForces(const YarnSheet& sheet, const VecX& q, const YarnPiece& piece,
                                                            const std::vector<Vec3>& N, const std::vector<Vec3>& n, Real R,
                                                            Real k_s, Real k_b) {
  const YarnGrid& grid = sheet.grid;
  const std::size_t count = piece.nodes.size();
  // Crimped points: a crossing's warp point at x + s R N, its weft point at x - s R N (s = warpSide).
  std::vector<Vec3> crimped(count);
  std::vector<Real> arc(count);
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t node = piece.nodes[k];
    crimped[k] = position(q, node);
    arc[k] = slide(q, node, piece.warp);
    if (!grid.isEnd(node)) crimped[k] += (piece.warp ? 1 : -1) * warpSide(grid, node) * R * N[node];
  }
  std::vector<Vec3> force(count, Vec3::Zero());
  for (std::size_t k = 0; k + 1 < count; ++k) {
    const yarn::SegmentVector g = yarn::stretchGradient(
        yarn::packSegment(position(q, piece.nodes[k]), arc[k], position(q, piece.nodes[k + 1]), arc[k + 1]), k_s);
    force[k] -= g.segment<3>(0);
    force[k + 1] -= g.segment<3>(4);
  }
  for (std::size_t k = 1; k + 1 < count; ++k) {
    const yarn::BendVector g = yarn::bendGradient(
        yarn::packBendStencil(crimped[k - 1], arc[k - 1], crimped[k], arc[k], crimped[k + 1], arc[k + 1]), k_b);
    force[k] -= g.segment<3>(4);  // only the stencil centred at the crossing (notes 9.4)
  }
  std::vector<std::pair<std::size_t, Real>> out;
  out.reserve(count);
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t node = piece.nodes[k];
    if (!grid.isEnd(node)) out.emplace_back(node, n[node].dot(force[k]));
  }
  return out;
}

}  // namespace

std::vector<Vec3> crossingPanelNormals(const YarnSheet& sheet, const VecX& q) {
  const YarnGrid& grid = sheet.grid;
  const CrossingSlots slots = crossingSlots(grid);
  std::vector<Vec3> N(grid.crossings.size(), Vec3::Zero());
  const auto crossings = static_cast<std::ptrdiff_t>(grid.crossings.size());
#pragma omp parallel for schedule(static) if (crossings >= kParallelMinStencils)
  for (std::ptrdiff_t k = 0; k < crossings; ++k) {
    const std::size_t c = static_cast<std::size_t>(k);
    const Vec3 tw = chord(grid, q, slots.warp[c]), tv = chord(grid, q, slots.weft[c]);
    const Vec3 cross = tw.cross(tv);
    const Real length = cross.norm();
    if (length > 1e-12 * tw.norm() * tv.norm() && length > 0) N[c] = cross / length;
  }
  return N;
}

std::vector<Vec3> crossingNormals(const YarnSheet& sheet, const VecX& q) {
  std::vector<Vec3> n = crossingPanelNormals(sheet, q);
  for (std::size_t c = 0; c < n.size(); ++c) n[c] *= -warpSide(sheet.grid, c);
  return n;
}

CrossingCompression crossingCompression(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q) {
  const std::size_t crossings = sheet.grid.crossings.size();
  const std::vector<Vec3> N = crossingPanelNormals(sheet, q);
  CrossingCompression out;
  out.normal = N;
  for (std::size_t c = 0; c < crossings; ++c) out.normal[c] *= -warpSide(sheet.grid, c);
  out.warp_push.assign(crossings, 0);
  out.weft_push.assign(crossings, 0);
  const Real R = fabric.yarn_radius_m, k_s = fabric.stretchStiffness(), k_b = fabric.bendingStiffness();
  // The pieces on all threads, their values added in piece order: the same sums on any thread count.
  const std::vector<YarnPiece>& pieces = sheet.grid.pieces;
  std::vector<std::vector<std::pair<std::size_t, Real>>> values(pieces.size());
  const auto count = static_cast<std::ptrdiff_t>(pieces.size());
#pragma omp parallel for schedule(dynamic, 4) if (static_cast<std::ptrdiff_t>(crossings) >= kParallelMinStencils)
  for (std::ptrdiff_t p = 0; p < count; ++p)
    if (!pieces[static_cast<std::size_t>(p)].seam)  // a seam passes through no crossing
      values[static_cast<std::size_t>(p)] = pieceNormalForces(sheet, q, pieces[static_cast<std::size_t>(p)], N, out.normal, R, k_s, k_b);
  for (std::size_t p = 0; p < pieces.size(); ++p) {
    std::vector<Real>& push = pieces[p].warp ? out.warp_push : out.weft_push;
    for (const auto& [node, value] : values[p]) push[node] += value;
  }
  out.force.resize(crossings);
  for (std::size_t c = 0; c < crossings; ++c) {
    out.weft_push[c] = -out.weft_push[c];  // -n . F(v)
    out.force[c] = N[c].isZero(0) ? 0 : std::max<Real>(0, 0.5 * (out.warp_push[c] + out.weft_push[c]));
  }
  return out;
}

std::vector<Real> crossingNormalForces(const YarnSheet& sheet, const WovenFabric& fabric, const VecX& q) {
  return crossingCompression(sheet, fabric, q).force;
}

}  // namespace textile_handling
