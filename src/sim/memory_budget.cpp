// Memory estimate and budget of simulations (memory_budget.h). The per-node figures come from peak
// resident sizes of drape_sim measured on 2026-12-02 (docs/simulation.md, "Memory budget").
#include "textile_handling/sim/memory_budget.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>

namespace textile_handling {

namespace {

// Bytes per node for each integrator / solver, and what self-collision adds; each is the largest
// measured (peak RSS - baseline) / nodes rounded up with a margin (docs/simulation.md).
constexpr double kBytesPerNodeRk4 = 2048;
constexpr double kBytesPerNodeBlockDiagonal = 2048;
constexpr double kBytesPerNodeSemiImplicitCg = 8192;
// The sparse LDL^T factor grows faster than the node count (fill-in): per node, this times log2(nodes).
constexpr double kBytesPerNodeLogDirect = 2048;
constexpr double kBytesPerNodeSelfCollision = 4096;
// Program, libraries and small fixed structures.
constexpr double kFixedBytes = 64.0 * 1024 * 1024;

std::size_t saturate(double bytes) {
  constexpr double kMax = static_cast<double>(std::numeric_limits<std::size_t>::max());
  if (!(bytes < kMax)) return std::numeric_limits<std::size_t>::max();
  return static_cast<std::size_t>(std::ceil(bytes));
}

}  // namespace

std::size_t estimateSimulationBytes(const SimulationMemoryInput& in) {
  const double nodes = std::max<double>(0, in.nodes);
  // Every figure was measured with 3 DOFs per node; memory scales with the DOFs (squared for blocks).
  const double dof_scale = std::max(1.0, static_cast<double>(in.dofs_per_node) / 3.0);
  double per_node = 0;
  switch (in.integrator) {
    case IntegratorType::kRK4: per_node = kBytesPerNodeRk4 * dof_scale; break;
    case IntegratorType::kBlockDiagonalEuler: per_node = kBytesPerNodeBlockDiagonal * dof_scale * dof_scale; break;
    case IntegratorType::kBackwardEulerNewton:  // the system and a few more vectors than CG's
    case IntegratorType::kSemiImplicitEuler:
      per_node = kBytesPerNodeSemiImplicitCg * dof_scale * dof_scale;
      if (in.integrator == IntegratorType::kSemiImplicitEuler && in.solver == LinearSolverKind::kDirect)
        per_node += kBytesPerNodeLogDirect * dof_scale * dof_scale * std::log2(std::max(2.0, nodes));
      break;
  }
  if (in.self_collision) per_node += kBytesPerNodeSelfCollision;
  return saturate(kFixedBytes + nodes * per_node);
}

std::size_t physicalMemoryBytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page_size = ::sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page_size <= 0) return 0;
  return saturate(static_cast<double>(pages) * static_cast<double>(page_size));
}

std::size_t defaultMemoryBudgetBytes() {
  const std::size_t physical = physicalMemoryBytes();
  return physical > 0 ? physical / 2 : std::size_t{1} << 30;
}

std::size_t effectiveMemoryBudget(std::size_t configured) {
  return configured > 0 ? configured : defaultMemoryBudgetBytes();
}

std::string formatBytes(std::size_t bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  double v = static_cast<double>(bytes);
  int u = 0;
  while (v >= 1024 && u < 6) {
    v /= 1024;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", v, units[u]);
  return buf;
}

void checkMemoryBudget(std::size_t estimate_bytes, std::size_t budget_bytes, const std::string& what,
                       std::size_t simultaneous) {
  const std::size_t budget = effectiveMemoryBudget(budget_bytes);
  const std::size_t count = std::max<std::size_t>(1, simultaneous);
  const std::size_t total = estimate_bytes > std::numeric_limits<std::size_t>::max() / count
                                ? std::numeric_limits<std::size_t>::max()
                                : estimate_bytes * count;
  if (total <= budget) return;
  const std::string need = count > 1 ? std::to_string(count) + " simultaneous simulations of " +
                                           formatBytes(estimate_bytes) + " each need " + formatBytes(total)
                                     : "needs about " + formatBytes(total);
  throw MemoryBudgetError(what + " " + need + ", more than the memory budget of " + formatBytes(budget) +
                          (budget_bytes == 0 ? " (default: half of the " + formatBytes(physicalMemoryBytes()) +
                                                   " of physical memory)"
                                             : "") +
                          "; use a coarser particle spacing or fewer workers, or raise the budget (drape_sim / drape_db "
                          "--memory-budget-mb, the drape_simulator parameter ~memory_budget_mb)");
}

}  // namespace textile_handling
