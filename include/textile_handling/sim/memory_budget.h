// Memory estimate of a simulation and the budget it must fit in, checked before anything big is
// allocated (buildDrapeScene() checks every scene: drape_sim, drape_bench, the database builder, the
// drape_simulator node). Calibration and figures: docs/simulation.md, "Memory budget".
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>

#include "textile_handling/sim/sim_errors.h"

#include "textile_handling/sim/drape_simulation.h"

namespace textile_handling {

/// What a simulation's memory depends on.
struct SimulationMemoryInput {
  Index nodes = 0;                 ///< active particles
  int dofs_per_node = 3;           ///< 3 for every cloth model
  IntegratorType integrator = IntegratorType::kSemiImplicitEuler;
  LinearSolverKind solver = LinearSolverKind::kCG;
  bool self_collision = false;
};

/// The memory input of `nodes` particles simulated with `settings` (integrator, linear solver), with or
/// without self-collision.
inline SimulationMemoryInput memoryInput(Index nodes, const SimulationSettings& settings, bool self_collision) {
  SimulationMemoryInput in;
  in.nodes = nodes;
  in.integrator = settings.integrator;
  in.solver = settings.solver.kind;
  in.self_collision = self_collision;
  return in;
}

/// Conservative estimate [bytes] of the peak memory of one simulation (scene, model, integrator,
/// solver, collision passes and the outputs drape_sim writes), from measured peak resident sizes.
/// Stored trajectory frames (simulation.trajectory_every) come on top: 24 bytes per node and frame.
/// Saturates at SIZE_MAX instead of overflowing.
std::size_t estimateSimulationBytes(const SimulationMemoryInput& input);

/// Physical memory of this machine [bytes] (sysconf), or 0 if unknown.
std::size_t physicalMemoryBytes();

/// The default budget: half of physical memory (1 GiB if it is unknown).
std::size_t defaultMemoryBudgetBytes();

/// `configured` if non-zero, else defaultMemoryBudgetBytes(): the meaning of a budget field of 0.
std::size_t effectiveMemoryBudget(std::size_t configured);

/// A simulation would need more memory than its budget allows.
class MemoryBudgetError : public SimError {
 public:
  explicit MemoryBudgetError(const std::string& what) : SimError(what) {}
};

/// Throws MemoryBudgetError if `simultaneous` simulations of `estimate_bytes` each exceed
/// effectiveMemoryBudget(budget_bytes). The message names `what`, the estimate, the budget and how to
/// raise the budget or lower the need (a coarser spacing). For several simulations running at once
/// (a database build on W threads), pass W.
void checkMemoryBudget(std::size_t estimate_bytes, std::size_t budget_bytes, const std::string& what,
                       std::size_t simultaneous = 1);

/// "1.5 GiB"-style text for messages.
std::string formatBytes(std::size_t bytes);

}  // namespace textile_handling
