// Prolongation of a drape from a coarse particle grid to a finer grid of the same textile: every fine
// particle's world position interpolated from the coarse particles around its textile-frame point.
#pragma once

#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

/// Positions (3 x fine.numActive(), node after node) [m] of the fine grid's particles, interpolated
/// from `coarse_positions` (3 x coarse.numActive()) of the coarse grid of the same textile:
/// bilinear in the coarse cell that contains the particle's textile point when its four corners are
/// particles; otherwise affine, from the nearest coarse particles that span a triangle, searched
/// within 1, 2, then 3 cells around that cell (extrapolating at the outline); otherwise (no such
/// triangle within 3 cells) the nearest coarse particle's position.
/// Throws SimError if a grid is empty or `coarse_positions` has the wrong size.
VecX prolongPositions(const ParticleGrid& coarse, const VecX& coarse_positions, const ParticleGrid& fine);

}  // namespace textile_handling
