// Edge lengths of a prolonged drape brought into a band around their rest lengths. A coarse drape
// interpolated onto a finer grid (prolongPositions()) can squeeze fine edges to a small fraction of their
// rest length where a coarse cell is folded, for instance next to a one-point hold; the particle model's
// tension law then gives forces of 1e10 times a particle's weight, and the first step of the fine
// simulation cannot be taken (towel held at (0.128, 0) m, a 1 cm drape onto the 2/3 cm grid: one edge at
// 0.11 of its rest length). Lengthening only the short edges stretches their neighbours instead, so both
// ends of the band are kept.
#pragma once

#include <vector>

#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

struct EdgeRelaxationResult {
  int sweeps = 0;              ///< Gauss-Seidel sweeps made
  Index corrections = 0;       ///< edge corrections applied over all sweeps
  Real min_ratio_before = 1;   ///< shortest edge / its rest length, before
  Real max_ratio_before = 1;   ///< longest edge / its rest length, before
  Real min_ratio_after = 1;
  Real max_ratio_after = 1;
};

/// Brings every grid edge (4-neighbour edges, rest length d, and both cell diagonals, rest length d sqrt 2)
/// whose length lies outside [min_ratio, max_ratio] times its rest length to the nearer end of that band:
/// Gauss-Seidel sweeps in compact order (position-based projection), each free end moved half the
/// difference along the edge; a fixed end stays and the other end moves the whole difference; an edge with
/// both ends fixed is left as is. An edge of zero length opens along its textile-frame direction. Edges
/// inside the band are not touched, so a drape without outliers comes back unchanged. Stops after a sweep
/// with no correction or after `max_sweeps` (the band is then not guaranteed; see the result's ratios).
/// positions: 3 x grid.numActive() [m], node after node, changed in place. fixed: compact indices of the
/// particles that must not move (the pins). min_ratio in (0, 1], max_ratio >= 1, max_sweeps >= 1.
/// Throws SimError naming the argument for a size mismatch, an index out of range or a bad value.
EdgeRelaxationResult relaxEdgeLengths(const ParticleGrid& grid, VecX& positions, const std::vector<Index>& fixed,
                                      Real min_ratio, Real max_ratio, int max_sweeps);

}  // namespace textile_handling
