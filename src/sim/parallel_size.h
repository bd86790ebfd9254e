// Internal to sim_core: the problem size below which the simulator's OpenMP loops run on one thread.
// A parallel region costs tens of microseconds (more with OMP_WAIT_POLICY=passive, and far more when
// the machine is oversubscribed); below these sizes the work it splits is smaller than that. Measured:
// bench/results/2026-12-06-parallel-threshold/.
#pragma once

#include "textile_handling/sim/types.h"

namespace textile_handling {

/// Scalar unknowns (nodes x DOFs per node) below which a per-node or per-matrix-entry loop is serial.
constexpr Index kParallelMinUnknowns = 12288;

/// Force stencils (one per node or per segment) below which a stencil loop is serial.
constexpr Index kParallelMinStencils = 4096;

/// True when a loop over a system with `nodes` nodes of `dofs_per_node` unknowns is worth splitting.
inline bool parallelWorthIt(Index nodes, int dofs_per_node) {
  return nodes * static_cast<Index>(dofs_per_node) >= kParallelMinUnknowns;
}

}  // namespace textile_handling
