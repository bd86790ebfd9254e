// The connectivity of a cloth's active-particle grid (neighbours, grid cells, areas), shared by the cloth
// models, self-collision, the silhouette renderers, the database and the recognizer. It depends on no
// cloth model.
#pragma once

#include <array>
#include <vector>

#include "textile_handling/sim/types.h"

namespace textile_handling {

class ParticleGrid;

/// Connectivity of an active-particle grid, independent of how it was rasterised.
struct ParticleTopology {
  Real spacing = 0.01;                       ///< rest distance d [m]
  std::vector<std::array<Index, 4>> neighbour;  ///< right(+x), up(+y), left(-x), down(-y); -1 if none
  std::vector<std::array<int, 2>> grid;      ///< (row i, column j) of every particle
  std::vector<Real> area;                    ///< area represented by each particle [m^2]

  Index size() const { return static_cast<Index>(neighbour.size()); }
  /// Builds the topology of the active nodes of a rasterised grid.
  static ParticleTopology fromGrid(const ParticleGrid& grid);
};

}  // namespace textile_handling
