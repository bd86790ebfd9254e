// The steps of one build pass of DrapeDatabaseBuilder, private to the builder library. The pass itself
// (drape_database_builder.cpp) runs them on its worker threads:
//   planner  (drape_build_plan.cpp):   which rows exist, which are still to run, as jobs;
//   worker   (drape_build_worker.cpp): one job, i.e. one simulation (or a loaded done one) -> stored rows;
//   mirrors  (drape_mirror_rows.cpp):  the mirrored rows derived from a simulated one.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "textile_handling/db/drape_database_builder.h"

namespace textile_handling {
namespace db {
namespace internal {

/// Mesh data shared by every job of a pass (every hold point has the same particle grid).
struct BuildMesh {
  std::vector<vision::Triangle> triangles;         ///< the grid's triangles, for the renderers
  std::map<MirrorKind, std::vector<Index>> perms;  ///< particle permutation per mirror (symmetric grid only)
};

/// The mesh of `config`'s particle grid. Throws InvalidInputError if the textile cannot be rasterised.
BuildMesh buildMesh(const DrapeBuildConfig& config, const TextileSymmetry& symmetry, bool symmetric_grid);

/// One unit of work: a simulated row (or a done one, loaded) and the pending mirror rows derived from it.
struct BuildJob {
  std::size_t plan_index = 0;        ///< the source row, an index into the pass's plan
  std::int64_t id = 0;               ///< its simulation id
  std::vector<std::size_t> derived;  ///< plan indices of the pending mirror rows of this source
  bool simulate = true;              ///< false: the source is done already, only derive its mirrors
};

/// What a pass has to do.
struct PassPlan {
  std::vector<std::int64_t> ids;  ///< simulation id of each plan entry (same order as the plan)
  std::vector<BuildJob> jobs;     ///< derive-only jobs first (cheap), then the simulations in plan order
  int planned = 0;                ///< rows in the plan
  int to_simulate = 0;            ///< simulated (not mirrored) rows in the plan
  int already_done = 0;           ///< simulated rows that were done before this pass
  int simulations = 0;            ///< jobs that run a simulation
};

/// Planner: adds the rows of `plan` to textile `textile_id`, generation `generation` with parameter text
/// `params` (rows that exist keep their state), marks pending mirror rows whose source failed as failed,
/// and lists the jobs for the pending rows. Throws DrapeDatabaseError.
PassPlan planPass(HangingDrapeDatabase& db, const DrapeBuildConfig& config, const std::vector<PlannedHoldPoint>& plan,
                  std::int64_t textile_id, std::int64_t generation, const std::string& params);

/// Everything the jobs of a pass read (shared by the worker threads, never written during the pass).
struct PassContext {
  const DrapeBuildConfig& config;
  int corner;                                ///< bracket corner 0..3, -1: the nearest particle
  const ParticleGrid& grid;                  ///< the particle grid (bracket corners)
  const std::vector<PlannedHoldPoint>& plan;
  const std::vector<std::int64_t>& ids;      ///< PassPlan::ids
  const BuildMesh& mesh;
  std::vector<double> view_angles;           ///< config.views.angles()
  std::string projection;                    ///< "orthographic" or "pinhole" (stored with each row)
};

/// What a job did.
struct JobOutcome {
  std::string failure;     ///< non-empty: the simulation failed; the source and its mirror rows are marked failed
  double wall_time_s = 0;  ///< the simulation's wall time (a simulated job that succeeded)
  bool superseded = false; ///< another builder stored the job's rows first; nothing was written
};

/// Worker: runs one job. Simulates the source (simulateRow) or loads it (loadDoneRow), derives its
/// mirror rows (mirrorRows) and stores all of them in one transaction. A failed simulation is no
/// exception: it is marked in the database and returned. Rows another builder finished meanwhile are
/// left as they are (JobOutcome::superseded). Throws DrapeDatabaseError (database failures,
/// damaged stored rows), which ends the pass.
/// How a job's simulation runs: simulateRow here, or on a RemoteSimulator.
using RowSimulator = std::function<SimulationResult(const BuildJob& job, std::string* failure)>;

JobOutcome runJob(HangingDrapeDatabase& db, const PassContext& ctx, const BuildJob& job, const RowSimulator& simulate);

/// The simulation of one hold point (retried once with smaller steps when configured) with its views;
/// `simulation_id` set. On failure returns an empty result and the reason in *failure.
SimulationResult simulateRow(const PassContext& ctx, const BuildJob& job, std::string* failure);

/// A done row loaded back (positions, stored metadata and views), as the source of its mirror rows.
/// Throws BlobFormatError if its held particle is not a particle of its positions.
SimulationResult loadDoneRow(HangingDrapeDatabase& db, std::int64_t id);

/// The pass's silhouette views of positions `x` (stacked xyz, m) held at particle `held`; the render
/// wall time [s] in *seconds.
std::vector<ViewInput> renderRowViews(const PassContext& ctx, const VecX& x, Index held, double* seconds);

/// Mirror derivation: the rows `derived` (plan indices of mirror images of source row `source_id`)
/// from the source's result: mirrored positions and held particle, the source's run metadata, and the
/// source's views mirrored (re-rendered if the view set is not closed under the mirror). Throws
/// BlobFormatError if the source's particle count does not match the grid.
std::vector<SimulationResult> mirrorRows(const PassContext& ctx, const SimulationResult& source, std::int64_t source_id,
                                         const std::vector<std::size_t>& derived);

}  // namespace internal
}  // namespace db
}  // namespace textile_handling
