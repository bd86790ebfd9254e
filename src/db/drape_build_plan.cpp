// Planner of a build pass: the pass's rows in the database and the jobs that are still to run.
#include <algorithm>
#include <utility>

#include "drape_build_steps.h"

namespace textile_handling {
namespace db {
namespace internal {

BuildMesh buildMesh(const DrapeBuildConfig& c, const TextileSymmetry& symmetry, bool symmetric_grid) {
  BuildMesh mesh;
  std::string err;
  const ParticleGrid grid = ParticleGrid::rasterize(c.textile, c.spacing, &err);
  if (grid.empty()) throw InvalidInputError("build: rasterisation failed: " + err);
  mesh.triangles = vision::trianglesFromTopology(ParticleTopology::fromGrid(grid));
  if (symmetric_grid)
    for (MirrorKind m : symmetry.mirrors()) mesh.perms[m] = mirrorPermutation(grid, symmetry, m);
  return mesh;
}

namespace {

std::vector<NewSimulation> planRows(const DrapeBuildConfig& c, const std::vector<PlannedHoldPoint>& plan,
                                    std::int64_t textile_id, std::int64_t generation, const std::string& params) {
  std::vector<NewSimulation> rows;
  for (const PlannedHoldPoint& h : plan) {
    NewSimulation r;
    r.textile_id = textile_id;
    r.generation = generation;
    r.hold = h.position;
    r.lattice_i = h.lattice_i;
    r.lattice_j = h.lattice_j;
    r.source = h.mirror;
    r.source_index = h.mirror == MirrorKind::kIdentity ? -1 : h.source;
    r.model = c.model.name;
    r.integrator = toString(c.settings.integrator);
    r.spacing = c.spacing;
    r.parameters = params;
    rows.push_back(r);
  }
  return rows;
}

}  // namespace

PassPlan planPass(HangingDrapeDatabase& db, const DrapeBuildConfig& c, const std::vector<PlannedHoldPoint>& plan,
                  std::int64_t textile_id, std::int64_t generation, const std::string& params) {
  PassPlan pp;
  const std::vector<NewSimulation> rows = planRows(c, plan, textile_id, generation, params);
  pp.ids = db.addSimulations(rows);
  pp.planned = static_cast<int>(rows.size());
  const std::vector<std::int64_t>& ids = pp.ids;
  std::vector<BuildJob>& jobs = pp.jobs;

  std::map<std::int64_t, SimulationRecord> state;
  for (auto& r : db.simulations(textile_id)) state[r.id] = r;

  // Simulated rows: a job for each pending one.
  std::map<std::size_t, std::size_t> job_of_source;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    if (plan[k].mirror != MirrorKind::kIdentity) continue;
    ++pp.to_simulate;
    const SimulationStatus st = state[ids[k]].status;
    if (st == SimulationStatus::kDone) ++pp.already_done;
    if (st == SimulationStatus::kPending) {
      job_of_source[k] = jobs.size();
      jobs.push_back({k, ids[k], {}, true});
    }
  }
  // Pending mirror rows: derived by their source's job (a derive-only job if the source is done).
  std::vector<std::pair<std::int64_t, std::string>> orphan_failures;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    if (plan[k].mirror == MirrorKind::kIdentity || state[ids[k]].status != SimulationStatus::kPending) continue;
    const std::size_t src = static_cast<std::size_t>(plan[k].source);
    const SimulationRecord& s = state[ids[src]];
    if (s.status == SimulationStatus::kPending) {
      jobs[job_of_source[src]].derived.push_back(k);
    } else if (s.status == SimulationStatus::kDone) {
      auto it = job_of_source.find(src);
      if (it == job_of_source.end()) {
        job_of_source[src] = jobs.size();
        jobs.push_back({src, ids[src], {}, false});
        it = job_of_source.find(src);
      }
      jobs[it->second].derived.push_back(k);
    } else {
      orphan_failures.emplace_back(ids[k], "source simulation " + std::to_string(ids[src]) + " failed: " + s.failure_reason);
    }
  }
  for (const auto& [id, reason] : orphan_failures) db.markFailed(id, reason, /*skip_done=*/true);
  // Derive-only jobs first (cheap), then simulations in plan order.
  std::stable_sort(jobs.begin(), jobs.end(), [](const BuildJob& a, const BuildJob& b) { return !a.simulate && b.simulate; });
  pp.simulations = static_cast<int>(std::count_if(jobs.begin(), jobs.end(), [](const BuildJob& j) { return j.simulate; }));
  return pp;
}

}  // namespace internal
}  // namespace db
}  // namespace textile_handling
