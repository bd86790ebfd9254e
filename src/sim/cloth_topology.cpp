#include "textile_handling/sim/cloth_topology.h"

#include <algorithm>

#include "textile_handling/sim/textile_geometry.h"

namespace textile_handling {

ParticleTopology ParticleTopology::fromGrid(const ParticleGrid& g) {
  ParticleTopology t;
  t.spacing = g.spacing();
  const Index n = g.numActive();
  t.neighbour.resize(n);
  t.grid.resize(n);
  t.area.assign(n, 0.0);
  for (int i = 0; i < g.rows(); ++i) {
    for (int j = 0; j < g.cols(); ++j) {
      const Index r = g.activeIndex(i, j);
      if (r < 0) continue;
      t.grid[r] = {i, j};
      for (int dir = 0; dir < 4; ++dir) t.neighbour[r][dir] = g.neighbour(r, dir);
    }
  }
  // Each complete cell gives a quarter of its area to each of its corners (exact for rectangles).
  const Real quarter = 0.25 * t.spacing * t.spacing;
  for (int i = 0; i + 1 < g.rows(); ++i) {
    for (int j = 0; j + 1 < g.cols(); ++j) {
      const Index c[4] = {g.activeIndex(i, j), g.activeIndex(i, j + 1), g.activeIndex(i + 1, j),
                          g.activeIndex(i + 1, j + 1)};
      if (c[0] < 0 || c[1] < 0 || c[2] < 0 || c[3] < 0) continue;
      for (Index k : c) t.area[k] += quarter;
    }
  }
  // Particles on one-particle-wide strips have no complete cell: give them a strip share.
  for (Index r = 0; r < n; ++r) {
    if (t.area[r] > 0) continue;
    int nb = 0;
    for (int dir = 0; dir < 4; ++dir) nb += t.neighbour[r][dir] >= 0;
    t.area[r] = quarter * std::max(nb, 1);
  }
  return t;
}

}  // namespace textile_handling
