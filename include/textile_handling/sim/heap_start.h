// A starting pose "picked from a heap": the flat sheet folded over itself along random lines (a crumpled
// heap approximated by isometric folds, so no edge starts stretched), then lifted by the held point so
// that the folded bundle hangs below it. Different folds lead the drape into different equilibria, as a
// robot's picks from a laundry heap do (docs/simulation.md, "Starting pose").
#pragma once

#include <cstdint>

#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

/// Most folds a heap start accepts (each fold at least doubles the stack height).
constexpr int kMaxHeapFolds = 6;

struct HeapStart {
  int folds = 0;                 ///< random folds; 0 = no heap start
  std::uint64_t seed = 0;        ///< the folds' random lines (the same seed gives the same start)
  Real lift_deg = 75;            ///< rotation that lifts the bundle below the held point [deg], in (0, 180)
};

/// Folds the flat sheet `folds` times. Each fold picks a random line through a random particle, keeps
/// the side with the held particle and wraps the other side over the stack (a half-cylinder of radius
/// (stack height above the particle) + layer_gap / 2, so every particle keeps its in-plane distances);
/// a line is accepted when the held particle lies >= 2 grid spacings from it and 15-60 % of the
/// particles fold. Then the bundle is rotated by lift_deg about the horizontal line through the held
/// particle perpendicular to the direction of its centroid, so the centroid goes down. A later fold
/// across an earlier crease stretches or squeezes it (the layers wrap around one axis), so grid edges
/// are finally brought back by strain limiting (Provot 1995), the held particle fixed: structural edges
/// into [0.98, 1.002] x rest, diagonal ones to at most 1.002 x rest.
///
/// Input: `grid` (n active particles), `hold_particle` in [0, n), `layer_gap` > 0 [m].
/// Output: 3n textile-frame positions [m] (x, y in the textile plane, z up) with the held particle at
/// its flat position (z = 0). A fold that finds no acceptable line within 200 tries is skipped.
/// Throws std::invalid_argument naming the field for folds outside [0, kMaxHeapFolds], lift_deg outside
/// (0, 180), a non-positive layer_gap or a held particle outside the grid.
VecX heapStartPositions(const ParticleGrid& grid, Index hold_particle, const HeapStart& heap, Real layer_gap);

}  // namespace textile_handling
