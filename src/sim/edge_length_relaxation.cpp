#include "textile_handling/sim/edge_length_relaxation.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "textile_handling/sim/sim_errors.h"

namespace textile_handling {

namespace {

struct GridEdge {
  Index a, b;
  Real rest;
  Vec3 textile_direction;  ///< unit, for opening an edge of zero length
};

// The 4-neighbour edges and both diagonals of every cell, each once.
std::vector<GridEdge> gridEdges(const ParticleGrid& g) {
  std::vector<GridEdge> edges;
  const Real d = g.spacing();
  const Real s = std::sqrt(Real(0.5));
  struct Step {
    Index di, dj;
    Real rest;
    Vec3 dir;
  };
  const Step steps[] = {{0, 1, d, Vec3(1, 0, 0)},
                        {1, 0, d, Vec3(0, 1, 0)},
                        {1, 1, d * std::sqrt(Real(2)), Vec3(s, s, 0)},
                        {1, -1, d * std::sqrt(Real(2)), Vec3(-s, s, 0)}};
  for (Index c = 0; c < g.numActive(); ++c) {
    const Index i = g.compactRows()[static_cast<std::size_t>(c)], j = g.compactCols()[static_cast<std::size_t>(c)];
    for (const Step& st : steps) {
      const Index n = g.activeIndex(i + st.di, j + st.dj);
      if (n >= 0) edges.push_back({c, n, st.rest, st.dir});
    }
  }
  return edges;
}

void ratioRange(const std::vector<GridEdge>& edges, const VecX& x, Real* lo, Real* hi) {
  *lo = 1;
  *hi = 1;
  for (const GridEdge& e : edges) {
    const Real r = (x.segment<3>(3 * e.b) - x.segment<3>(3 * e.a)).norm() / e.rest;
    *lo = std::min(*lo, r);
    *hi = std::max(*hi, r);
  }
}

}  // namespace

EdgeRelaxationResult relaxEdgeLengths(const ParticleGrid& grid, VecX& positions, const std::vector<Index>& fixed,
                                      Real min_ratio, Real max_ratio, int max_sweeps) {
  const Index n = grid.numActive();
  if (positions.size() != 3 * n)
    throw SimError("relaxEdgeLengths: positions have " + std::to_string(positions.size()) + " values, the grid needs " +
                   std::to_string(3 * n));
  if (!(min_ratio > 0 && min_ratio <= 1)) throw SimError("relaxEdgeLengths: min_ratio must be in (0, 1]");
  if (!(max_ratio >= 1 && std::isfinite(max_ratio))) throw SimError("relaxEdgeLengths: max_ratio must be finite and >= 1");
  if (max_sweeps < 1) throw SimError("relaxEdgeLengths: max_sweeps must be >= 1");
  if (!positions.allFinite()) throw SimError("relaxEdgeLengths: positions must be finite");
  std::vector<char> is_fixed(static_cast<std::size_t>(n), 0);
  for (Index f : fixed) {
    if (f < 0 || f >= n) throw SimError("relaxEdgeLengths: fixed index " + std::to_string(f) + " out of range");
    is_fixed[static_cast<std::size_t>(f)] = 1;
  }
  const std::vector<GridEdge> edges = gridEdges(grid);
  EdgeRelaxationResult out;
  ratioRange(edges, positions, &out.min_ratio_before, &out.max_ratio_before);
  while (out.sweeps < max_sweeps) {
    ++out.sweeps;
    Index corrected = 0;
    for (const GridEdge& e : edges) {
      const bool fa = is_fixed[static_cast<std::size_t>(e.a)] != 0, fb = is_fixed[static_cast<std::size_t>(e.b)] != 0;
      if (fa && fb) continue;
      const Vec3 ab = positions.segment<3>(3 * e.b) - positions.segment<3>(3 * e.a);
      const Real len = ab.norm();
      // The relative slack keeps an edge that was just corrected from coming back through rounding.
      if (len >= min_ratio * e.rest * (1 - 1e-9) && len <= max_ratio * e.rest * (1 + 1e-9)) continue;
      const Real target = (len < min_ratio * e.rest ? min_ratio : max_ratio) * e.rest;
      const Vec3 u = len > 1e-12 * e.rest ? Vec3(ab / len) : e.textile_direction;
      const Real change = target - len;  // > 0: the ends move apart
      const Real wa = fa ? 0 : fb ? 1 : 0.5;
      positions.segment<3>(3 * e.a) -= wa * change * u;
      positions.segment<3>(3 * e.b) += (1 - wa) * change * u;
      ++corrected;
    }
    out.corrections += corrected;
    if (corrected == 0) break;
  }
  ratioRange(edges, positions, &out.min_ratio_after, &out.max_ratio_after);
  return out;
}

}  // namespace textile_handling
